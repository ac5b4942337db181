"""Feet found from the model (:mod:`mpcbox.tasks.legged.ground_feet`): the lowest body of
each leg in the standing posture, checked against feet named by hand."""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import mujoco
import pytest

from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks import scene_path
from mpcbox.tasks.legged.ground_feet import ground_feet


def _humanoid() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))


@pytest.mark.parametrize("key", ["stand", "squat"])
def test_the_humanoid_stands_on_its_foot_bodies_left_then_right(key):
    model = _humanoid()
    qpos = model.key_qpos[model.key(key).id]
    assert ground_feet(model, qpos, 2) == ("body:foot_left", "body:foot_right")


def test_left_and_right_follow_the_root_not_the_world():
    """Turned by 180 deg about the vertical, the robot's left foot is still its left."""
    model = _humanoid()
    qpos = model.key_qpos[model.key("stand").id].copy()
    qpos[3:7] = [0.0, 0.0, 0.0, 1.0]
    assert ground_feet(model, qpos, 2) == ("body:foot_left", "body:foot_right")


def test_a_count_the_legs_do_not_give_is_refused_with_the_legs_found():
    model = _humanoid()
    one_leg = model.key_qpos[model.key("stand_on_left_leg").id]
    with pytest.raises(InvalidArgumentError, match=r"2 feet.*1 leg\(s\) \(.*foot_left\)"):
        ground_feet(model, one_leg, 2)
    with pytest.raises(InvalidArgumentError, match=r"4 feet.*2 leg\(s\).*foot_right.*foot_left"):
        ground_feet(model, model.key_qpos[0], 4)
    with pytest.raises(InvalidArgumentError, match="count"):
        ground_feet(model, model.key_qpos[0], 0)


def test_dm_control_quadruped_stands_on_its_four_toes():
    pytest.importorskip("dm_control")
    from mpcbox.tasks.legged.quadruped import DM_CONTROL_FEET, dm_control_quadruped

    model = dm_control_quadruped().compile()
    feet = ground_feet(model, model.qpos0, 4)
    assert sorted(feet) == sorted(f"body:{name}" for name in DM_CONTROL_FEET)


@pytest.mark.parametrize("name", ["humanoid", "walker"])
def test_dm_control_bipeds(name):
    suite = pytest.importorskip("dm_control.suite")
    path = Path(suite.__file__).parent / f"{name}.xml"
    model = mujoco.MjModel.from_xml_path(str(path))
    assert ground_feet(model, model.qpos0, 2) == ("body:left_foot", "body:right_foot")


def test_biped_stand_finds_the_feet_of_a_robot_it_does_not_know():
    from mpcbox.tasks.legged.biped import BipedStand

    problem = BipedStand(str(scene_path("humanoid.xml")), keyframe="stand", threads=1)
    assert problem.both_feet == ("body:foot_left", "body:foot_right")
    assert [f.name for f in problem.feet] == ["foot_left", "foot_right"]
    problem.close()


def test_quadruped_stand_finds_the_feet_of_a_robot_it_does_not_know():
    pytest.importorskip("dm_control")
    from mpcbox.tasks.legged.quadruped import DM_CONTROL_FEET, QuadrupedStand, dm_control_quadruped

    problem = QuadrupedStand(dm_control_quadruped(), threads=1)
    assert sorted(f.name for f in problem.feet) == sorted(DM_CONTROL_FEET)
    problem.close()


sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


@pytest.mark.menagerie
@pytest.mark.parametrize(
    "robot",
    [
        "unitree_g1",
        "unitree_h1",
        "booster_t1",
        "berkeley_humanoid",
        "apptronik_apollo",
        "fourier_n1",
        "pal_talos",
        "pndbotics_adam_lite",
        "robotis_op3",
        "agility_cassie",
        "anybotics_anymal_b",
        "anybotics_anymal_c",
        "unitree_go1",
        "unitree_go2",
        "unitree_a1",
    ],
)
def test_menagerie_feet_match_those_named_by_hand(robot):
    from menagerie_robots import MORE_ROBOTS, ROBOTS

    from mpcbox.core import menagerie
    from mpcbox.core.model import compile_spec, load_spec
    from mpcbox.tasks.legged.quadruped import MENAGERIE_FEET

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available(robot, None)):
        pytest.skip(f"no offline Menagerie copy with {robot} (set MENAGERIE_ROOT)")
    named = {k.partition("/")[0]: v for k, v in {**ROBOTS, **MORE_ROBOTS}.items()}
    named.update(MENAGERIE_FEET)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # visual meshes missing offline
        model = compile_spec(load_spec(f"menagerie:{robot}"))
    qpos = model.key_qpos[0] if model.nkey else model.qpos0
    feet = ground_feet(model, qpos, len(named[robot]))

    def body(entry: str) -> str:
        kind, _, name = entry.partition(":")
        if kind == "geom":
            return model.body(int(model.geom(name).bodyid[0])).name
        return name

    got = [body(f) for f in feet]
    expected = [body(f) for f in named[robot]]
    if len(expected) == 2:
        assert got == expected  # (left, right)
    else:
        assert sorted(got) == sorted(expected)


def test_bad_inputs_are_named():
    from mpcbox.errors import ShapeError, UnknownNameError

    model = _humanoid()
    with pytest.raises(ShapeError, match="qpos"):
        ground_feet(model, model.key_qpos[0][:-1], 2)
    with pytest.raises(UnknownNameError, match="root"):
        ground_feet(model, model.key_qpos[0], 2, root="pelvis_nope")
    with pytest.raises(InvalidArgumentError, match="tolerance"):
        ground_feet(model, model.key_qpos[0], 2, tolerance=-1.0)


def test_a_quadruped_stand_on_three_named_feet_warns() -> None:
    """A fuzz run stood a Go1 on three named feet without a word (the QP then plans forces
    on three feet, and the balance measure moves to their middle)."""
    pytest.importorskip("dm_control")
    from mpcbox.tasks.legged.quadruped import DM_CONTROL_FEET, QuadrupedStand, dm_control_quadruped

    three = [f"body:{name}" for name in DM_CONTROL_FEET[:3]]
    with pytest.warns(UserWarning, match="names 3 feet"):
        problem = QuadrupedStand(dm_control_quadruped(), feet=three, threads=1)
    assert len(problem.feet) == 3
