"""The default end effector of arm tasks, and reach targets the arm cannot take."""

from __future__ import annotations

import mujoco
import pytest

from mpcbox.core.end_effector import end_effector
from mpcbox.core.posture import environment_contacts, reach_posture, self_collisions
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, SolverError
from mpcbox.tasks import scene_path
from mpcbox.tasks.reach import ArmReach

#: A two-link arm on a pedestal, its shoulder 0.2 m above a floor, a hand welded to its last
#: link and a sliding finger on the hand; ``SITE`` is replaced by an optional flange site.
ARM = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 0.1">
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="upper" pos="0 0 0.1">
        <joint name="shoulder" axis="0 1 0" range="-3 3"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <body name="lower" pos="0.3 0 0">
          <joint name="elbow" axis="0 1 0" range="-3 3"/>
          <geom type="capsule" fromto="0.04 0 0 0.25 0 0" size="0.025" mass="0.5"/>
          SITE
          <body name="hand" pos="0.3 0 0">
            <geom type="box" size="0.02 0.03 0.02" mass="0.1"/>
            <body name="finger" pos="0.03 0 0">
              <joint name="slide" type="slide" axis="0 1 0" range="0 0.02"/>
              <geom type="box" size="0.01 0.005 0.01" mass="0.01"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="shoulder" gear="20" ctrlrange="-1 1"/>
    <motor joint="elbow" gear="10" ctrlrange="-1 1"/>
    <position joint="slide" kp="10" ctrlrange="0 0.02"/>
  </actuator>
  <keyframe>
    <key name="home" qpos="-0.6 1.2 0.01" ctrl="0 0 0.01"/>
  </keyframe>
</mujoco>
"""


def arm(site: str = "") -> str:
    return ARM.replace("SITE", site)


def test_the_hand_welded_to_the_last_driven_link_is_the_tip():
    """Not the finger (a slide joint), not the last link (the hand is welded to it)."""
    assert end_effector(mujoco.MjModel.from_xml_string(arm())) == "hand"


def test_an_attachment_site_wins():
    site = '<site name="attachment_site" pos="0.28 0 0"/>'
    assert end_effector(mujoco.MjModel.from_xml_string(arm(site))) == "attachment_site"


def test_several_tips_are_listed_instead_of_guessed():
    model = mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))
    with pytest.raises(InvalidArgumentError, match=r"several arm tips.*frame="):
        end_effector(model)
    sites = '<site name="a/attachment_site"/><site name="b/attachment_site"/>'
    with pytest.raises(InvalidArgumentError, match=r"several attachment sites"):
        end_effector(mujoco.MjModel.from_xml_string(arm(sites)))


def test_not_a_compiled_model_is_a_named_error():
    with pytest.raises(InvalidTypeError, match=r"model must be a compiled mujoco\.MjModel"):
        end_effector("franka_emika_panda")


def test_no_rotational_joint_is_a_named_error():
    body = '<body><joint type="slide"/><geom size="0.1"/></body>'
    xml = f"<mujoco><worldbody>{body}</worldbody></mujoco>"
    with pytest.raises(InvalidArgumentError, match="no hinge or ball joint"):
        end_effector(mujoco.MjModel.from_xml_string(xml))


def test_arm_reach_picks_the_end_effector_and_reaches_a_free_target():
    problem = ArmReach(arm(), target=[0.1, 0.0, 0.05], relative=True)
    assert problem.frame == "hand"
    assert problem.goal.position_error < 1e-3
    assert not environment_contacts(problem.model, problem.qpos_ref)


def test_a_target_below_the_floor_or_out_of_reach_is_refused():
    """The IK used to push the arm into the floor and report the target as reached; the
    reference then held the arm pressed into it. (mink does not watch the first link against
    the floor: both hang from the world; the check after the IK does.)"""
    model = mujoco.MjModel.from_xml_string(arm())
    start = model.key_qpos[0]
    below = [0.4, 0.0, -0.05]
    with pytest.raises(SolverError, match=r"cannot reach \[0\.4, 0\.0, -0\.05\]"):
        reach_posture(model, start, frame="hand", position=below, max_error=0.01)
    with pytest.raises(SolverError, match=r"body hand into floor"):
        reach_posture(model, start, frame="hand", position=below)
    # Without collision avoidance the caller takes the posture as it is.
    free = reach_posture(model, start, frame="hand", position=below, avoid_collisions=False)
    assert environment_contacts(model, free.qpos)
    with pytest.raises(SolverError, match=r"cannot reach \[2\.0, 0\.0, 0\.2\].* 1\.\d+ m away"):
        reach_posture(model, start, frame="hand", position=[2.0, 0.0, 0.2], max_error=0.01)
    with pytest.raises(SolverError, match="hand"):
        ArmReach(arm(), target=[2.0, 0.0, 0.2])


def test_pairs_touching_at_the_start_are_reported_not_refused():
    """A model whose keyframe has its gripper's fingers pressed together (i2rt's YAM in
    Menagerie) was refused at every target: the closed fingers were read as the posture's
    self-collision. Pairs that touch at the start are the model's own; new ones still raise."""
    second = (
        '<body name="finger2" pos="0.03 0.005 0"><joint name="slide2" type="slide" '
        'axis="0 1 0" range="-0.01 0"/><geom type="box" size="0.01 0.005 0.01" mass="0.01"/>'
        "</body>"
    )
    xml = arm().replace("</body>\n          </body>", "</body>\n" + second + "</body>", 1)
    model = mujoco.MjModel.from_xml_string(xml)
    start = model.key_qpos[0].copy()  # finger at y = 0.01 overlaps finger2 by 5 mm
    pair = tuple(sorted(self_collisions(model, start)))
    assert len(pair) == 1
    reached = reach_posture(
        model, start, frame="hand", position=[0.45, 0.0, 0.3], avoid_collisions=False
    )
    assert reached.position_error < 1e-3
    assert tuple(sorted(reached.collisions)) == pair


