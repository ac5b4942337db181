"""Latency compensation in the real-time loop (mpcbox.sim.lookahead) on the CPU."""

from __future__ import annotations

import time

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, PeriodWarning
from mpcbox.sim.lookahead import Lookahead, check_lookahead
from mpcbox.sim.planner_thread import PlannerThread
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.tasks.swingup import CartpoleSwingup


class Recorder(mpcbox.Controller):
    """Sleeps ``delay`` s, records the (state, time) it was asked to plan from and returns a
    control that changes at every call (so the world's switch between plans matters)."""

    def __init__(self, problem, delay, period):
        self.problem, self.delay, self.period = problem, delay, period
        self.seen: list[tuple[np.ndarray, float]] = []

    def reset(self):
        self.seen = []

    def __call__(self, state, time_):
        self.seen.append((state.copy(), float(time_)))
        time.sleep(self.delay)
        return np.array([0.8 * np.sin(1.3 * len(self.seen))])


class NeverCatches:
    """A catch that never engages: the prediction then goes step by step (feedback)."""

    def control(self, state):
        return None


@pytest.fixture(scope="module")
def problem():
    return CartpoleSwingup()


@pytest.mark.parametrize(
    ("lookahead", "delay", "feedback"),
    [(0.04, 0.03, False), ("auto", 0.03, False), (0.08, 0.005, False), (0.04, 0.03, True)],
)
def test_each_tick_plans_from_the_state_the_world_reaches_at_the_plans_start(
    problem, lookahead, delay, feedback
):
    """Without disturbances the prediction under the previous plans is exactly the world's
    state when the new plan takes over, at any latency: the world keeps each plan until a
    later one starts, as the prediction assumed (with a lookahead of several ticks, several
    published plans wait for their start). Open-loop plans are rolled out in one call; with
    a catch, the prediction steps the feedback."""
    ctrl = Recorder(problem, delay, 0.02)
    if feedback:
        ctrl.catch = NeverCatches()
    res = simulate_realtime(problem, ctrl, 0.8, lookahead=lookahead, stop_on_failure=False)
    rt = res.realtime
    dt = problem.model.opt.timestep
    assert rt.ticks >= 5
    assert rt.lookahead_s.shape == (rt.ticks,)
    if lookahead == "auto":  # the period before any tick was timed, then the tick times
        assert rt.lookahead_s[0] == pytest.approx(0.02)
        later = rt.lookahead_s[3:]
        assert np.all(later >= 0.02) and np.all(later <= 0.1)
    else:
        np.testing.assert_allclose(rt.lookahead_s, round(lookahead / dt) * dt)
    assert rt.lookahead_mean_s == pytest.approx(rt.lookahead_s.mean())
    checked = 0
    for state, t in ctrl.seen[1:]:  # the first call is the prime, from the initial state
        k = int(np.argmin(np.abs(res.time - t)))
        if abs(res.time[k] - t) > 1e-9:
            continue  # planned beyond the end of the run
        np.testing.assert_allclose(state, res.states[k], atol=1e-6)
        checked += 1
    assert checked >= 5
    # Without the lookahead the planner gets observed states (at the world's times), which
    # the world has left by publication.
    plain = Recorder(problem, 0.03, 0.02)
    simulate_realtime(problem, plain, 0.3, stop_on_failure=False)
    assert all(abs(t / dt - round(t / dt)) < 1e-6 for _, t in plain.seen)


def test_the_world_keeps_the_previous_plan_until_the_new_one_starts(problem):
    ctrl = Recorder(problem, 0.0, 0.02)
    planner = PlannerThread(problem, ctrl, period=0.02, max_ticks=1, lookahead=0.05)
    planner.prime(problem.initial_state(), 0.0)  # plan 1 at t = 0
    first = planner.control(0.01)
    planner._publish(np.array([0.5]), 0.05)  # a plan from the state predicted at 0.05
    np.testing.assert_array_equal(planner.control(0.03), first)
    np.testing.assert_array_equal(planner.control(0.05), [0.5])
    np.testing.assert_array_equal(planner.control(0.2), [0.5])
    # Without a lookahead the latest plan is used at once.
    now = PlannerThread(problem, ctrl, period=0.02, max_ticks=1)
    now.prime(problem.initial_state(), 0.0)
    now._publish(np.array([0.5]), 0.05)
    np.testing.assert_array_equal(now.control(0.03), [0.5])


