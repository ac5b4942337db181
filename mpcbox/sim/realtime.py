r"""An asynchronous, real-time closed loop: the world does not wait for the planner.

:func:`simulate` calls the controller and steps the world in lock-step, so a slow planner
gets a world that freezes while it thinks. :func:`simulate_realtime` runs them concurrently,
as on a robot:

- the **world** (the calling thread) advances the simulation model in wall-clock time: step
  ``k`` (simulated time :math:`t_k = k\,\delta t`) happens at wall time
  :math:`w_0 + t_k / \text{speed}`; it sleeps when early and never waits for the planner
  (when the world itself is slower than that, it falls behind, reported as ``world_lag_s``);
- the **planner** (a thread of its own) repeatedly takes the latest state
  :math:`(x(t_s), t_s)`, calls ``controller(x, t_s)`` and publishes the plan; a new tick
  starts ``period`` simulated seconds after the previous one, or at once when that one
  finished late;
- the **executed control** at world time :math:`t` is the latest plan at :math:`t`: for a
  controller with a spline plan (the sampling controllers: ``spline`` and ``knots``
  attributes) the plan's knots, copied when published, evaluated :math:`t - t_s` seconds
  into the plan; for a controller with a feedback law (iLQR-MPC's ``policy()``, see
  :mod:`mpcbox.controllers.ilqr.policy`) that law at the world's current state and time, so
  the feedback goes on at every step while the next replan runs, and the planner ticks only
  every ``replan_period``; for any other controller the control it returned, held. A sampling
  controller's LQR catch (``catch="lqr"``) is applied by the world to its current state at
  every step, as the controller applies it in :func:`simulate`.

Latency is part of the experiment. For tick :math:`i` started at simulated time
:math:`t_{s,i}` and taking :math:`\ell_i` wall seconds, the simulated time that passes is
:math:`a_i = \ell_i \cdot \text{speed}` (the *state age* at publication: how old the state
the plan starts from is when the plan takes over). A tick is *over the period* when
:math:`a_i > p` (the controller's ``period``, or the simulation step without one), and the
planner *kept up* when the 99th percentile of :math:`a_i` is at most :math:`p`.

With ``lookahead`` (:mod:`mpcbox.sim.lookahead`) each tick plans from the state predicted
:math:`L` seconds ahead under the previous plan, and the world switches to the new plan at
:math:`t_s + L`: a plan then starts about when it is published instead of :math:`a_i` late.
The state age and "kept up" are measured as without it (a tick's wall time, prediction
included, against the period).

With ``delay`` the world runs without the wall clock: it waits for each tick, as
:func:`simulate` does, each tick takes ``delay`` simulated seconds and the next one starts
when it is done (or a period after it started), so the same latency gives the same run on
any machine.

Outcomes are those of :func:`simulate`; an exception raised in the planner thread ends the
run as ``"controller error"`` with the trajectory up to that point. The planner thread is
always joined before returning (also when the world raises).
"""

from __future__ import annotations

import gc
import math
import sys
import time as _time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, PeriodWarning
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.divergence import DivergenceMonitor
from mpcbox.sim.lookahead import check_lookahead, whole_steps
from mpcbox.sim.planner_thread import PlannerThread
from mpcbox.sim.run_start import start_run
from mpcbox.sim.simulation import SimulationResult, finish_run
from mpcbox.sim.viewer import Viewer
from mpcbox.sim.viewer_choice import as_viewer
from mpcbox.validation import boolean, checked_keywords, non_negative, positive

#: Python's thread switch interval during a real-time run (s).
GIL_SWITCH_INTERVAL_S = 5e-4


