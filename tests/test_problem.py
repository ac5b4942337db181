"""Problem: tangent-space states, finite-difference linearization, costs, rollouts, errors."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.cost import (
    ComOverSupport,
    ControlCost,
    Cost,
    FrameHeight,
    FramePosition,
    HeightAbove,
    StateCost,
    Upright,
)
from mpcbox.core.derivatives import residual_fd
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.balance import HumanoidBalance

HUMANOID = scene_path("humanoid.xml")


@pytest.fixture(scope="module")
def balance() -> HumanoidBalance:
    return HumanoidBalance()


def random_humanoid_state(problem: mpcbox.Problem, rng: np.random.Generator, scale: float = 0.1):
    x = problem.reference_state()
    dx = scale * rng.standard_normal(problem.nx)
    return problem.state_add(x, dx), dx


def test_tangent_difference_matches_mj_differentiate_pos(balance):
    rng = np.random.default_rng(0)
    m = balance.model
    qa = np.array([random_humanoid_state(balance, rng, 0.5)[0][: m.nq] for _ in range(20)])
    qb = np.array([random_humanoid_state(balance, rng, 0.5)[0][: m.nq] for _ in range(20)])
    ours = balance.tangent.difference(qb, qa)
    for i in range(20):
        ref = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, ref, 1.0, qa[i], qb[i])
        np.testing.assert_allclose(ours[i], ref, atol=1e-10)


def test_state_add_inverts_state_difference(balance):
    rng = np.random.default_rng(1)
    x0 = balance.reference_state()
    dx = 0.3 * rng.standard_normal(balance.nx)
    x1 = balance.state_add(x0, dx)
    np.testing.assert_allclose(balance.state_difference(x1, x0), dx, atol=1e-10)


def test_linearization_predicts_small_perturbations():
    # Pendulum away from any contact: the one-step map is smooth, so A dx + B du must predict
    # the change of the next state to second order.
    problem = mpcbox.Problem(scene_path("pendulum.xml"))
    x0 = np.array([0.7, -0.3])
    u0 = np.array([0.5])
    lin = problem.linearize(x0, u0)
    rng = np.random.default_rng(2)
    for _ in range(5):
        dx = 1e-4 * rng.standard_normal(problem.nx)
        du = 1e-4 * rng.standard_normal(problem.nu)
        pred = lin.A @ dx + lin.B @ du
        actual = problem.state_difference(
            problem.step(problem.state_add(x0, dx), u0 + du), problem.step(x0, u0)
        )
        np.testing.assert_allclose(actual, pred, rtol=1e-3, atol=1e-8)


def test_humanoid_linearization_is_tangent_space(balance):
    x, _ = random_humanoid_state(balance, np.random.default_rng(3), 0.02)
    lin = balance.linearize(x, balance.ctrl_ref)
    assert lin.A.shape == (54, 54) and lin.B.shape == (54, 21)
    assert np.all(np.isfinite(lin.A)) and np.all(np.isfinite(lin.B))
    forward = balance.linearize(x, balance.ctrl_ref, centered=False)
    # Forward and centered differences agree to first order.
    assert np.max(np.abs(forward.B - lin.B)) < 1e-3 * max(1.0, np.max(np.abs(lin.B)))


def test_linearize_trajectory_threads_match_serial(balance):
    rng = np.random.default_rng(4)
    states = np.array([random_humanoid_state(balance, rng, 0.02)[0] for _ in range(6)])
    ctrls = balance.ctrl_ref + 0.05 * rng.standard_normal((6, balance.nu))
    serial = balance.linearize_trajectory(states, ctrls, threads=1)
    threaded = balance.linearize_trajectory(states, ctrls, threads=2)
    np.testing.assert_array_equal(serial.A, threaded.A)
    np.testing.assert_array_equal(serial.B, threaded.B)
    np.testing.assert_array_equal(serial.A[3], balance.linearize(states[3], ctrls[3]).A)


@pytest.mark.parametrize(
    "term",
    [
        ComOverSupport("foot_left", weight=10.0, root="torso"),
        Upright("torso", weight=[2.0, 3.0]),
        FrameHeight("hand_left", 1.5, weight=4.0),
        HeightAbove("hand_left", "foot_right", 1.0, weight=2.0),
        FramePosition("hand_right", np.array([0.2, -0.3, 1.0]), weight=1.0),
        FramePosition("foot_right", np.zeros(3), weight=[1.0, 1.0, 0.0]),
    ],
    ids=lambda t: type(t).__name__,
)
def test_analytic_residual_jacobians_match_finite_differences(term):
    problem = mpcbox.Problem(HUMANOID, keyframe="stand_on_left_leg", cost=Cost([term]))
    x, _ = random_humanoid_state(problem, np.random.default_rng(5), 0.1)
    u = np.zeros(problem.nu)
    data = problem.scratch_data()
    problem.set_state(data, x)
    mujoco.mj_forward(problem.planning_model, data)
    jac = term.jacobian(problem.planning_model, data)
    r0 = term.residual(problem.features(x, u))[0]
    fd_x, fd_u = residual_fd(problem.dynamics, problem.tangent, term, x, u, r0, problem.fd_eps)
    np.testing.assert_allclose(jac.dq, fd_x[:, : problem.nv], atol=2e-5)
    np.testing.assert_allclose(jac.du, fd_u, atol=1e-8)


def test_quadratize_is_gauss_newton_of_the_cost(balance):
    x, _ = random_humanoid_state(balance, np.random.default_rng(6), 0.05)
    u = balance.ctrl_ref + 0.1
    quad = balance.quadratize(x, u)
    assert quad.value == pytest.approx(balance.running_cost(x, u), rel=1e-12)
    # The gradient matches finite differences of the cost itself.
    eps = 1e-6
    for i in [0, 5, 10, 30, 50]:
        dx = np.zeros(balance.nx)
        dx[i] = eps
        up = balance.running_cost(balance.state_add(x, dx), u)
        dn = balance.running_cost(balance.state_add(x, -dx), u)
        assert (up - dn) / (2 * eps) == pytest.approx(quad.lx[i], rel=1e-3, abs=1e-4)
    np.testing.assert_allclose(quad.lxx, quad.lxx.T, atol=1e-12)
    assert np.linalg.eigvalsh(quad.lxx).min() > -1e-9


def test_rollout_sensordata_rows_match_forward(balance):
    rng = np.random.default_rng(7)
    ctrls = balance.ctrl_ref + 0.1 * rng.standard_normal((3, 8, balance.nu))
    x0 = balance.reference_state()
    roll = balance.rollout(x0, ctrls)
    assert roll.states.shape == (3, 9, balance.nstate)
    # Row t of sensordata belongs to states[:, t]; the step matches Problem.step.
    np.testing.assert_allclose(roll.states[1, 1], balance.step(x0, ctrls[1, 0]), atol=1e-12)
    feats = balance.features(roll.states[2, 4], ctrls[2, 4])
    np.testing.assert_allclose(roll.sensordata[2, 4], feats.sensordata[0], atol=1e-9)
    costs = balance.rollout_cost(roll)
    manual = sum(balance.running_cost(roll.states[0, t], roll.ctrls[0, t]) for t in range(8))
    manual += balance.terminal_cost(roll.states[0, 8])
    assert costs[0] == pytest.approx(manual, rel=1e-9)


def test_rollouts_that_mujoco_reset_after_diverging_are_marked_nan(capfd):
    """With one Newton iteration MuJoCo's CPU solver blows up on the humanoid: mj_step warns
    (mjWARN_BADQACC) and resets. Those rollouts must not be scored from the reset pose, and
    the warning is read from the rollout, not printed."""
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = HumanoidStand().with_planning_timestep(0.01)
    model = problem.planning_model
    model.opt.iterations = 1
    rng = np.random.default_rng(0)
    ctrls = np.repeat(problem.clip_ctrl(problem.ctrl_ref + rng.normal(0, 0.2, (8, 1, 21))), 40, 1)
    roll = problem.rollout(problem.initial_state(), ctrls)
    printed = capfd.readouterr()
    assert "QACC" not in printed.out + printed.err
    # Reference: step each sequence by hand and read MuJoCo's warning counter, over the T
    # steps of the states and over one more (the terminal sensors are read in step T + 1).
    data = mujoco.MjData(model)
    warned, warned_terminal = [], []
    for seq in ctrls:
        mujoco.mj_resetData(model, data)
        problem.set_state(data, problem.initial_state())
        for t, u in enumerate([*seq, seq[-1]]):
            if t == len(seq):
                warned.append(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0)
            data.ctrl[:] = u
            mujoco.mj_step(model, data)
        warned_terminal.append(data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0)
    nan = ~np.isfinite(roll.states).all(axis=(1, 2))
    assert np.array_equal(nan, np.array(warned)) and 0 < nan.sum() < 8
    costs = problem.rollout_cost(roll)
    assert np.array_equal(~np.isfinite(costs), np.array(warned_terminal))


def test_equilibrium_holds_the_pose(balance):
    eq = balance.equilibrium
    assert abs(eq.vertical_residual) <= 1e-3
    # Holding ctrl_ref from the equilibrium, the root barely moves over 0.1 s.
    data = mujoco.MjData(balance.model)
    balance.set_state(data, balance.reference_state())
    data.ctrl[:] = balance.ctrl_ref
    for _ in range(20):
        mujoco.mj_step(balance.model, data)
    assert np.linalg.norm(data.qpos[:3] - balance.qpos_ref[:3]) < 2e-3


def test_planning_model_is_separate():
    problem = mpcbox.Problem(HUMANOID, keyframe="stand", planning_timestep=0.015)
    assert problem.model.opt.timestep == pytest.approx(0.005)
    assert problem.planning_model.opt.timestep == pytest.approx(0.015)
    assert problem.dt == pytest.approx(0.015)


def test_bad_inputs_raise_clear_errors(balance):
    with pytest.raises(mpcbox.ModelNotFoundError, match="no MJCF file"):
        mpcbox.Problem("does/not/exist.xml")
    # A bare name (a Menagerie robot given the way problems/*.py take it) gets a hint.
    with pytest.raises(mpcbox.ModelNotFoundError, match="write 'menagerie:unitree_g1'"):
        mpcbox.Problem("unitree_g1")
    with pytest.raises(mpcbox.UnknownNameError, match="stand_on_left_leg"):
        mpcbox.Problem(HUMANOID, keyframe="nope")
    with pytest.raises(mpcbox.UnknownNameError, match="foot_left"):
        mpcbox.Problem(HUMANOID, cost=Cost([ComOverSupport("foot_middle", weight=1.0)]))
    with pytest.raises(mpcbox.ShapeError, match="state must have shape"):
        balance.linearize(np.zeros(3), balance.ctrl_ref)
    with pytest.raises(mpcbox.ShapeError, match="ctrl must have shape"):
        balance.linearize(balance.reference_state(), np.zeros(3))
    bad = balance.reference_state()
    bad[7] = np.nan
    with pytest.raises(mpcbox.DivergenceError, match="non-finite"):
        balance.linearize(bad, balance.ctrl_ref)
    with pytest.raises(mpcbox.InvalidArgumentError, match="weight"):
        mpcbox.Problem(HUMANOID, cost=Cost([ControlCost(weight=[np.inf] * 21)]))
    with pytest.raises(mpcbox.InvalidArgumentError, match="fd_eps"):
        mpcbox.Problem(HUMANOID, fd_eps=-1.0)
    static = "<mujoco><worldbody><geom type='plane' size='1 1 0.1'/></worldbody></mujoco>"
    with pytest.raises(mpcbox.InvalidArgumentError, match="degrees of freedom"):
        mpcbox.Problem(static)
    with pytest.raises(mpcbox.ShapeError, match="qpos_ref"):
        mpcbox.Problem(HUMANOID, cost=Cost([StateCost(np.zeros(5), weight_qpos=1.0)]))
    with pytest.raises(ValueError):  # every mpcbox argument error is a ValueError too
        mpcbox.Problem(HUMANOID, keyframe="nope")


def test_zero_quaternions_are_refused_and_a_reference_quaternion_is_normalized(balance):
    """A zero root quaternion (free joint at qpos[3:7]) was accepted: LQR about it returned a
    NaN gain, a simulation from it ended in "controller error" with NumPy warnings."""
    zero = balance.reference_state()
    zero[3:7] = 0.0
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"initial_state\[3:7\] is a zero"):
        mpcbox.simulate(balance, mpcbox.LQR(balance), 0.01, initial_state=zero)
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"state\[3:7\] is a zero quaternion"):
        mpcbox.LQR(balance, state=zero)
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"qpos_ref\[3:7\] is a zero"):
        mpcbox.Problem(HUMANOID, qpos_ref=zero[: balance.nq])
    scaled = balance.qpos_ref.copy()
    scaled[3:7] *= 2.0  # MuJoCo normalizes it when it steps; the reference must be the same
    problem = mpcbox.Problem(HUMANOID, qpos_ref=scaled, limit_clearance=0.0)  # hip on its limit
    np.testing.assert_allclose(problem.qpos_ref, balance.qpos_ref, rtol=0, atol=1e-15)


def test_quadratic_value_term_is_half_dx_P_dx(balance):
    rng = np.random.default_rng(8)
    M = rng.standard_normal((balance.nx, balance.nx))
    P = M @ M.T
    value = mpcbox.QuadraticValue(balance.qpos_ref, P=P)
    prob = balance.with_cost(Cost([ControlCost(weight=0.0)], [value]))
    x, _ = random_humanoid_state(prob, rng, 0.05)
    dx = prob.state_difference(x, prob.reference_state())
    assert prob.terminal_cost(x) == pytest.approx(0.5 * dx @ P @ dx, rel=1e-10)
    quad = prob.quadratize(x, prob.ctrl_ref, terminal=True)
    np.testing.assert_allclose(quad.lxx, P, rtol=1e-10, atol=1e-10 * np.abs(P).max())
    # The original Problem keeps its own cost.
    assert balance.cost is not prob.cost and len(balance.cost.terminal) == 0
    with pytest.raises(mpcbox.CostDefinitionError, match="positive semidefinite"):
        balance.with_cost(
            Cost([ControlCost(weight=0.0)], [mpcbox.QuadraticValue(balance.qpos_ref, P=-P)])
        )


SERVO_RANGE_WITHOUT_ZERO = """
<mujoco>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 1 0" range="-1 1"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05"/>
    </body>
  </worldbody>
  <actuator><position name="servo" joint="hinge" kp="10" ctrlrange="0.2 0.8"/></actuator>
</mujoco>
"""


def test_default_reference_control_outside_ctrlrange_is_clipped_with_a_warning():
    """Without a keyframe the reference control is zero; a servo whose range excludes zero
    would be clamped by MuJoCo (no effect of that control in the linearization)."""
    with pytest.warns(
        mpcbox.errors.EquilibriumWarning, match=r"'servo' \(0 outside \[0.2, 0.8\]\)"
    ):
        problem = mpcbox.Problem(SERVO_RANGE_WITHOUT_ZERO)
    assert problem.ctrl_ref == pytest.approx([0.2])
    lin = problem.linearize(problem.reference_state(), problem.ctrl_ref)
    assert np.abs(lin.B).max() > 0  # the servo acts in the linearization
    # A reference control the user gives is not changed: it is refused by name.
    with pytest.raises(
        mpcbox.InvalidArgumentError, match=r"^ctrl_ref\[0\] = 0 is outside actuator 0's"
    ):
        mpcbox.Problem(SERVO_RANGE_WITHOUT_ZERO, ctrl_ref=[0.0])
