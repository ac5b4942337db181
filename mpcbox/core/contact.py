r"""Contact points, their Jacobians, and linearized friction cones.

A contact point is a point fixed in a body, where the ground may push with a force
:math:`f = (f_x, f_y, f_n) \in \mathbb R^3` in the world frame (the ground normal is the world
``z`` axis). Its generalized force is :math:`J^T f` with the translational Jacobian
:math:`J` ``(3, nv)`` of the point.

The Coulomb cone :math:`\|f_t\| \le \mu f_n` (friction coefficient :math:`\mu`, the
``friction`` argument below) is replaced by a pyramid with ``F`` facets of
outward normals :math:`n_i = (\cos\theta_i, \sin\theta_i)`, :math:`\theta_i = 2\pi i / F`:

.. math:: n_i^T f_t - \mu f_n \le 0, \qquad 0 \le f_n \le f_{\max} .

With ``F = 4`` this is the usual :math:`|f_x| \le \mu f_n,\ |f_y| \le \mu f_n`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import names
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.validation import positive, positive_int

_CAPSULE = int(mujoco.mjtGeom.mjGEOM_CAPSULE)
_SPHERE = int(mujoco.mjtGeom.mjGEOM_SPHERE)
_BOX = int(mujoco.mjtGeom.mjGEOM_BOX)
_CYLINDER = int(mujoco.mjtGeom.mjGEOM_CYLINDER)
_ELLIPSOID = int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)
_MESH = int(mujoco.mjtGeom.mjGEOM_MESH)


class ContactPoints(NamedTuple):
    """Points fixed in bodies where the ground may push.

    Attributes:
        body: Body id of each point, ``(k,)``.
        local: Position of each point in its body's frame, ``(k, 3)``.
        label: Name of the object each point was derived from, ``(k,)`` (a geom, site or body).
    """

    body: np.ndarray
    local: np.ndarray
    label: tuple[str, ...]

    @property
    def count(self) -> int:
        """Number of points ``k``."""
        return len(self.body)

    def world(self, data: mujoco.MjData) -> np.ndarray:
        """World positions ``(k, 3)`` of the points (needs kinematics in ``data``)."""
        rot = data.xmat[self.body].reshape(-1, 3, 3)
        return data.xpos[self.body] + np.einsum("kij,kj->ki", rot, self.local)

    def groups(self) -> list[np.ndarray]:
        """Indices of the points grouped by body, in order of first appearance."""
        out: dict[int, list[int]] = {}
        for i, b in enumerate(self.body):
            out.setdefault(int(b), []).append(i)
        return [np.array(v, dtype=int) for v in out.values()]


#: Geom types that can stand on the ground: their lowest points become contact points.
STANDING_GEOMS = frozenset(
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_BOX,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        mujoco.mjtGeom.mjGEOM_ELLIPSOID,
        mujoco.mjtGeom.mjGEOM_MESH,
    )
)

#: Points of a flat sole (a box's or cylinder's bottom, a mesh foot) within this height of
#: its lowest point, as a fraction of the geom's bounding radius, stand on the ground.
SOLE_BAND = 0.05

#: A sole whose corners all lie within this distance (m) of their centroid is a point: its
#: corners are replaced by the centroid. A rounded foot's lowest part (Google's Barkour: a
#: mesh tip whose bottom vertices span 1 x 1.1 cm) would otherwise give four nearly equal
#: points, whose friction pyramids make QP-MPC's problem degenerate (every OSQP solve of the
#: standing Barkour hit its iteration cap) for a moment it cannot carry anyway.
POINT_SOLE = 0.01

#: Directions of the rim points sampled around each end of a cylinder.
_RIM = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)


def _sole(points: np.ndarray, band: float) -> list[np.ndarray]:
    """The corners of the lowest part of a geom: of the world ``points`` ``(p, 3)`` within
    ``band`` of the lowest, the extreme ones along the four diagonals of the principal axes
    of their horizontal spread, so a flat sole gives its four corners and a cylinder lying
    on its side the two ends of its lowest line (the geom's own axes would miss one end:
    one of them is vertical then); their centroid alone when they all lie within
    :data:`POINT_SOLE` of it."""
    low = points[points[:, 2] <= points[:, 2].min() + band]
    if len(low) > 4:
        spread = low[:, :2] - low[:, :2].mean(axis=0)
        axes = np.linalg.eigh(spread.T @ spread)[1]  # principal axes, as columns
        picked: list[int] = []
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                direction = sx * axes[:, 0] + sy * axes[:, 1]
                i = int(np.argmax(low[:, :2] @ direction))
                if i not in picked:
                    picked.append(i)
        low = low[picked]
    centre = low.mean(axis=0)
    if len(low) > 1 and np.linalg.norm(low - centre, axis=1).max() <= POINT_SOLE:
        return [centre]
    return list(low)


def geom_points(model: mujoco.MjModel, data: mujoco.MjData, gid: int) -> list[np.ndarray]:
    """World points at the bottom of a geom: capsule ends, sphere and ellipsoid bottoms, the
    corners of a box's, cylinder's or mesh's lowest part."""
    down = np.array([0.0, 0.0, -1.0])
    pos = data.geom_xpos[gid]
    rot = data.geom_xmat[gid].reshape(3, 3)
    size = model.geom_size[gid]
    gtype = model.geom_type[gid]
    band = SOLE_BAND * float(model.geom_rbound[gid])
    if gtype == _CAPSULE:
        axis = rot[:, 2] * size[1]
        return [pos + axis + size[0] * down, pos - axis + size[0] * down]
    if gtype == _SPHERE:
        return [pos + size[0] * down]
    if gtype == _ELLIPSOID:
        # Support point along -z: c - S e_z / sqrt(e_z^T S e_z), S = R diag(r^2) R^T.
        shape = (rot * size**2) @ rot.T
        return [pos - shape[:, 2] / np.sqrt(shape[2, 2])]
    if gtype == _BOX:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        world = pos + (corners * size) @ rot.T
        lowest = np.argsort(world[:, 2])[:4]
        return list(world[lowest])
    if gtype == _CYLINDER:
        rim = np.stack([np.cos(_RIM), np.sin(_RIM), np.zeros_like(_RIM)], axis=1) * size[0]
        end = np.array([0.0, 0.0, size[1]])
        local = np.vstack([rim + end, rim - end])
        return _sole(pos + local @ rot.T, band)
    if gtype == _MESH and model.geom_dataid[gid] >= 0:
        mesh = int(model.geom_dataid[gid])
        start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        local = model.mesh_vert[start : start + count]  # in the geom's frame
        return _sole(pos + local @ rot.T, band)
    raise InvalidArgumentError(
        f"contacts: geom {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, gid)!r} has a type "
        "without contact points (use a capsule, sphere, ellipsoid, box, cylinder or mesh "
        "geom, or a site)"
    )


