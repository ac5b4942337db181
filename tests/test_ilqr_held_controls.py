"""iLQR with knots that hold their control for several model steps (``control_steps``)."""

from __future__ import annotations

import numpy as np
import pytest
from test_ilqr import X0, point_mass, riccati

import mpcbox
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.held_controls import compose_held, scale_running
from mpcbox.core.derivatives import Quadratization
from mpcbox.core.dynamics import Linearization
from mpcbox.errors import InvalidArgumentError

STEPS = 3
KNOTS = 12


def held_riccati(problem: mpcbox.Problem, steps: int, knots: int):
    """The Riccati recursion of the knot map ``(A^s, sum_j A^j B)`` with the running weights
    counted ``s`` times, composed here independently of the solver."""
    A1, B1 = problem.linearize(np.zeros(4), np.zeros(2))
    A = np.linalg.matrix_power(A1, steps)
    B = sum(np.linalg.matrix_power(A1, j) @ B1 for j in range(steps))
    return riccati(problem, A, B, scale=steps, knots=knots)


def test_compose_held_is_the_jacobian_of_the_held_steps():
    # A damped pendulum: nonlinear, but the composition of one step's Jacobians is exact for
    # the linearization about its equilibrium, where every step has the same Jacobians.
    problem = mpcbox.Problem(
        """<mujoco><option timestep="0.01"/><worldbody><body>
        <joint name="j" axis="0 1 0" damping="0.2"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="1"/>
        </body></worldbody><actuator><motor joint="j"/></actuator></mujoco>""",
        threads=1,
    )
    x0, u0 = np.zeros(2), np.zeros(1)
    A1, B1 = problem.linearize(x0, u0, centered=True)
    A, B = compose_held(Linearization(A1, B1), 4)
    # Central differences of four steps of the model under one held control.
    eps, fd_A, fd_B = 1e-6, np.zeros((2, 2)), np.zeros((2, 1))

    def after(x, u):
        return problem.rollout(x, np.tile(u, (4, 1))).states[0, -1]

    for i in range(2):
        dx = np.zeros(2)
        dx[i] = eps
        fd_A[:, i] = (after(x0 + dx, u0) - after(x0 - dx, u0)) / (2 * eps)
    fd_B[:, 0] = (after(x0, u0 + eps) - after(x0, u0 - eps)) / (2 * eps)
    np.testing.assert_allclose(A, fd_A, atol=1e-6)
    np.testing.assert_allclose(B, fd_B, atol=1e-6)
    # Batched, as the solver calls it, and one step is the identity map.
    batch = compose_held(Linearization(np.stack([A1, A1]), np.stack([B1, B1])), 4)
    np.testing.assert_allclose(batch.A[1], A)
    assert compose_held(Linearization(A1, B1), 1).A is A1


def test_scale_running_leaves_the_terminal_row():
    rows = Quadratization(
        np.ones(3), np.ones((3, 2)), np.ones((3, 1)), np.ones((3, 2, 2)), np.ones((3, 1, 1)),
        np.ones((3, 1, 2)),
    )  # fmt: skip
    scaled = scale_running(rows, 5)
    for field in scaled:
        assert np.all(field[:2] == 5.0) and np.all(field[2] == 1.0)


def test_one_iteration_on_a_linear_quadratic_problem_is_the_held_riccati_solution():
    problem = point_mass()
    gains, xs, us = held_riccati(problem, STEPS, KNOTS)
    ilqr = ILQR(problem, horizon=KNOTS, control_steps=STEPS, regularization=0.0)
    assert ilqr.knot_dt == pytest.approx(STEPS * problem.dt)
    one = ilqr.solve(X0, max_iterations=1)
    np.testing.assert_allclose(one.ctrls, us, atol=1e-6)
    np.testing.assert_allclose(one.states, xs, atol=1e-6)  # the knots, every third step
    np.testing.assert_allclose(one.K, gains, rtol=1e-5, atol=1e-6)
    # The cost the solver reports is the plan's exact cost: every model step summed.
    roll = problem.rollout(X0, np.repeat(one.ctrls, STEPS, axis=0))
    np.testing.assert_allclose(roll.states[0, ::STEPS], one.states, atol=1e-9)
    assert one.cost == pytest.approx(float(problem.rollout_cost(roll)[0]), rel=1e-9)


def test_mpc_holds_each_knots_control_and_regulates():
    problem = point_mass()
    controller = ILQR(problem, horizon=KNOTS, control_steps=STEPS, replan_period=STEPS * problem.dt)
    sim = mpcbox.simulate(problem, controller, 3.0, initial_state=X0)
    ctrls = sim.ctrls[: STEPS * (len(sim.ctrls) // STEPS)].reshape(-1, STEPS, 2)
    assert np.abs(ctrls - ctrls[:, :1]).max() < 1e-12  # constant within each knot
    assert np.abs(ctrls[:, 0]).max() > 0.1  # and it does act
    assert np.linalg.norm(sim.states[-1]) < 0.05 * np.linalg.norm(X0)
    assert controller.stats["replans"] == pytest.approx(len(ctrls), abs=1)
    # The same plan length in knots of one step: nearly the same closed loop (the held
    # controls change every 0.15 s; the largest state difference is 4 % of the start's).
    fine = ILQR(problem, horizon=KNOTS * STEPS, replan_period=problem.dt)
    reference = mpcbox.simulate(problem, fine, 3.0, initial_state=X0)
    assert np.abs(sim.states - reference.states).max() < 0.06


def test_control_steps_is_checked():
    problem = point_mass()
    with pytest.raises(InvalidArgumentError, match="control_steps"):
        ILQR(problem, horizon=5, control_steps=0)
    with pytest.raises(InvalidArgumentError, match="control_steps"):
        ILQR(problem, horizon=5, control_steps=2, warm_start_states=True)
    with pytest.raises(InvalidArgumentError, match="control_steps"):
        ILQR(problem, horizon=5, control_steps=2, states_init=np.zeros((6, 4)))
    ilqr = ILQR(problem, horizon=5, control_steps=2)
    with pytest.raises(InvalidArgumentError, match="states_init"):
        ilqr.solve(X0, states_init=np.zeros((6, 4)))


def test_planners_built_on_ilqr_refuse_held_controls():
    from mpcbox.controllers.ipopt_controller import IpoptConfig
    from mpcbox.controllers.trajectory.offline_plan import OfflinePlanTracker

    with pytest.raises(InvalidArgumentError, match="control_steps"):
        IpoptConfig(ilqr_options={"control_steps": 2})
    with pytest.raises(InvalidArgumentError, match="control_steps"):
        OfflinePlanTracker(point_mass(), [np.zeros((5, 2))], solver_options={"control_steps": 3})
