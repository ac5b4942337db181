"""Contact-force QP-MPC: model, constraints, forces against the simulator, solver plumbing."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.contact import cone_violation
from mpcbox.disturbances import Push
from mpcbox.equilibrium import actuator_moment
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.qp_mpc import QPMPC, load_qp, to_qpsolvers
from mpcbox.simulation import simulate
from mpcbox.tasks.humanoid_balance import HumanoidBalance
from mpcbox.tasks.humanoid_two_feet import HumanoidTwoFeet


@pytest.fixture(scope="module")
def one_leg() -> HumanoidBalance:
    return HumanoidBalance(threads=1)


@pytest.fixture(scope="module")
def two_feet() -> HumanoidTwoFeet:
    return HumanoidTwoFeet(threads=1)


@pytest.fixture(scope="module")
def qp(one_leg) -> QPMPC:
    return QPMPC(one_leg)


def test_sizes_and_contacts(qp, one_leg):
    assert qp.points.count == 4  # two capsules on the stance foot, two ends each
    assert set(qp.points.label) == {"foot_left"}
    N = qp.horizon
    assert qp.nvar == N * (one_leg.nx + one_leg.nu + 12) + N * 6
    # The 0.02 s QP step is composed of 4 steps of the 0.005 s planning model.
    assert qp.substeps == 4 and qp.model.opt.timestep == pytest.approx(0.005)
    assert qp.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


def test_force_input_matrix_matches_the_actuator_columns(qp, one_leg):
    """``h M~^-1`` used for the forces reproduces the FD ``B`` of one substep ``h`` through the
    actuator moments, and the composed 0.02 s model matches 4 simulated substeps."""
    m, nv = qp.model, one_leg.nv
    h = m.opt.timestep
    data = mujoco.MjData(m)
    one_leg.set_state(data, qp.state_ref)
    mujoco.mj_fwdPosition(m, data)
    M = np.zeros((nv, nv))
    mujoco.mj_fullM(m, data, M)
    M += h * np.diag(m.dof_damping)
    Bv = h * np.linalg.solve(M, actuator_moment(m, data).T)
    Bh = qp._lin["Bh"]
    np.testing.assert_allclose(Bh[nv : 2 * nv], Bv, atol=1e-6 * np.abs(Bv).max())
    np.testing.assert_allclose(Bh[:nv], h * Bv, atol=1e-3 * np.abs(h * Bv).max())
    # Composition: a small control change held over the QP step, against the nonlinear model.
    du = np.zeros(one_leg.nu)
    du[0] = 1e-3
    ends = []
    for ctrl in (qp.ctrl_ref, qp.ctrl_ref + du):
        one_leg.set_state(data, qp.state_ref)
        data.ctrl[:] = ctrl
        mujoco.mj_step(m, data, qp.substeps)
        ends.append(one_leg.get_state(data))
    fd = one_leg.state_difference(ends[1], ends[0])
    np.testing.assert_allclose(qp._lin["B"] @ du, fd, atol=2e-2 * np.abs(fd).max())


def _contact_force_per_body(model, data, bodies):
    total = {b: 0.0 for b in bodies}
    f6 = np.zeros(6)
    for i in range(data.ncon):
        con = data.contact[i]
        mujoco.mj_contactForce(model, data, i, f6)
        world = con.frame.reshape(3, 3).T @ f6[:3]
        for g, sign in ((con.geom[0], -1.0), (con.geom[1], 1.0)):
            b = int(model.geom_bodyid[g])
            if b in total:
                total[b] += sign * world[2]
    return total


@pytest.mark.parametrize(
    "task",
    [
        "one_leg",
        pytest.param(
            "two_feet",
            marks=pytest.mark.xfail(
                reason="known issue: on two feet the N=10 QP-MPC drifts in torso pitch (its "
                "terminal cost is too optimistic), shifting the load between the feet (~13%)",
                strict=False,
            ),
        ),
    ],
)
def test_predicted_forces_match_the_simulator_and_respect_the_cones(task, request):
    problem = request.getfixturevalue(task)
    ctl = QPMPC(problem)
    plans = []
    solve = ctl.solve

    def record(state):
        plan = solve(state)
        plans.append(plan)
        return plan

    ctl.solve = record
    res = simulate(problem, ctl, 1.0)
    assert res.survived and res.metrics.fallbacks == 0
    for plan in plans:
        # Returned forces: inside the pyramid and bounds to 1e-6 of the weight.
        assert cone_violation(plan.forces, ctl.mu, ctl.facets, ctl.f_max) <= 1e-6 * ctl.weight
        # Raw solver output: within the solver tolerance.
        assert plan.violation <= 1e-2 * ctl.weight
    data = mujoco.MjData(problem.model)
    problem.set_state(data, res.states[-1])
    data.ctrl[:] = res.ctrls[-2]  # the control held over the last step
    mujoco.mj_forward(problem.model, data)
    bodies = [int(b) for b in np.unique(ctl.points.body)]
    measured = _contact_force_per_body(problem.model, data, bodies)
    plan = ctl.solve(res.states[-1])
    for body in bodies:
        predicted = plan.forces[0][ctl.points.body == body, 2].sum()
        assert predicted == pytest.approx(measured[body], rel=0.10), (task, body)


@pytest.mark.xfail(
    reason="not reached: measured 4 s runs, push 0.1 s at 0.5 s: one leg falls at 2.65 s after "
    "10 N and 2.29 s after 20 N (a slow torso-pitch drift); two feet falls at 2.75 s with no "
    "push (57 fallbacks). LQR on the QP's own rigid-stance model fails in the simulator the "
    "same way, LQR on the soft-contact model does not: the rigid stance model is the culprit",
    strict=False,
)
def test_survives_a_moderate_push(one_leg, two_feet):
    """Push recovery on one leg (20 N) and two feet (100 N), 0.1 s at 0.5 s, 4 s runs (long
    enough to see the slow drift that follows the push)."""
    for problem, force in ((one_leg, 20.0), (two_feet, 100.0)):
        push = [Push(force=(force, 0.0, 0.0), start=0.5, duration=0.1)]
        res = simulate(problem, QPMPC(problem), 4.0, pushes=push)
        assert res.survived and res.metrics.fallbacks == 0, problem.name


@pytest.mark.xfail(
    reason="not reached: with settle=1.5 s QP-MPC's largest one-leg push is 28 N (fails 32 N); "
    "LQR survives 35 N in 3 s runs; with longer runs QP-MPC falls after 10 N (see the xfail above)",
    strict=False,
)
def test_push_limit_at_least_lqr(one_leg):
    from mpcbox.evaluation import largest_push
    from mpcbox.lqr import LQR

    kw = dict(tolerance=8.0, max_force=64.0, settle=1.5)
    lqr = largest_push(one_leg, LQR(one_leg), **kw)
    qp = largest_push(one_leg, QPMPC(one_leg), **kw)
    assert qp.force >= lqr.force


def test_warm_start_reduces_iterations(one_leg):
    push = [Push(force=(20.0, 0.0, 0.0), start=0.2, duration=0.1)]
    iters = {}
    for warm in (True, False):
        ctl = QPMPC(one_leg, warm_start=warm)
        res = simulate(one_leg, ctl, 0.6, pushes=push)
        assert res.survived
        iters[warm] = ctl.stats["iterations"]
    assert iters[True] < iters[False]


def test_failed_solve_falls_back_and_is_counted(one_leg):
    ctl = QPMPC(one_leg, osqp_settings=dict(max_iter=1, check_termination=1))
    res = simulate(one_leg, ctl, 0.1)
    assert res.metrics.fallbacks >= 1
    assert any(k.startswith("failed:") for k in ctl.stats)
    assert np.all(np.isfinite(res.ctrls))


def test_qpsolvers_backend_agrees_with_osqp(qp, one_leg, tmp_path):
    import qpsolvers

    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05  # roll rate of the root
    plan = qp.solve(state)
    path = qp.export(tmp_path / "tick.npz")
    data = load_qp(path)
    assert data.P.shape == (qp.nvar, qp.nvar) and data.A.shape == (qp.ncon, qp.nvar)
    sol = qpsolvers.solve_problem(to_qpsolvers(data), solver="clarabel")
    assert sol.found
    u0 = qp._lin["ctrl"] + sol.x[qp._ou : qp._ou + one_leg.nu]
    np.testing.assert_allclose(u0, plan.ctrls[0], atol=2e-2)
    other = QPMPC(one_leg, solver="clarabel")
    np.testing.assert_allclose(other.solve(state).ctrls[0], u0, atol=1e-3)


def test_bad_input(one_leg):
    with pytest.raises(InvalidArgumentError, match="mu"):
        QPMPC(one_leg, mu=0.0)
    with pytest.raises(InvalidArgumentError, match="mu"):
        QPMPC(one_leg, mu=-1.0)
    with pytest.raises(InvalidArgumentError, match="horizon"):
        QPMPC(one_leg, horizon=0)
    with pytest.raises(UnknownNameError) as err:
        QPMPC(one_leg, contacts=["left_foot"])
    assert "foot_left" in str(err.value)
    with pytest.raises(UnknownNameError, match="foot_left"):
        QPMPC(one_leg, contacts=["site:left_foot"])
    with pytest.raises(UnknownNameError, match="osqp"):
        QPMPC(one_leg, solver="gurobi-not-installed")
    with pytest.raises(InvalidArgumentError, match="facets"):
        QPMPC(one_leg, facets=3)