class RealtimeStats(NamedTuple):
    """Timing of the planner in a real-time run.

    Attributes:
        ticks: Planner ticks published during the run (the priming tick excluded).
        latency_ms: Wall time of each tick ``(ticks,)`` (ms).
        state_age_s: Simulated time between each tick's state and its publication
            ``(ticks,)`` (s).
        latency_p50_ms: Median tick latency (ms).
        latency_p99_ms: 99th percentile tick latency (ms).
        state_age_mean_s: Mean state age at publication (s).
        over_period: Ticks whose state age exceeded the period.
        over_period_share: ``over_period / ticks`` (0 without ticks).
        kept_up: The 99th percentile state age is at most the period (and there were ticks).
        period_s: The period the planner had to keep (s).
        speed: Simulated seconds per wall-clock second the world was asked to keep.
        sim_time_s: Simulated time reached (s).
        wall_time_s: Wall time of the world loop (s).
        world_lag_s: Largest lag of the world behind its wall-clock schedule (s of wall
            time); near zero when the simulation itself keeps up with ``speed``.
        prime_ms: Wall time of the priming tick before the clock started (ms; 0 without).
        lookahead_s: Simulated time each tick planned ahead of its observed state
            ``(ticks,)`` (s; zeros without ``lookahead``).
        lookahead_mean_s: Mean of ``lookahead_s`` (0 without ticks).
        delay_s: The simulated latency of the run (``delay``), or ``None`` (wall clock).
    """

    ticks: int
    latency_ms: np.ndarray
    state_age_s: np.ndarray
    latency_p50_ms: float
    latency_p99_ms: float
    state_age_mean_s: float
    over_period: int
    over_period_share: float
    kept_up: bool
    period_s: float
    speed: float
    sim_time_s: float
    wall_time_s: float
    world_lag_s: float
    prime_ms: float
    lookahead_s: np.ndarray = np.zeros(0)
    lookahead_mean_s: float = 0.0
    delay_s: float | None = None


@dataclass
class RealtimeResult(SimulationResult):
    """A :class:`~mpcbox.sim.simulation.SimulationResult` with the planner's timing.

    Attributes:
        realtime: The :class:`RealtimeStats` of the run.
    """

    realtime: RealtimeStats | None = None


def whole_steps_delay(delay: float, dt: float) -> float:
    """The latency a simulated ``delay`` (s) has on a world stepping ``dt`` (s): a plan
    takes effect at the first step at or after it is ready, so ``delay`` rounded up to whole
    steps (:func:`~mpcbox.sim.lookahead.whole_steps`); a
    :class:`~mpcbox.errors.PeriodWarning` says so when that changes it."""
    whole = whole_steps(delay, dt) * dt
    if abs(whole - delay) > 1e-6 * dt:
        warnings.warn(
            f"delay={delay:g} s is not a whole number of simulation steps ({dt:g} s): a "
            f"plan takes effect at a step, so the run's latency is {whole:g} s",
            PeriodWarning,
            stacklevel=3,
        )
        return whole
    return float(delay)


def _within_run(name: str, seconds: float, duration: float) -> float:
    """``seconds`` of a latency setting, at most the run's ``duration`` (a named error
    otherwise: no plan would take effect)."""
    if seconds > duration:
        raise InvalidArgumentError(
            f"{name} must be at most the run's duration ({duration:g} s), got {seconds:g} s: "
            "no plan would take effect"
        )
    return seconds