def collision_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Whether each geom ``(ngeom,)`` takes part in collisions: a nonzero ``contype`` or
    ``conaffinity``, or a member of an explicit ``<pair>`` (Apptronik's Apollo touches the
    floor only through pairs)."""
    out = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    out[model.pair_geom1] = True
    out[model.pair_geom2] = True
    return out


def contact_points(
    model: mujoco.MjModel, contacts: Sequence[str] | str, qpos: np.ndarray | None = None
) -> ContactPoints:
    """Contact points from geom, site or body names.

    Names are looked up as a geom, then a body, then a site; a prefix ``"geom:"``,
    ``"body:"`` or ``"site:"`` restricts the lookup to one kind.

    * a **geom** gives the bottom of each end of a capsule, the bottom of a sphere or
      ellipsoid, the four lowest corners of a box, or the (up to four) corners of the lowest
      part of a cylinder or a mesh (its vertices within :data:`SOLE_BAND` of its bounding
      radius above the lowest, extreme along the diagonals of the geom's axes; their
      centroid alone when they lie within :data:`POINT_SOLE` of it), at posture ``qpos``;
    * a **site** gives its own position;
    * a **body** gives the points of each of its collision geoms (:func:`collision_geoms`)
      of those types.

    Args:
        model: The model.
        contacts: Names (or one name).
        qpos: Posture ``(nq,)`` where "bottom" is evaluated (default ``qpos0``).

    Returns:
        The :class:`ContactPoints`, in body-local coordinates.

    Raises:
        UnknownNameError: If a name is none of a geom, site or body (lists the valid names).
        InvalidArgumentError: If no name is given or a body has no usable geom.
    """
    if isinstance(contacts, str):
        contacts = [contacts]
    contacts = list(contacts)
    if not contacts:
        raise InvalidArgumentError("contacts must name at least one geom, site or body")
    data = mujoco.MjData(model)
    if qpos is not None:
        data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    bodies: list[int] = []
    points: list[np.ndarray] = []
    labels: list[str] = []

    def add(body: int, world: np.ndarray, label: str) -> None:
        rot = data.xmat[body].reshape(3, 3)
        bodies.append(body)
        points.append(rot.T @ (world - data.xpos[body]))
        labels.append(label)

    for entry in contacts:
        if not isinstance(entry, str):
            raise InvalidArgumentError(f"contacts must hold names (str), got {entry!r}")
        kind, _, name = entry.rpartition(":")
        if kind not in ("", "geom", "body", "site"):
            kind, name = "", entry
        found = {
            k: mujoco.mj_name2id(model, obj, name)
            for k, obj in (
                ("geom", mujoco.mjtObj.mjOBJ_GEOM),
                ("body", mujoco.mjtObj.mjOBJ_BODY),
                ("site", mujoco.mjtObj.mjOBJ_SITE),
            )
            if kind in ("", k)
        }
        hit = next((k for k, i in found.items() if i >= 0), None)
        if hit == "geom":
            gid = found["geom"]
            for p in geom_points(model, data, gid):
                add(int(model.geom_bodyid[gid]), p, name)
        elif hit == "body":
            bid = found["body"]
            colliding = collision_geoms(model)
            geoms = [
                g
                for g in range(model.ngeom)
                if model.geom_bodyid[g] == bid
                and colliding[g]
                and int(model.geom_type[g]) in STANDING_GEOMS
            ]
            if not geoms:
                raise InvalidArgumentError(
                    f"contacts: body {name!r} has no collision geom to stand on (a capsule, "
                    "sphere, ellipsoid, box, cylinder or mesh)"
                )
            for g in geoms:
                for p in geom_points(model, data, g):
                    add(bid, p, name)
        elif hit == "site":
            sid = found["site"]
            add(int(model.site_bodyid[sid]), data.site_xpos[sid].copy(), name)
        else:
            kinds = list(found)
            valid = [n for k in kinds for n in names(model, k)]
            raise UnknownNameError("contact " + " or ".join(kinds), name, valid)
    return ContactPoints(np.array(bodies, dtype=int), np.array(points), tuple(labels))


def contact_jacobian(
    model: mujoco.MjModel, data: mujoco.MjData, points: ContactPoints
) -> np.ndarray:
    """Stacked translational Jacobians of the points, shape ``(3 k, nv)``.

    Rows ``3 i : 3 i + 3`` map ``qvel`` to the world velocity of point ``i``. ``data`` needs
    kinematics and ``cdof`` (``mj_forward`` or ``mj_kinematics`` + ``mj_comPos``).
    """
    world = points.world(data)
    jac = np.zeros((3 * points.count, model.nv))
    for i, (body, p) in enumerate(zip(points.body, world)):
        mujoco.mj_jac(model, data, jac[3 * i : 3 * i + 3], None, p, int(body))
    return jac


def body_twist_jacobian(
    model: mujoco.MjModel, data: mujoco.MjData, body: int, point: np.ndarray
) -> np.ndarray:
    """Jacobian ``(6, nv)`` of a body's twist: velocity of ``point`` (3 rows), then angular."""
    jac = np.zeros((6, model.nv))
    mujoco.mj_jac(model, data, jac[:3], jac[3:], point, int(body))
    return jac


