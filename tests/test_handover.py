"""The hand-over between two controllers (mpcbox.controllers.handover) on the CPU."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.handover import HandOver
from mpcbox.sim.planner_thread import PlannerThread
from mpcbox.tasks.humanoid.getup import HumanoidGetup
from mpcbox.tasks.humanoid.stand import HumanoidStand
from mpcbox.tasks.swingup import CartpoleSwingup


class Constant(mpcbox.Controller):
    """Returns ``value`` on every control; counts calls and resets."""

    def __init__(self, nu, value, period=0.02):
        self.value, self.period, self.nu = float(value), period, nu
        self.calls = self.resets = 0

    def reset(self):
        self.resets += 1

    def __call__(self, state, time):
        self.calls += 1
        return np.full(self.nu, self.value)


def _high(state):
    return state[0] > 1.0


def _low(state):
    return state[0] < -1.0


def test_delegates_by_phase_with_hysteresis_and_counts_switches():
    a, b = Constant(2, 1.0), Constant(2, 2.0)
    ctrl = HandOver(a, b, engage=_high, release=_low, prime=False)
    # Positions 0, 2 (engage), 0 and -0.5 (between the thresholds: stay), -2 (release), 0.
    path = [0.0, 2.0, 0.0, -0.5, -2.0, 0.0]
    out = [ctrl(np.array([x, 0.0]), 0.02 * i)[0] for i, x in enumerate(path)]
    assert out == [1.0, 2.0, 2.0, 2.0, 1.0, 1.0]
    assert ctrl.switches == 2 and ctrl.phase == 0
    assert ctrl.switch_times == pytest.approx([0.02, 0.08])
    assert (a.calls, b.calls) == (3, 3)
    stats = ctrl.stats
    assert stats["switches"] == 2 and stats["first_calls"] == 3 and stats["second_calls"] == 3
    ctrl.reset()
    assert ctrl.switches == 0 and ctrl.phase == 0 and a.resets == b.resets == 2
    assert ctrl.spline is None and ctrl.knots is None


def test_priming_runs_the_second_controller_once_on_the_first_call():
    a, b = Constant(1, 1.0), Constant(1, 2.0)
    ctrl = HandOver(a, b, engage=_high, release=_low)
    assert ctrl(np.zeros(2), 0.0)[0] == 1.0
    ctrl(np.zeros(2), 0.02)
    assert (a.calls, b.calls) == (2, 1)


def test_bad_arguments_are_rejected():
    a = Constant(1, 0.0)
    with pytest.raises(mpcbox.InvalidTypeError, match="second"):
        HandOver(a, object(), engage=_high, release=_low)
    with pytest.raises(mpcbox.InvalidTypeError, match="engage"):
        HandOver(a, Constant(1, 0.0), engage=1.0, release=_low)
    with pytest.raises(mpcbox.InvalidArgumentError, match="period"):
        HandOver(a, Constant(1, 0.0, period=0.05), engage=_high, release=_low)


@pytest.fixture(scope="module")
def cartpole():
    return CartpoleSwingup()


def _pair(problem, transfer):
    # One candidate: predictive sampling then keeps its (warm-started) nominal exactly.
    first = mpcbox.make_controller("ps", problem, num_samples=1, horizon=0.4, num_knots=5)
    second = mpcbox.make_controller("ps", problem, num_samples=1, horizon=0.3, num_knots=4)
    cart_right = lambda x: x[0] > 0.5  # noqa: E731
    cart_left = lambda x: x[0] < -0.5  # noqa: E731
    return HandOver(first, second, engage=cart_right, release=cart_left, transfer=transfer)


@pytest.mark.parametrize("transfer", [True, False])
def test_a_switch_hands_the_plan_over_or_starts_cold(cartpole, transfer):
    ctrl = _pair(cartpole, transfer)
    first, second = ctrl.controllers
    x = cartpole.initial_state()
    ctrl(x, 0.0)
    first.knots = first.knots + np.linspace(0.0, 1.0, 5)[:, None]  # a plan of its own
    plan = first.knots.copy()
    right = x.copy()
    right[0] = 1.0
    ctrl(right, 0.06)
    assert ctrl.phase == 1 and ctrl.switches == 1
    assert ctrl.knots is second.knots and ctrl.spline is second.spline
    if transfer:
        expected = first.spline.evaluate(plan, second.spline.knot_times + 0.06)
    else:
        expected = np.tile(cartpole.clip_ctrl(cartpole.ctrl_ref), (4, 1))
    np.testing.assert_allclose(second.knots, cartpole.clip_ctrl(expected), atol=1e-12)


def test_the_real_time_planner_evaluates_the_active_controllers_spline(cartpole):
    ctrl = _pair(cartpole, True)
    planner = PlannerThread(cartpole, ctrl, period=0.02, max_ticks=1)
    x = cartpole.initial_state()
    planner.prime(x, 0.0)
    first, second = ctrl.controllers
    np.testing.assert_allclose(planner.control(0.35), first.action(0.35), atol=1e-12)
    right = x.copy()
    right[0] = 1.0
    planner.prime(right, 1.0)
    assert ctrl.phase == 1
    # 0.35 s is past the second spline's 0.3 s horizon: its last knot, not the first's plan.
    np.testing.assert_allclose(planner.control(1.35), second.knots[-1], atol=1e-12)
    np.testing.assert_allclose(planner.control(1.1), second.action(0.1), atol=1e-12)


def test_getup_stages_hand_over_to_the_standing_task_and_back():
    task = HumanoidGetup(settle=0.3)
    lying, standing = task.initial_state(), task.reference_state()
    assert not task.is_up(lying) and task.is_down(lying)
    assert task.is_up(standing) and not task.is_down(standing)
    small = dict(num_samples=4, horizon=0.1, backend="cpu")
    ctrl = task.handover_controller("mppi", stand_options=small, **small)
    getup, stand = ctrl.controllers
    assert isinstance(stand.problem, HumanoidStand)
    assert isinstance(getup.problem, HumanoidGetup)
    for time, state, phase in ((0.0, lying, 0), (0.02, standing, 1), (0.04, lying, 0)):
        u = ctrl(state, time)
        assert ctrl.phase == phase and u.shape == (task.nu,)
    assert ctrl.switches == 2
    with pytest.raises(mpcbox.InvalidArgumentError, match="release_height"):
        HumanoidGetup(release_height=1.2)
    with pytest.raises(mpcbox.InvalidArgumentError, match="release_height"):
        HumanoidGetup(handover_height=0.8)


@pytest.mark.parametrize("stand", ["lqr", "qp"])
def test_a_feedback_standing_stage_runs_at_the_getup_period_and_holds_the_stand(stand):
    task = HumanoidGetup(settle=0.3, handover_speed=0.5, handover_offset=0.1)
    small = dict(num_samples=4, horizon=0.1, backend="cpu", seed=3)
    ctrl = task.handover_controller("ps", stand=stand, **small)
    getup, keeper = ctrl.controllers
    assert keeper.period == getup.period == 0.02
    standing = task.stand_problem().reference_state()
    res = mpcbox.simulate(task, ctrl, 1.0, initial_state=standing, stop_on_failure=False)
    # It hands over at once and the feedback law keeps the torso within 2 cm of its start.
    assert ctrl.switch_times == [0.0] and ctrl.phase == 1
    heights = task.torso_heights(res.states)
    assert np.abs(heights - heights[0]).max() < 0.02


def test_a_standing_ilqr_replans_at_the_getup_period_only_without_feedback():
    task = HumanoidGetup(settle=0.3)
    small = dict(num_samples=4, horizon=0.1, backend="cpu", seed=1)
    # Its feedback law would run at every simulation step, between the planner's ticks.
    with pytest.raises(mpcbox.InvalidArgumentError, match="feedback"):
        task.handover_controller("ps", stand="ilqr", **small)
    ctrl = task.handover_controller(
        "ps", stand="ilqr", stand_options={"feedback": False, "horizon": 10}, **small
    )
    getup, keeper = ctrl.controllers
    assert keeper.period == keeper.replan_period == getup.period == 0.02
    u = ctrl(task.stand_problem().reference_state(), 0.0)
    assert ctrl.phase == 1 and u.shape == (task.nu,) and np.all(np.isfinite(u))


def test_the_standing_stage_can_plan_on_the_getup_task_with_its_own_options():
    task = HumanoidGetup(settle=0.3)
    small = dict(num_samples=4, horizon=0.1, backend="cpu", seed=1)
    ctrl = task.handover_controller(
        "mppi", stand_on="getup", stand_options={"noise_scale": 0.1}, **small
    )
    getup, keeper = ctrl.controllers
    # Both plan on (a planning copy of) the get-up task, not on HumanoidStand.
    assert type(keeper.problem) is type(getup.problem) is HumanoidGetup
    assert keeper.period == getup.period
    np.testing.assert_allclose(keeper.noise_scale, 0.1)
    np.testing.assert_allclose(getup.noise_scale, task.controller_configs["mppi"].noise_scale)
    ctrl(task.reference_state(), 0.0)
    assert ctrl.phase == 1
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"stand_on.*'stand', 'getup'"):
        task.handover_controller("mppi", stand_on="self", **small)
    with pytest.raises(mpcbox.InvalidArgumentError, match="stand_task"):
        task.handover_controller("mppi", stand_on="getup", stand_task={"root_cost": 1.0})
    with pytest.raises(mpcbox.InvalidTypeError, match="stand_options must be a dict"):
        task.handover_controller("mppi", stand_options=[("noise_scale", 0.1)], **small)


def test_getup_stage_tests_check_the_shapes_of_what_they_read():
    task = HumanoidGetup(settle=0.3)
    for check in (task.is_up, task.is_down, task.balance_state, task.posture_distance):
        with pytest.raises(mpcbox.ShapeError, match=r"state must have shape \(55,\)"):
            check(np.zeros(3))
    with pytest.raises(mpcbox.ShapeError, match="states"):
        task.torso_heights(np.zeros((2, 3)))
    states = np.tile(task.reference_state(), (2, 1))
    with pytest.raises(mpcbox.ShapeError, match=r"time must have shape \(2,\)"):
        task.getup_time(np.zeros(3), states)
    assert task.getup_time(np.array([0.0, 0.1]), states) == 0.0


def test_the_engage_test_can_ask_for_a_slow_centre_of_mass_over_the_feet():
    task = HumanoidGetup(settle=0.3)
    standing = task.reference_state()
    speed, offset = task.balance_state(standing)
    assert speed == 0.0 and offset < 0.05
    moving = standing.copy()
    moving[task.nq : task.nq + 3] = [0.6, 0.0, 0.8]  # the whole body translating at 1 m/s
    assert task.balance_state(moving)[0] == pytest.approx(1.0, rel=1e-9)
    assert task.is_up(moving)
    assert not HumanoidGetup(settle=0.3, handover_speed=0.9).is_up(moving)
    assert HumanoidGetup(settle=0.3, handover_speed=1.1).is_up(moving)
    assert not HumanoidGetup(settle=0.3, handover_offset=0.5 * offset).is_up(standing)
    assert HumanoidGetup(settle=0.3, handover_offset=2.0 * offset).is_up(standing)
    bent = standing.copy()
    bent[task.nq - 1] += 0.3  # one elbow
    assert task.posture_distance(standing) == 0.0
    assert task.posture_distance(bent) == pytest.approx(0.3, rel=1e-9)
    assert not HumanoidGetup(settle=0.3, handover_posture=0.2).is_up(bent)
    assert HumanoidGetup(settle=0.3, handover_posture=0.4).is_up(bent)
    for option in ("handover_speed", "handover_offset", "handover_posture"):
        with pytest.raises(mpcbox.InvalidArgumentError, match=option):
            HumanoidGetup(settle=0.3, **{option: 0.0})
    with pytest.raises(mpcbox.UnknownNameError, match="controller"):
        task.handover_controller("ps", stand="nope", backend="cpu")
    with pytest.raises(mpcbox.UnknownOptionError, match="bogus"):
        task.handover_controller("ps", stand="lqr", stand_options={"bogus": 1}, backend="cpu")
