"""Closed-loop simulation of a Problem under a Controller, with disturbances and metrics.

:func:`simulate` reports what every run has (survival, cost, control effort, compute time,
controller statistics) in :class:`Metrics`, plus the task's own measures
(:meth:`~mpcbox.Problem.measures`, :mod:`mpcbox.sim.measures`) sampled at every step.
"""

from __future__ import annotations

import time as _time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.errors import MpcboxError, PeriodWarning
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.divergence import DivergenceMonitor
from mpcbox.sim.measures import Measure
from mpcbox.sim.run_start import controller_count, controller_fallbacks, start_run
from mpcbox.sim.viewer import Viewer
from mpcbox.sim.viewer_choice import as_viewer
from mpcbox.validation import (
    checked_keywords,
    positive,
)

#: Outcomes of a run, in :attr:`Metrics.outcome`.
OUTCOMES: dict[str, str] = {
    "success": "no failure, the task's goal met, the controller mostly did its own work",
    "failed": "the task's failure (a fall, for example) before the end",
    "diverged": "the simulation blew up (MuJoCo warning or reset, non-finite state)",
    "controller error": "the controller raised or returned an invalid control",
    "goal missed": "survived but missed the task's goal (Problem.goal_failure)",
    "degraded": "survived, but more than the allowed share of the controller's solves fell back",
}


class Metrics(NamedTuple):
    r"""Summary of one closed-loop run.

    Attributes:
        survived: No failure (fall, divergence, controller error) before the end.
        time_to_fall: Time of the failure, or the duration when the run survived (s).
        cost: Mean running cost :math:`\frac1N \sum_k \ell(x_k, u_k)` of the task's cost
            over the ``N`` applied controls (NaN when a state is not finite).
        control_effort: RMS of the applied controls over time and actuators.
        compute_mean_ms: Mean time of the controller's online solves (ms); calls that only
            held the plan and offline solves are left out (see ``held_ticks``,
            ``offline_ms``).
        compute_p50_ms: Median time of the online solves (ms).
        compute_p99_ms: 99th percentile time of the online solves (ms).
        realtime_factor: Simulated seconds per wall-clock second (controller included).
        fallbacks: Controller fallbacks (failed solves, divergences) in this run, from the
            change of its ``stats["fallbacks"]``.
        stalls: Solves that found no step improving on their warm start and kept it (an
            iLQR replan that keeps the last feedback law), from the change of the
            controller's ``stats["stalled"]``; 0 for a controller that counts none. Not
            failures, but a controller that stalls on most solves adds little to its law.
        measures: Summaries of the task's measures over the run, by
            :meth:`~mpcbox.sim.measures.Measure.key` (e.g. ``"tilt_rms_deg"``), in their
            units; empty when the task declares none.
        success: ``outcome == "success"``.
        outcome: One of :data:`OUTCOMES`.
        degraded_ticks: Calls whose solve fell back (equal to ``fallbacks``).
        solve_ticks: Calls that solved online (``Controller.last_call == "solve"``).
        held_ticks: Calls that followed the current plan without solving.
        offline_ms: Total time of offline solves (ms), e.g. IPOPT's before the loop.
        period_s: The budget of one online solve: seconds between the controller's solves,
            its ``replan_period`` when it has one (a controller that adds feedback between
            solves is called more often), else seconds between calls (the simulation step
            when the controller sets no ``period``).
        kept_up: Real-time runs (:func:`mpcbox.sim.realtime.simulate_realtime`): whether
            the planner's p99 tick fit in ``period_s``; ``None`` for lock-step runs.
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
    success: bool = False
    outcome: str = "success"
    degraded_ticks: int = 0
    solve_ticks: int = 0
    held_ticks: int = 0
    offline_ms: float = 0.0
    period_s: float = 0.0
    kept_up: bool | None = None
    stalls: int = 0


@dataclass
class SimulationResult:
    """Time series and metrics of one closed-loop run (``T`` recorded steps).

    Attributes:
        problem: Problem name.
        controller: Controller name.
        time: Times ``(T,)`` (s).
        states: States ``(T, nstate)``.
        ctrls: Applied controls ``(T, nu)``; the last row holds no applied control.
        compute_times: Time of each online solve ``(solves,)`` (s); held and offline
            calls are counted in :class:`Metrics` but not listed here.
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


