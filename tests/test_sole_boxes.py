"""Flat mesh soles planned on as boxes (:mod:`mpcbox.core.sole_boxes`).

The test model is a block standing on a flat mesh sole, a 0.2 x 0.08 m rectangle sampled
with vertices inside it as well as on its rim (as a scanned foot is), 3 cm high.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from mpcbox.core.sole_boxes import BOX_THICKNESS, box_soles
from mpcbox.errors import InvalidArgumentError

LENGTH, WIDTH, HEIGHT = 0.2, 0.08, 0.03


def _sole_vertices() -> str:
    xs = np.linspace(-LENGTH / 2, LENGTH / 2, 5)
    ys = np.linspace(-WIDTH / 2, WIDTH / 2, 3)
    pts = [(x, y, z) for x in xs for y in ys for z in (-HEIGHT / 2, HEIGHT / 2)]
    return " ".join(f"{v:.6f}" for p in pts for v in p)


def _rounded_vertices() -> str:
    pts = []
    for theta in np.linspace(0.2, np.pi - 0.2, 7):
        for phi in np.linspace(0.0, 2 * np.pi, 9, endpoint=False):
            ring = np.sin(theta) * np.array([0.1 * np.cos(phi), 0.04 * np.sin(phi)])
            pts.append((*ring, 0.03 * np.cos(theta)))
    pts += [(0, 0, 0.03), (0, 0, -0.03)]
    return " ".join(f"{v:.6f}" for p in pts for v in p)


def _model(sole: str = "flat", tilt_deg: float = 0.0) -> mujoco.MjModel:
    verts = _sole_vertices() if sole == "flat" else _rounded_vertices()
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, np.array([1.0, 0.0, 0.0]), np.radians(tilt_deg))
    xml = f"""
    <mujoco>
      <asset><mesh name="sole" vertex="{verts}"/></asset>
      <worldbody>
        <geom name="floor" type="plane" size="1 1 0.1"/>
        <body name="block" pos="0 0 0.1">
          <freejoint/>
          <geom name="sole" type="mesh" mesh="sole" pos="0.01 0 -0.05"
                quat="{" ".join(map(str, quat))}" mass="1"/>
          <geom name="top" type="box" size="0.05 0.03 0.03" pos="0 0 0.02" mass="2"/>
        </body>
        <body name="other" pos="0.5 0 0.1">
          <freejoint/>
          <geom type="mesh" mesh="sole" pos="0 0 -0.05" mass="1"/>
        </body>
      </worldbody>
    </mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def _resting_qpos(model: mujoco.MjModel, sink: float = 5e-4) -> np.ndarray:
    """Each free body lowered until its lowest collision vertex is ``sink`` below z = 0."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    qpos = model.qpos0.copy()
    for body in (1, 2):
        low = np.inf
        for g in range(model.ngeom):
            if model.geom_bodyid[g] != body or model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
                continue
            mesh = model.geom_dataid[g]
            start = model.mesh_vertadr[mesh]
            v = model.mesh_vert[start : start + model.mesh_vertnum[mesh]]
            world = data.geom_xpos[g] + v @ data.geom_xmat[g].reshape(3, 3).T
            low = min(low, world[:, 2].min())
        adr = model.jnt_qposadr[model.body_jntadr[body]]
        qpos[adr + 2] -= low + sink
    return qpos


def _contacts(model: mujoco.MjModel, qpos: np.ndarray, body: int = 1) -> np.ndarray:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_fwdPosition(model, data)
    pts = [c.pos.copy() for c in data.contact[: data.ncon] if model.geom_bodyid[c.geom2] == body]
    return np.array(sorted(map(tuple, np.round(pts, 6))))


def _tilted(qpos: np.ndarray, angle: float, axis: int = 1) -> np.ndarray:
    out = qpos.copy()
    dq = np.zeros(3)
    dq[axis] = angle
    quat = out[3:7].copy()
    mujoco.mju_quatIntegrate(quat, dq, 1.0)
    out[3:7] = quat
    return out


def test_a_flat_mesh_sole_becomes_the_box_spanning_it():
    model = _model()
    qpos = _resting_qpos(model)
    boxed = box_soles(model, qpos, [1])
    assert boxed.geoms == ("sole",)  # the other body's sole is not among the feet
    g = 1
    thickness = BOX_THICKNESS * float(model.geom_rbound[g])
    np.testing.assert_allclose(
        boxed.half_sizes[0], [LENGTH / 2, WIDTH / 2, thickness / 2], atol=1e-6
    )
    assert boxed.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH  # the input is not changed
    # The box's bottom face is the sole's plane: level, at the same height.
    data = mujoco.MjData(boxed.model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(boxed.model, data)
    signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])
    corners = data.geom_xpos[g] + (signs * boxed.half_sizes[0]) @ data.geom_xmat[g].reshape(3, 3).T
    bottom = np.sort(corners[:, 2])[:4]
    np.testing.assert_allclose(bottom, -5e-4, atol=1e-7)
    np.testing.assert_allclose(np.ptp(corners[:, 0]), LENGTH, atol=1e-6)


def _toe_model() -> mujoco.MjModel:
    """A sole with a pointed toe (its bounding rectangle sticks out of the mesh) and a post
    at one heel corner (the mesh's principal axes, its geom frame, are not the sole's)."""
    sole = [(-0.1, -0.04), (-0.1, 0.04), (0.08, -0.04), (0.08, 0.04), (0.13, 0.0)]
    pts = [(x, y, 0.0) for x, y in sole] + [(0.9 * x, 0.9 * y, 0.02) for x, y in sole]
    pts += [(-0.1, 0.04, 0.12), (-0.08, 0.04, 0.12), (-0.1, 0.02, 0.12)]
    verts = " ".join(f"{v:.5f}" for p in pts for v in p)
    return mujoco.MjModel.from_xml_string(f"""
    <mujoco>
      <asset><mesh name="sole" vertex="{verts}"/></asset>
      <worldbody>
        <geom name="floor" type="plane" size="1 1 0.1"/>
        <body name="block" pos="0 0 0.2">
          <freejoint/>
          <geom name="sole" type="mesh" mesh="sole"/>
          <geom type="sphere" size="0.01" pos="0 0 0.1"/>
        </body>
      </worldbody>
    </mujoco>""")


def test_the_foot_bounding_volumes_contain_the_box():
    """The box sticks out of the mesh's bounding volumes here; the body's tree is grown to
    contain it, and the contacts found with MuJoCo's midphase equal those without it."""
    model = _toe_model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mesh = model.mesh_vert[: model.mesh_vertnum[0]]
    low = (data.geom_xpos[1] + mesh @ data.geom_xmat[1].reshape(3, 3).T)[:, 2].min()
    qpos = model.qpos0.copy()
    qpos[2] -= low + 5e-4
    boxed = box_soles(model, qpos, [1])
    assert boxed.geoms == ("sole",)
    out = boxed.model
    data = mujoco.MjData(out)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(out, data)
    signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])
    corners = data.geom_xpos[1] + (signs * out.geom_size[1]) @ data.geom_xmat[1].reshape(3, 3).T
    local = (corners - data.xipos[1]) @ data.ximat[1].reshape(3, 3)  # the tree's frame
    start, count = out.body_bvhadr[1], out.body_bvhnum[1]
    old = model.bvh_aabb[start : start + count]
    assert np.any(np.abs(local - old[0, :3]) > old[0, 3:] + 1e-9)  # out of the old root
    for node in out.bvh_aabb[start : start + count]:
        assert np.all(np.abs(local - node[:3]) <= node[3:] + 1e-9)
    brute = copy.copy(out)
    brute.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_MIDPHASE)
    for tilt in np.radians([-4.0, 0.0, 4.0]):
        for z in np.linspace(-0.001, 0.006, 8):
            pose = _tilted(qpos, tilt)
            pose[2] += z
            np.testing.assert_array_equal(_contacts(out, pose), _contacts(brute, pose))