@checked_keywords
def simulate_realtime(
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
    speed: float = 1.0,
    prime: bool = True,
    viewer: Viewer | str | Path | None = None,
    lookahead: float | str | None = None,
    delay: float | None = None,
) -> RealtimeResult:
    """Simulate ``problem.model`` in real time with ``controller`` planning concurrently.

    See the module docstring for the loop, the executed control and the timing measures;
    the arguments shared with :func:`~mpcbox.sim.simulation.simulate` mean the same.

    Args:
        problem: The Problem (its simulation model is simulated).
        controller: The controller; ``reset()`` is called first. It is called from the
            planner thread only.
        duration: Simulated time (s).
        noise: Smooth actuator noise, sampled with ``seed``.
        pushes: Forces applied to bodies over time intervals.
        mismatch: Changes to the simulated model the controller does not know about.
        seed: Seed of the noise.
        initial_state: Start state (default ``problem.initial_state()``).
        stop_on_failure: Stop at the first task failure.
        degraded_limit: Largest share of fallbacks for a success, in ``[0, 1]``.
        speed: Simulated seconds per wall-clock second (> 0; 1 is real time, 0.5 gives the
            planner twice the wall time per simulated second).
        prime: Solve one tick from the initial state before the clock starts (a robot
            waits for its first plan; compile time is not latency). Without it the world
            applies ``problem.ctrl_ref`` until the first plan arrives.
        viewer: Show the run while it goes, as for :func:`~mpcbox.sim.simulation.simulate`;
            the world thread draws (a frame's rendering time is world time, seen as
            ``world_lag_s`` when it falls behind), reading the planner's latest traces.
        lookahead: Latency compensation (:mod:`mpcbox.sim.lookahead`): ``None`` (default)
            plans from the observed state; seconds (``>= 0``, at most ``duration``) or
            ``"auto"`` (the recent median tick time, capped at ``duration``) plan from the
            state predicted that far ahead, rounded up to whole simulation steps.
        delay: A simulated latency (s, ``>= 0``) instead of the wall clock: the world waits
            for each tick as in :func:`~mpcbox.sim.simulation.simulate`, every tick takes
            ``delay`` simulated seconds (its plan takes effect then; the previous plan runs
            meanwhile) and the next tick starts when it is done or one period after it
            started, whichever is later: the wall-clock loop with every tick taking
            ``delay / speed`` seconds, but deterministic and independent of the machine,
            so latency can be studied and compensated (``lookahead="auto"`` predicts
            ``delay`` ahead) reproducibly. ``speed`` then has no effect (it must stay 1),
            and the state age of every tick is ``delay``, rounded up to whole simulation
            steps (a plan takes effect at a step; a :class:`~mpcbox.errors.PeriodWarning`
            says when that changes it). No tick starts whose plan would take effect only at
            the run's end.

    Returns:
        A :class:`RealtimeResult`; ``metrics.kept_up`` repeats ``realtime.kept_up``.
    """
    speed = positive("speed", speed)
    prime = boolean("prime", prime)
    lookahead = check_lookahead(lookahead)
    if delay is not None:
        delay = non_negative("delay", delay)
        if speed != 1.0:
            raise InvalidArgumentError(
                f"speed={speed:g} has no effect with delay (the world waits for each tick): "
                "leave speed at 1.0"
            )
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
    model, data, dt, steps, state0 = run.model, run.data, run.dt, run.steps, run.state0
    pushes, push_ids, measures, noise_seq = run.pushes, run.push_ids, run.measures, run.noise
    duration, degraded_limit = run.duration, run.degraded_limit
    stop_on_failure, fallbacks0 = run.stop_on_failure, run.fallbacks0
    if isinstance(lookahead, float):
        _within_run("lookahead", lookahead, duration)
    if delay is not None:
        delay = _within_run("delay", whole_steps_delay(delay, dt), duration)
    period = getattr(controller, "period", None)
    if period is None and callable(getattr(controller, "policy", None)):
        period = getattr(controller, "replan_period", None)  # the world runs the feedback
    period = dt if period is None else positive("controller.period", period)

    times = np.empty(steps + 1)
    states = np.empty((steps + 1, problem.nstate))
    ctrls = np.zeros((steps + 1, problem.nu))
    samples = np.empty((len(measures), steps + 1))
    failure: str | None = None
    outcome = "success"
    fail_time = duration
    monitor = DivergenceMonitor(data)
    planner = PlannerThread(
        problem,
        controller,
        period=period,
        max_ticks=steps + 2,
        lookahead=lookahead,
        speed=speed,
        delay=delay,
        end=float(data.time) + steps * dt,
    )
    if view is not None:
        view.start(problem, controller, model, data)
    prime_s = planner.prime(state0, float(data.time)) if prime else 0.0
    last = steps
    lag = 0.0
    sim0 = float(data.time)
    # The world and the planner share the GIL: hand it over within 0.5 ms instead of
    # Python's default 5 ms, so neither waits long for the other's Python code.
    switch = sys.getswitchinterval()
    sys.setswitchinterval(min(switch, GIL_SWITCH_INTERVAL_S))
    # Objects alive now (models, buffers, compiled kernels) are never garbage: keep the
    # collector from walking them in a full collection in the middle of a tick.
    gc.collect()
    gc.freeze()
    wall0 = _time.perf_counter()
    try:
        if delay is None:
            planner.start(state0, float(data.time))
        for k in range(steps + 1):
            now = float(data.time)
            if delay is None:  # a simulated latency runs without the wall clock
                early = wall0 + (now - sim0) / speed - _time.perf_counter()
                if early > 0:
                    _time.sleep(early)
                else:
                    lag = max(lag, -early)
            times[k] = now
            states[k] = problem.get_state(data)
            plan = planner.observe(states[k], now)
            if delay is not None:
                planner.tick_inline()
                plan = None  # the plan in force now, after this step's tick
            for i, measure in enumerate(measures):
                samples[i, k] = measure.sample(model, data)
            if failure is None:
                reason = problem.failure(model, data)
                if reason is not None:
                    failure, fail_time, outcome = reason, now, "failed"
                    if reason.startswith("non-finite"):
                        outcome = "diverged"
                    if stop_on_failure or outcome == "diverged":
                        last = k
                        break
            error = planner.error
            if error is not None:
                failure, fail_time, outcome, last = error, now, "controller error", k
                break
            if k == steps:
                break
            if view is not None:
                view.step(data)
            data.ctrl[:] = problem.clip_ctrl(planner.control(now, states[k], plan) + noise_seq[k])
            ctrls[k] = data.ctrl
            data.xfrc_applied[:] = 0.0
            for push, bid in zip(pushes, push_ids):
                if push.active(now):
                    data.xfrc_applied[bid] += push.wrench()
            monitor.before_step()
            mujoco.mj_step(model, data)
            reason = monitor.after_step()
            if reason is not None:
                failure, fail_time, outcome, last = reason, now, "diverged", k
                break
        wall = _time.perf_counter() - wall0
    finally:
        planner.stop()
        sys.setswitchinterval(switch)
        gc.unfreeze()
        if view is not None:
            view.finish()
    calls = planner.calls()
    if prime:
        calls["offline"].append(prime_s)
    stats = _stats(planner, period, speed, float(times[last]), wall, lag, prime_s, delay)
    res = finish_run(
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
        period_s=period,
        pushes=pushes,
        mismatch=mismatch,
        noise=noise,
        seed=seed,
        kept_up=stats.kept_up,
    )
    return RealtimeResult(**vars(res), realtime=stats)