@checked_keywords
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
    degraded_limit: float = 0.5,
    viewer: Viewer | str | Path | None = None,
) -> SimulationResult:
    """Simulate ``problem.model`` in closed loop with ``controller``.

    The controller is called every ``controller.period`` seconds (rounded to whole simulation
    steps, with a :class:`~mpcbox.errors.PeriodWarning` when that changes it; every step when
    ``None``) and its control is held in between. Actuator noise is
    added to the held control at every step; MuJoCo clamps the sum to ``ctrlrange``.

    A run ends as one of :data:`OUTCOMES`:

    - ``"diverged"``: MuJoCo warned about a NaN, infinite or huge acceleration, position,
      velocity or control (and reset the state or zeroed the control), time failed to
      advance, or the state is not finite (:class:`~mpcbox.sim.divergence.DivergenceMonitor`);
    - ``"controller error"``: the controller raised (any exception; the message is kept in
      ``failure``) or returned a control of the wrong shape or not finite;
    - ``"failed"``: :meth:`Problem.failure <mpcbox.Problem.failure>` reported a failure
      (a fall);
    - ``"goal missed"``: none of the above, but
      :meth:`Problem.goal_failure <mpcbox.Problem.goal_failure>` says the task's goal was not
      met (a pole left hanging, an arm short of its target);
    - ``"degraded"``: none of the above, but more than ``degraded_limit`` of the
      controller's solves (calls that solved, not those that held a plan) fell back
      (``stats["fallbacks"]``): the run is not that controller's success;
    - ``"success"`` otherwise.

    Whatever ends the run, the trajectory recorded up to that point is kept.

    Args:
        problem: The Problem (its simulation model is simulated).
        controller: The controller; ``reset()`` is called first.
        duration: Simulated time (s).
        noise: Smooth actuator noise, sampled with ``seed``.
        pushes: Forces applied to bodies over time intervals.
        mismatch: Changes to the simulated model that the controller does not know about.
        seed: Seed of the noise (numpy's legacy generator, as in the published recipe).
        initial_state: Start state (default ``problem.initial_state()``).
        stop_on_failure: Stop at the first task failure (falls; divergence and controller
            errors always stop the run).
        degraded_limit: Largest share of fallbacks among the controller's solves, in
            ``[0, 1]``, for a run to count as a success.
        viewer: Show the run while it goes (:mod:`mpcbox.sim.viewer`): a
            :class:`~mpcbox.sim.viewer.Viewer`, ``"live"`` (a window), ``"auto"`` or a
            ``.gif`` / ``.mp4`` path (:func:`~mpcbox.sim.viewer_choice.as_viewer`). It draws
            the state before each step, with a sampling controller's best traces.

    Returns:
        A :class:`SimulationResult`.
    """
    view = as_viewer(viewer)
    run = start_run(
        problem,
        controller,
        duration,
        noise=noise,
        pushes=pushes,
        mismatch=mismatch,
        seed=seed,
        initial_state=initial_state,
        stop_on_failure=stop_on_failure,
        degraded_limit=degraded_limit,
    )
    model, data, dt, steps = run.model, run.data, run.dt, run.steps
    pushes, push_ids, measures, noise_seq = run.pushes, run.push_ids, run.measures, run.noise
    duration, degraded_limit = run.duration, run.degraded_limit
    stop_on_failure, fallbacks0 = run.stop_on_failure, run.fallbacks0
    period = getattr(controller, "period", None)
    every = 1 if period is None else max(1, round(positive("controller.period", period) / dt))
    if period is not None and abs(every * dt - period) > 1e-9 * max(1.0, period):
        warnings.warn(
            f"controller.period {period:g} s is not a whole number of simulation steps of "
            f"{dt:g} s; the controller is called every {every * dt:g} s",
            PeriodWarning,
            stacklevel=2,
        )

    times = np.empty(steps + 1)
    states = np.empty((steps + 1, problem.nstate))
    ctrls = np.zeros((steps + 1, problem.nu))
    samples = np.empty((len(measures), steps + 1))
    calls: dict[str, list[float]] = {"solve": [], "hold": [], "offline": []}
    failure: str | None = None
    outcome = "success"
    fail_time = duration
    ctrl = problem.ctrl_ref.copy()
    monitor = DivergenceMonitor(data)
    if view is not None:
        view.start(problem, controller, model, data)
    wall0 = _time.perf_counter()
    last = steps
    try:
        for k in range(steps + 1):
            times[k] = data.time
            states[k] = problem.get_state(data)
            for i, measure in enumerate(measures):
                samples[i, k] = measure.sample(model, data)
            if failure is None:
                reason = problem.failure(model, data)
                if reason is not None:
                    failure, fail_time, outcome = reason, float(data.time), "failed"
                    if reason.startswith("non-finite"):
                        outcome = "diverged"
                    if stop_on_failure or outcome == "diverged":
                        last = k
                        break
            if k == steps:
                break
            if k % every == 0:
                t0 = _time.perf_counter()
                try:
                    out = controller(states[k].copy(), float(data.time))
                except Exception as exc:  # any controller error ends the run, recorded
                    failure, fail_time, last = _error_text(exc), float(data.time), k
                    outcome = "controller error"
                    break
                kind = getattr(controller, "last_call", "solve")
                calls[kind if kind in calls else "solve"].append(_time.perf_counter() - t0)
                out = np.asarray(out, dtype=np.float64)
                if out.shape != (problem.nu,) or not np.all(np.isfinite(out)):
                    failure, fail_time, last = (
                        f"controller returned an invalid control (shape {out.shape}, finite="
                        f"{bool(np.all(np.isfinite(out)))})",
                        float(data.time),
                        k,
                    )
                    outcome = "controller error"
                    break
                ctrl = out
            if view is not None:
                view.step(data)
            data.ctrl[:] = problem.clip_ctrl(ctrl + noise_seq[k])
            ctrls[k] = data.ctrl
            data.xfrc_applied[:] = 0.0
            for push, bid in zip(pushes, push_ids):
                if push.active(float(data.time)):
                    data.xfrc_applied[bid] += push.wrench()
            monitor.before_step()
            mujoco.mj_step(model, data)
            reason = monitor.after_step()
            if reason is not None:
                # Keep the step that diverged in the record: what MuJoCo left (often a reset).
                failure, fail_time, outcome = reason, float(times[k]), "diverged"
                last = k
                break
    finally:
        wall = _time.perf_counter() - wall0
        if view is not None:
            view.finish()
    return finish_run(
        problem,
        controller,
        duration=duration,
        times=times[: last + 1],
        states=states[: last + 1],
        ctrls=ctrls[: last + 1],
        samples=samples[:, : last + 1],
        measures=measures,
        calls=calls,
        failure=failure,
        outcome=outcome,
        fail_time=fail_time,
        wall=wall,
        fallbacks0=fallbacks0,
        stalls0=run.stalls0,
        degraded_limit=degraded_limit,
        period_s=float(getattr(controller, "replan_period", None) or every * dt),
        pushes=pushes,
        mismatch=mismatch,
        noise=noise,
        seed=seed,
    )


