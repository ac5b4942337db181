"""find_equilibrium through the actuator model: servos, gains and biases, gears, activation
dynamics, tendons, muscles, limits, and a Menagerie-style arm with position servos."""

from __future__ import annotations

import pathlib
import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.actuation import actuator_moment
from mpcbox.errors import EquilibriumWarning, InfeasibleEquilibriumError, UnsupportedModelError
from mpcbox.tasks import scene_path

pytestmark = pytest.mark.filterwarnings("error::mpcbox.errors.EquilibriumWarning")

ARM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="upper">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <body name="lower" pos="0.3 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.025" mass="0.6"/>
      </body>
    </body>
  </worldbody>
  <actuator>{actuators}</actuator>
</mujoco>
"""
POSTURE = np.array([-0.4, 0.7])


def arm(actuators: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM.format(actuators=actuators))


def holding_force(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Generalized force that holds ``qpos`` at rest (independent of find_equilibrium)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    data.qacc[:] = 0
    mujoco.mj_inverse(model, data)
    return data.qfrc_inverse.copy()


def drift(model: mujoco.MjModel, eq: mpcbox.Equilibrium, seconds: float = 2.0) -> float:
    """Largest joint deviation after simulating ``seconds`` from the equilibrium."""
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:], data.act[:] = eq.qpos, eq.ctrl, eq.act
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return float(np.max(np.abs(data.qpos - eq.qpos)))


def test_position_servos_hold_the_arm_with_setpoints_offset_by_tau_over_kp():
    kp = np.array([80.0, 50.0])
    model = arm(
        '<position joint="shoulder" kp="80" kv="8" ctrlrange="-3 3"/>'
        '<position joint="elbow" kp="50" kv="5" ctrlrange="-3 3"/>'
    )
    tau = holding_force(model, POSTURE)
    eq = mpcbox.find_equilibrium(model, POSTURE)
    np.testing.assert_allclose(eq.ctrl, POSTURE + tau / kp, rtol=0, atol=1e-12)
    assert np.all(np.abs(eq.ctrl - POSTURE) > 1e-3)  # gravity matters here
    np.testing.assert_allclose(eq.actuator_force, tau, atol=1e-9)
    assert eq.shortfall < 1e-9 and eq.actuated.all()
    assert drift(model, eq) < 1e-3
    # Read as torques (the old behaviour), the set-points would let the arm sag away.
    naive = eq._replace(ctrl=np.linalg.lstsq(np.eye(2), tau, rcond=None)[0])
    assert drift(model, naive) > 0.1


def test_velocity_servo_and_general_affine_gain_and_bias():
    # Velocity servo at rest: force = kv * ctrl. General: gear 2, length L = 2 q,
    # force = (5 + 2 L) ctrl + (1 - 3 L), generalized force 2 * force.
    model = arm(
        '<velocity joint="shoulder" kv="40"/>'
        '<general joint="elbow" gear="2" gaintype="affine" gainprm="5 2 0"'
        ' biastype="affine" biasprm="1 -3 -0.5"/>'
    )
    tau = holding_force(model, POSTURE)
    eq = mpcbox.find_equilibrium(model, POSTURE)
    length = 2.0 * POSTURE[1]
    expected = [tau[0] / 40.0, (tau[1] / 2.0 - 1.0 + 3.0 * length) / (5.0 + 2.0 * length)]
    np.testing.assert_allclose(eq.ctrl, expected, rtol=1e-12)
    np.testing.assert_allclose(eq.residual, 0.0, atol=1e-10)


def test_motor_with_gear_ten_gives_a_tenth_of_the_torque():
    model = arm('<motor joint="shoulder" gear="10"/><motor joint="elbow" gear="10"/>')
    eq = mpcbox.find_equilibrium(model, POSTURE)
    np.testing.assert_allclose(eq.ctrl, holding_force(model, POSTURE) / 10.0, rtol=1e-12)
    assert eq.act.shape == (0,)


@pytest.mark.parametrize("jacobian", ["dense", "sparse"])
def test_coupled_joints_share_the_load_through_the_equality(jacobian):
    """The elbow follows the shoulder (joint equality, q_e = q_s) and only the shoulder has a
    position servo. The coupling's force lambda (J = [-1, 1]) takes the elbow's load, so the
    servo supplies g_s + g_e (set-point q_s + (g_s + g_e) / kp) and the arm holds still."""
    xml = ARM.format(actuators='<position joint="shoulder" kp="100"/>').replace(
        "</mujoco>",
        '<equality><joint joint1="elbow" joint2="shoulder" polycoef="0 1 0 0 0"/></equality>'
        "</mujoco>",
    )
    xml = xml.replace(
        '<option timestep="0.002"/>', f'<option timestep="0.002" jacobian="{jacobian}"/>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    posture = np.array([-0.4, -0.4])
    g = holding_force(model, posture)
    eq = mpcbox.find_equilibrium(model, posture)
    np.testing.assert_allclose(eq.ctrl, [posture[0] + g.sum() / 100.0], rtol=1e-9)
    np.testing.assert_allclose(eq.qfrc_equality, [-g[1], g[1]], atol=1e-9)
    assert eq.shortfall < 1e-9
    assert drift(model, eq) < 2e-3


def test_filter_activation_rests_at_act_equal_ctrl_and_integrator_holds_its_state():
    model = arm(
        '<general joint="shoulder" dyntype="filter" dynprm="0.05" gainprm="20"/>'
        '<general joint="elbow" dyntype="integrator" gainprm="20" actlimited="true"'
        ' actrange="-1 1"/>'
    )
    tau = holding_force(model, POSTURE)
    eq = mpcbox.find_equilibrium(model, POSTURE)
    assert eq.act.shape == (2,)
    np.testing.assert_allclose(eq.act, tau / 20.0, rtol=1e-12)
    assert eq.ctrl[0] == eq.act[0]  # filter: act_dot = (ctrl - act) / tau = 0
    assert eq.ctrl[1] == 0.0  # integrator: act_dot = ctrl = 0, the state holds the force
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:], data.act[:] = eq.qpos, eq.ctrl, eq.act
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.act_dot, 0.0, atol=1e-12)
    np.testing.assert_allclose(data.qacc, 0.0, atol=1e-9)


def test_tendon_transmission():
    # Fixed tendons: the shoulder motor drives 0.5 * shoulder, the elbow one couples both
    # joints (elbow - shoulder), so the elbow motor also loads the shoulder.
    xml = ARM.format(
        actuators='<motor tendon="t_shoulder"/><motor tendon="t_elbow" gear="3"/>'
    ).replace(
        "<actuator>",
        '<tendon><fixed name="t_shoulder"><joint joint="shoulder" coef="0.5"/></fixed>'
        '<fixed name="t_elbow"><joint joint="elbow" coef="1"/>'
        '<joint joint="shoulder" coef="-1"/></fixed></tendon><actuator>',
    )
    model = mujoco.MjModel.from_xml_string(xml)
    tau = holding_force(model, POSTURE)
    eq = mpcbox.find_equilibrium(model, POSTURE)
    # tau_elbow = 3 u1, tau_shoulder = 0.5 u0 - 3 u1.
    u1 = tau[1] / 3.0
    np.testing.assert_allclose(eq.ctrl, [(tau[0] + 3.0 * u1) / 0.5, u1], rtol=1e-12)
    assert eq.shortfall < 1e-10


MUSCLE_ARM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <site name="anchor" pos="0 0 0.3"/>
    <body name="link">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.02" mass="0.5"/>
      <site name="insertion" pos="0.25 0 0"/>
    </body>
  </worldbody>
  <tendon>
    <spatial name="cable"><site site="anchor"/><site site="insertion"/></spatial>
  </tendon>
  <actuator>
    <muscle name="biceps" tendon="cable" force="40"/>
  </actuator>
</mujoco>
"""