def _two_fingers(finger_range: str, finger2_range: str, key_slide: float) -> mujoco.MjModel:
    """The test arm with a second finger beside the first on the hand, both on slides."""
    second = (
        '<body name="finger2" pos="0.03 0.005 0"><joint name="slide2" type="slide" '
        f'axis="0 1 0" range="{finger2_range}"/>'
        '<geom type="box" size="0.01 0.005 0.01" mass="0.01"/></body>'
    )
    xml = arm().replace("</body>\n          </body>", "</body>\n" + second + "</body>", 1)
    xml = xml.replace('range="0 0.02"', f'range="{finger_range}"')
    xml = xml.replace('qpos="-0.6 1.2 0.01"', f'qpos="-0.6 1.2 {key_slide} 0"')
    return mujoco.MjModel.from_xml_string(xml)


def test_a_start_past_a_joint_limit_with_the_other_jaw_in_the_way_still_gets_an_ik():
    """MuJoCo's joint limits are soft, so a start can lie past one (the benchmark's
    perturbed gripper of the low-cost arm did). mink's joint limit then asks the finger back
    into its range, toward the other jaw, which its collision limit forbids: the first QP had
    no solution, and mink's own NoSolutionFound escaped."""
    target = [0.45, 0.0, 0.3]
    for past in (0.016, 0.02):  # 1 and 5 mm past the finger's range, 1-5 mm from the jaw
        model = _two_fingers("0 0.015", "0 0.001", past)
        start = model.key_qpos[0]
        assert not self_collisions(model, start)
        reached = reach_posture(model, start, frame="hand", position=target)
        assert reached.position_error < 1e-3 and reached.collisions == ()
        assert model.jnt_range[2, 0] <= reached.qpos[2] <= model.jnt_range[2, 1] + 1e-3


def test_an_unnamed_tip_is_named_as_the_problem_rather_than_looked_up():
    """The arm's tip found by the tree is a body without a name: the error says so (it
    once invented 'body N' and then failed to find it, an error about a name no one wrote)."""
    xml = """
    <mujoco><worldbody><body name="upper"><joint name="shoulder" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02"/>
      <body pos="0 0 0.3"><joint name="elbow" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02"/></body>
    </body></worldbody>
    <actuator><motor joint="shoulder"/><motor joint="elbow"/></actuator></mujoco>"""
    with pytest.raises(InvalidArgumentError, match=r"tip is body 2, which has no name"):
        end_effector(mujoco.MjModel.from_xml_string(xml))
