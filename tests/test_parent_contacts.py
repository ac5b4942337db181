"""Links colliding with the static body they hang from (``mpcbox.core.parent_contacts``).

MuJoCo filters parent-child contacts except when the parent is welded to the world. The
fixture is an arm whose static ``base`` box overlaps its ``shoulder`` box by 1 cm, as
Kinova's Gen3 overlaps its base by 12 mm; a motor turns the shoulder about the vertical.
"""

from __future__ import annotations

import os
import warnings

import mujoco
import numpy as np
import pytest

from mpcbox import ModelWarning, Problem
from mpcbox.core.parent_contacts import static_parent_contacts
from mpcbox.errors import InvalidArgumentError

ARM = """
<mujoco>
  <option {option}/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 0.1">
      <geom type="box" size="0.1 0.1 0.1"/>
      <body name="shoulder" pos="0 0 0.19">
        <joint name="yaw" axis="0 0 1" damping="0.01"/>
        <geom type="box" size="0.2 0.05 0.1" mass="2"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="yaw" joint="yaw" ctrlrange="-5 5"/></actuator>
</mujoco>
"""


def _yaw_acceleration(problem: Problem, torque: float) -> float:
    model = problem.model
    data = mujoco.MjData(model)
    data.ctrl[:] = torque
    mujoco.mj_forward(model, data)
    return float(data.qacc[0])


def test_the_overlap_with_a_static_parent_is_found_with_its_depth() -> None:
    model = mujoco.MjModel.from_xml_string(ARM.format(option=""))
    (found,) = static_parent_contacts(model)
    assert (found.parent, found.child) == ("base", "shoulder")
    assert found.depth == pytest.approx(0.01, abs=1e-6)


def test_a_link_hinged_from_the_world_body_itself_is_not_reported() -> None:
    # The floor belongs to the world body: a link hanging straight from it touching the floor
    # is an ordinary contact, not the filter's exception.
    xml = """
    <mujoco><worldbody>
      <geom type="plane" size="1 1 0.1"/>
      <body name="link" pos="0 0 0.05">
        <joint name="pitch" axis="0 1 0"/><geom type="sphere" size="0.1"/>
      </body>
    </worldbody><actuator><motor joint="pitch"/></actuator></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon > 0  # the sphere is in the floor
    assert static_parent_contacts(model) == ()


def test_nothing_is_reported_when_the_model_turns_the_parent_filter_off() -> None:
    model = mujoco.MjModel.from_xml_string(ARM.format(option="").replace("<option />", ""))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    assert static_parent_contacts(model) == ()


def test_problem_excludes_the_pair_says_so_and_the_joint_turns_freely() -> None:
    with pytest.warns(ModelWarning, match="'base' with 'shoulder' \\(10.0 mm deep\\)"):
        problem = Problem(ARM.format(option=""))
    assert [(c.parent, c.child) for c in problem.excluded_contacts] == [("base", "shoulder")]
    assert "excluded contact: base/shoulder" in repr(problem)
    # Free yaw: qacc = torque / inertia about z (box 0.4 x 0.1: m (a^2 + b^2) / 12).
    inertia = 2.0 * (0.4**2 + 0.1**2) / 12.0
    assert _yaw_acceleration(problem, 1.0) == pytest.approx(1.0 / inertia, rel=1e-6)
    # The planning model has the exclusion too.
    data = mujoco.MjData(problem.planning_model)
    mujoco.mj_forward(problem.planning_model, data)
    assert data.ncon == 0


def test_keep_simulates_the_contact_and_warns() -> None:
    with pytest.warns(ModelWarning, match="resist"):
        problem = Problem(ARM.format(option=""), parent_contacts="keep")
    assert problem.excluded_contacts == ()
    inertia = 2.0 * (0.4**2 + 0.1**2) / 12.0
    # Friction of the overlapping boxes holds most of the torque back.
    assert abs(_yaw_acceleration(problem, 1.0)) < 0.5 / inertia


def test_a_compiled_model_cannot_be_changed_so_the_warning_names_the_fix() -> None:
    model = mujoco.MjModel.from_xml_string(ARM.format(option=""))
    with pytest.warns(ModelWarning, match="pass the MJCF"):
        problem = Problem(model)
    assert problem.excluded_contacts == ()


def test_a_model_without_such_contacts_is_left_alone() -> None:
    xml = ARM.format(option="").replace('pos="0 0 0.19"', 'pos="0 0 0.31"')
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelWarning)
        problem = Problem(xml)
    assert problem.excluded_contacts == ()
    assert "excluded" not in repr(problem)


def test_a_bad_choice_is_refused_with_the_valid_ones() -> None:
    with pytest.raises(InvalidArgumentError, match=r"parent_contacts.*exclude.*keep"):
        Problem(ARM.format(option=""), parent_contacts="drop")


@pytest.mark.menagerie
def test_kinova_gen3_base_and_shoulder_are_excluded_and_lqr_reaches() -> None:
    from mpcbox.core import menagerie

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("kinova_gen3")):
        pytest.skip("no kinova_gen3 in the offline Menagerie copy")
    import mpcbox
    from mpcbox.registry import make_controller
    from mpcbox.tasks.reach import ArmReach

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        problem = ArmReach("menagerie:kinova_gen3", target=[0, 0.3, -0.2646], relative=True)
    pairs = [(c.parent, c.child) for c in problem.excluded_contacts]
    assert ("base_link", "shoulder_link") in pairs
    sim = mpcbox.simulate(problem, make_controller("lqr", problem), 2.0, seed=0)
    # With the contact kept, joint_1 crept at 0.17 rad/s and LQR was 1.6 cm away at 2 s.
    assert problem.reach_error(sim.states[-1]) < 0.01
    assert np.all(np.isfinite(sim.states))
