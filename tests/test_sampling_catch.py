"""Sampling with an LQR catch: closed-loop rollouts, the basin level and the loop's hand-over."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.sampling.catch import LQRCatch, basin_level, linear_level
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.swingup import AcrobotSwingup, CartpoleSwingup, PendulumSwingup


@pytest.fixture(scope="module")
def pendulum() -> PendulumSwingup:
    return PendulumSwingup()


def test_policy_rollouts_equal_open_loop_rollouts_under_the_identity(pendulum) -> None:
    rng = np.random.default_rng(0)
    ctrls = pendulum.clip_ctrl(rng.uniform(-3.0, 3.0, (6, 40, pendulum.nu)))
    start = pendulum.initial_state()
    open_loop = pendulum.dynamics.rollout(start, ctrls)
    closed = pendulum.dynamics.rollout_policy(start, ctrls, lambda states, c: c)
    np.testing.assert_array_equal(closed.states, open_loop.states)
    np.testing.assert_array_equal(closed.sensordata, open_loop.sensordata)
    np.testing.assert_array_equal(pendulum.rollout_cost(closed), pendulum.rollout_cost(open_loop))


def test_policy_rollouts_take_one_start_per_row_and_see_each_state(pendulum) -> None:
    starts = np.array([pendulum.reference_state() + np.array([0.1 * i, 0.0]) for i in range(3)])
    ctrls = np.zeros((3, 10, pendulum.nu))
    seen = []

    def record(states, c):
        seen.append(states.copy())
        return c

    roll = pendulum.dynamics.rollout_policy(starts, ctrls, record)
    for i in range(3):
        alone = pendulum.dynamics.rollout(starts[i], ctrls[i : i + 1])
        np.testing.assert_array_equal(roll.states[i], alone.states[0])
    np.testing.assert_array_equal(np.stack(seen, axis=1), roll.states[:, :-1])


def test_linear_level_is_where_the_lqr_first_reaches_its_control_limit(pendulum) -> None:
    catch = LQRCatch(pendulum, pendulum.model.opt.timestep, level=1.0)
    lqr = catch.rollout_lqr
    level = linear_level(lqr, pendulum)
    Pinv = np.linalg.pinv(catch.P)
    direction = Pinv @ lqr.K[0]
    dx = np.sqrt(level) * direction / np.sqrt(lqr.K[0] @ direction)
    assert dx @ catch.P @ dx == pytest.approx(level)
    room = min(lqr.ctrl0[0] - pendulum.ctrl_low[0], pendulum.ctrl_high[0] - lqr.ctrl0[0])
    assert abs(lqr.K[0] @ dx) == pytest.approx(room, rel=1e-9)
    # every other point of the level set asks for less
    rng = np.random.default_rng(1)
    for z in rng.standard_normal((50, pendulum.nx)):
        z *= np.sqrt(level / (z @ catch.P @ z))
        assert abs(lqr.K[0] @ z) <= room * (1 + 1e-9)


def test_basin_level_holds_fresh_states_and_sits_above_the_linear_level(pendulum) -> None:
    catch = LQRCatch(pendulum, pendulum.model.opt.timestep, seed=3)
    assert catch.level >= linear_level(catch.rollout_lqr, pendulum)
    # fresh draws inside the estimated basin converge under the saturated LQR
    rng = np.random.default_rng(11)
    held = 0
    for _ in range(20):
        dx = rng.standard_normal(pendulum.nx)
        dx *= np.sqrt(0.9 * catch.level / (dx @ catch.P @ dx)) * rng.uniform() ** 0.5
        state = pendulum.state_add(pendulum.reference_state(), dx)
        for _ in range(400):
            state = pendulum.step(state, catch.control(state))
        held += catch.value(state) < 1e-3 * catch.level
    assert held >= 19
    # far outside it the LQR alone lets the pendulum fall: the level is not everything
    outside = pendulum.state_add(pendulum.reference_state(), np.array([1.5, 0.0]))
    assert not catch.engaged(outside)
    assert catch.control(outside) is None


def test_basin_level_refuses_a_level_that_cannot_be_kept(pendulum) -> None:
    lqr = LQRCatch(pendulum, pendulum.model.opt.timestep, level=1.0).rollout_lqr
    # a horizon too short to converge from anywhere: no level passes
    with pytest.raises(mpcbox.MpcboxError, match="no basin"):
        basin_level(pendulum, lqr, samples=8, seconds=pendulum.dt)


def test_catch_replaces_only_the_rows_inside_the_basin(pendulum) -> None:
    catch = LQRCatch(pendulum, pendulum.model.opt.timestep, level=5.0)
    ref = pendulum.reference_state()
    states = np.stack([ref, ref + np.array([2.0, 0.0]), ref + np.array([2 * np.pi, 0.0])])
    ctrls = np.full((3, pendulum.nu), 0.7)
    out = catch.policy(states, ctrls)
    np.testing.assert_allclose(out[0], catch.rollout_lqr.ctrl0)
    assert out[1, 0] == 0.7  # outside: the sample's control
    np.testing.assert_allclose(out[2], catch.rollout_lqr.ctrl0)  # a whole turn away: wrapped
    nan = catch.policy(np.full((1, pendulum.nstate), np.nan), ctrls[:1])
    assert nan[0, 0] == 0.7


def test_mppi_with_a_catch_swings_the_cart_pole_up_and_holds_it_with_the_lqr() -> None:
    problem = CartpoleSwingup()
    ctrl = mpcbox.make_controller("mppi", problem, catch="lqr", seed=0)
    res = mpcbox.simulate(problem, ctrl, 8.0)
    assert res.survived, res.failure
    err = np.array([problem.upright_error(s) for s in res.states])
    assert np.all(err[-100:] < 0.05)
    assert ctrl.stats["catch_calls"] > 0
    assert ctrl.last_call == "catch"


def test_acrobot_mppi_default_swings_up_from_hanging_and_the_catch_holds_it() -> None:
    problem = AcrobotSwingup()
    ctrl = mpcbox.make_controller("mppi", problem)
    assert ctrl.catch is not None
    result = mpcbox.simulate(problem, ctrl, 5.0)
    assert result.survived, result.failure
    errors = problem.upright_errors(result.states)
    assert errors[0] > 3.0  # hanging
    assert errors[result.time >= 4.0].max() < 0.01
    assert ctrl.last_call == "catch"


def test_traces_follow_the_catch_the_planner_scored() -> None:
    problem = CartpoleSwingup()
    ctrl = mpcbox.make_controller("mppi", problem, catch="lqr", num_samples=16, seed=2)
    ctrl.record_traces(3)
    state = problem.reference_state()
    state[problem.nq] = 0.05  # inside the basin: the LQR overrides every sample
    assert ctrl.catch.engaged(state)
    ctrl.plan(state, 0.0)
    paths = ctrl.traces.positions
    np.testing.assert_allclose(paths[1:], np.broadcast_to(paths[0], paths[1:].shape))
    assert np.ptp(ctrl.traces.costs) == pytest.approx(0.0, abs=1e-9)
    # ... and that path is the LQR's closed loop, not the open-loop spline's
    steps = ctrl.horizon_steps
    lqr_only = ctrl.problem.dynamics.rollout_policy(
        state, np.zeros((1, steps, problem.nu)), ctrl.catch.policy
    )
    held = ctrl.trace_recorder.positions(lqr_only.states)
    np.testing.assert_allclose(paths[0], held[0], atol=1e-12)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"catch": "lqr", "backend": "warp"}, "catch='lqr' needs backend='cpu'"),
        ({"catch": "energy"}, "catch.*lqr"),
        ({"catch": "lqr", "catch_level": -1.0}, "catch_level"),
    ],
)
def test_bad_catch_options_are_refused_by_name(options, match, pendulum) -> None:
    with pytest.raises(InvalidArgumentError, match=match):
        mpcbox.make_controller("mppi", pendulum, **options)