@pytest.mark.parametrize("angle", [-0.2, 0.0, 0.3])
def test_muscle_on_a_spatial_tendon_holds_the_hinge(angle):
    model = mujoco.MjModel.from_xml_string(MUSCLE_ARM)
    eq = mpcbox.find_equilibrium(model, np.array([angle]))
    assert 0.0 < eq.ctrl[0] < 1.0 and eq.act[0] == eq.ctrl[0]
    assert eq.actuator_force[0] < 0  # muscles pull
    assert eq.shortfall < 1e-9
    assert drift(model, eq) < 1e-3
    # The muscle curves matter: 10 % less activation lets the link drop.
    weaker = eq._replace(ctrl=0.9 * eq.ctrl, act=0.9 * eq.act)
    assert drift(model, weaker) > 1e-2


def test_joint_actuatorfrcrange_bounds_the_control_and_names_the_joint():
    """A motor on the shoulder whose joint clamps actuator torque to +-1 N m, less than the
    holding torque: the control is bounded by the joint's range, not by the motor's."""
    xml = ARM.format(actuators='<motor joint="shoulder"/><motor joint="elbow"/>').replace(
        '<joint name="shoulder" type="hinge" axis="0 1 0"/>',
        '<joint name="shoulder" type="hinge" axis="0 1 0" actuatorfrcrange="-1 1"/>',
    )
    model = mujoco.MjModel.from_xml_string(xml)
    g = holding_force(model, POSTURE)
    assert abs(g[0]) > 1.0
    with pytest.raises(InfeasibleEquilibriumError, match="actuatorfrcrange of joint 'shoulder'"):
        mpcbox.find_equilibrium(model, POSTURE, on_infeasible="raise")
    eq = mpcbox.find_equilibrium(model, POSTURE, on_infeasible="ignore")
    assert eq.ctrl[0] == pytest.approx(np.sign(g[0]) * 1.0)
    assert eq.shortfall == pytest.approx(abs(g[0]) - 1.0)


