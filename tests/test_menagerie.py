"""Menagerie loading: missing visual meshes are dropped, missing collision meshes are errors.

The first tests write small MJCF files that reference mesh files which do not exist, so they
run anywhere. Tests marked ``menagerie`` need an offline copy (``MENAGERIE_ROOT``) and skip
without one.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mpcbox.core import menagerie
from mpcbox.errors import BackendUnavailableError, ModelLoadError, UnknownNameError

CUBE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def write_scene(folder: Path, *, visual_missing: bool, collision_missing: bool) -> Path:
    (folder / "assets").mkdir()
    (folder / "assets" / "present.obj").write_text(CUBE_OBJ)
    xml = f"""
<mujoco>
  <compiler meshdir="assets"/>
  <asset>
    <mesh name="present" file="present.obj"/>
    <mesh name="looks" file="{"gone" if visual_missing else "present"}.obj"/>
    <mesh name="hits" file="{"absent" if collision_missing else "present"}.obj"/>
  </asset>
  <worldbody>
    <body name="link">
      <freejoint/>
      <geom type="mesh" mesh="looks" contype="0" conaffinity="0" group="2"/>
      <geom name="bumper" type="mesh" mesh="hits"/>
      <geom type="mesh" mesh="present" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>"""
    path = folder / "robot.xml"
    path.write_text(xml)
    return path


def test_missing_visual_mesh_is_dropped_with_a_warning(tmp_path: Path) -> None:
    path = write_scene(tmp_path, visual_missing=True, collision_missing=False)
    with pytest.raises(ValueError):  # MuJoCo itself cannot compile it
        mujoco.MjModel.from_xml_path(str(path))
    spec = mujoco.MjSpec.from_file(str(path))
    with pytest.warns(menagerie.MissingMeshWarning, match="looks"):
        dropped = menagerie.drop_missing_visual_meshes(spec)
    assert dropped == ["looks"]
    model = spec.compile()
    assert model.ngeom == 2 and model.nmesh == 2  # the collision geom and mesh are kept
    assert model.geom("bumper").contype == 1


def test_missing_collision_mesh_is_an_error_naming_the_geom(tmp_path: Path) -> None:
    path = write_scene(tmp_path, visual_missing=False, collision_missing=True)
    spec = mujoco.MjSpec.from_file(str(path))
    with pytest.raises(ModelLoadError, match=r"bumper.*absent"):
        menagerie.drop_missing_visual_meshes(spec)


def test_nothing_missing_changes_nothing(tmp_path: Path) -> None:
    path = write_scene(tmp_path, visual_missing=False, collision_missing=False)
    spec = mujoco.MjSpec.from_file(str(path))
    assert menagerie.drop_missing_visual_meshes(spec) == []
    assert spec.compile().ngeom == 3


def test_a_model_loaded_by_path_drops_missing_visual_meshes_too(tmp_path: Path) -> None:
    """A user's own file (or a Menagerie robot given by path) loads as a Menagerie name does."""
    from mpcbox.core.model import load_spec

    path = write_scene(tmp_path, visual_missing=True, collision_missing=False)
    with pytest.warns(menagerie.MissingMeshWarning, match="looks"):
        spec = load_spec(str(path))
    assert spec.compile().ngeom == 2


def test_a_model_loaded_by_path_with_a_missing_collision_mesh_is_a_named_error(
    tmp_path: Path,
) -> None:
    from mpcbox import Problem

    path = write_scene(tmp_path, visual_missing=False, collision_missing=True)
    with pytest.raises(ModelLoadError, match=r"bumper.*absent"):
        Problem(str(path))


def test_unknown_robot_lists_the_valid_names() -> None:
    pytest.importorskip("mujoco_menagerie")
    with pytest.raises(
        ValueError, match=r"unknown Menagerie robot 'unitree_g2'.*did you mean.*'unitree_g1'"
    ):
        menagerie.robot_xml("unitree_g2")


@pytest.mark.menagerie
def test_panda_loads_from_menagerie_root() -> None:
    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("franka_emika_panda")):
        pytest.skip("no offline Menagerie copy with franka_emika_panda (set MENAGERIE_ROOT)")
    model = menagerie.robot_spec("franka_emika_panda").compile()
    assert model.nu == 8 and model.nkey >= 1
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.menagerie
@pytest.mark.parametrize(
    ("robot", "frame"),
    [("franka_emika_panda", "hand"), ("universal_robots_ur5e", "attachment_site")],
)
def test_arm_reach_on_a_menagerie_arm_lqr_reaches_within_5mm(robot: str, frame: str) -> None:
    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available(robot)):
        pytest.skip(f"no offline Menagerie copy with {robot} (set MENAGERIE_ROOT)")
    import warnings

    import mpcbox
    from mpcbox.tasks.reach import ArmReach

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", menagerie.MissingMeshWarning)
        problem = ArmReach(
            f"menagerie:{robot}", frame=frame, target=[0.0, 0.2, -0.2], relative=True
        )
    start = problem.reach_error(problem.initial_state())
    assert start == pytest.approx(np.hypot(0.2, 0.2), abs=1e-9)
    assert problem.goal.position_error < 1e-3  # the IK goal reaches the target
    result = mpcbox.simulate(problem, mpcbox.LQR(problem), 3.0, seed=0)
    assert result.survived, result.failure
    assert problem.reach_error(result.states[-1]) < 0.005  # m, from 28 cm


def test_menagerie_root_works_without_the_package(tmp_path, monkeypatch) -> None:
    """An offline copy in MENAGERIE_ROOT is enough: the package is not needed to read it."""
    import builtins

    (tmp_path / "toy_robot").mkdir()
    (tmp_path / "toy_robot" / "scene.xml").write_text("<mujoco/>")
    (tmp_path / "toy_robot" / "toy.xml").write_text("<mujoco/>")
    real_import = builtins.__import__

    def no_package(name, *args, **kwargs):
        if name == "mujoco_menagerie":
            raise ImportError("not installed")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_package)
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    assert menagerie.robot_xml("toy_robot") == tmp_path / "toy_robot" / "scene.xml"
    assert menagerie.robot_xml("toy_robot", "toy") == tmp_path / "toy_robot" / "toy.xml"
    with pytest.raises(UnknownNameError, match="'toy_robot'"):
        menagerie.robot_xml("toy_robt")
    with pytest.raises(UnknownNameError, match="'scene'"):
        menagerie.robot_xml("toy_robot", "arm")
    monkeypatch.delenv("MENAGERIE_ROOT")
    with pytest.raises(BackendUnavailableError, match="MENAGERIE_ROOT"):
        menagerie.robot_xml("toy_robot")
