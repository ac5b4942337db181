r"""Saved closed-loop runs: :class:`Trajectory`, CSV + JSON files, and open-loop replay.

A trajectory holds what a run did (``T`` recorded steps): times, states
:math:`x_k = [q_k, v_k, a_k]`, the applied controls :math:`u_k` (noise included), the
task's measures, the sites' world positions, and the initial state, pushes, mismatch and
noise seed.

:func:`save_trajectory` writes two files side by side:

* ``NAME.csv``: one row per step, columns ``time, qpos_0.., qvel_0.., act_0.., ctrl_0..,
  measure_<name>.., site_<name>_x/_y/_z..``, numbers with 17 significant digits (float64
  values load back bit for bit);
* ``NAME.json``: the metadata (problem, controller, task name and options, failure, seed,
  noise, pushes, mismatch, model sizes and timestep, joint, actuator and site names).

:func:`replay` applies the saved controls (noise included) and pushes open loop from the
saved initial state; MuJoCo being deterministic, it reaches the saved final state.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.simulation import SimulationResult
from mpcbox.sim.viewer_choice import as_viewer
from mpcbox.validation import as_array, checked_keywords, instance


class Trajectory(NamedTuple):
    """One closed-loop run, as saved and loaded (``T`` recorded steps).

    Attributes:
        problem: Problem name.
        controller: Controller name.
        time: Times ``(T,)`` (s).
        states: States ``(T, nstate)``, ``[qpos, qvel, act]``.
        ctrls: Applied controls ``(T, nu)`` (noise included); the last row was not applied.
        series: Samples ``(T,)`` of each task measure, by name, in the measure's unit.
        sites: World positions ``(T, 3)`` of the model's named sites (m), by site name.
        failure: Why the run stopped early, or ``None``.
        initial_state: The state the run started from ``(nstate,)``.
        pushes: The pushes of the run.
        mismatch: The model mismatch of the simulated plant, or ``None``.
        noise: The actuator noise (already in ``ctrls``), or ``None``.
        seed: Seed of the noise.
        metadata: Everything else in the JSON sidecar (task name and options, scenario,
            model sizes, names of joints, actuators and sites, ...).
    """

    problem: str
    controller: str
    time: np.ndarray
    states: np.ndarray
    ctrls: np.ndarray
    series: dict[str, np.ndarray]
    sites: dict[str, np.ndarray]
    failure: str | None
    initial_state: np.ndarray
    pushes: tuple[Push, ...]
    mismatch: ModelMismatch | None
    noise: ActuatorNoise | None
    seed: int
    metadata: dict[str, Any]


class Replay(NamedTuple):
    r"""An open-loop re-simulation of a :class:`Trajectory`.

    Attributes:
        time: Times ``(T,)`` (s).
        states: States ``(T, nstate)`` of the re-simulation.
        final_error: :math:`\max_i |x_{T-1,i} - \hat x_{T-1,i}|` between the replayed and the
            saved final state (0 when bit-exact; NaN where either is not finite).
    """

    time: np.ndarray
    states: np.ndarray
    final_error: float


def _names(model: mujoco.MjModel, kind: str, count: int) -> list[str]:
    obj = getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}")
    return [mujoco.mj_id2name(model, obj, i) or str(i) for i in range(count)]


def site_positions(
    problem: Problem, states: np.ndarray, sites: Sequence[str] | None = None
) -> dict[str, np.ndarray]:
    """World positions of sites along a run: forward kinematics of each state.

    Args:
        problem: The Problem whose simulation model the states belong to.
        states: States ``(T, nstate)``.
        sites: Site names (default: every named site of the model).

    Returns:
        ``{site name: positions (T, 3)}`` (m).
    """
    model = problem.model
    if sites is None:
        sites = [n for n in _names(model, "site", model.nsite) if not n.isdigit()]
    ids = [object_id(model, "site", name) for name in sites]
    if not ids:
        return {}
    data = mujoco.MjData(model)
    out = np.full((len(states), len(ids), 3), np.nan)
    nq = problem.nq
    for k, state in enumerate(states):
        if not np.all(np.isfinite(state)):
            continue
        data.qpos[:] = state[:nq]
        mujoco.mj_kinematics(model, data)
        out[k] = data.site_xpos[ids]
    return {name: out[:, i] for i, name in enumerate(sites)}


def make_trajectory(
    problem: Problem,
    *,
    controller: str,
    time: np.ndarray,
    states: np.ndarray,
    ctrls: np.ndarray,
    series: Mapping[str, np.ndarray] | None = None,
    failure: str | None = None,
    pushes: Sequence[Push] = (),
    mismatch: ModelMismatch | None = None,
    noise: ActuatorNoise | None = None,
    seed: int = 0,
    sites: Sequence[str] | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> Trajectory:
    """A :class:`Trajectory` of ``problem`` from recorded arrays (site positions computed).

    Args:
        problem: The Problem that was simulated.
        controller: Controller name.
        time: Times ``(T,)`` (s).
        states: States ``(T, nstate)``.
        ctrls: Applied controls ``(T, nu)``.
        series: Task measure samples ``(T,)`` by name.
        failure: Why the run stopped early, or ``None``.
        pushes: Pushes of the run.
        mismatch: Model mismatch of the simulated plant.
        noise: Actuator noise of the run (already in ``ctrls``).
        seed: Noise seed.
        sites: Sites whose positions are recorded (default: every named site).
        metadata: Extra JSON-serializable entries (e.g. ``{"task": "pendulum_swingup"}``).

    Raises:
        ShapeError: If the arrays do not match the problem's sizes or each other.
    """
    time = as_array("time", time, (None,))
    steps = len(time)
    if steps == 0:
        raise InvalidArgumentError("time must hold at least one step")
    states = as_array("states", states, (steps, problem.nstate))
    ctrls = as_array("ctrls", ctrls, (steps, problem.nu))
    series = {k: as_array(f"series[{k!r}]", v, (steps,)) for k, v in (series or {}).items()}
    model = problem.model
    meta = {
        "nq": problem.nq,
        "nv": problem.nv,
        "na": problem.na,
        "nu": problem.nu,
        "timestep": float(model.opt.timestep),
        "joints": _names(model, "joint", model.njnt),
        "actuators": _names(model, "actuator", model.nu),
    }
    meta.update(dict(metadata or {}))
    return Trajectory(
        problem=problem.name,
        controller=str(controller),
        time=time.copy(),
        states=states.copy(),
        ctrls=ctrls.copy(),
        series=series,
        sites=site_positions(problem, states, sites),
        failure=failure,
        initial_state=states[0].copy(),
        pushes=tuple(pushes),
        mismatch=mismatch,
        noise=noise,
        seed=int(seed),
        metadata=meta,
    )


def trajectory_from_result(
    result: SimulationResult,
    problem: Problem,
    *,
    sites: Sequence[str] | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> Trajectory:
    """The :class:`Trajectory` of a :func:`~mpcbox.simulate` result on ``problem``.

    Args:
        result: The run.
        problem: The Problem it ran on.
        sites: Sites whose positions are recorded (default: every named site).
        metadata: Extra JSON-serializable entries (e.g. the task name and options).
    """
    return make_trajectory(
        problem,
        controller=result.controller,
        time=result.time,
        states=result.states,
        ctrls=result.ctrls,
        series=result.series,
        failure=result.failure,
        pushes=result.pushes,
        mismatch=result.mismatch,
        noise=result.noise,
        seed=result.seed,
        sites=sites,
        metadata=metadata,
    )


# ---------------------------------------------------------------- JSON of the disturbances
def jsonable(value: Any) -> Any:
    """``value`` with arrays and tuples as lists and non-finite floats as ``None``, for JSON."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        return jsonable(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, tuple | list):
        return [jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    return value


def push_to_dict(push: Push) -> dict[str, Any]:
    """A :class:`~mpcbox.Push` as a JSON-ready dict."""
    return {
        "force": jsonable(np.asarray(push.force, dtype=float)),
        "torque": jsonable(np.asarray(push.torque, dtype=float)),
        "start": float(push.start),
        "duration": float(push.duration),
        "body": push.body,
    }


def disturbance_record(traj: Trajectory) -> dict[str, Any]:
    """The seed, pushes, noise and mismatch of ``traj`` as JSON-ready entries."""
    noise = traj.noise
    mismatch = traj.mismatch
    return {
        "seed": traj.seed,
        "pushes": [push_to_dict(p) for p in traj.pushes],
        "noise": None
        if noise is None
        else {"std": jsonable(noise.std), "width": noise.width, "scale": noise.scale},
        "mismatch": None
        if mismatch is None
        else {
            "mass_scale": mismatch.mass_scale,
            "friction_scale": mismatch.friction_scale,
            "body_mass_scale": mismatch.body_mass_scale,
        },
    }


@checked_keywords
def replay(traj: Trajectory, problem: Problem, *, viewer: Any = None) -> Replay:
    """Re-simulate ``traj`` open loop on ``problem``'s simulation model.

    From ``traj.initial_state``, step ``k`` applies ``traj.ctrls[k]`` and the saved pushes
    active at that time (on the model with the saved mismatch), exactly as
    :func:`~mpcbox.simulate` did; ``T - 1`` steps for ``T`` recorded states.

    Args:
        traj: A saved run.
        problem: The Problem it ran on (same sizes and timestep).
        viewer: Shows the replay as it runs: a :class:`~mpcbox.sim.viewer.Viewer`,
            ``"live"`` (a window held to wall-clock time, so the run is seen in real time)
            or a ``.gif`` / ``.mp4`` path (:func:`~mpcbox.sim.viewer_choice.as_viewer`).

    Returns:
        A :class:`Replay` with the re-simulated states and the final-state error.

    Raises:
        InvalidArgumentError: If the problem's sizes or timestep differ from the saved ones.
    """
    instance("traj", traj, Trajectory, "an mpcbox Trajectory (load_trajectory)")
    instance("problem", problem, Problem, "an mpcbox.Problem")
    model = problem.model if traj.mismatch is None else traj.mismatch.apply(problem.model)
    saved = {k: traj.metadata.get(k) for k in ("nq", "nv", "na", "nu", "timestep")}
    have = {
        "nq": problem.nq,
        "nv": problem.nv,
        "na": problem.na,
        "nu": problem.nu,
        "timestep": float(model.opt.timestep),
    }
    for key, value in have.items():
        if saved[key] is not None and saved[key] != value:
            raise InvalidArgumentError(
                f"the trajectory was recorded with {key}={saved[key]}, but problem "
                f"{problem.name!r} has {key}={value}: replay it on the task it ran on"
            )
    data = mujoco.MjData(model)
    problem.set_state(data, traj.initial_state)
    mujoco.mj_forward(model, data)
    push_ids = [object_id(model, "body", p.body) for p in traj.pushes]
    view = as_viewer(viewer)
    if view is not None:
        view.start(problem, None, model, data)  # a replay has no planner
    steps = len(traj.time)
    times = np.empty(steps)
    states = np.empty((steps, problem.nstate))
    try:
        for k in range(steps):
            times[k] = data.time
            states[k] = problem.get_state(data)
            if view is not None:
                view.step(data)
            if k == steps - 1:
                break
            data.ctrl[:] = traj.ctrls[k]
            data.xfrc_applied[:] = 0.0
            for push, bid in zip(traj.pushes, push_ids):
                if push.active(float(data.time)):
                    data.xfrc_applied[bid] += push.wrench()
            mujoco.mj_step(model, data)
    finally:
        if view is not None:
            view.finish()
    diff = np.abs(states[-1] - traj.states[-1])
    error = float(np.max(diff)) if np.all(np.isfinite(diff)) else math.nan
    return Replay(times, states, error)


__all__ = [
    "Replay",
    "Trajectory",
    "disturbance_record",
    "jsonable",
    "make_trajectory",
    "push_to_dict",
    "replay",
    "site_positions",
    "trajectory_from_result",
]
