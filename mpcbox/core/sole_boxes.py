r"""Plan on boxes where a robot stands on flat mesh soles.

MuJoCo collides a mesh with a plane at the mesh's deepest vertex and at most a few of its
neighbours in the convex hull's graph that lie within the margin. On a flat sole every
vertex of the sole is "deepest" to within rounding, so a tilt of :math:`10^{-13}` rad
picks other vertices, up to a sole's length away: the contact set jumps, and a
finite-difference Jacobian taken across the jump is meaningless. Fourier's N1 stands on such
soles; its LQR about the equilibrium had a spectral radius of 17 and fell in 0.13 s.

A box resting on a plane is collided at its four bottom corners, all of them, for any small
tilt. :func:`box_soles` replaces each flat mesh sole resting on a plane with the box that
spans the sole's lowest part, in a copy of the model used for planning and linearization;
the simulation keeps the mesh.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.contact import collision_geoms
from mpcbox.core.model import check_mjmodel, object_id
from mpcbox.validation import finite_array

_MESH = int(mujoco.mjtGeom.mjGEOM_MESH)
_PLANE = int(mujoco.mjtGeom.mjGEOM_PLANE)

#: Vertices within this height (m) of a mesh's lowest along the floor's normal form its sole.
SOLE_SLAB = 2e-4

#: A sole is flat when it spans at least this fraction of its geom's bounding radius in
#: both directions along the floor (a rounded shoe's lowest 0.2 mm is a small patch, an
#: edge a line); only flat soles become boxes.
MIN_SPAN = 0.25

#: Thickness of a box, as a fraction of its geom's bounding radius (the box's top is
#: inside the foot).
BOX_THICKNESS = 0.05


class SoleBoxes(NamedTuple):
    """The result of :func:`box_soles`.

    Attributes:
        model: A copy of the model with the boxes (the model itself when nothing changed).
        geoms: Names (or ``"geom <id>"``) of the mesh geoms now boxes.
        half_sizes: Each box's half sizes ``(len(geoms), 3)`` (m): along the sole's long
            axis, its short axis and the floor's normal.
    """

    model: mujoco.MjModel
    geoms: tuple[str, ...]
    half_sizes: np.ndarray


def _name(model: mujoco.MjModel, gid: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, gid) or f"geom {gid}"


def resting_on_planes(model: mujoco.MjModel, data: mujoco.MjData) -> dict[int, np.ndarray]:
    """Geoms in contact with a plane in ``data`` (after collision), with the plane's normal
    ``(3,)`` (world frame, pointing away from the plane) for each."""
    out: dict[int, np.ndarray] = {}
    for con in data.contact[: data.ncon]:
        g1, g2 = int(con.geom1), int(con.geom2)
        if model.geom_type[g1] == _PLANE:
            out[g2] = data.geom_xmat[g1].reshape(3, 3)[:, 2].copy()
        elif model.geom_type[g2] == _PLANE:
            out[g1] = data.geom_xmat[g2].reshape(3, 3)[:, 2].copy()
    return out


def _sole_box(
    model: mujoco.MjModel, data: mujoco.MjData, gid: int, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The box on a mesh's flat sole, in the geom's frame: center ``(3,)``, half sizes
    ``(3,)`` and rotation ``(3, 3)`` (columns: the sole's long axis, its short axis, the
    floor's normal); ``None`` when the lowest part is not a flat face (see
    :data:`MIN_SPAN`)."""
    up = data.geom_xmat[gid].reshape(3, 3).T @ normal  # the floor's normal, geom frame
    mesh = int(model.geom_dataid[gid])
    start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    verts = np.asarray(model.mesh_vert[start : start + count], dtype=float)
    height = verts @ up
    sole = verts[height <= height.min() + SOLE_SLAB]
    if len(sole) < 3:
        return None
    flat = sole - np.outer(sole @ up, up)
    _, _, vt = np.linalg.svd(flat - flat.mean(axis=0), full_matrices=False)
    long_axis = vt[0] - (vt[0] @ up) * up
    if np.linalg.norm(long_axis) < 1e-9:  # the sole's vertices coincide: a point
        return None
    long_axis /= np.linalg.norm(long_axis)
    rot = np.column_stack([long_axis, np.cross(up, long_axis), up])
    local = sole @ rot
    lo, hi = local.min(axis=0), local.max(axis=0)
    rbound = float(model.geom_rbound[gid])
    if np.any(hi[:2] - lo[:2] < MIN_SPAN * rbound):
        return None
    thickness = BOX_THICKNESS * rbound
    lo[2], hi[2] = height.min(), height.min() + thickness
    return rot @ ((lo + hi) / 2.0), (hi - lo) / 2.0, rot


