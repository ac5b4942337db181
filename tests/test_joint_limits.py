"""A reference posture kept off its joints' limits (mpcbox.core.joint_limits)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.core.joint_limits import LIMIT_CLEARANCE, clear_of_limits, movable_joints
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, PostureWarning

# An arm swinging about z (gravity does not act on it) whose keyframe puts the motor-driven
# "elbow" on its upper limit; a passive "finger" rests on its limit; "a" and "b" are coupled
# by an equality; "slide" has a 4 cm range and sits 1 mm past its upper end.
XML = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.01"/>
  <worldbody>
    <body name="upper">
      <joint name="elbow" type="hinge" axis="0 0 1" range="-2 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <body name="fingerbody" pos="0.3 0 0">
        <joint name="finger" type="hinge" axis="0 0 1" range="-1 0"/>
        <geom type="box" size="0.02 0.01 0.01" mass="0.05"/>
      </body>
      <body name="abody" pos="0.1 0 0">
        <joint name="a" type="hinge" axis="0 0 1" range="0 1"/>
        <geom type="box" size="0.01 0.01 0.01" mass="0.05"/>
      </body>
      <body name="bbody" pos="0.2 0 0">
        <joint name="b" type="hinge" axis="0 0 1" range="0 1"/>
        <geom type="box" size="0.01 0.01 0.01" mass="0.05"/>
      </body>
      <body name="sbody" pos="0.15 0 0">
        <joint name="slide" type="slide" axis="0 1 0" range="0 0.04"/>
        <geom type="box" size="0.01 0.01 0.01" mass="0.05"/>
      </body>
    </body>
  </worldbody>
  <equality><joint joint1="a" joint2="b"/></equality>
  <actuator>
    <motor joint="elbow" ctrlrange="-5 5"/>
    <motor joint="a" ctrlrange="-1 1"/>
    <position joint="slide" kp="50" ctrlrange="0 0.04"/>
  </actuator>
  <keyframe><key name="rest" qpos="0 0 0 0 0.041"/></keyframe>
</mujoco>
"""


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(XML)


def test_movable_joints_are_driven_and_uncoupled(model):
    names = [model.joint(j).name for j in movable_joints(model)]
    assert names == ["elbow", "slide"]  # finger: passive; a: coupled to b


def test_clear_of_limits_moves_driven_joints_inside(model):
    qpos, moves = clear_of_limits(model, model.key_qpos[0])
    # elbow: range 2 rad, so the full clearance; slide: 5 % of its 4 cm range.
    assert qpos[0] == pytest.approx(-LIMIT_CLEARANCE)
    assert qpos[4] == pytest.approx(0.04 - 0.05 * 0.04)
    np.testing.assert_array_equal(qpos[1:4], model.key_qpos[0][1:4])
    assert [(m.joint, m.old) for m in moves] == [("elbow", 0.0), ("slide", 0.041)]
    # Clearance 0 moves a joint past its limit onto it and leaves one on its limit.
    qpos0, moves0 = clear_of_limits(model, model.key_qpos[0], 0.0)
    assert qpos0[0] == 0.0 and qpos0[4] == pytest.approx(0.04)
    assert [m.joint for m in moves0] == ["slide"]
    inside = np.array([-0.5, -0.5, 0.5, 0.5, 0.02])
    assert clear_of_limits(model, inside)[1] == []
    # Far outside (more than 5 % of the range): a posture of its own, left as given.
    far = np.array([0.5, 0.0, 0.0, 0.0, 0.05])
    with pytest.warns(PostureWarning, match="far outside their range left as given: elbow"):
        kept, moved = clear_of_limits(model, far, warn=True)
    np.testing.assert_array_equal(kept[[0, 4]], [0.5, 0.05])
    assert moved == []


def test_problem_linearizes_off_the_limit(model):
    """On the limit a finite difference engages the limit on one side only and ``A`` gets
    the limit's stiffness; moved inside, the elbow is a free rotor (``A`` of a double
    integrator with damping)."""
    with pytest.warns(PostureWarning, match="elbow 0 -> -0.01"):
        problem = Problem(XML, keyframe="rest", threads=1)
    assert [m.joint for m in problem.limit_moves] == ["elbow", "slide"]
    assert problem.qpos_ref[0] == pytest.approx(-LIMIT_CLEARANCE)
    nv = problem.nv
    with pytest.warns(PostureWarning, match="slide 0.041 -> 0.04"):
        on_limit = Problem(XML, keyframe="rest", limit_clearance=0.0, threads=1)
    assert on_limit.qpos_ref[0] == 0.0
    for centered in (False, True):
        lin = problem.linearize(problem.reference_state(), problem.ctrl_ref, centered=centered)
        assert abs(lin.A[nv, 0]) < 1e-6  # the elbow's velocity does not depend on its angle
        lin0 = on_limit.linearize(on_limit.reference_state(), on_limit.ctrl_ref, centered=centered)
        assert abs(lin0.A[nv, 0]) > 1.0  # the limit's stiffness, from one side only
    with pytest.raises(InvalidArgumentError, match="limit_clearance"):
        Problem(XML, limit_clearance=-1.0, threads=1)
