"""Multiple-shooting iLQR (FDDP): defects, their closing, swing-ups from a state guess, MPC."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.config import config_options
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.multiple_shooting import GappedRollout, straight_line_states
from mpcbox.controllers.ilqr.result import StopReason
from mpcbox.errors import InvalidArgumentError, ShapeError
from mpcbox.tasks.swingup import CartpoleSwingup, PendulumSwingup

T = 150


def _pendulum():
    problem = PendulumSwingup(planning_timestep=0.02)
    return problem, problem.initial_state(), problem.reference_state()


def test_feasible_guess_has_no_defects_and_reproduces_single_shooting():
    problem, x0, _ = _pendulum()
    solver = ILQR(problem, horizon=60, ctrls_init=np.array([0.5]), threads=1)
    ctrls = np.tile([0.5], (60, 1))
    states = problem.rollout(x0, ctrls).states[0]
    gaps, cost = GappedRollout(problem, solver.ctrl_low, solver.ctrl_high).defects(states, ctrls)
    assert np.max(np.abs(gaps)) < 1e-12
    single = solver.solve(x0)
    multiple = solver.solve(x0, states_init=states)
    assert cost == pytest.approx(single.costs[0], rel=1e-12)
    assert multiple.cost == pytest.approx(single.cost, rel=1e-9)
    assert multiple.iterations == single.iterations and multiple.defect == 0.0


def test_partial_step_shrinks_every_defect_by_one_minus_alpha():
    problem, x0, goal = _pendulum()
    solver = ILQR(problem, horizon=40, threads=1)
    roll = GappedRollout(problem, solver.ctrl_low, solver.ctrl_high)
    states = straight_line_states(problem, x0, goal, 40)
    ctrls = np.zeros((40, 1))
    gaps, _ = roll.defects(states, ctrls)
    assert np.max(np.abs(gaps)) > 0.1
    k, K = np.full((40, 1), 0.3), np.zeros((40, 1, problem.nx))
    for alpha in (0.25, 0.5):
        new_states, new_ctrls, cost = roll.gapped(x0, states, ctrls, gaps, k, K, alpha)
        assert np.allclose(new_ctrls, alpha * 0.3)
        new_gaps, new_cost = roll.defects(new_states, new_ctrls)
        assert np.allclose(new_gaps, (1 - alpha) * gaps, atol=1e-9)
        assert new_cost == pytest.approx(cost, rel=1e-12)


def test_defects_left_open_at_the_iteration_cap_are_not_convergence():
    problem, x0, goal = _pendulum()
    solver = ILQR(problem, horizon=40, step_sizes=(0.5,), threads=1)
    states = straight_line_states(problem, x0, goal, 40)
    res = solver.solve(x0, np.zeros(1), states_init=states, max_iterations=2)
    start = GappedRollout(problem, solver.ctrl_low, solver.ctrl_high).defects(
        states, np.zeros((40, 1))
    )
    assert res.defect == pytest.approx(0.25 * np.max(np.abs(start[0])), rel=1e-9)
    assert not res.converged and res.stop_reason is StopReason.ITERATION_LIMIT
    assert res.start == "states"
    assert "defect" in res.status


def test_pendulum_swingup_from_zero_controls_and_a_straight_line():
    problem, x0, goal = _pendulum()
    solver = ILQR(problem, horizon=T, max_iterations=200, ctrls_init=np.zeros(1), threads=1)
    single = solver.solve(x0)
    assert not single.converged and single.stop_reason is StopReason.SADDLE
    res = solver.solve(x0, states_init=straight_line_states(problem, x0, goal, T))
    assert res.converged and res.defect == 0.0 and res.start == "states"
    assert single.start == "guess"
    assert problem.upright_error(res.states[-1]) < 0.05
    assert np.all(np.abs(res.ctrls) <= 2.0 + 1e-12)
    rollout = problem.rollout(x0, res.ctrls)  # a trajectory of the model, its cost the same
    assert np.allclose(rollout.states[0], res.states, atol=1e-9)
    assert float(problem.rollout_cost(rollout)[0]) == pytest.approx(res.cost, rel=1e-9)


def test_cartpole_swingup_from_zero_controls_and_a_straight_line():
    problem = CartpoleSwingup(planning_timestep=0.02)
    x0 = problem.initial_state()
    guess = straight_line_states(problem, x0, problem.reference_state(), T, arrival=105)
    solver = ILQR(problem, horizon=T, max_iterations=400, ctrls_init=np.zeros(1), threads=1)
    res = solver.solve(x0, states_init=guess)
    assert res.converged and res.defect == 0.0
    assert problem.upright_error(res.states[-1]) < 0.05
    assert abs(res.states[-1, 0]) < 0.1


def test_mpc_starts_from_a_state_guess_and_warm_starts_states():
    problem = PendulumSwingup()
    options = config_options(PendulumSwingup.controller_configs["ilqr"])
    horizon, dt = options["horizon"], options["planning_timestep"]
    planning = problem.with_planning_timestep(dt)
    guess = straight_line_states(
        planning, problem.initial_state(), problem.reference_state(), horizon
    )
    options.update(
        states_init=guess, ctrls_init=np.zeros(1), warm_start_states=True, replan_period=0.1
    )
    controller = ILQR(problem, **options)
    result = mpcbox.simulate(problem, controller, 4.0)
    assert result.failure is None
    assert problem.upright_error(result.states[-1]) < 0.1
    assert controller.stats["fallbacks"] == 0


def test_bad_state_guesses_raise_named_errors():
    problem, x0, goal = _pendulum()
    solver = ILQR(problem, horizon=10, threads=1)
    with pytest.raises(ShapeError, match="states_init"):
        solver.solve(x0, states_init=np.zeros((10, problem.nstate)))
    with pytest.raises(InvalidArgumentError, match="states_init"):
        solver.solve(x0, states_init=np.full((11, problem.nstate), np.nan))
    with pytest.raises(InvalidArgumentError, match="arrival"):
        straight_line_states(problem, x0, goal, 10, arrival=11)
    with pytest.raises(ShapeError, match="states_init"):
        ILQR(problem, horizon=10, states_init=np.zeros((3, problem.nstate)))