def _corners(center: np.ndarray, half: np.ndarray, rot: np.ndarray) -> np.ndarray:
    signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    return center + (signs * half) @ rot.T


def _grow_bvh(model: mujoco.MjModel, body: int, points: np.ndarray) -> None:
    """Grow every node of ``body``'s bounding-volume tree (in its inertial frame) to
    contain ``points`` ``(p, 3)`` given in the body's frame."""
    start, count = int(model.body_bvhadr[body]), int(model.body_bvhnum[body])
    if start < 0:
        return
    inertial = np.zeros(9)
    mujoco.mju_quat2Mat(inertial, model.body_iquat[body])
    local = (points - model.body_ipos[body]) @ inertial.reshape(3, 3)
    for node in range(start, start + count):
        center, half = model.bvh_aabb[node, :3], model.bvh_aabb[node, 3:]
        lo = np.minimum(center - half, local.min(axis=0))
        hi = np.maximum(center + half, local.max(axis=0))
        model.bvh_aabb[node] = np.concatenate([(lo + hi) / 2.0, (hi - lo) / 2.0])


def box_soles(model: mujoco.MjModel, qpos: np.ndarray, bodies: Sequence[int | str]) -> SoleBoxes:
    """Replace the flat mesh soles of ``bodies`` that rest on a plane at ``qpos`` with boxes.

    A collision mesh geom of one of ``bodies`` is replaced when, at posture ``qpos``, it
    touches a plane geom and its vertices within :data:`SOLE_SLAB` of its lowest (along the
    plane's normal) span at least :data:`MIN_SPAN` times its bounding radius in both
    directions along the plane: a flat sole, not an edge or a rounded shoe. The box's
    bottom face is the rectangle that bounds those vertices, aligned with their principal
    axes; it is :data:`BOX_THICKNESS` times the bounding radius thick. The body's
    bounding-volume tree is grown to contain the box, so MuJoCo's midphase still finds its
    contacts.

    Args:
        model: The model (not changed).
        qpos: Posture ``(nq,)`` at which the soles rest on the ground.
        bodies: Ids or names of the bodies whose geoms may be soles (the feet).

    Returns:
        The :class:`SoleBoxes`: a copy with the boxes, or ``model`` itself if no sole
        qualified.

    Raises:
        InvalidArgumentError: If ``qpos`` is not ``(nq,)`` finite values.
        UnknownNameError: If a body does not exist (lists those that do).
    """
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,))
    wanted = {object_id(model, "body", b, "bodies") for b in bodies}
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_fwdPosition(model, data)
    resting = resting_on_planes(model, data)
    collides = collision_geoms(model)
    boxes: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]] = []
    for gid, normal in sorted(resting.items()):
        if (
            model.geom_bodyid[gid] not in wanted
            or model.geom_type[gid] != _MESH
            or model.geom_dataid[gid] < 0
            or not collides[gid]
        ):
            continue
        box = _sole_box(model, data, gid, normal)
        if box is not None:
            boxes.append((gid, *box))
    if not boxes:
        return SoleBoxes(model, (), np.zeros((0, 3)))
    out = copy.copy(model)
    for gid, center, half, rot in boxes:
        frame = np.zeros(9)
        mujoco.mju_quat2Mat(frame, model.geom_quat[gid])
        frame = frame.reshape(3, 3)  # geom to body
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (frame @ rot).ravel())
        out.geom_type[gid] = int(mujoco.mjtGeom.mjGEOM_BOX)
        out.geom_dataid[gid] = -1
        out.geom_size[gid] = half
        out.geom_pos[gid] = model.geom_pos[gid] + frame @ center
        out.geom_quat[gid] = quat
        out.geom_rbound[gid] = float(np.linalg.norm(half))
        out.geom_aabb[gid] = np.concatenate([np.zeros(3), half])
        body = int(model.geom_bodyid[gid])
        _grow_bvh(out, body, model.geom_pos[gid] + _corners(center, half, rot) @ frame.T)
    return SoleBoxes(out, tuple(_name(model, b[0]) for b in boxes), np.array([b[2] for b in boxes]))
