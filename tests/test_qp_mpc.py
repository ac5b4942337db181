"""Contact-force QP-MPC: model, constraints, forces against the simulator, solver plumbing."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from mpcbox.controllers.lqr import LQR
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.controllers.qp_mpc.controller import QPMPC, TRUNCATED_UNUSABLE
from mpcbox.controllers.qp_mpc.solvers import constraint_residual, load_qp, to_qpsolvers
from mpcbox.core.contact import cone_violation
from mpcbox.core.equilibrium import actuator_moment
from mpcbox.errors import InvalidArgumentError, UnknownNameError, UnknownOptionError
from mpcbox.sim.disturbances import Push
from mpcbox.sim.simulation import simulate
from mpcbox.tasks.humanoid.balance import HumanoidBalance
from mpcbox.tasks.humanoid.two_feet import HumanoidTwoFeet


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
    # States, controls, forces, and per force one slack (force not predicted by the soft model).
    assert qp.stance_model == "soft"
    assert qp.nvar == N * (one_leg.nx + one_leg.nu + 12) + N * 12
    rigid = QPMPC(one_leg, stance_model="rigid")
    assert rigid.nvar == N * (one_leg.nx + one_leg.nu + 12) + N * 6  # 6 stance-twist slacks
    assert not qp.soft_model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    # The 0.02 s QP step is composed of 4 steps of the 0.005 s planning model.
    assert qp.substeps == 4 and qp.model.opt.timestep == pytest.approx(0.005)
    assert qp.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


def test_tuned_config_puts_the_contacts_on_the_stance_foot():
    from mpcbox.registry import make_controller

    for leg in ("left", "right"):
        problem = HumanoidBalance(leg=leg, threads=1)
        controller = make_controller("qp", problem)
        assert set(controller.points.label) == {f"foot_{leg}"}
        assert controller.points.count == 4
        problem.close()


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
    Bh = qp.linearization.Bh
    np.testing.assert_allclose(Bh[nv : 2 * nv], Bv, atol=1e-6 * np.abs(Bv).max())
    np.testing.assert_allclose(Bh[:nv], h * Bv, atol=1e-3 * np.abs(h * Bv).max())
    # Composition: a small control change held over the QP step, against the nonlinear
    # soft-contact model that the soft stance predicts with.
    du = np.zeros(one_leg.nu)
    du[0] = 1e-3
    ends = []
    soft = mujoco.MjData(qp.soft_model)
    for ctrl in (qp.ctrl_ref, qp.ctrl_ref + du):
        one_leg.set_state(soft, qp.state_ref)
        soft.ctrl[:] = ctrl
        mujoco.mj_step(qp.soft_model, soft, qp.substeps)
        ends.append(one_leg.get_state(soft))
    fd = one_leg.state_difference(ends[1], ends[0])
    np.testing.assert_allclose(qp.linearization.B @ du, fd, atol=2e-2 * np.abs(fd).max())


def test_force_law_predicts_the_soft_contact_forces(qp, one_leg):
    """``fbar + F_x dx + F_u du`` matches the simulator's contact forces near the reference,
    and at the reference the stance foot carries the whole weight."""
    lin = qp.linearization
    fbar = lin.fbar.reshape(-1, 3)
    assert fbar[:, 2].sum() == pytest.approx(1.0, rel=1e-3)  # in weights
    rng = np.random.default_rng(0)
    dx = 1e-4 * rng.standard_normal(one_leg.nx)
    du = 1e-3 * rng.standard_normal(one_leg.nu)
    actual = qp.dynamics.point_forces(one_leg.state_add(qp.state_ref, dx), qp.ctrl_ref + du)
    predicted = lin.fbar + lin.Fx @ dx + lin.Fu @ du
    change = actual - lin.fbar
    np.testing.assert_allclose(predicted - lin.fbar, change, atol=0.05 * np.abs(change).max())


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
        "two_feet",
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
        assert (
            cone_violation(plan.forces, ctl.friction, ctl.facets, ctl.f_max)
            <= 1e-6 * ctl.body_weight
        )
        # Raw solver output: within the solver tolerance.
        assert plan.violation <= 1e-2 * ctl.body_weight
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


def test_survives_a_moderate_push(one_leg, two_feet):
    """Push recovery on one leg (20 N) and two feet (60 N), 0.1 s at 0.5 s, 4 s runs (long
    enough to see the slow drift that follows the push), with no solve falling back. (With
    the presets' OSQP rho 0.3, one of 200 solves falls back after 80 N on two feet.)"""
    for problem, force in ((one_leg, 20.0), (two_feet, 60.0)):
        push = [Push(force=(force, 0.0, 0.0), start=0.5, duration=0.1)]
        ctl = QPMPC(problem, problem.controller_configs["qp"])
        res = simulate(problem, ctl, 4.0, pushes=push)
        assert res.survived and res.metrics.fallbacks == 0, problem.name


def test_push_limit_at_least_lqr(one_leg):
    from mpcbox.comparison.push_limits import largest_push, push_grid
    from mpcbox.comparison.scenario import PushTest
    from mpcbox.controllers.lqr import LQR

    # LQR's largest push by bisection; QP-MPC then survives 1.4 times it, which LQR does not
    # (one QP-MPC trial instead of a second bisection: QP-MPC's largest is about 60 N).
    test = PushTest(tolerance=4.0, max_force=96.0, settle=2.5)
    lqr = largest_push(one_leg, LQR(one_leg), test)
    assert 20.0 <= lqr.force and lqr.smallest_failed <= 1.4 * lqr.force
    qp = push_grid(
        one_leg, QPMPC(one_leg, one_leg.controller_configs["qp"]), [1.4 * lqr.force], test
    )
    print(f"largest push of LQR {lqr.force:.1f} N; QP-MPC at {qp.forces[0]:.1f} N: {qp.survived}")
    assert qp.survived.all()


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
    stats = ctl.stats
    assert res.metrics.fallbacks >= 1
    # Every failed solve is one fallback tick, counted by status and in total.
    assert stats["failed_solves"] == stats["fallbacks"] == stats["fallbacks_lqr"]
    assert stats["failed_solves"] == sum(v for k, v in stats.items() if k.startswith("failed:"))
    assert stats["solves"] >= stats["failed_solves"]
    assert np.all(np.isfinite(res.ctrls))


def test_rescue_backend_solves_what_osqp_fails(one_leg):
    """OSQP limited to one iteration fails every solve; Clarabel re-solves each one, so no
    tick falls back, and the rescued plan is the one Clarabel finds alone."""
    ctl = QPMPC(one_leg, osqp_settings=dict(max_iter=1, check_termination=1), rescue="clarabel")
    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05  # roll rate of the root
    u = ctl(state, 0.0)
    alone = QPMPC(one_leg, solver="clarabel").solve(state)
    np.testing.assert_allclose(u, one_leg.clip_ctrl(alone.ctrls[0]), atol=1e-6)
    res = simulate(one_leg, ctl, 0.06)
    stats = ctl.stats
    assert res.survived and stats["fallbacks"] == 0 and stats["failed_solves"] == 0
    assert (
        stats["rescued_solves"]
        == stats["solves"]
        == sum(v for k, v in stats.items() if k.startswith("failed:"))
    )
    with pytest.raises(UnknownNameError, match="clarabel"):
        QPMPCConfig(rescue="not-a-solver")


def test_time_limit_uses_the_last_iterate(one_leg):
    """A solve stopped at its time budget is not a failure while its last iterate is close
    to feasible (``truncated_residual``): the iterate is the plan (no fallback) and is
    counted as truncated; without a budget nothing is."""
    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05  # roll rate of the root
    full = QPMPC(one_leg)
    full(state, 0.0)
    cut = QPMPC(one_leg, time_limit=1e-7, truncated_residual=1e9)
    u = cut(state, 0.0)
    assert "time limit" in cut.last_status
    assert cut.stats["truncated_solves"] == cut.stats["solves"] == 1
    assert cut.stats["fallbacks"] == 0 and full.stats["truncated_solves"] == 0
    assert cut.stats["solver_iterations"] < full.stats["solver_iterations"]
    assert np.all(np.isfinite(u)) and not np.allclose(u, full.last_plan.ctrls[0])
    res = simulate(one_leg, cut, 0.1)
    assert res.metrics.fallbacks == 0
    assert cut.stats["truncated_solves"] == cut.stats["solves"] == res.metrics.solve_ticks


def test_time_limit_rejects_an_iterate_far_from_feasible(one_leg):
    """A truncated iterate whose first stage violates its rows by more than
    ``truncated_residual`` is a failed solve: the fallback (LQR) runs, and the status and
    counts say why."""
    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05
    probe = QPMPC(one_leg, time_limit=1e-7, truncated_residual=1e9)
    probe(state, 0.0)
    first = constraint_residual(probe.qp, probe._prev_z, probe.layout.first_stage_rows)
    whole = constraint_residual(probe.qp, probe._prev_z)
    assert 1e-9 < first <= whole  # one iteration from a cold start is not feasible
    converged = QPMPC(one_leg)
    converged(state, 0.0)
    assert constraint_residual(converged.qp, converged._prev_z) < 1e-3
    strict = QPMPC(one_leg, time_limit=1e-7, truncated_residual=first / 2)
    u = strict(state, 0.0)
    assert strict.last_status == TRUNCATED_UNUSABLE
    stats = strict.stats
    assert stats["fallbacks"] == stats["failed_solves"] == stats[f"failed:{TRUNCATED_UNUSABLE}"]
    assert stats["fallbacks"] == 1 and stats["truncated_solves"] == 0
    np.testing.assert_allclose(u, LQR(one_leg)(state, 0.0), atol=1e-9)
    loose = QPMPC(one_leg, time_limit=1e-7, truncated_residual=first * 2)
    loose(state, 0.0)
    assert loose.stats["truncated_solves"] == 1 and loose.stats["fallbacks"] == 0
    with pytest.raises(InvalidArgumentError, match="truncated_residual"):
        QPMPCConfig(truncated_residual=0.0)


def test_lqr_feedback_between_ticks_tracks_the_plan(one_leg):
    """``between_ticks="lqr"``: called every simulation step, solving every ``period``; in
    between, the plan's control plus the LQR gain on the error to the plan's predicted
    state, linearly interpolated: zero feedback on the prediction, ``-K e`` off it."""
    h = float(one_leg.model.opt.timestep)
    ctl = QPMPC(one_leg, period=0.02, between_ticks="lqr")
    assert ctl.period == pytest.approx(h) and ctl.replan_period == pytest.approx(0.02)
    assert QPMPC(one_leg, period=0.02).period == pytest.approx(0.02)  # "hold": as before
    x0 = one_leg.reference_state()
    x0[one_leg.nq + 3] = 0.05  # roll rate of the root
    u0 = ctl(x0, 0.0)
    plan, K = ctl.last_plan, ctl._fallback_lqr().K
    assert ctl.last_call == "solve"
    np.testing.assert_allclose(u0, one_leg.clip_ctrl(plan.ctrls[0]), atol=1e-12)
    t = 0.75 * ctl.dt  # three quarters of the way to the plan's first predicted state
    on_plan = one_leg.state_add(ctl.state_ref, 0.25 * plan.dx[0] + 0.75 * plan.dx[1])
    np.testing.assert_allclose(ctl(on_plan, t), one_leg.clip_ctrl(plan.ctrls[0]), atol=1e-9)
    assert ctl.last_call == "hold" and ctl.stats["solves"] == 1
    kick = np.zeros(one_leg.nx)
    kick[one_leg.nv + 3] = 0.02  # a roll rate off the prediction
    off_plan = one_leg.state_add(on_plan, kick)
    expected = one_leg.clip_ctrl(plan.ctrls[0] - K @ kick)
    np.testing.assert_allclose(ctl(off_plan, t), expected, atol=1e-9)
    assert not np.allclose(expected, one_leg.clip_ctrl(plan.ctrls[0]))
    ctl(off_plan, 0.02)  # a replanning period after the solve
    assert ctl.last_call == "solve" and ctl.stats["solves"] == 2
    res = simulate(one_leg, ctl, 0.1)
    assert res.survived and res.metrics.fallbacks == 0
    assert res.metrics.solve_ticks == 5 and res.metrics.held_ticks == round(0.1 / h) - 5
    assert res.metrics.period_s == pytest.approx(0.02)  # a solve's budget
    with pytest.raises(InvalidArgumentError, match=r"between_ticks.*'hold', 'lqr'"):
        QPMPCConfig(between_ticks="pid")
    # Every solve failing is a degraded run, however many held calls come in between.
    failing = QPMPC(one_leg, period=0.02, between_ticks="lqr", osqp_settings=dict(max_iter=1))
    res = simulate(one_leg, failing, 0.1)
    assert res.metrics.fallbacks == res.metrics.solve_ticks < res.metrics.held_ticks
    assert res.metrics.outcome == "degraded", res.failure


@pytest.mark.parametrize("fallback", ["lqr", "plan"])
def test_fallback_after_failed_solves(one_leg, fallback):
    ctl = QPMPC(one_leg, horizon=10, dt=0.02, period=0.02, fallback=fallback)
    x0 = one_leg.reference_state()
    ctl(x0, 0.0)
    plan = ctl.last_plan
    ctl.solve = lambda state: None  # every later solve fails
    x1 = x0.copy()
    x1[one_leg.nq + 3] = 0.1  # a roll rate the plan did not predict
    lqr = ctl._fallback_lqr()
    for k in range(1, 11):
        u = ctl(x1, 0.02 * k)
        if fallback == "plan" and k < 10:  # open-loop replay while the plan lasts
            np.testing.assert_allclose(u, one_leg.clip_ctrl(plan.ctrls[k]), atol=1e-12)
        else:
            np.testing.assert_allclose(u, lqr(x1, 0.02 * k), atol=1e-12)
    stats = ctl.stats
    assert stats["fallbacks"] == 10
    replayed = 9 if fallback == "plan" else 0
    assert stats["fallbacks_plan"] == replayed and stats["fallbacks_lqr"] == 10 - replayed


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
    u0 = qp.linearization.ctrl + sol.x[qp.layout.ou : qp.layout.ou + one_leg.nu]
    np.testing.assert_allclose(u0, plan.ctrls[0], atol=2e-2)
    other = QPMPC(one_leg, solver="clarabel")
    np.testing.assert_allclose(other.solve(state).ctrls[0], u0, atol=1e-3)


def test_bad_input(one_leg):
    with pytest.raises(InvalidArgumentError, match="friction"):
        QPMPC(one_leg, friction=0.0)
    with pytest.raises(InvalidArgumentError, match="friction"):
        QPMPC(one_leg, friction=-1.0)
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
    with pytest.raises(InvalidArgumentError, match=r"fallback.*'lqr'"):
        QPMPC(one_leg, fallback="hold")
    with pytest.raises(InvalidArgumentError, match="time_limit"):
        QPMPCConfig(time_limit=0.0)
    with pytest.raises(InvalidArgumentError, match=r"time_limit.*osqp"):
        QPMPCConfig(time_limit=0.01, solver="clarabel")


@pytest.mark.parametrize("stance_model", ["soft", "rigid"])
def test_terminal_matrices(two_feet, stance_model):
    """Every terminal choice builds for both stance models (two feet: 12 stance-twist rows, 24
    force rows). ``"cost"`` is the running ``Q``; the Riccati ones solve their DARE, so they
    dominate the ``Q`` they weigh (``P - Q = A^T (P^{-1} + B R^{-1} B^T)^{-1} A >= 0``). On
    the soft-contact model sliding the whole body is uncontrollable, and ``"lqr"`` weighs
    the rest of the state, ``(I - Pi_u) x``."""
    from mpcbox.controllers.qp_mpc.dynamics import compose
    from mpcbox.controllers.uncontrollable import uncontrollable_marginal_projector

    opts = dict(contacts=two_feet.contacts, stance_model=stance_model, horizon=3)
    for terminal in ("cost", "lqr", "stance"):
        qp = QPMPC(two_feet, terminal=terminal, terminal_scale=2.0, **opts)
        P = qp.P_terminal / 2.0
        np.testing.assert_allclose(P, P.T, atol=1e-12 * np.abs(P).max())
        if terminal != "lqr":
            assert np.linalg.eigvalsh(P - qp.Q).min() > -1e-6 * np.abs(P).max()
        if terminal == "cost":
            np.testing.assert_allclose(P, qp.Q, atol=1e-9 * np.abs(qp.Q).max())
        if terminal == "lqr":  # the soft-contact model at dt, composed of its substeps
            soft = copy.copy(two_feet.planning_model)
            soft.opt.timestep = qp.dt / qp.substeps
            d = mujoco.MjData(soft)
            two_feet.set_state(d, qp.state_ref)
            d.ctrl[:] = qp.ctrl_ref
            nx, nu = two_feet.nx, two_feet.nu
            Ah, Bh = np.zeros((nx, nx)), np.zeros((nx, nu))
            mujoco.mjd_transitionFD(soft, d, two_feet.fd_eps, True, Ah, Bh, None, None)
            A, S = compose(Ah, qp.substeps)
            B = S @ Bh
            sliding = uncontrollable_marginal_projector(A, B)
            assert sliding is not None and np.linalg.matrix_rank(sliding, 1e-6) >= 2
            keep = np.eye(nx) - sliding
            Q = keep.T @ qp.Q @ keep
            assert np.linalg.eigvalsh(P - Q).min() > -1e-6 * np.abs(P).max()
            np.testing.assert_allclose(P @ sliding, 0.0, atol=1e-9 * np.abs(P).max())
            G = qp.R + B.T @ P @ B
            rhs = Q + A.T @ P @ A - A.T @ P @ B @ np.linalg.solve(G, B.T @ P @ A)
            np.testing.assert_allclose(rhs, P, atol=1e-6 * np.abs(P).max())


def test_config_object_and_keywords_agree(one_leg):
    """``QPMPC(problem, config)`` and keyword options build the same controller; options
    outside :class:`QPMPCConfig` (such as the old ``mu``) are rejected, naming the valid ones;
    a bad field is named in the error."""
    a = QPMPC(one_leg, QPMPCConfig(horizon=5, friction=0.5, stance_model="rigid"))
    b = QPMPC(one_leg, horizon=5, friction=0.5, stance_model="rigid")
    assert a.config == b.config and a.friction == 0.5
    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05
    np.testing.assert_array_equal(a.solve(state).ctrls, b.solve(state).ctrls)
    with pytest.raises(UnknownOptionError, match="friction"):
        QPMPC(one_leg, mu=0.7)
    with pytest.raises(InvalidArgumentError, match="drift_gain"):
        QPMPCConfig(drift_gain=2.0)
    with pytest.raises(InvalidArgumentError, match="stance_weight"):
        QPMPCConfig(stance_weight=None)
    with pytest.raises(InvalidArgumentError, match="terminal"):
        QPMPCConfig(terminal="riccati")


def test_lifted_points_are_dropped_without_changing_the_plan(one_leg):
    """Both feet named on one leg: the swing foot (10 cm up at the reference) is dropped by
    default; kept, its points can carry no force, so the plan is the same."""
    feet = ("body:foot_left", "body:foot_right")
    dropped = QPMPC(one_leg, contacts=feet)
    kept = QPMPC(one_leg, contacts=feet, lifted_points="keep")
    assert set(dropped.points.label) == {"foot_left"} and dropped.points.count == 4
    assert kept.points.count == 8 and kept.nvar > dropped.nvar
    state = one_leg.reference_state()
    state[one_leg.nq + 3] = 0.05  # roll rate of the root
    a, b = dropped.solve(state), kept.solve(state)
    np.testing.assert_allclose(a.ctrls[0], b.ctrls[0], atol=2e-2)
    assert np.all(b.forces[:, kept.points.label.index("foot_right") :] == 0.0)
    with pytest.raises(InvalidArgumentError, match="lifted_points"):
        QPMPCConfig(lifted_points="never")


@pytest.mark.menagerie
def test_quadruped_forces_go_to_the_points_on_the_ground():
    """Menagerie's A1 with its four calves as contact bodies (20 points: calf capsule ends and
    foot spheres). The calf capsule's end touches the floor next to the foot sphere, 1 cm above
    the sphere's bottom; its force must go to the foot's point on the ground, and a point at
    that threshold must not flip inside the finite differences of the force law. Standing
    under 1 N m of torque noise then needs no fallback."""
    from mpcbox.core.equilibrium import find_equilibrium
    from mpcbox.core.model import compile_spec, load_spec
    from mpcbox.core.problem import Problem
    from mpcbox.sim.disturbances import ActuatorNoise

    spec = load_spec("menagerie:unitree_a1")
    model = compile_spec(spec)
    eq = find_equilibrium(model, model.key_qpos[0])
    problem = Problem(spec, qpos_ref=eq.qpos, ctrl_ref=eq.ctrl, threads=1)
    feet = [f"body:{leg}_calf" for leg in ("FR", "FL", "RR", "RL")]
    keep = QPMPC(problem, contacts=feet, lifted_points="keep")
    touching, _ = keep.dynamics.activity(keep.state_ref)
    assert keep.points.count == 20
    # Every calf stands on a point; on newer Menagerie A1s (foot solimp width 0.02 instead
    # of 0.031) one calf's capsule end is within the margin too and shares the force.
    assert all(touching[i : i + 5].any() for i in range(0, 20, 5)) and touching.sum() <= 8
    fbar = keep.linearization.fbar.reshape(-1, 3)
    assert np.all(fbar[~touching] == 0.0)
    assert fbar[touching, 2].sum() == pytest.approx(1.0, rel=0.02)  # in body weights
    # Force law against the simulator for a small step: within 10% of the change (a point
    # flipping inside the differences gives entries of ~1e5, a thousand times the change).
    rng = np.random.default_rng(0)
    dx = 1e-5 * rng.standard_normal(problem.nx)
    lin = keep.linearization
    # Under the nominal contact mode, as the finite differences take it: on newer A1s a
    # capsule end sits within 1e-5 m of the margin and would flip in or out here.
    moved = problem.state_add(keep.state_ref, dx)
    actual = keep.dynamics.point_forces(moved, keep.ctrl_ref, touching)
    change = actual - lin.fbar
    np.testing.assert_allclose(lin.Fx @ dx, change, atol=0.1 * np.abs(change).max())
    ctl = QPMPC(problem, contacts=feet)
    assert ctl.points.count == touching.sum()  # the lifted points are dropped
    assert sorted(set(ctl.points.label)) == sorted(f[5:] for f in feet)
    gain = model.actuator_gainprm[:, 0] * model.actuator_gear[:, 0]
    res = simulate(problem, ctl, 1.0, noise=ActuatorNoise(std=1.0 / gain), seed=0)
    assert res.survived and ctl.stats["failed_solves"] == 0 and ctl.stats["fallbacks"] == 0


def test_force_law_of_a_lifted_point_is_dropped_or_cancelled(one_leg):
    """With the stance foot 3 cm above the floor every point is lifted (normal force bound 0).
    ``"drop"`` leaves their linearized force law out (free rows), ``"cancel"`` keeps it (rows
    equal to the law); a touching foot keeps its law either way."""
    drop = QPMPC(one_leg, lifted_force_law="drop")
    cancel = QPMPC(one_leg, lifted_force_law="cancel")
    L = drop.formulation.layout
    rows = slice(L.r_st, L.r_st + L.horizon * L.ns)
    lifted = one_leg.reference_state()
    lifted[2] += 0.03
    for state, free in ((one_leg.reference_state(), False), (lifted, True)):
        _, lo_d, hi_d = drop.formulation.vectors(drop.linearization, state)
        _, lo_c, hi_c = cancel.formulation.vectors(cancel.linearization, state)
        assert np.all(np.isfinite(lo_c[rows])) and np.array_equal(lo_c[rows], hi_c[rows])
        assert np.all(np.isinf(lo_d[rows])) == free and np.all(np.isinf(hi_d[rows])) == free
        if not free:
            np.testing.assert_array_equal(lo_d[rows], lo_c[rows])
    with pytest.raises(InvalidArgumentError, match="lifted_force_law"):
        QPMPCConfig(lifted_force_law="never")


BLOCK = """
<mujoco>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body {name} pos="0 0 0.1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor joint="x"/><motor joint="z"/></actuator>
</mujoco>
"""


def test_default_contacts_name_the_touching_body_or_refuse_an_unnamed_one():
    """Contacts found by touch are passed on by name: an unnamed body touching the floor (as
    in mujoco-warp's adhesion test model) used to raise a raw TypeError (str + None)."""
    from mpcbox.controllers.qp_mpc.controller import default_contacts
    from mpcbox.core.problem import Problem

    named = Problem(BLOCK.format(name='name="block"'), threads=1)
    assert default_contacts(named, named.reference_state()) == ["body:block"]
    unnamed = Problem(BLOCK.format(name=""), threads=1)
    with pytest.raises(InvalidArgumentError, match=r"unnamed bodies \(ids \[1\]\).*contacts="):
        QPMPC(unnamed)
    floating = Problem(BLOCK.format(name='name="block"').replace("0 0 0.1", "0 0 0.5"), threads=1)
    with pytest.raises(InvalidArgumentError, match=r"nothing touches the ground.*for LQR, iLQR"):
        QPMPC(floating)


def test_free_first_stage_forces_unbound_only_the_touching_points_of_stage_zero(one_leg):
    """``first_stage_forces="free"`` lifts the pyramid and normal bounds of the first stage's
    touching points; the swing foot's points (lifted) keep their zero bound, later stages keep
    all bounds, and at the reference, where no bound is active, the plan is the same."""
    feet = ("body:foot_left", "body:foot_right")
    bounded = QPMPC(one_leg, contacts=feet, lifted_points="keep")
    free = QPMPC(one_leg, contacts=feet, lifted_points="keep", first_stage_forces="free")
    state = one_leg.reference_state()
    L = free.formulation.layout
    k, F = L.points, L.facets
    _, lo_b, hi_b = bounded.formulation.vectors(bounded.linearization, state)
    _, lo_f, hi_f = free.formulation.vectors(free.linearization, state)
    touching, _ = free.dynamics.activity(state)
    assert 0 < touching.sum() < k  # the stance foot touches, the swing foot does not
    fn = slice(L.r_fn, L.r_fn + k)
    assert np.all(np.isinf(hi_f[fn][touching])) and np.all(np.isinf(lo_f[fn][touching]))
    assert np.all(hi_f[fn][~touching] == 0.0) and np.all(lo_f[fn][~touching] == 0.0)
    pyramid0 = hi_f[L.r_fr : L.r_fr + k * F].reshape(k, F)
    assert np.all(np.isinf(pyramid0[touching])) and np.all(pyramid0[~touching] == 0.0)
    later = np.r_[L.r_fr + k * F : L.r_fn, L.r_fn + k : L.r_u]
    np.testing.assert_array_equal(hi_f[later], hi_b[later])
    np.testing.assert_array_equal(lo_f[later], lo_b[later])
    np.testing.assert_allclose(free.solve(state).ctrls[0], bounded.solve(state).ctrls[0], atol=1e-3)
    with pytest.raises(InvalidArgumentError, match="first_stage_forces"):
        QPMPCConfig(first_stage_forces="loose")
    with pytest.raises(InvalidArgumentError, match="stance_model='soft'"):
        QPMPCConfig(first_stage_forces="free", stance_model="rigid")


def test_joint_limits_hold_the_plan_inside_each_range(one_leg):
    """``joint_limits=True`` adds each limited hinge's range at every stage (a numpy joint
    type compared with a tuple of MuJoCo's enum values had left it without any)."""
    free = QPMPC(one_leg)
    settings = {"max_iter": 20000, "adaptive_rho": True}
    held = QPMPC(one_leg, joint_limits=True, osqp_settings=settings)
    limits = held.formulation.limits
    limited = [
        j
        for j in range(one_leg.model.njnt)
        if one_leg.model.jnt_limited[j] and one_leg.model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    assert len(limits.qpos) == len(limited) > 0
    rows = held.formulation.A.shape[0] - free.formulation.A.shape[0]
    assert rows == held.horizon * len(limited)
    crossed = 0
    for k in range(len(limits.qpos)):
        # 0.02 rad below the upper limit, moving towards it at 0.5 rad/s.
        state = one_leg.initial_state()
        state[limits.qpos[k]] = limits.high[k] - 0.02
        state[one_leg.nq + limits.dofs[k]] = 0.5
        peaks = []
        for controller in (free, held):
            controller.reset()
            plan = controller.solve(state)
            assert plan is not None
            q = one_leg.qpos_ref[limits.qpos[k]] + plan.dx[:, limits.dofs[k]]
            peaks.append(float(q.max() - limits.high[k]))
        crossed += peaks[0] > 0.01
        assert peaks[1] <= 1e-3, (k, peaks)
    assert crossed >= 1  # without the limits some plan goes through one