@pytest.mark.parametrize("angle", [1e-9, -1e-9, 1e-6, -1e-6, 1e-4])
def test_the_box_keeps_its_four_corners_under_small_tilts(angle):
    model = _model()
    qpos = _resting_qpos(model)
    boxed = box_soles(model, qpos, [1]).model
    for axis in (0, 1):
        pts = _contacts(boxed, _tilted(qpos, angle, axis))
        assert len(pts) == 4
        np.testing.assert_allclose(np.ptp(pts[:, 0]), LENGTH, atol=1e-4)
        np.testing.assert_allclose(np.ptp(pts[:, 1]), WIDTH, atol=1e-4)


def test_box_soles_make_the_contact_forces_smooth_in_the_tilt():
    """Generalized contact force against tilt: the box's is smooth (finite differences at
    two step sizes agree) where the mesh's contact set may jump."""
    model = _model()
    qpos = _resting_qpos(model)
    boxed = box_soles(model, qpos, [1]).model

    def force(angle: float) -> np.ndarray:
        data = mujoco.MjData(boxed)
        data.qpos[:] = _tilted(qpos, angle)
        mujoco.mj_forward(boxed, data)
        return data.qfrc_constraint[:6].copy()

    slopes = [(force(h) - force(-h)) / (2 * h) for h in (1e-5, 1e-6)]
    np.testing.assert_allclose(slopes[0], slopes[1], rtol=1e-3, atol=1e-3 * np.abs(slopes[1]).max())