def friction_pyramid(friction: float, facets: int = 4) -> np.ndarray:
    r"""Rows ``G`` ``(facets, 3)`` with :math:`G f \le 0` the linearized friction cone.

    Row ``i`` is :math:`(\cos\theta_i, \sin\theta_i, -\mu)`, :math:`\theta_i = 2\pi i / F`.

    Args:
        friction: Friction coefficient :math:`\mu` (> 0).
        facets: Number of facets, ``4`` or ``8`` (any even number >= 4 works).

    Raises:
        InvalidArgumentError: If ``friction <= 0`` or ``facets`` is not an even integer >= 4.
    """
    friction = positive("friction", friction)
    facets = positive_int("facets", facets)
    if facets < 4 or facets % 2:
        raise InvalidArgumentError(f"facets must be an even integer >= 4, got {facets}")
    theta = 2.0 * np.pi * np.arange(facets) / facets
    return np.column_stack([np.cos(theta), np.sin(theta), np.full(facets, -friction)])


def cone_violation(forces: np.ndarray, friction: float, facets: int, f_max: float) -> float:
    """Largest violation of the pyramid (friction coefficient ``friction``, ``facets``) and
    ``0 <= f_n <= f_max`` over forces ``(..., 3)``."""
    forces = np.asarray(forces, dtype=np.float64).reshape(-1, 3)
    if forces.size == 0:
        return 0.0
    g = forces @ friction_pyramid(friction, facets).T
    fn = forces[:, 2]
    return float(max(np.max(g), np.max(-fn), np.max(fn - f_max), 0.0))


def project_to_pyramid(
    forces: np.ndarray, friction: float, facets: int, f_max: float
) -> np.ndarray:
    """Nearby forces ``(..., 3)`` inside the pyramid: clamp ``f_n``, then shrink ``f_t``.

    Used to remove the solver's tolerance-level violations from a plan; it moves a force by
    no more than that violation (times a factor depending on ``friction`` and ``facets``).
    """
    out = np.array(forces, dtype=np.float64, copy=True).reshape(-1, 3)
    out[:, 2] = np.clip(out[:, 2], 0.0, f_max)
    normals = friction_pyramid(friction, facets)[:, :2]
    support = np.max(out[:, :2] @ normals.T, axis=1)
    limit = friction * out[:, 2]
    scale = np.where(support > limit, limit / np.maximum(support, 1e-300), 1.0)
    out[:, :2] *= scale[:, None]
    return out.reshape(np.shape(forces))