def test_posture_beyond_the_actuator_limits_warns_or_raises_naming_the_actuator():
    model = arm(
        '<motor name="weak_shoulder" joint="shoulder" gear="1" ctrlrange="-1 1"/>'
        '<motor name="elbow" joint="elbow" gear="10" ctrlrange="-1 1"/>'
    )
    tau = holding_force(model, POSTURE)
    assert abs(tau[0]) > 1.5  # beyond ctrlrange * gear = 1 N m
    with pytest.warns(EquilibriumWarning, match=r"'shoulder'.*'weak_shoulder'.*ctrlrange"):
        eq = mpcbox.find_equilibrium(model, POSTURE)
    assert abs(eq.ctrl[0]) == 1.0
    assert eq.shortfall == pytest.approx(abs(tau[0]) - 1.0, abs=1e-9)
    with pytest.raises(InfeasibleEquilibriumError, match="weak_shoulder"):
        mpcbox.find_equilibrium(model, POSTURE, on_infeasible="raise")
    quiet = mpcbox.find_equilibrium(model, POSTURE, on_infeasible="ignore")
    np.testing.assert_array_equal(quiet.ctrl, eq.ctrl)


def test_force_limit_of_a_position_servo_bounds_the_setpoint():
    model = arm(
        '<position name="servo" joint="shoulder" kp="100" forcelimited="true"'
        ' forcerange="-1 1"/><position joint="elbow" kp="100"/>'
    )
    with pytest.warns(EquilibriumWarning, match="'servo' is at its .* forcerange limit"):
        eq = mpcbox.find_equilibrium(model, POSTURE)
    assert abs(eq.actuator_force[0]) == pytest.approx(1.0, abs=1e-9)


def test_servo_whose_ctrlrange_misses_its_force_range_is_pinned_not_crashed():
    """The posture is outside the servo's set-point range (as Menagerie's Panda at ``qpos0``,
    whose joint 4 range excludes 0): the control range and the force range's set-points do
    not overlap. MuJoCo clamps the set-point into its range and the force to its limit, so
    the control sits at the range's end nearest the posture and the shortfall is reported
    (the bounded least squares used to raise scipy's ValueError on the inverted bounds)."""
    model = arm(
        '<position name="servo" joint="shoulder" kp="100" ctrlrange="0.5 1" forcerange="-1 1"/>'
        '<position joint="elbow" kp="100"/>'
    )
    with pytest.raises(InfeasibleEquilibriumError, match=r"'servo' is at its .* ctrlrange limit"):
        mpcbox.find_equilibrium(model, POSTURE, on_infeasible="raise")
    eq = mpcbox.find_equilibrium(model, POSTURE, on_infeasible="ignore")
    assert eq.ctrl[0] == 0.5
    assert eq.actuator_force[0] == pytest.approx(1.0)  # MuJoCo's clamp: kp (0.5 + 0.4) -> 1
    tau = holding_force(model, POSTURE)
    assert eq.shortfall == pytest.approx(abs(tau[0] - 1.0), abs=1e-9)


