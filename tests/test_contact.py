"""Contact points, Jacobians and friction pyramids."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.core.contact import (
    POINT_SOLE,
    collision_geoms,
    cone_violation,
    contact_jacobian,
    contact_points,
    friction_pyramid,
    project_to_pyramid,
)
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.tasks import scene_path


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))


def _stand(model: mujoco.MjModel) -> np.ndarray:
    return model.key_qpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "stand")]


def test_body_gives_capsule_ends_at_the_bottom(model):
    qpos = _stand(model)
    pts = contact_points(model, "body:foot_left", qpos)
    assert pts.count == 4
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    world = pts.world(data)
    # Bottom of the 0.027 m capsules, 0.5 mm into the floor in keyframe "stand".
    np.testing.assert_allclose(world[:, 2], world[0, 2], atol=1e-9)
    assert abs(world[0, 2]) < 2e-3
    # Ends of the capsules: heel at x = -0.05, toe at x = 0.13 in the foot frame.
    np.testing.assert_allclose(sorted(pts.local[:, 0]), [-0.05, -0.05, 0.13, 0.13], atol=1e-6)
    assert len(pts.groups()) == 1


def test_geom_site_and_prefixes(model):
    assert contact_points(model, ["foot1_left"]).count == 2
    assert contact_points(model, "site:foot_left").count == 1
    # Without a prefix a body wins over the site of the same name.
    assert contact_points(model, "foot_left").count == 4
    both = contact_points(model, ["body:foot_left", "body:foot_right"])
    assert both.count == 8 and len(both.groups()) == 2


# A foot body with a mesh sole (a 20 x 8 x 4 cm box as a mesh, yawed 30 deg), a cylinder
# standing upright, a tilted ellipsoid, and a box that collides only through a <pair>.
SHAPES = """
<mujoco>
  <asset>
    <mesh name="sole" vertex="-.1 -.04 -.02  .1 -.04 -.02  .1 .04 -.02  -.1 .04 -.02
                               -.1 -.04 .02  .1 -.04 .02  .1 .04 .02  -.1 .04 .02"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="foot" pos="0 0 .1" euler="0 0 30">
      <geom name="sole" type="mesh" mesh="sole"/>
    </body>
    <body name="can" pos="1 0 .1"><geom name="can" type="cylinder" size=".05 .1"/></body>
    <body name="egg" pos="2 0 .1" euler="40 0 0">
      <geom name="egg" type="ellipsoid" size=".03 .05 .08"/>
    </body>
    <body name="paired" pos="3 0 .1">
      <geom name="paired" type="box" size=".05 .05 .05" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <contact><pair geom1="floor" geom2="paired"/></contact>
</mujoco>
"""


def test_mesh_cylinder_and_ellipsoid_feet_stand_on_their_lowest_points():
    model = mujoco.MjModel.from_xml_string(SHAPES)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    # The mesh sole: its four bottom corners, in the foot's frame.
    sole = contact_points(model, "body:foot")
    np.testing.assert_allclose(
        sorted(map(tuple, np.round(sole.local, 9))),
        sorted((x, y, -0.02) for x in (-0.1, 0.1) for y in (-0.04, 0.04)),
        atol=1e-9,
    )
    # The upright cylinder: four points of its bottom rim, 0.05 m from its axis.
    can = contact_points(model, "can").world(data)
    assert len(can) == 4
    np.testing.assert_allclose(can[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(can[:, :2] - [1.0, 0.0], axis=1), 0.05)
    # The tilted ellipsoid: its support point along -z, c - S e_z / sqrt(e_z' S e_z).
    (egg,) = contact_points(model, "egg").world(data)
    rot = data.geom_xmat[model.geom("egg").id].reshape(3, 3)
    shape = rot @ np.diag([0.03, 0.05, 0.08]) ** 2 @ rot.T
    lowest = 0.1 - np.sqrt(shape[2, 2])
    assert egg[2] == pytest.approx(lowest, abs=1e-12)
    assert egg[2] < 0.1 - 0.05  # lower than the middle radius would put it


# A rounded foot tip: a low-poly ball (radius 1.5 cm) whose bottom is a flat 1 x 1 cm
# facet, a thin cylinder (radius 4 mm) and, for contrast, a 3 cm cylinder.
TIPS = """
<mujoco>
  <asset>
    <mesh name="tip" vertex="-.005 -.005 -.015  .005 -.005 -.015  .005 .005 -.015
                              -.005 .005 -.015  -.015 0 0  .015 0 0  0 -.015 0  0 .015 0
                              0 0 .015"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="tip" pos="0 0 .1" euler="0 0 20"><geom name="tip" type="mesh" mesh="tip"/></body>
    <body name="pin" pos="1 0 .1"><geom name="pin" type="cylinder" size=".004 .05"/></body>
    <body name="post" pos="2 0 .1"><geom name="post" type="cylinder" size=".03 .05"/></body>
  </worldbody>