def test_prediction_steps_the_task_model_under_the_given_control(problem):
    look = Lookahead(problem, 0.05, period=0.02, speed=1.0)
    # Rounded up: a plan takes effect at the first world step at or after its start.
    assert look.steps(0.05) == 5 and look.steps(0.0) == 0
    assert look.steps(0.004) == 1 and look.steps(0.016) == 2 and look.steps(0.011) == 2
    state = problem.initial_state()
    state[problem.nq] = 0.3
    pred, t = look.predict(state, 1.0, 5, lambda _t, _x: np.array([0.4]))
    data = mujoco.MjData(problem.model)
    problem.set_state(data, state)
    for _ in range(5):
        data.ctrl[:] = 0.4
        mujoco.mj_step(problem.model, data)
    np.testing.assert_allclose(pred, problem.get_state(data), atol=1e-12)
    assert t == pytest.approx(1.05)
    same, t0 = look.predict(state, 1.0, 0, lambda _t, _x: np.array([0.4]))
    assert same is state and t0 == 1.0
    # Controls known in advance: one rollout call, the same states as step by step.
    ctrls = np.linspace(-0.5, 0.5, 7)[:, None]
    feed, tf = look.predict(state, 1.0, 7, lambda t_, _x: ctrls[round((t_ - 1.0) / 0.01)])
    roll, tr = look.predict_open_loop(state, 1.0, ctrls)
    np.testing.assert_allclose(roll, feed, atol=1e-12)
    assert tr == pytest.approx(tf) == pytest.approx(1.07)
    # A prediction that diverges (MuJoCo's reset) leaves the observed state.
    back, tb = look.predict(state, 1.0, 5, lambda _t, _x: np.array([np.nan]))
    assert back is state and tb == 1.0
    wild = state.copy()
    wild[problem.nq :] = 1e12  # beyond MuJoCo's limit: it resets on the first step
    back, tb = look.predict_open_loop(wild, 1.0, ctrls)
    assert back is wild and tb == 1.0


@pytest.mark.parametrize(
    ("value", "error", "text"),
    [
        (-0.1, InvalidArgumentError, "lookahead"),
        ("fast", InvalidArgumentError, "'auto'"),
        (True, InvalidTypeError, "lookahead"),
        ([0.1], InvalidTypeError, "lookahead"),
        (float("inf"), InvalidArgumentError, "finite"),
    ],
)
def test_bad_lookahead_is_rejected_by_name(problem, value, error, text):
    with pytest.raises(error, match=text):
        check_lookahead(value)
    with pytest.raises(error, match=text):
        simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.1, lookahead=value)


def test_scenarios_pass_the_lookahead_to_real_time_runs_only(problem):
    scenario = mpcbox.Scenario(duration=0.3, noise_scale=0.0, realtime=True, lookahead=0.05)
    assert "lookahead 0.05 s" in scenario.label
    res = scenario.run(problem, Recorder(problem, 0.0, 0.05), seed=0)
    np.testing.assert_allclose(res.realtime.lookahead_s, 0.05)
    with pytest.raises(InvalidArgumentError, match="realtime"):
        mpcbox.Scenario(duration=0.3, lookahead="auto")
    with pytest.raises(InvalidArgumentError, match="lookahead"):
        mpcbox.Scenario(duration=0.3, realtime=True, lookahead="later")
    delayed = mpcbox.Scenario(duration=0.3, noise_scale=0.0, realtime=True, delay=0.03)
    assert "delay 0.03 s" in delayed.label
    res = delayed.run(problem, Recorder(problem, 0.0, 0.05), seed=0)
    assert res.realtime.delay_s == 0.03
    with pytest.raises(InvalidArgumentError, match="delay"):
        mpcbox.Scenario(duration=0.3, delay=0.03)
    with pytest.raises(InvalidArgumentError, match="delay"):
        mpcbox.Scenario(duration=0.3, realtime=True, delay=-1.0)


def test_lookahead_zero_and_none_plan_from_the_observed_state(problem):
    assert check_lookahead(None) is None and check_lookahead(0) == 0.0
    ctrl = Recorder(problem, 0.0, 0.05)
    res = simulate_realtime(problem, ctrl, 0.3, lookahead=0.0, stop_on_failure=False)
    assert np.all(res.realtime.lookahead_s == 0.0)
    res = simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.3, stop_on_failure=False)
    assert res.realtime.lookahead_mean_s == 0.0