def test_humanoid_motors_keep_the_plain_least_squares_control():
    model = mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "stand_on_left_leg")
    eq = mpcbox.find_equilibrium(model, model.key_qpos[key])
    data = mujoco.MjData(model)
    data.qpos[:] = eq.qpos
    mujoco.mj_forward(model, data)
    moment = actuator_moment(model, data)
    np.testing.assert_array_equal(eq.ctrl, np.linalg.lstsq(moment.T, eq.qfrc, rcond=None)[0])
    assert eq.shortfall < 1e-9 and not eq.actuated[:6].any()


def test_aloha_position_servos_hold_the_arms_at_the_keyframe():
    mujoco_warp = pytest.importorskip("mujoco_warp")
    scene = pathlib.Path(mujoco_warp.__file__).parent / "test_data" / "aloha_pot" / "scene.xml"
    if not scene.exists():
        pytest.skip(f"no ALOHA test model at {scene}")
    model = mujoco.MjModel.from_xml_path(str(scene))
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "neutral_pose")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        eq = mpcbox.find_equilibrium(model, model.key_qpos[key])
    arms = [
        model.jnt_qposadr[j]
        for j in range(model.njnt)
        if model.joint(j).name.startswith(("left", "right"))
    ]
    assert len(arms) == 16
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:] = eq.qpos, eq.ctrl
    for _ in range(1000):  # 2 s
        mujoco.mj_step(model, data)
    assert np.max(np.abs(data.qpos[arms] - eq.qpos[arms])) < 1e-3
    # The keyframe's own set-points (ctrl = q) let the arms sag under gravity.
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:] = eq.qpos, model.key_ctrl[key]
    for _ in range(1000):
        mujoco.mj_step(model, data)
    assert np.max(np.abs(data.qpos[arms] - eq.qpos[arms])) > 1e-2


def test_without_actuators_everything_is_residual():
    model = arm("")
    eq = mpcbox.find_equilibrium(model, POSTURE)
    assert eq.ctrl.shape == (0,) and eq.shortfall == 0.0 and not eq.actuated.any()
    np.testing.assert_allclose(eq.residual, holding_force(model, POSTURE), rtol=1e-12)


def test_unsupported_dynamics_name_the_actuator():
    model = arm('<general name="custom" joint="shoulder" dyntype="user"/><motor joint="elbow"/>')
    with pytest.raises(UnsupportedModelError, match=r"'custom'.*USER"):
        mpcbox.find_equilibrium(model, POSTURE)


def test_gravity_compensation_through_the_actuators_leaves_the_servo_at_the_posture():
    # actuatorgravcomp routes the body's gravcomp into qfrc_actuator: the servo adds nothing.
    model = mujoco.MjModel.from_xml_string(
        ARM.format(actuators='<position joint="shoulder" kp="50"/>')
        .replace('<body name="upper">', '<body name="upper" gravcomp="1">')
        .replace(
            '<body name="lower" pos="0.3 0 0">', '<body name="lower" pos="0.3 0 0" gravcomp="1">'
        )
        .replace(
            'name="shoulder" type="hinge"', 'name="shoulder" actuatorgravcomp="true" type="hinge"'
        )
        .replace('name="elbow" type="hinge"', 'name="elbow" actuatorgravcomp="true" type="hinge"')
    )
    eq = mpcbox.find_equilibrium(model, POSTURE)
    assert abs(eq.qfrc[0]) > 1.0  # the posture needs a torque ...
    np.testing.assert_allclose(eq.ctrl, POSTURE[:1], atol=1e-12)  # ... that gravcomp supplies
    np.testing.assert_allclose(eq.residual, 0.0, atol=1e-12)