def _stats(
    planner: PlannerThread,
    period: float,
    speed: float,
    sim_time: float,
    wall: float,
    lag: float,
    prime_s: float,
    delay: float | None = None,
) -> RealtimeStats:
    """The :class:`RealtimeStats` of a finished run."""
    latency = np.asarray(planner.latencies, dtype=np.float64)
    age = latency * speed if delay is None else np.full(latency.shape, delay)
    ticks = int(latency.size)
    over = int(np.sum(age > period))
    p99 = float(np.percentile(age, 99)) if ticks else math.inf
    ahead = np.asarray(planner.lookaheads, dtype=np.float64)
    return RealtimeStats(
        ticks=ticks,
        latency_ms=latency * 1e3,
        state_age_s=age,
        latency_p50_ms=float(np.percentile(latency, 50) * 1e3) if ticks else math.nan,
        latency_p99_ms=float(np.percentile(latency, 99) * 1e3) if ticks else math.nan,
        state_age_mean_s=float(age.mean()) if ticks else math.nan,
        over_period=over,
        over_period_share=over / ticks if ticks else 0.0,
        kept_up=bool(ticks and p99 <= period),
        period_s=float(period),
        speed=float(speed),
        sim_time_s=sim_time,
        wall_time_s=float(wall),
        world_lag_s=float(lag),
        prime_ms=prime_s * 1e3,
        lookahead_s=ahead,
        lookahead_mean_s=float(ahead.mean()) if ticks else 0.0,
        delay_s=delay,
    )