def test_a_sampling_controller_plans_ahead_over_several_pending_plans(problem):
    """Spline plans (arrays of knots) waiting for their start: a lookahead of several
    periods keeps several published plans; the run goes on without a controller error."""
    ctrl = mpcbox.make_controller(
        "ps", problem, num_samples=8, horizon=0.4, num_knots=4, period=0.02
    )
    res = simulate_realtime(problem, ctrl, 0.5, lookahead=0.08, stop_on_failure=False)
    assert res.metrics.outcome in ("success", "goal missed"), res.failure
    assert res.realtime.ticks >= 5
    np.testing.assert_allclose(res.realtime.lookahead_s, 0.08)


def test_a_fault_of_the_planner_loop_ends_the_run_as_a_controller_error(problem, monkeypatch):
    def broken(*_args, **_kwargs):
        raise RuntimeError("publication broke")

    monkeypatch.setattr(PlannerThread, "_publish", broken)
    res = simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.5, prime=False)
    assert res.metrics.outcome == "controller error"
    assert "publication broke" in res.failure


@pytest.mark.parametrize(("asked", "delay"), [(0.03, 0.03), (0.05, 0.05), (0.015, 0.02)])
def test_a_simulated_delay_applies_each_plan_exactly_delay_later(problem, asked, delay):
    """Without the wall clock: tick i plans from the state at t_i and its plan reaches the
    world at t_i + delay; one planner, so ticks start max(period, delay) apart. A delay
    between two world steps (0.01 s here) acts as the next step, and the run says so."""
    ctrl = Recorder(problem, 0.0, 0.02)
    if asked == delay:
        res = simulate_realtime(problem, ctrl, 0.5, delay=asked, stop_on_failure=False)
    else:
        with pytest.warns(PeriodWarning, match=r"delay=0.015 s .* latency is 0.02 s"):
            res = simulate_realtime(problem, ctrl, 0.5, delay=asked, stop_on_failure=False)
    rt = res.realtime
    assert rt.delay_s == pytest.approx(delay) and rt.ticks == len(ctrl.seen) - 1
    np.testing.assert_allclose(rt.state_age_s, delay)
    over = delay > 0.02  # the state age against the 0.02 s period
    assert rt.kept_up is not over and rt.over_period == (rt.ticks if over else 0)
    starts = np.array([t for _, t in ctrl.seen])
    # The primed tick at 0 (in force at once, as a robot waits for its first plan), the
    # next a period later, then one every max(period, delay).
    gaps = max(0.02, delay) * np.arange(len(starts) - 1)
    np.testing.assert_allclose(starts, np.concatenate([[0.0], 0.02 + gaps]), atol=1e-9)
    # No tick whose plan would take effect only at the run's end (never applied).
    assert np.all(starts[1:] + delay < res.time[-1] - 1e-9)
    values = [np.array([0.8 * np.sin(1.3 * (i + 1))]) for i in range(len(starts))]
    for k, t in enumerate(res.time[:-1]):
        arrived = [i for i, s in enumerate(starts) if i == 0 or s + delay <= t + 1e-9]
        np.testing.assert_allclose(res.ctrls[k], values[max(arrived)], atol=1e-12)


def test_a_simulated_delay_is_reproducible_and_compensated_exactly(problem):
    runs = []
    for _ in range(2):
        ctrl = Recorder(problem, 0.0, 0.02)
        res = simulate_realtime(
            problem, ctrl, 0.6, delay=0.05, lookahead="auto", stop_on_failure=False
        )
        runs.append((res, ctrl))
    (first, ctrl), (second, _) = runs
    np.testing.assert_array_equal(first.states, second.states)
    np.testing.assert_allclose(first.realtime.lookahead_s, 0.05)
    checked = 0
    for state, t in ctrl.seen[1:]:  # each plan starts from the world's state at its start
        k = int(np.argmin(np.abs(first.time - t)))
        if abs(first.time[k] - t) < 1e-9:
            np.testing.assert_allclose(state, first.states[k], atol=1e-6)
            checked += 1
    assert checked >= 8


@pytest.mark.parametrize(
    ("value", "error"), [(-0.01, InvalidArgumentError), ("soon", InvalidTypeError)]
)
def test_bad_delay_is_rejected_by_name(problem, value, error):
    with pytest.raises(error, match="delay"):
        simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.1, delay=value)


class Shrinking(Recorder):
    """Slow ticks first, then fast ones: ``lookahead="auto"`` shrinks."""

    def __call__(self, state, time_):
        self.delay = 0.045 if len(self.seen) < 6 else 0.002
        return super().__call__(state, time_)


