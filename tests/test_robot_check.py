"""``check_robot`` and ``mpcbox inspect``: a model's findings before any controller runs."""

from __future__ import annotations

import json
import pathlib

import pytest

from mpcbox.cli import main
from mpcbox.core.robot_check import LEVELS, check_robot
from mpcbox.errors import UnknownNameError
from tests.test_parent_contacts import ARM as PARENT_ARM
from tests.test_servo_ringing import ARM as RINGING_ARM

# A torque-driven pendulum whose elbow keyframe sits on its lower limit, with dry friction.
PENDULUM = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="{dt}" integrator="{integrator}"/>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="1"/>
      <body name="lower" pos="0 0 -0.3">
        <joint name="elbow" axis="0 1 0" range="0 2" frictionloss="{friction}" stiffness="{k}"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="{mass}"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="shoulder" joint="shoulder" ctrlrange="-20 20"/>
    <motor name="elbow" joint="elbow" ctrlrange="-20 20"/>
  </actuator>
  <keyframe><key name="bent" qpos="0.3 0"/><key name="down" qpos="0 1"/></keyframe>
</mujoco>
"""


def pendulum(dt=0.002, integrator="implicitfast", friction=0.0, k=0.0, mass=0.5) -> str:
    return PENDULUM.format(dt=dt, integrator=integrator, friction=friction, k=k, mass=mass)


def topics(report) -> dict[str, tuple[str, str]]:
    return {f.topic: (f.level, f.text) for f in report.findings}


def test_a_plain_arm_is_all_ok_and_its_equilibrium_holds_open_loop() -> None:
    report = check_robot(pendulum(), keyframe="down")
    found = topics(report)
    assert report.level == "ok", report.format()
    assert "2 motor" in found["model"][1] and "fixed base" in found["model"][1]
    # Gravity torques through the motors: held to round-off, so it does not drift.
    assert found["equilibrium"][0] == "ok" and found["open-loop hold"][0] == "ok"
    drift = float(found["open-loop hold"][1].split("at most ")[1].split(" ")[0])
    assert drift < 1e-6


def test_each_known_problem_is_named_at_its_level() -> None:
    report = check_robot(pendulum(friction=0.5))  # keyframe 'bent': elbow on its limit
    found = topics(report)
    assert found["joint limits"][0] == "note" and "elbow 0 -> 0.01" in found["joint limits"][1]
    assert (
        found["dry friction"][0] == "note"
        and "frictionloss (up to 0.5)" in found["dry friction"][1]
    )
    assert report.level == "note"
    rk4 = topics(check_robot(pendulum(integrator="RK4")))
    assert rk4["integrator"][0] == "note" and "plan_rk4=True" in rk4["integrator"][1]
    ringing = check_robot(RINGING_ARM.format(dt=0.002, armature=0.0))
    assert ringing.level == "warning"
    text = " ".join(topics(ringing)["servo ringing"][1].split())
    assert "'wrist_servo'" in text and "At 0.5 ms 'wrist_servo' still rings" in text
    # A little armature: it rings at 2 ms and the check says that 1 ms cures it.
    cured = topics(check_robot(RINGING_ARM.format(dt=0.002, armature=0.001), hold=0))
    assert cured["servo ringing"][0] == "warning"
    assert cured["servo ringing"][1].endswith("At 1 ms none rings or diverges.")
    parent = topics(check_robot(PARENT_ARM.format(option="")))
    assert (
        parent["parent contacts"][0] == "note"
        and "'base' with 'shoulder'" in (parent["parent contacts"][1])
    )


def test_a_diverging_hold_is_an_error_that_quotes_mujoco(capfd) -> None:
    # An elbow spring far too stiff for explicit Euler at 10 ms.
    report = check_robot(pendulum(dt=0.01, integrator="Euler", k=1e7, mass=0.01), keyframe=1)
    level, text = topics(report)["open-loop hold"]
    assert level == "error" and "diverged" in text
    assert report.level == "error"
    # The servo step test blows up as well: said, not printed (MuJoCo's warnings collected).
    level, text = topics(report)["servo ringing"]
    assert level == "warning" and "diverges after a set-point step of 'shoulder', 'elbow'" in text
    assert text.endswith("still diverge: a shorter timestep is no cure there.")
    assert "WARNING" not in capfd.readouterr().err


def test_no_actuators_and_a_floating_body_in_the_air() -> None:
    bare = check_robot(
        "<mujoco><worldbody><body><joint/><geom size='0.1'/></body></worldbody></mujoco>"
    )
    assert topics(bare)["actuators"] == ("error", "the model has no actuators: nothing to control")
    suite = pytest.importorskip("dm_control.suite")
    humanoid = pathlib.Path(suite.__file__).parent / "humanoid.xml"
    found = topics(check_robot(str(humanoid), servo_test=False, hold=0))
    assert found["equilibrium"][0] == "warning" and "standing keyframe" in found["equilibrium"][1]
    assert "open-loop hold" not in found


def test_bad_arguments_name_what_exists() -> None:
    with pytest.raises(UnknownNameError, match="'bent', 'down'"):
        check_robot(pendulum(), keyframe="up")
    with pytest.raises(ValueError, match="hold"):
        check_robot(pendulum(), hold=-1.0)
    assert list(LEVELS) == ["ok", "note", "warning", "error"]


def test_the_command_prints_writes_json_and_exits_by_level(tmp_path, capsys) -> None:
    path = tmp_path / "arm.xml"
    path.write_text(pendulum())
    out = tmp_path / "check.json"
    assert main(["inspect", str(path), "--keyframe", "down", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["level"] == "ok" and {f["topic"] for f in data["findings"]} >= {"equilibrium"}
    assert "ok   equilibrium" in capsys.readouterr().out
    ringing = tmp_path / "ringing.xml"
    ringing.write_text(RINGING_ARM.format(dt=0.002, armature=0.0))
    assert main(["inspect", str(ringing), "--hold", "0"]) == 1
    assert main(["inspect", str(tmp_path / "missing.xml")]) == 2
    assert "no MJCF file" in capsys.readouterr().err
    assert main(["inspect", str(path), "--keyframe", "up"]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["inspect", str(path), "--hold", "-1"])
    assert exc.value.code == 2


def test_a_floating_robot_gets_the_legged_task_that_finds_its_feet(capsys) -> None:
    suite = pytest.importorskip("dm_control.suite")
    quadruped = str(pathlib.Path(suite.__file__).parent / "quadruped.xml")
    assert main(["inspect", quadruped, "--hold", "0", "--no-servo-test"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # the lines are wrapped
    assert "stands on 4 feet (body:toe_front_left" in out
    assert f"mpcbox compare quadruped_stand --model {quadruped}" in out


def test_a_posture_that_falls_open_loop_is_a_note_not_ok() -> None:
    """A pole on a driven cart, kept at a tilt no actuator can hold: it falls without
    feedback. That is no instability of the model (no MuJoCo warning), but not "ok" either:
    a fuzz run found Cassie's 79 cm fall graded "ok"."""
    cartpole = """
    <mujoco><option timestep="0.002"/><worldbody>
      <body name="cart"><joint name="slide" type="slide" axis="1 0 0"/>
        <geom type="box" size="0.1 0.05 0.05" mass="1"/>
        <body name="pole"><joint name="hinge" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0.2"/></body>
      </body></worldbody>
      <actuator><motor joint="slide" ctrlrange="-5 5"/></actuator>
      <keyframe><key name="tilted" qpos="0 0.2"/></keyframe></mujoco>"""
    level, text = topics(check_robot(cartpole, keyframe="tilted"))["open-loop hold"]
    assert level == "note" and "not held without feedback" in text, text
    held = topics(check_robot(pendulum(), keyframe="down"))["open-loop hold"]
    assert held[0] == "ok"


def test_a_keyframe_far_outside_a_joint_range_is_a_warning_not_ok() -> None:
    """The elbow's range is [0, 2] rad; a keyframe at -1 rad is not a rounding onto the limit
    (which a Problem moves inside, a note) but a posture the limit pushes back: a fuzz run
    found it graded "ok", with only the equilibrium's torque left to hint at the cause."""
    far = pendulum().replace('<key name="down" qpos="0 1"/>', '<key name="down" qpos="0 -1"/>')
    level, text = topics(check_robot(far, keyframe="down", hold=0))["joint limits"]
    assert level == "warning" and "elbow -1 not in [0, 2]" in text, text
    near = topics(check_robot(pendulum(), hold=0))["joint limits"]  # 'bent': on the limit
    assert near[0] == "note"
