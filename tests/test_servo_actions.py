"""Set-point planning for torque-driven robots: motors as servos in the planning model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.base import Controller
from mpcbox.controllers.servo_actions import ServoActions, ServoLaw, servo_spec
from mpcbox.core.model import compile_spec
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnsupportedModelError

# Two links under gravity on torque motors (gear 2 on the elbow, 40 and 10 N m of torque),
# plus a slide joint on a position servo that the conversion must leave alone.
ARM = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <body name="upper">
      <joint name="shoulder" axis="0 1 0" range="-2 2" damping="0.2" armature="0.02"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1.5"/>
      <body name="lower" pos="0.3 0 0">
        <joint name="elbow" axis="0 1 0" range="-2.5 2.5" damping="0.1" armature="0.01"/>
        <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="0.5"/>
        <body name="finger" pos="0.25 0 0">
          <joint name="slide" type="slide" axis="1 0 0" range="0 0.04"/>
          <geom type="box" size="0.01 0.01 0.01" mass="0.05"/>
          <site name="tip"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="shoulder" joint="shoulder" ctrlrange="-40 40"/>
    <motor name="elbow" joint="elbow" gear="2" ctrlrange="-5 5"/>
    <position name="slide" joint="slide" kp="1000" kv="10" ctrlrange="0 0.04"/>
  </actuator>
  <keyframe><key qpos="0.2 -0.4 0.02"/></keyframe>
</mujoco>
"""


def run(model: mujoco.MjModel, ctrl_of, seconds: float = 1.0) -> np.ndarray:
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0]
    for _ in range(round(seconds / model.opt.timestep)):
        state = np.r_[data.qpos, data.qvel]
        data.ctrl[:] = ctrl_of(state)
        mujoco.mj_step(model, data)
    return np.r_[data.qpos, data.qvel]


def test_the_world_through_the_law_moves_as_the_servo_model():
    spec, law = servo_spec(ARM, bandwidth=25.0, damping_ratio=0.8)
    servo = compile_spec(spec)
    world = mujoco.MjModel.from_xml_string(ARM)
    np.testing.assert_array_equal(law.actuators, [0, 1])  # the position servo stays
    # Gains from the joints' inertia (mass-matrix diagonal) at the keyframe.
    data = mujoco.MjData(world)
    data.qpos[:] = world.key_qpos[0]
    mujoco.mj_forward(world, data)
    mass = np.zeros((world.nv, world.nv))
    mujoco.mj_fullM(world, data, mass)
    inertia = np.diag(mass)[:2]
    np.testing.assert_allclose(law.kp, inertia * 25.0**2)
    np.testing.assert_allclose(law.kv, 2 * 0.8 * inertia * 25.0)
    np.testing.assert_allclose(servo.actuator_forcerange[:2], [[-40, 40], [-10, 10]])
    np.testing.assert_allclose(servo.actuator_ctrlrange[:2], [[-2, 2], [-2.5, 2.5]])
    # The same set-points, held: the servo model and the torque world through the law end
    # in the same state (the world's damping is explicit, the model's implicit).
    setpoints = np.array([0.6, 0.3, 0.03])
    planned = run(servo, lambda s: setpoints)
    moved = run(world, lambda s: law.controls(s, setpoints, world.nq))
    np.testing.assert_allclose(moved, planned, atol=1e-4)
    assert abs(planned[1] - 0.3) < 0.05  # the elbow servo got there (gravity sags it a bit)
    # The default bandwidth is 0.1 / timestep.
    np.testing.assert_allclose(servo_spec(ARM)[1].kp, inertia * (0.1 / 0.002) ** 2)
    # Saturated: the world's motor control is clipped to its range.
    far = law.controls(np.r_[world.key_qpos[0], np.zeros(3)], np.array([2.0, -2.5, 0.0]), 3)
    np.testing.assert_allclose(far[:2], [40.0, -5.0])


def test_servo_actions_reach_the_target_with_mppi():
    from mpcbox.tasks.reach import ArmReach

    world = ArmReach(ARM, frame="tip", target=np.array([-0.1, 0.0, 0.15]), relative=True)
    ctrl = world.servo_planner("mppi", num_samples=16, horizon=0.5, guess_candidate=True)
    assert ctrl.name == "mppi-servo" and ctrl.period is None
    sim = mpcbox.simulate(world, ctrl, 1.5, seed=0)
    assert world.reach_error(sim.states[-1]) < world.tolerance
    assert sim.metrics.solve_ticks == 75  # replans every 0.02 s, holds the plan in between


def test_bad_inputs_are_named():
    with pytest.raises(UnsupportedModelError, match="motors"):
        servo_spec(ARM.replace("<motor", "<velocity kv='1'").replace('gear="2"', ""))
    with pytest.raises(InvalidArgumentError, match="bandwidth"):
        servo_spec(ARM, bandwidth=0.0)
    with pytest.raises(InvalidArgumentError, match="damping_ratio"):
        servo_spec(ARM, damping_ratio=-1.0)

    class Hold(Controller):
        def __call__(self, state, time):
            return np.zeros(3)

    world = mpcbox.Problem(ARM)
    _, law = servo_spec(ARM)
    with pytest.raises(InvalidTypeError, match="planner"):
        ServoActions(world, object(), law)  # type: ignore[arg-type]
    with pytest.raises(InvalidTypeError, match="law"):
        ServoActions(world, Hold(), (1, 2))  # type: ignore[arg-type]
    assert isinstance(law, ServoLaw)
    from mpcbox.tasks.reach import ArmReach

    servos = ArmReach(
        ARM.replace("<motor", "<position kp='50'").replace('gear="2" ', ""),
        frame="tip",
        target=np.zeros(3),
        relative=True,
    )
    with pytest.raises(UnsupportedModelError, match="motors"):
        servos.servo_planner("mppi")