def test_plans_start_at_least_a_period_apart_when_the_lookahead_shrinks(problem):
    ctrl = Shrinking(problem, 0.0, 0.02)
    simulate_realtime(problem, ctrl, 0.8, lookahead="auto", stop_on_failure=False)
    starts = np.array([t for _, t in ctrl.seen])
    assert len(starts) > 12
    assert np.all(np.diff(starts) >= 0.02 - 1e-9)


class Spy:
    """Records the (state, time) a controller is asked to plan from; everything else (its
    ``policy``, ``period``, ``reset``) is the controller's."""

    def __init__(self, inner):
        self.inner = inner
        self.seen: list[tuple[np.ndarray, float]] = []

    def __call__(self, state, time_):
        self.seen.append((state.copy(), float(time_)))
        return self.inner(state, time_)

    def __getattr__(self, name):
        return getattr(self.inner, name)


@pytest.mark.parametrize(
    ("steps", "lookahead", "delay"), [(3, 0.05, 0.02), (4, 0.1, 0.03), (3, 0.07, 0.05)]
)
def test_a_feedback_law_held_within_knots_is_predicted_as_the_world_runs_it(
    problem, steps, lookahead, delay
):
    """iLQR-MPC with knots of several steps holds each knot's control, which its law
    computes at the knot's first step. The prediction evaluates the plans' laws over several
    knots; it must use copies of its own, starting from the world's law as the world holds
    it at the observed time (mid-knot too), or the world holds a control computed at a
    predicted state (the prediction one computed at the world's). Without disturbances every
    plan then starts from the world's state at its start. The cart-pole starts off upright,
    where the laws' controls stay within their bounds (clipped controls would hide it)."""
    ilqr = mpcbox.ILQR(problem, horizon=12, control_steps=steps, replan_period=0.02)
    spy = Spy(ilqr)
    start = problem.reference_state()
    start[1] += 0.15
    start[3] += 0.3
    res = simulate_realtime(
        problem,
        spy,
        0.6,
        delay=delay,
        lookahead=lookahead,
        initial_state=start,
        stop_on_failure=False,
    )
    assert np.abs(res.ctrls).max() < 1.0  # within the cart's force bound
    checked = 0
    for state, t in spy.seen[1:]:
        k = int(np.argmin(np.abs(res.time - t)))
        if abs(res.time[k] - t) < 1e-9:
            np.testing.assert_allclose(state, res.states[k], atol=1e-9)
            checked += 1
    assert checked >= 10


def test_a_lookahead_longer_than_the_run_is_refused_and_auto_is_capped(problem):
    with pytest.raises(InvalidArgumentError, match=r"lookahead must be at most .*0.3 s"):
        simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.3, lookahead=1e9)
    look = Lookahead(problem, "auto", period=0.02, speed=1.0, limit=0.3)
    assert look.seconds([]) == pytest.approx(0.02)
    assert look.seconds([50.0, 60.0]) == pytest.approx(0.3)  # a slow tick, capped


def test_speed_has_no_meaning_with_a_simulated_delay(problem):
    with pytest.raises(InvalidArgumentError, match=r"speed=2 has no effect with delay"):
        simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.1, delay=0.02, speed=2.0)
    with pytest.raises(InvalidArgumentError, match="speed has no effect with delay"):
        mpcbox.Scenario(realtime=True, delay=0.02, speed=2.0)
    with pytest.raises(InvalidArgumentError, match="speed needs realtime"):
        mpcbox.Scenario(speed=2.0)


def test_scenario_keeps_plain_floats_that_hash_and_print_alike():
    one = mpcbox.Scenario(realtime=True, delay=np.array(0.03), lookahead=-0.0)
    two = mpcbox.Scenario(realtime=True, delay=0.03, lookahead=0.0)
    assert one == two and hash(one) == hash(two)
    assert type(one.delay) is float and "lookahead 0 s" in one.label and "-0" not in one.label
    sped = mpcbox.Scenario(realtime=True, speed=np.float32(2.0))
    assert type(sped.speed) is float and hash(sped) == hash(mpcbox.Scenario(realtime=True, speed=2))


def test_a_misspelled_keyword_is_named_with_the_valid_ones(problem):
    from mpcbox.errors import UnknownOptionError

    with pytest.raises(UnknownOptionError, match=r"'look_ahead'.*lookahead"):
        simulate_realtime(problem, Recorder(problem, 0.0, 0.05), 0.1, look_ahead="auto")
