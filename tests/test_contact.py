"""Contact points, Jacobians and friction pyramids."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.core.contact import (
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