def finish_run(
    problem: Problem,
    controller: Controller,
    *,
    duration: float,
    times: np.ndarray,
    states: np.ndarray,
    ctrls: np.ndarray,
    samples: np.ndarray,
    measures: tuple[Measure, ...],
    calls: dict[str, list[float]],
    failure: str | None,
    outcome: str,
    fail_time: float,
    wall: float,
    fallbacks0: float,
    degraded_limit: float,
    period_s: float,
    pushes: tuple[Push, ...],
    mismatch: ModelMismatch | None,
    noise: ActuatorNoise | None,
    seed: int,
    kept_up: bool | None = None,
    stalls0: float = 0.0,
) -> SimulationResult:
    """The :class:`SimulationResult` of a finished loop (shared by :func:`simulate` and the
    real-time loop, :mod:`mpcbox.sim.realtime`).

    Args:
        problem: The Problem.
        controller: The controller (its ``stats`` are read).
        duration: The asked duration (s).
        times: Recorded times ``(T,)``.
        states: Recorded states ``(T, nstate)``.
        ctrls: Applied controls ``(T, nu)``.
        samples: Measure samples ``(len(measures), T)``.
        measures: The task's measures.
        calls: Durations (s) of the controller's calls by ``last_call`` kind.
        failure: Why the loop stopped, or ``None``.
        outcome: The loop's outcome so far (goal and degradation are checked here).
        fail_time: Time of the failure (s).
        wall: Wall time of the loop (s).
        fallbacks0: The controller's fallback counter before the loop.
        degraded_limit: Largest share of fallbacks for a success.
        period_s: Seconds between controller calls.
        pushes: The pushes applied.
        mismatch: The model mismatch.
        noise: The actuator noise.
        seed: The noise seed.
        kept_up: Real-time runs: whether the planner kept up (:attr:`Metrics.kept_up`).
        stalls0: The controller's stall counter before the loop.
    """
    n = times.shape[0]
    series = {m.name: samples[i] for i, m in enumerate(measures)}
    summaries: dict[str, float] = {}
    for measure in measures:
        summaries.update(measure.summarize(series[measure.name], times))
    stats = dict(getattr(controller, "stats", {}) or {})
    fallbacks = max(0, round(controller_fallbacks(controller) - fallbacks0))
    stalls = max(0, round(controller_count(controller, "stalled") - stalls0))
    # The share is of the calls that solved: held calls (feedback between solves) cannot
    # fall back and would dilute it.
    ncalls = len(calls["solve"]) + len(calls["offline"]) or sum(len(v) for v in calls.values())
    if failure is None:
        goal = problem.goal_failure(times, states)
        if goal is not None:
            failure, outcome = goal, "goal missed"
        elif ncalls and fallbacks > degraded_limit * ncalls:
            failure = f"degraded: {fallbacks} of {ncalls} controller solves fell back"
            outcome = "degraded"
    ctimes = np.asarray(calls["solve"])
    sim_time = float(times[-1]) if n else 0.0
    applied = max(1, n - 1)
    survived = outcome in ("success", "goal missed", "degraded")
    metrics = Metrics(
        survived=survived,
        time_to_fall=duration if survived else fail_time,
        cost=_mean_cost(problem, states[:applied], ctrls[:applied]),
        control_effort=float(np.sqrt(np.mean(ctrls[:applied] ** 2))),
        compute_mean_ms=float(ctimes.mean() * 1e3) if ctimes.size else 0.0,
        compute_p50_ms=float(np.percentile(ctimes, 50) * 1e3) if ctimes.size else 0.0,
        compute_p99_ms=float(np.percentile(ctimes, 99) * 1e3) if ctimes.size else 0.0,
        realtime_factor=sim_time / wall if wall > 0 else float("inf"),
        fallbacks=fallbacks,
        measures=summaries,
        success=outcome == "success",
        outcome=outcome,
        degraded_ticks=fallbacks,
        solve_ticks=len(calls["solve"]),
        held_ticks=len(calls["hold"]),
        offline_ms=float(sum(calls["offline"]) * 1e3),
        period_s=period_s,
        kept_up=kept_up,
        stalls=stalls,
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


def _error_text(exc: BaseException) -> str:
    """``"controller error: <type>: <message>"``; the type is left out for mpcbox errors."""
    if isinstance(exc, MpcboxError):
        return f"controller error: {exc}"
    return f"controller error: {type(exc).__name__}: {exc}"


def _mean_cost(problem: Problem, states: np.ndarray, ctrls: np.ndarray) -> float:
    """Mean running cost over the rows of ``states`` ``(N, nstate)`` and ``ctrls`` ``(N, nu)``.

    Each row is evaluated on the planning model (``mj_forward``, then the cost's features);
    NaN when a row is not finite or cannot be evaluated (a control beyond MuJoCo's limit).
    """
    if not (np.all(np.isfinite(states)) and np.all(np.isfinite(ctrls))):
        return float("nan")
    try:
        return float(np.mean([problem.running_cost(x, u) for x, u in zip(states, ctrls)]))
    except MpcboxError:
        return float("nan")
