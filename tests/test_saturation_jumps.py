"""The one-step velocity jump of a servo whose force saturates under MuJoCo's implicit step."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.core.robot_check import check_robot
from mpcbox.core.saturation_jumps import saturation_jumps
from mpcbox.errors import InvalidTypeError, ShapeError

# A two-link arm on force-limited position servos (kp 400, kv 40, 5 N m), tilted shoulder
# so that the links couple through the mass matrix; the elbow's own damping is implicit
# under every integrator.
ARM = """
<mujoco>
  <option timestep="{dt}" integrator="{integrator}" gravity="0 0 0"/>
  <worldbody>
    <body name="upper">
      <joint name="shoulder" axis="0 1 0" damping="0.5" armature="0.01"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0.1" size="0.03" mass="1.5"/>
      <body name="lower" pos="0.3 0 0.1">
        <joint name="elbow" axis="0 1 0" damping="0.2" armature="0.005"/>
        <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.02" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="shoulder" joint="shoulder" kp="400" kv="40" forcerange="-5 5"/>
    <position name="elbow" joint="elbow" kp="400" kv="40" forcerange="-5 5"/>
    <motor name="free_motor" joint="elbow" gear="2"/>
  </actuator>
</mujoco>
"""
QPOS = np.array([0.3, -0.7])


def arm(integrator: str = "implicitfast", dt: float = 0.002) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM.format(dt=dt, integrator=integrator))


def measured_jump(model: mujoco.MjModel, i: int) -> float:
    """The actuator's velocity after one step from rest at QPOS with its force just inside
    its limit, subtracted from that with the force just past it; the others hold QPOS."""
    out = []
    for excess in (-1e-9, 1e-9):
        data = mujoco.MjData(model)
        data.qpos[:] = QPOS
        mujoco.mj_forward(model, data)
        data.ctrl[:2] = data.actuator_length[:2]  # zero force on the servos
        limit = model.actuator_forcerange[i, 1]
        kp = model.actuator_gainprm[i, 0]
        data.ctrl[i] = data.actuator_length[i] + limit * (1 + excess) / kp
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)  # actuator_velocity of the new state
        out.append(float(data.actuator_velocity[i]))
    return out[1] - out[0]


@pytest.mark.parametrize("integrator", ["implicitfast", "implicit"])
def test_the_predicted_jump_is_the_one_mujoco_makes(integrator: str) -> None:
    model = arm(integrator)
    jumps = saturation_jumps(model, QPOS)
    assert jumps.implicit and jumps.names == ("shoulder", "elbow", "free_motor")
    for i in (0, 1):
        measured = measured_jump(model, i)
        assert measured > 0.01  # a real jump, not round-off
        assert jumps.velocity_jump[i] == pytest.approx(measured, rel=1e-5)
        assert 0.0 < jumps.fraction[i] < 1.0
    # The motor has neither a force limit nor a velocity gain.
    assert jumps.velocity_jump[2] == 0.0 and jumps.fraction[2] == 0.0


def test_the_jump_shrinks_with_the_timestep_and_explicit_integrators_have_none() -> None:
    coarse = saturation_jumps(arm(dt=0.002), QPOS).velocity_jump[:2]
    fine = saturation_jumps(arm(dt=0.0005), QPOS).velocity_jump[:2]
    assert np.all(fine < 0.5 * coarse)
    for integrator in ("Euler", "RK4"):
        model = arm(integrator)
        jumps = saturation_jumps(model, QPOS)
        assert not jumps.implicit and not np.any(jumps.velocity_jump)
        assert jumps.message() == ""
        assert abs(measured_jump(model, 1)) < 1e-6  # continuous in the force


def test_inspect_notes_large_jumps_only() -> None:
    finding = {f.topic: f for f in check_robot(arm(), hold=0.0, servo_test=False).findings}
    note = finding["servo saturation"]
    assert note.level == "note"
    assert "'shoulder'" in note.text or "'elbow'" in note.text
    euler = {f.topic: f for f in check_robot(arm("Euler"), hold=0, servo_test=False).findings}
    assert euler["servo saturation"].level == "ok"
    # Heavy links: the velocity gain is small against the inertia, the jump a small part.
    heavy = mujoco.MjModel.from_xml_string(
        ARM.format(dt=0.002, integrator="implicitfast").replace('mass="0.5"', 'mass="50"')
    )
    jumps = saturation_jumps(heavy, QPOS)
    assert jumps.fraction[1] < 0.5 < saturation_jumps(arm(), QPOS).fraction[1]


def test_bad_inputs_are_named() -> None:
    with pytest.raises(InvalidTypeError, match="model"):
        saturation_jumps("arm.xml")  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match="qpos"):
        saturation_jumps(arm(), np.zeros(3))