def test_rounded_tilted_and_lifted_soles_keep_their_mesh():
    rounded = _model("rounded")
    assert box_soles(rounded, _resting_qpos(rounded), [1]).geoms == ()
    tilted = _model(tilt_deg=5.0)  # the sole's face is 5 deg off its geom's axes
    assert box_soles(tilted, _resting_qpos(tilted), [1]).geoms == ()
    flat = _model()
    lifted = _resting_qpos(flat, sink=-0.01)  # 1 cm above the floor
    result = box_soles(flat, lifted, [1])
    assert result.geoms == () and result.model is flat


def _biped_xml() -> str:
    """A torso on an actuated ankle over the flat mesh sole, standing in its keyframe."""
    return f"""
    <mujoco>
      <asset><mesh name="sole" vertex="{_sole_vertices()}"/></asset>
      <worldbody>
        <geom name="floor" type="plane" size="1 1 0.1"/>
        <body name="torso" pos="0 0 0.3">
          <freejoint/>
          <geom type="capsule" fromto="0 0 0 0 0 0.2" size="0.04" mass="5"/>
          <body name="foot" pos="0 0 -0.2">
            <joint name="ankle" axis="0 1 0" damping="1"/>
            <geom type="capsule" fromto="0 0 0 0 0 0.2" size="0.02" mass="1"/>
            <geom name="sole" type="mesh" mesh="sole" pos="0 0 -0.015" mass="0.5"/>
          </body>
        </body>
      </worldbody>
      <actuator><motor joint="ankle" ctrlrange="-50 50"/></actuator>
      <keyframe><key name="stand" qpos="0 0 0.3 1 0 0 0 0"/></keyframe>
    </mujoco>"""


def test_legged_balance_plans_on_box_soles_and_says_so():
    from mpcbox.tasks.legged.balance import LeggedBalance

    xml = _biped_xml()
    problem = LeggedBalance(xml, feet=["body:foot"], threads=1)
    sole = mujoco.mj_name2id(problem.model, mujoco.mjtObj.mjOBJ_GEOM, "sole")
    assert problem.planning_changes == ("box soles ['sole']",)
    assert "planning: box soles ['sole']" in repr(problem)
    assert problem.model.geom_type[sole] == mujoco.mjtGeom.mjGEOM_MESH  # simulated as given
    assert problem.planning_model.geom_type[sole] == mujoco.mjtGeom.mjGEOM_BOX
    coarse = problem.with_planning_timestep(0.01)  # a coarser planning copy keeps the box
    assert coarse.planning_model.geom_type[sole] == mujoco.mjtGeom.mjGEOM_BOX
    as_given = LeggedBalance(xml, feet=["body:foot"], threads=1, mesh_soles="mesh")
    assert as_given.planning_changes == ()
    assert as_given.planning_model.geom_type[sole] == mujoco.mjtGeom.mjGEOM_MESH
    with pytest.raises(InvalidArgumentError, match="mesh_soles"):
        LeggedBalance(xml, feet=["body:foot"], threads=1, mesh_soles="boxes")


def test_bad_inputs_are_named():
    from mpcbox.errors import ShapeError, UnknownNameError

    model = _model()
    qpos = _resting_qpos(model)
    assert box_soles(model, qpos, ["block"]).geoms == ("sole",)  # a body by name
    with pytest.raises(UnknownNameError, match=r"bodies.*block"):
        box_soles(model, qpos, ["foot"])
    with pytest.raises(ShapeError, match="qpos"):
        box_soles(model, qpos[:-1], [1])
    bad = qpos.copy()
    bad[0] = np.nan
    with pytest.raises(InvalidArgumentError, match="qpos"):
        box_soles(model, bad, [1])
