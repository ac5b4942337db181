"""The set-point step test that finds servos ringing at the model's timestep."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.servo_ringing import servo_ringing
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.reach import ArmReach

# Two links: a heavy shoulder and a light wrist, each on a force-limited position servo
# (kp 1000, kv 100, 30 N m: the Unitree Z1's actuator class). The wrist's inertia is
# ~2e-4 kg m^2, so kv h / I is about 1000 at 2 ms.
ARM = """
<mujoco>
  <option timestep="{dt}" integrator="implicitfast"/>
  <default>
    <general biastype="affine" gainprm="1000" biasprm="0 -1000 -100" forcerange="-30 30"/>
  </default>
  <worldbody>
    <body name="upper" pos="0 0 0.5">
      <joint name="shoulder" axis="0 1 0" damping="1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" mass="2"/>
      <body name="wrist" pos="0.3 0 0">
        <joint name="wrist" axis="1 0 0" damping="1" armature="{armature}"/>
        <geom type="cylinder" fromto="0 0 0 0.04 0 0" size="0.012" mass="0.3"/>
        <site name="tip" pos="0.04 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <general name="shoulder_servo" joint="shoulder" ctrlrange="-2 2"/>
    <general name="wrist_servo" joint="wrist" ctrlrange="-2.8 2.8"/>
  </actuator>
</mujoco>
"""


def arm(dt: float = 0.002, armature: float = 0.0) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM.format(dt=dt, armature=armature))


def free_wrist_response(model: mujoco.MjModel, ctrl: float, steps: int) -> np.ndarray:
    data = mujoco.MjData(model)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_GRAVITY
    data.ctrl[1] = ctrl
    out = np.empty(steps)
    for k in range(steps):
        mujoco.mj_step(model, data)
        out[k] = data.qvel[1]
    return out


def test_a_stiff_light_wrist_rings_and_the_heavy_shoulder_does_not() -> None:
    report = servo_ringing(arm())
    assert report.names == ("shoulder_servo", "wrist_servo")
    assert report.ringing_names == ("wrist_servo",)
    assert report.crossing_rate[1] > 0.9 and report.amplitude[1] > 0.3
    assert report.crossing_rate[0] < 0.1
    # The explicit velocity step's ratio, from the model's own inertia and kv.
    model = arm()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    wrist_inertia = 1.0 / np.linalg.inv(mass)[1, 1]
    np.testing.assert_allclose(report.velocity_gain_ratio[1], 100 * 0.002 / wrist_inertia)
    assert report.velocity_gain_ratio[1] > 2.0
    message = report.message()
    assert "'wrist_servo'" in message and "shoulder_servo" not in message
    assert "kv h / I" in message and "2 ms" in message


def test_the_same_step_by_hand_rings_and_a_heavier_wrist_settles() -> None:
    """At 2 ms the wrist's velocity flips sign at nearly every step late in the run; with
    armature (kv h / I near 4) it approaches its set-point without a sign change, and the
    test says so."""
    late = free_wrist_response(arm(), 0.7, 250)[125:]
    assert np.mean(np.sign(late[1:]) != np.sign(late[:-1])) > 0.9
    settled = free_wrist_response(arm(armature=0.05), 0.7, 250)[125:]
    assert np.all(np.sign(settled[1:]) == np.sign(settled[:-1]))
    assert servo_ringing(arm(armature=0.05)).ringing_names == ()


def test_motors_and_unforced_servos_do_not_ring() -> None:
    motors = mujoco.MjModel.from_xml_string(
        ARM.format(dt=0.002, armature=0.0).replace(
            'biastype="affine" gainprm="1000" biasprm="0 -1000 -100" forcerange="-30 30"',
            'gear="1"',
        )
    )
    assert not servo_ringing(motors).ringing.any()
    # Without a force limit the servo's kv stays implicit at every step.
    unlimited = mujoco.MjModel.from_xml_string(
        ARM.format(dt=0.002, armature=0.0).replace(' forcerange="-30 30"', "")
    )
    assert servo_ringing(unlimited).ringing_names == ()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"step": 0.0}, "step must be in"),
        ({"min_crossing_rate": 1.5}, "min_crossing_rate must be in"),
        ({"duration": -1.0}, "duration"),
        ({"qpos": [0.0]}, "qpos"),
        ({"qpos": [np.nan, 0.0]}, "qpos must be finite"),
    ],
)
def test_bad_arguments_are_named(kwargs, match) -> None:
    with pytest.raises(InvalidArgumentError, match=match):
        servo_ringing(arm(), **kwargs)


def test_arm_reach_warns_about_a_ringing_servo_and_keeps_the_report() -> None:
    xml = ARM.format(dt=0.002, armature=0.0)
    with pytest.warns(mpcbox.ModelWarning, match="'wrist_servo' rings"):
        task = ArmReach(xml, frame="tip", target=[0.0, 0.0, 0.05], relative=True)
    assert task.servo_report is not None and task.servo_report.ringing_names == ("wrist_servo",)
    with warnings.catch_warnings():
        warnings.simplefilter("error", mpcbox.ModelWarning)
        quiet = ArmReach(
            xml, frame="tip", target=[0.0, 0.0, 0.05], relative=True, servo_check=False
        )
    assert quiet.servo_report is None
