"""The start of a closed-loop run, shared by :func:`~mpcbox.sim.simulation.simulate` and
:func:`~mpcbox.sim.realtime.simulate_realtime`: argument checks with named errors, the
simulated model and data at the initial state, the noise sequence and the controller's reset.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.measures import Measure, check_measures
from mpcbox.validation import boolean, in_range, instance, positive
from mpcbox.validation import seed as check_seed


class RunStart(NamedTuple):
    """A closed-loop run, checked and set up (what :func:`simulate` and
    :func:`~mpcbox.sim.realtime.simulate_realtime` share before their loops).

    Attributes:
        model: The simulated model (with the mismatch applied).
        data: Its data, at the initial state after ``mj_forward``.
        dt: Simulation timestep (s).
        steps: Simulation steps of the run.
        state0: The initial state ``(nstate,)``.
        pushes: The pushes, as a tuple.
        push_ids: Body id of each push.
        measures: The task's measures.
        noise: Actuator noise per step ``(steps, nu)`` (zeros without noise).
        fallbacks0: The controller's fallback counter after its ``reset()``.
        duration: Simulated time (s), checked.
        degraded_limit: Checked ``degraded_limit``.
        stop_on_failure: Checked ``stop_on_failure``.
        stalls0: The controller's stall counter (``stats["stalled"]``) after its
            ``reset()``.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    dt: float
    steps: int
    state0: np.ndarray
    pushes: tuple[Push, ...]
    push_ids: list[int]
    measures: tuple[Measure, ...]
    noise: np.ndarray
    fallbacks0: float
    duration: float
    degraded_limit: float
    stop_on_failure: bool
    stalls0: float = 0.0


def start_run(
    problem: Problem,
    controller: Controller,
    duration: float,
    *,
    noise: ActuatorNoise | None,
    pushes: Sequence[Push],
    mismatch: ModelMismatch | None,
    seed: int,
    initial_state: np.ndarray | None,
    stop_on_failure: bool,
    degraded_limit: float,
) -> RunStart:
    """Check the arguments of a closed-loop run (named errors), build the simulated model
    and data at the initial state, sample the noise and reset the controller.

    The arguments are those of :func:`simulate`.
    """
    instance("problem", problem, Problem, "an mpcbox.Problem")
    duration = positive("duration", duration)
    if isinstance(controller, type):
        raise InvalidTypeError(
            f"controller must be a controller instance, got the class {controller.__name__}; "
            f"build it first, e.g. {controller.__name__}(problem)"
        )
    if not isinstance(controller, Controller) and not callable(controller):
        raise InvalidTypeError(f"controller must be an mpcbox.Controller, got {type(controller)}")
    seed = check_seed("seed", seed)
    degraded_limit = in_range(
        "degraded_limit", degraded_limit, 0.0, 1.0, low_open=False, high_open=False
    )
    stop_on_failure = boolean("stop_on_failure", stop_on_failure)
    if noise is not None:
        instance("noise", noise, ActuatorNoise, "an mpcbox.ActuatorNoise")
    if mismatch is not None:
        instance("mismatch", mismatch, ModelMismatch, "an mpcbox.ModelMismatch")
    if isinstance(pushes, (str, bytes)) or not isinstance(pushes, Sequence):
        raise InvalidTypeError(f"pushes must be a sequence of Push, got {type(pushes).__name__}")
    pushes = tuple(pushes)
    for push in pushes:
        if not isinstance(push, Push):
            raise InvalidTypeError(f"pushes must hold Push objects, got {type(push).__name__}")
    model = problem.model if mismatch is None else mismatch.apply(problem.model)
    data = mujoco.MjData(model)
    dt = float(model.opt.timestep)
    if duration < dt * (1 - 1e-9):
        raise InvalidArgumentError(
            f"duration must be at least one simulation step (the model's timestep, {dt:g} s), "
            f"got {duration:g}"
        )
    steps = math.ceil(duration / dt - 1e-9)
    state0 = problem.initial_state() if initial_state is None else initial_state
    state0 = problem.check_state(state0, "initial_state")
    problem.set_state(data, state0)
    mujoco.mj_forward(model, data)
    push_ids = [object_id(model, "body", p.body, f"pushes[{i}].body") for i, p in enumerate(pushes)]
    late = [i for i, p in enumerate(pushes) if p.start >= steps * dt]
    if late:
        warnings.warn(
            f"pushes{late} start at or after the run's end ({steps * dt:g} s) and are never "
            "applied (Push.start defaults to 1 s)",
            UserWarning,
            stacklevel=3,
        )
    measures = check_measures(problem.measures(), type(problem).__name__)

    noise_seq = (
        np.zeros((steps, problem.nu))
        if noise is None
        else noise.sample(steps, problem.nu, dt, seed)
    )
    if not np.all(np.isfinite(noise_seq)):
        raise InvalidArgumentError("noise produced non-finite samples: check its std values")
    if hasattr(controller, "reset"):
        controller.reset()
    fallbacks0 = controller_fallbacks(controller)
    stalls0 = controller_count(controller, "stalled")
    return RunStart(
        model,
        data,
        dt,
        steps,
        state0,
        pushes,
        push_ids,
        measures,
        noise_seq,
        fallbacks0,
        duration,
        degraded_limit,
        stop_on_failure,
        stalls0,
    )


def controller_count(controller: Controller, key: str) -> float:
    """The controller's ``stats[key]`` counter (0 when it keeps none)."""
    try:
        return float((getattr(controller, "stats", {}) or {}).get(key, 0.0))
    except Exception:  # a broken stats property must not end the run
        return 0.0


def controller_fallbacks(controller: Controller) -> float:
    """The controller's fallback counter (0 when it keeps none)."""
    return controller_count(controller, "fallbacks")


__all__ = ["RunStart", "controller_count", "controller_fallbacks", "start_run"]
