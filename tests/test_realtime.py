"""The asynchronous real-time loop (mpcbox.sim.realtime) on the CPU."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import mpcbox
from mpcbox.sim.planner_thread import PlannerThread
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.tasks.swingup import CartpoleSwingup


class Sleeper(mpcbox.Controller):
    """Returns the reference control after ``delay`` seconds; can raise on call ``fail_at``."""

    def __init__(self, problem, delay, period, fail_at=None, bad_at=None):
        self.problem, self.delay, self.period = problem, delay, period
        self.fail_at, self.bad_at, self.calls = fail_at, bad_at, 0

    def reset(self):
        self.calls = 0

    def __call__(self, state, time_):
        self.calls += 1
        if self.calls == self.fail_at:
            raise RuntimeError("planner broke")
        if self.calls == self.bad_at:
            return np.full(self.problem.nu, np.nan)
        time.sleep(self.delay)
        return self.problem.ctrl_ref.copy()


def _planner_threads():
    return [t for t in threading.enumerate() if t.name == "mpcbox-planner" and t.is_alive()]


@pytest.fixture(scope="module")
def problem():
    return CartpoleSwingup()


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_the_world_does_not_wait_for_a_slow_planner(problem, speed):
    delay, period, duration = 0.06, 0.02, 0.6
    res = simulate_realtime(problem, Sleeper(problem, delay, period), duration, speed=speed)
    rt = res.realtime
    assert res.metrics.outcome in ("success", "goal missed"), res.failure
    assert res.time[-1] == pytest.approx(duration)
    # Simulated time follows the wall clock times the speed (a lock-step loop would take
    # ticks x delay = 1.8 s of wall time for this run at speed 1).
    assert rt.sim_time_s / rt.wall_time_s == pytest.approx(speed, rel=0.15)
    assert rt.ticks <= duration / speed / delay + 2
    assert rt.ticks >= 2
    # Every tick took longer than the period: none kept up, states are stale by > period.
    assert rt.over_period == rt.ticks
    assert rt.over_period_share == 1.0
    assert not rt.kept_up and res.metrics.kept_up is False
    assert np.all(rt.state_age_s > period)
    assert rt.state_age_mean_s == pytest.approx(delay * speed, rel=0.5)
    assert res.metrics.period_s == period
    assert not _planner_threads()


def test_a_fast_planner_keeps_up(problem):
    period = 0.05
    res = simulate_realtime(problem, Sleeper(problem, 0.0, period), 0.5)
    rt = res.realtime
    assert rt.kept_up and res.metrics.kept_up
    assert rt.over_period == 0
    # One tick per period of simulated time (the first one primed before the clock).
    assert abs(rt.ticks - 0.5 / period) <= 2
    assert rt.prime_ms >= 0.0 and res.metrics.offline_ms == pytest.approx(rt.prime_ms)


def test_sampling_controller_in_real_time(problem):
    ctrl = mpcbox.make_controller(
        "mppi", problem, num_samples=16, horizon=0.3, num_knots=3, period=0.1
    )
    res = simulate_realtime(problem, ctrl, 0.6)
    rt = res.realtime
    assert res.metrics.outcome in ("success", "goal missed"), res.failure
    assert rt.ticks >= 3
    assert np.all(rt.state_age_s > 0)
    assert res.metrics.solve_ticks == rt.ticks
    assert np.all(np.isfinite(res.ctrls))
    assert not _planner_threads()


def test_executed_control_is_the_latest_spline_at_the_current_time(problem):
    ctrl = mpcbox.make_controller("ps", problem, num_samples=8, horizon=0.3, num_knots=4)
    planner = PlannerThread(problem, ctrl, period=0.02, max_ticks=1)
    state = problem.initial_state()
    planner.prime(state, 1.0)
    for offset in (0.0, 0.013, 0.1, 0.25):
        expected = ctrl.action(offset)
        np.testing.assert_allclose(planner.control(1.0 + offset), expected, atol=1e-12)
    # A later change of the controller's knots does not touch the published plan.
    before = planner.control(1.05)
    ctrl.knots = ctrl.knots + 1.0
    np.testing.assert_array_equal(planner.control(1.05), before)


def test_the_world_runs_ilqrs_feedback_law_of_the_latest_plan(problem):
    """iLQR-MPC publishes its plan's feedback law; the world evaluates it at its own state
    and time at every step, so the feedback does not pause while a replan runs."""
    ctrl = mpcbox.make_controller("ilqr", problem, horizon=20, first_iterations=3)
    planner = PlannerThread(problem, ctrl, period=ctrl.replan_period, max_ticks=1)
    state = problem.initial_state()
    planner.prime(state, 1.0)
    primed = planner.control(1.01)  # without the world's state: the returned control, held
    policy = ctrl.policy()
    assert policy is not None and policy.plan_time == 1.0
    rng = np.random.default_rng(0)
    for offset in (0.0, 0.007, 0.013, 0.019):  # before the next replan is due (0.02 s)
        x = state + 0.05 * rng.standard_normal(state.shape)
        expected = problem.clip_ctrl(ctrl(x, 1.0 + offset))  # the controller's own law
        np.testing.assert_allclose(planner.control(1.0 + offset, x), expected, atol=1e-12)
    assert ctrl.stats["replans"] == 1
    np.testing.assert_allclose(primed, problem.clip_ctrl(ctrl(state, 1.0)), atol=1e-12)
    # Without feedback the replan's control is held, in the world as in simulate.
    held = mpcbox.make_controller("ilqr", problem, horizon=20, first_iterations=3, feedback=False)
    assert held.period == held.replan_period
    planner = PlannerThread(problem, held, period=held.period, max_ticks=1)
    planner.prime(state, 1.0)
    assert held.policy() is None
    np.testing.assert_array_equal(planner.control(1.01, x), planner.control(1.01))


def test_ilqr_in_real_time_ticks_at_its_replan_period(problem):
    ctrl = mpcbox.make_controller("ilqr", problem, horizon=20, first_iterations=3)
    res = simulate_realtime(problem, ctrl, 0.4)
    rt = res.realtime
    assert rt.period_s == ctrl.replan_period  # not the simulation step: the world's feedback
    assert abs(rt.ticks - 0.4 / ctrl.replan_period) <= 2
    assert rt.ticks == pytest.approx(ctrl.stats["replans"] - 1, abs=1)  # the first is primed
    assert np.all(np.isfinite(res.ctrls))
    # The executed controls vary between ticks: the law runs on the world's states.
    per_tick = round(ctrl.replan_period / problem.model.opt.timestep)
    assert per_tick > 1
    blocks = res.ctrls[: per_tick * (len(res.ctrls) // per_tick)].reshape(-1, per_tick, problem.nu)
    assert np.ptp(blocks, axis=1).max() > 0
    assert not _planner_threads()


def test_the_world_applies_a_sampling_controllers_catch_to_its_current_state(problem):
    ctrl = mpcbox.make_controller(
        "ps", problem, num_samples=8, horizon=0.3, num_knots=4, catch="lqr", catch_level=50.0
    )
    planner = PlannerThread(problem, ctrl, period=0.02, max_ticks=1)
    upright = problem.reference_state()
    planner.prime(problem.initial_state(), 0.0)
    # Inside the basin the world gets the catch's LQR control for the state it passes, at
    # any time; outside it (or without a state) the published spline.
    near = upright.copy()
    near[problem.nq] = 0.05
    assert ctrl.catch.engaged(near)
    np.testing.assert_allclose(planner.control(0.01, near), ctrl.catch.control(near))
    hanging = problem.initial_state()
    assert not ctrl.catch.engaged(hanging)
    np.testing.assert_allclose(planner.control(0.01, hanging), ctrl.action(0.01), atol=1e-12)
    np.testing.assert_allclose(planner.control(0.01), ctrl.action(0.01), atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "text"),
    [({"fail_at": 4}, "RuntimeError: planner broke"), ({"bad_at": 3}, "invalid control")],
)
def test_planner_errors_end_the_run_with_the_partial_trajectory(problem, kwargs, text):
    stub = Sleeper(problem, 0.0, 0.05, **kwargs)
    res = simulate_realtime(problem, stub, 2.0)
    assert res.metrics.outcome == "controller error"
    assert text in res.failure
    assert not res.metrics.survived
    assert 0.05 <= res.time[-1] < 2.0
    assert res.states.shape[0] == res.time.shape[0] > 1
    assert res.metrics.time_to_fall == pytest.approx(res.time[-1])
    assert not _planner_threads()


def test_an_error_in_the_priming_tick_stops_at_the_start(problem):
    res = simulate_realtime(problem, Sleeper(problem, 0.0, 0.05, fail_at=1), 1.0)
    assert res.metrics.outcome == "controller error"
    assert res.time.shape == (1,)
    assert res.realtime.ticks == 0 and not res.realtime.kept_up
    assert not _planner_threads()


def test_the_planner_thread_is_joined_when_the_world_raises(problem, monkeypatch):
    def broken(*_args, **_kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(problem, "failure", broken)
    with pytest.raises(KeyboardInterrupt):
        simulate_realtime(problem, Sleeper(problem, 0.01, 0.02), 1.0)
    assert not _planner_threads()


def test_bad_speed_is_rejected(problem):
    with pytest.raises(mpcbox.errors.InvalidArgumentError, match="speed"):
        simulate_realtime(problem, Sleeper(problem, 0.0, 0.05), 0.1, speed=0.0)


def test_compare_reports_whether_each_planner_kept_up(problem):
    from mpcbox.comparison.runner import compare
    from mpcbox.comparison.scenario import Scenario

    def slow(p):
        return Sleeper(p, 0.03, 0.01)

    def fast(p):
        return Sleeper(p, 0.0, 0.05)

    lockstep = Scenario(duration=0.2, noise_scale=0.0)
    live = Scenario(duration=0.3, noise_scale=0.0, realtime=True)
    assert live.label.endswith("real time")
    result = compare(problem, [slow, fast], [lockstep, live], seeds=1, workers=1, progress=False)
    rows = {(r.scenario, r.controller): r for r in result.rows()}
    assert rows[(lockstep.label, "slow")].kept_up is None
    assert rows[(live.label, "slow")].kept_up == 0.0
    assert rows[(live.label, "fast")].kept_up == 1.0
    header = [c.strip() for c in result.to_markdown().splitlines()[0].strip("|").split("|")]
    assert header[header.index("period (ms)") + 1] == "kept up"
    assert "kept_up" in result.to_csv().splitlines()[0].split(",")
    plain = compare(problem, [fast], lockstep, seeds=1, workers=1, progress=False)
    assert "kept up" not in plain.to_markdown().splitlines()[0]
    assert "kept_up" not in plain.to_csv().splitlines()[0].split(",")


def test_realtime_runner_is_exported_and_lockstep_runs_report_no_kept_up(problem):
    assert mpcbox.simulate_realtime is simulate_realtime
    res = mpcbox.simulate_realtime(problem, Sleeper(problem, 0.0, 0.05), 0.2, speed=2.0)
    assert res.realtime.speed == 2.0 and res.metrics.kept_up is True
    plain = mpcbox.simulate(problem, Sleeper(problem, 0.0, 0.05), 0.2)
    assert plain.metrics.kept_up is None and not hasattr(plain, "realtime")


def test_actuator_noise_is_added_to_the_held_control(problem):
    noise = mpcbox.ActuatorNoise(std=0.2)
    res = simulate_realtime(problem, Sleeper(problem, 0.0, 0.05), 0.3, noise=noise, seed=3)
    n = res.ctrls.shape[0] - 1
    dt = problem.model.opt.timestep
    expected = problem.clip_ctrl(problem.ctrl_ref + noise.sample(n, problem.nu, dt, 3))
    np.testing.assert_allclose(res.ctrls[:n], expected, atol=1e-12)
    assert np.std(res.ctrls[:n]) > 0.01


def test_gil_switch_interval_and_gc_are_restored_after_a_run(problem):
    import gc
    import sys

    before = sys.getswitchinterval()
    frozen = gc.get_freeze_count()
    simulate_realtime(problem, Sleeper(problem, 0.0, 0.05), 0.1)
    assert sys.getswitchinterval() == before
    assert gc.get_freeze_count() == frozen
