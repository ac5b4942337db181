"""Feet of a legged robot, named as sites, bodies or geoms, and their sole points."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.contact import contact_points
from mpcbox.core.model import names
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnknownNameError

#: Object kinds a foot may be, in the order an unprefixed name is looked up.
FOOT_KINDS: tuple[str, ...] = ("site", "body", "geom")
_OBJ = {
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "geom": mujoco.mjtObj.mjOBJ_GEOM,
}


class Foot(NamedTuple):
    """One stance foot.

    Attributes:
        kind: ``"site"``, ``"body"`` or ``"geom"``.
        name: The object's name.
        id: The object's id.
        body: Id of the body the foot moves with.
        sole: The sole point in that body's frame ``(3,)``: the site itself, the bottom of
            the geom (mean of its lowest points), or the mean of the lowest points of the
            body's collision geoms (those within ``margin`` of the lowest).
        contact: How :func:`~mpcbox.core.contact.contact_points` names it (``"geom:FR"``).
        point: Whether the sole is one point (a site, or lowest points within 1 mm of each
            other, as under a sphere) rather than an area (a capsule's or box's bottom).
    """

    kind: str
    name: str
    id: int
    body: int
    sole: np.ndarray
    contact: str
    point: bool

    def world(self, data: mujoco.MjData) -> np.ndarray:
        """World position ``(3,)`` of the sole (needs kinematics in ``data``)."""
        if self.kind == "site":
            return data.site_xpos[self.id].copy()
        return data.xpos[self.body] + data.xmat[self.body].reshape(3, 3) @ self.sole


def _lookup(model: mujoco.MjModel, entry: str) -> tuple[str, str, int]:
    if not isinstance(entry, str):
        raise InvalidTypeError(f"feet must hold names (str), got {type(entry).__name__} {entry!r}")
    kind, _, name = entry.rpartition(":")
    if kind not in ("", *FOOT_KINDS):
        kind, name = "", entry
    kinds = FOOT_KINDS if kind == "" else (kind,)
    for k in kinds:
        idx = mujoco.mj_name2id(model, _OBJ[k], name)
        if idx >= 0:
            return k, name, idx
    valid = [f"{k}:{n}" if kind == "" else n for k in kinds for n in names(model, k)]
    raise UnknownNameError("foot " + " or ".join(kinds), name, valid, "feet")


def support_centre(points: np.ndarray) -> np.ndarray:
    """The middle of a sole's contact points ``(p, 3)``: the area centroid of their
    horizontal convex hull (the midpoint of the two extremes when they lie on a line), at
    their mean height. Unlike their mean it does not lean towards the part of the sole with
    more points (a Unitree H1's toe capsule has three contact points, its heel one)."""
    xy = points[:, :2]
    centre = xy.mean(axis=0)
    spread = xy - centre
    values, axes = np.linalg.eigh(spread.T @ spread)
    if values[1] <= 1e-12:  # one point
        middle = centre
    elif values[0] <= 1e-9 * values[1]:  # on a line: the midpoint of its two ends
        along = spread @ axes[:, 1]
        middle = centre + 0.5 * (along.max() + along.min()) * axes[:, 1]
    else:
        from scipy.spatial import ConvexHull

        hull = xy[ConvexHull(xy).vertices]  # counter-clockwise
        nxt = np.roll(hull, -1, axis=0)
        cross = hull[:, 0] * nxt[:, 1] - nxt[:, 0] * hull[:, 1]
        middle = ((hull + nxt) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())
    return np.array([middle[0], middle[1], points[:, 2].mean()])


def find_feet(
    model: mujoco.MjModel, feet: Sequence[str] | str, qpos: np.ndarray, *, margin: float = 0.01
) -> tuple[Foot, ...]:
    """Resolve foot names at posture ``qpos`` ``(nq,)``.

    A name is looked up as a site, then a body, then a geom; a prefix ``"site:"``,
    ``"body:"`` or ``"geom:"`` picks one kind (a Menagerie Go1 has a site *and* a geom
    called ``"FR"``).

    Args:
        model: The model.
        feet: Foot names (or one name).
        qpos: Posture at which "lowest" is judged.
        margin: Collision-geom points of a body foot within this height of its lowest point
            count as its sole (m).

    Raises:
        UnknownNameError: If a name is no site, body or geom (lists those that exist).
        InvalidArgumentError: If no foot is given, a foot repeats, or a geom or body has
            nothing to stand on (see :func:`~mpcbox.core.contact.contact_points`).
    """
    if isinstance(feet, str):
        feet = [feet]
    if not isinstance(feet, (list, tuple)):
        raise InvalidTypeError(
            f"feet must be a name or a sequence of names, got {type(feet).__name__} {feet!r}"
        )
    feet = list(feet)
    if not feet:
        raise InvalidArgumentError("feet must name at least one site, body or geom")
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    out: list[Foot] = []
    for entry in feet:
        kind, name, idx = _lookup(model, entry)
        if any(f.kind == kind and f.name == name for f in out):
            raise InvalidArgumentError(f"feet: {kind} {name!r} is given twice")
        point = True
        if kind == "site":
            body = int(model.site_bodyid[idx])
            world = data.site_xpos[idx]
        else:
            points = contact_points(model, f"{kind}:{name}", qpos)
            world_points = points.world(data)
            low = world_points[:, 2] <= world_points[:, 2].min() + margin
            body = int(points.body[0])
            world = support_centre(world_points[low])
            point = bool(np.max(np.linalg.norm(world_points[low] - world, axis=1)) < 1e-3)
        rot = data.xmat[body].reshape(3, 3)
        sole = rot.T @ (world - data.xpos[body])
        out.append(Foot(kind, name, idx, body, sole, f"{kind}:{name}", point))
    return tuple(out)
