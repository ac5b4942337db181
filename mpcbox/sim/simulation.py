"""Closed-loop simulation of a Problem under a Controller, with disturbances and metrics.

:func:`simulate` reports what every run has (survival, cost, control effort, compute time,
controller statistics) in :class:`Metrics`, plus the task's own measures
(:meth:`~mpcbox.Problem.measures`, :mod:`mpcbox.sim.measures`) sampled at every step.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, MpcboxError
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.measures import Measure, check_measures
from mpcbox.validation import as_array, positive


class Metrics(NamedTuple):
    r"""Summary of one closed-loop run.

    Attributes:
        survived: No failure (fall, non-finite state) before the end.
        time_to_fall: Time of the failure, or the duration when the run survived (s).
        cost: Mean running cost :math:`\frac1N \sum_k \ell(x_k, u_k)` of the task's cost
            over the ``N`` applied controls (NaN when a state is not finite).
        control_effort: RMS of the applied controls over time and actuators.
        compute_mean_ms: Mean controller time per call (ms).
        compute_p50_ms: Median controller time per call (ms).
        compute_p99_ms: 99th percentile controller time per call (ms).
        realtime_factor: Simulated seconds per wall-clock second (controller included).
        fallbacks: Controller fallbacks (failed solves, divergences), from its ``stats``.
        measures: Summaries of the task's measures over the run, by
            :meth:`~mpcbox.sim.measures.Measure.key` (e.g. ``"tilt_rms_deg"``), in their
            units; empty when the task declares none.
    """

    survived: bool
    time_to_fall: float
    cost: float
    control_effort: float
    compute_mean_ms: float
    compute_p50_ms: float
    compute_p99_ms: float
    realtime_factor: float
    fallbacks: int
    measures: dict[str, float]


@dataclass
class SimulationResult:
    """Time series and metrics of one closed-loop run (``T`` recorded steps).

    Attributes:
        problem: Problem name.
        controller: Controller name.
        time: Times ``(T,)`` (s).
        states: States ``(T, nstate)``.
        ctrls: Applied controls ``(T, nu)``; the last row holds no applied control.
        compute_times: Controller time per call ``(calls,)`` (s).
        failure: Why the run stopped early, or ``None``.
        metrics: The run's :class:`Metrics`.
        series: Samples ``(T,)`` of each task measure, by measure name, in its unit.
        measures: The task's measures (:meth:`~mpcbox.Problem.measures`).
        controller_stats: The controller's ``stats`` after the run.
        pushes: The pushes applied during the run.
        mismatch: The model mismatch of the simulated plant, or ``None``.
        noise: The actuator noise (already added to ``ctrls``), or ``None``.
        seed: Seed of the noise.
    """

    problem: str
    controller: str
    time: np.ndarray
    states: np.ndarray
    ctrls: np.ndarray
    compute_times: np.ndarray
    failure: str | None
    metrics: Metrics
    series: dict[str, np.ndarray] = field(default_factory=dict)
    measures: tuple[Measure, ...] = ()
    controller_stats: dict[str, float] = field(default_factory=dict)
    pushes: tuple[Push, ...] = ()
    mismatch: ModelMismatch | None = None
    noise: ActuatorNoise | None = None
    seed: int = 0

    @property
    def survived(self) -> bool:
        """Shortcut for ``metrics.survived``."""
        return self.metrics.survived


def simulate(
    problem: Problem,
    controller: Controller,
    duration: float,
    *,
    noise: ActuatorNoise | None = None,
    pushes: Sequence[Push] = (),
    mismatch: ModelMismatch | None = None,
    seed: int = 0,
    initial_state: np.ndarray | None = None,
    stop_on_failure: bool = True,
) -> SimulationResult:
    """Simulate ``problem.model`` in closed loop with ``controller``.

    The controller is called every ``controller.period`` seconds (rounded to whole simulation
    steps; every step when ``None``) and its control is held in between. Actuator noise is
    added to the held control at every step; MuJoCo clamps the sum to ``ctrlrange``.

    Args:
        problem: The Problem (its simulation model is simulated).
        controller: The controller; ``reset()`` is called first.
        duration: Simulated time (s).
        noise: Smooth actuator noise, sampled with ``seed``.
        pushes: Forces applied to bodies over time intervals.
        mismatch: Changes to the simulated model that the controller does not know about.
        seed: Seed of the noise (numpy's legacy generator, as in the published recipe).
        initial_state: Start state (default ``problem.initial_state()``).
        stop_on_failure: Stop at the first failure reported by ``problem.failure``.

    Returns:
        A :class:`SimulationResult`.
    """
    duration = positive("duration", duration)
    if not isinstance(controller, Controller) and not callable(controller):
        raise InvalidArgumentError(
            f"controller must be an mpcbox.Controller, got {type(controller)}"
        )
    for push in pushes:
        if not isinstance(push, Push):
            raise InvalidArgumentError(f"pushes must hold Push objects, got {type(push).__name__}")
    model = problem.model if mismatch is None else mismatch.apply(problem.model)
    data = mujoco.MjData(model)
    dt = float(model.opt.timestep)
    steps = math.ceil(duration / dt - 1e-9)
    state0 = problem.initial_state() if initial_state is None else initial_state
    state0 = as_array("initial_state", state0, (problem.nstate,))
    problem.set_state(data, state0)
    mujoco.mj_forward(model, data)
    push_ids = [object_id(model, "body", p.body) for p in pushes]
    measures = check_measures(problem.measures(), type(problem).__name__)

    period = getattr(controller, "period", None)
    every = 1 if period is None else max(1, round(positive("controller.period", period) / dt))
    noise_seq = (
        np.zeros((steps, problem.nu))
        if noise is None
        else noise.sample(steps, problem.nu, dt, seed)
    )
    if hasattr(controller, "reset"):
        controller.reset()

    times = np.empty(steps + 1)
    states = np.empty((steps + 1, problem.nstate))
    ctrls = np.zeros((steps + 1, problem.nu))
    samples = np.empty((len(measures), steps + 1))
    compute: list[float] = []
    failure: str | None = None
    fail_time = duration
    ctrl = problem.ctrl_ref.copy()
    wall0 = _time.perf_counter()
    last = steps
    for k in range(steps + 1):
        times[k] = data.time
        states[k] = problem.get_state(data)
        for i, measure in enumerate(measures):
            samples[i, k] = measure.sample(model, data)
        reason = problem.failure(model, data)
        if reason is not None:
            failure, fail_time = reason, float(data.time)
            if stop_on_failure:
                last = k
                break
        if k == steps:
            break
        if k % every == 0:
            t0 = _time.perf_counter()
            try:
                out = controller(states[k].copy(), float(data.time))
            except MpcboxError as exc:
                failure, fail_time, last = f"controller error: {exc}", float(data.time), k
                break
            compute.append(_time.perf_counter() - t0)
            out = np.asarray(out, dtype=np.float64)
            if out.shape != (problem.nu,) or not np.all(np.isfinite(out)):
                failure, fail_time, last = (
                    f"controller returned an invalid control (shape {out.shape}, finite="
                    f"{bool(np.all(np.isfinite(out)))})",
                    float(data.time),
                    k,
                )
                break
            ctrl = out
        data.ctrl[:] = problem.clip_ctrl(ctrl + noise_seq[k])
        ctrls[k] = data.ctrl
        data.xfrc_applied[:] = 0.0
        for push, bid in zip(pushes, push_ids):
            if push.active(float(data.time)):
                data.xfrc_applied[bid] += push.wrench()
        mujoco.mj_step(model, data)
    wall = _time.perf_counter() - wall0

    n = last + 1
    times, states, ctrls, samples = times[:n], states[:n], ctrls[:n], samples[:, :n]
    series = {m.name: samples[i] for i, m in enumerate(measures)}
    summaries: dict[str, float] = {}
    for measure in measures:
        summaries.update(measure.summarize(series[measure.name]))
    ctimes = np.asarray(compute)
    stats = dict(getattr(controller, "stats", {}) or {})
    sim_time = float(times[-1]) if n else 0.0
    applied = max(1, n - 1)
    metrics = Metrics(
        survived=failure is None,
        time_to_fall=fail_time if failure is not None else duration,
        cost=_mean_cost(problem, states[:applied], ctrls[:applied]),
        control_effort=float(np.sqrt(np.mean(ctrls[:applied] ** 2))),
        compute_mean_ms=float(ctimes.mean() * 1e3) if ctimes.size else 0.0,
        compute_p50_ms=float(np.percentile(ctimes, 50) * 1e3) if ctimes.size else 0.0,
        compute_p99_ms=float(np.percentile(ctimes, 99) * 1e3) if ctimes.size else 0.0,
        realtime_factor=sim_time / wall if wall > 0 else float("inf"),
        fallbacks=round(stats.get("fallbacks", 0)),
        measures=summaries,
    )
    return SimulationResult(
        problem=problem.name,
        controller=getattr(controller, "name", type(controller).__name__),
        time=times,
        states=states,
        ctrls=ctrls,
        compute_times=ctimes,
        failure=failure,
        metrics=metrics,
        series=series,
        measures=measures,
        controller_stats=stats,
        pushes=tuple(pushes),
        mismatch=mismatch,
        noise=noise,
        seed=seed,
    )


def _mean_cost(problem: Problem, states: np.ndarray, ctrls: np.ndarray) -> float:
    """Mean running cost over the rows of ``states`` ``(N, nstate)`` and ``ctrls`` ``(N, nu)``.

    Each row is evaluated on the planning model (``mj_forward``, then the cost's features);
    NaN when a row is not finite.
    """
    if not (np.all(np.isfinite(states)) and np.all(np.isfinite(ctrls))):
        return float("nan")
    return float(np.mean([problem.running_cost(x, u) for x, u in zip(states, ctrls)]))