</mujoco>
"""


def test_a_sole_narrower_than_point_sole_is_one_point_at_its_centre():
    model = mujoco.MjModel.from_xml_string(TIPS)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    # The facet's corners lie 7.1 mm from its centre (< POINT_SOLE): one point there.
    (tip,) = contact_points(model, "body:tip").world(data)
    np.testing.assert_allclose(tip, [0.0, 0.0, 0.085], atol=1e-12)
    (pin,) = contact_points(model, "pin").world(data)
    np.testing.assert_allclose(pin, [1.0, 0.0, 0.05], atol=1e-12)
    # A 3 cm cylinder keeps four rim points: it can carry a moment.
    post = contact_points(model, "post").world(data)
    assert len(post) == 4 and 0.03 > POINT_SOLE
    np.testing.assert_allclose(np.linalg.norm(post[:, :2] - [2.0, 0.0], axis=1), 0.03)


def test_a_geom_that_touches_only_through_a_pair_is_a_collision_geom():
    model = mujoco.MjModel.from_xml_string(SHAPES)
    assert collision_geoms(model)[model.geom("paired").id]
    assert contact_points(model, "body:paired").count == 4
    bare = SHAPES.replace('<contact><pair geom1="floor" geom2="paired"/></contact>', "")
    with pytest.raises(InvalidArgumentError, match="no collision geom to stand on"):
        contact_points(mujoco.MjModel.from_xml_string(bare), "body:paired")


def test_unknown_names_list_the_valid_ones(model):
    with pytest.raises(UnknownNameError) as err:
        contact_points(model, ["foot_middle"])
    assert "foot_left" in str(err.value) and "foot1_left" in str(err.value)
    with pytest.raises(UnknownNameError) as err:
        contact_points(model, ["site:foot1_left"])
    assert "'foot_left'" in str(err.value)
    with pytest.raises(InvalidArgumentError):
        contact_points(model, [])


def test_contact_jacobian_matches_finite_differences(model):
    qpos = _stand(model).copy()
    qpos[7:] += 0.1
    pts = contact_points(model, "body:foot_right", qpos)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    jac = contact_jacobian(model, data, pts)
    p0 = pts.world(data).ravel()
    eps = 1e-7
    fd = np.zeros_like(jac)
    for i in range(model.nv):
        dq = np.zeros(model.nv)
        dq[i] = eps
        q = qpos.copy()
        mujoco.mj_integratePos(model, q, dq, 1.0)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        fd[:, i] = (pts.world(data).ravel() - p0) / eps
    np.testing.assert_allclose(jac, fd, atol=1e-5)


@pytest.mark.parametrize("facets", [4, 8])
def test_pyramid(facets):
    G = friction_pyramid(0.5, facets)
    assert G.shape == (facets, 3)
    inside = np.array([0.2, -0.2, 1.0])
    outside = np.array([0.6, 0.0, 1.0])
    assert np.all(G @ inside <= 0)
    assert np.any(G @ outside > 0)
    if facets == 4:
        np.testing.assert_allclose(np.sort(np.abs(G[:, :2]).sum(axis=1)), 1.0, atol=1e-12)
    rng = np.random.default_rng(0)
    forces = rng.normal(size=(50, 3)) * [1, 1, 2]
    proj = project_to_pyramid(forces, 0.5, facets, 1.5)
    assert cone_violation(proj, 0.5, facets, 1.5) <= 1e-12


def test_pyramid_rejects_bad_input():
    with pytest.raises(InvalidArgumentError, match="friction"):
        friction_pyramid(0.0)
    with pytest.raises(InvalidArgumentError, match="facets"):
        friction_pyramid(0.5, 5)


# A cylinder lying on its side (axis along the world's x after a 90 deg pitch), its body
# yawed by 30 deg: its lowest part is a line along the axis.
LYING = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="toe" pos="0.3 0.2 0.03" euler="0 0 30">
      <freejoint/>
      <geom name="roll" type="cylinder" size=".03 .1" euler="0 90 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_cylinder_lying_on_its_side_stands_on_both_ends_of_its_lowest_line():
    """The corners used to be taken along the geom's own axes, one of which is vertical for
    a lying cylinder, so both picks fell at one end (Adam Lite's toes: soles at their front
    tips, 17 cm from the middle)."""
    from mpcbox.tasks.legged.feet import find_feet, support_centre

    model = mujoco.MjModel.from_xml_string(LYING)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    points = contact_points(model, "roll").world(data)
    # On the floor, to the rim's sampling (16 directions: within 0.03 (1 - cos 22.5 deg)).
    assert np.ptp(points[:, 2]) < 1e-9 and 0.0 <= points[0, 2] < 2.5e-3
    axis = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    along = (points[:, :2] - [0.3, 0.2]) @ axis
    assert along.min() == pytest.approx(-0.1) and along.max() == pytest.approx(0.1)
    (foot,) = find_feet(model, ["body:toe"], data.qpos)
    np.testing.assert_allclose(foot.sole[:2], 0.0, atol=1e-9)  # under the middle
    # The middle of a sole is its hull's area centroid, not the mean of its points: a
    # square with three extra points along one edge still has its centre in the middle.
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    extra = np.array([[1, 0.25, 0], [1, 0.5, 0], [1, 0.75, 0]], dtype=float)
    np.testing.assert_allclose(support_centre(np.vstack([square, extra])), [0.5, 0.5, 0.0])
    np.testing.assert_allclose(support_centre(square[:2]), [0.5, 0.0, 0.0])
