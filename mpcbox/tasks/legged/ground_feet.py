"""Find a legged robot's feet: the lowest bodies of its legs in a standing posture."""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.core.contact import STANDING_GEOMS, collision_geoms, geom_points
from mpcbox.core.model import check_mjmodel, object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import finite_array, positive, positive_int

#: Bodies whose collision geoms reach within this height (m) of the robot's lowest point
#: stand on the ground.
GROUND_TOLERANCE = 0.02


def _lowest(model: mujoco.MjModel, data: mujoco.MjData) -> dict[int, float]:
    """The lowest height of each body's standing collision geoms (bodies without any are
    left out)."""
    collides = collision_geoms(model)
    out: dict[int, float] = {}
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body == 0 or not collides[g] or int(model.geom_type[g]) not in STANDING_GEOMS:
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and model.geom_dataid[g] < 0:
            continue
        z = min(float(p[2]) for p in geom_points(model, data, g))
        out[body] = min(out.get(body, np.inf), z)
    return out


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and its ancestors up to the world, in that order."""
    chain = [body]
    while chain[-1] != 0:
        chain.append(int(model.body_parentid[chain[-1]]))
    return chain


def _name(model: mujoco.MjModel, body: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body {body}"


def ground_feet(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    count: int,
    *,
    root: int | str | None = None,
    tolerance: float = GROUND_TOLERANCE,
) -> tuple[str, ...]:
    """The ``count`` feet of a robot standing at ``qpos``, as ``"body:NAME"`` entries.

    Every body whose collision geoms (of a type that can stand: capsule, sphere, ellipsoid,
    box, cylinder, mesh) reach within ``tolerance`` of the robot's lowest point touches the
    ground. These bodies are grouped by leg, a leg being the branch of the kinematic tree
    below the lowest body that holds them all (the pelvis or trunk); each leg's foot is its
    lowest body. Two feet come as (left, right): left is the one further along the
    ``root``'s y axis (MuJoCo's convention: x forward, z up).

    Args:
        model: The model.
        qpos: A standing posture ``(nq,)`` (the keyframe; the root's height does not
            matter).
        count: How many feet the robot stands on (2 for a biped, 4 for a quadruped).
        root: Name or id of the root body for left and right (default: the body of the
            first free joint, else the body holding all feet).
        tolerance: See above (m).

    Raises:
        InvalidArgumentError: If the ground bodies do not form ``count`` legs (the message
            lists the legs found with their bodies, so the feet can be named instead).
        UnknownNameError: If ``root`` does not exist (lists the bodies).
    """
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,))
    count = positive_int("count", count)
    tolerance = positive("tolerance", tolerance)
    if root is not None:
        root = object_id(model, "body", root, "root")
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    lowest = _lowest(model, data)
    if not lowest:
        raise InvalidArgumentError("feet: the model has no body with a collision geom to stand on")
    bottom = min(lowest.values())
    touching = sorted(b for b, z in lowest.items() if z <= bottom + tolerance)
    chains = {b: _ancestors(model, b) for b in touching}
    common = [b for b in chains[touching[0]] if all(b in c for c in chains.values())]
    hub = common[0]  # the lowest body holding every touching body
    legs: dict[int, list[int]] = {}
    for b, chain in chains.items():
        below = chain[: chain.index(hub)]
        legs.setdefault(below[-1] if below else hub, []).append(b)
    if len(legs) != count:
        found = "; ".join(
            f"{_name(model, leg)}: {', '.join(_name(model, b) for b in bodies)}"
            for leg, bodies in legs.items()
        )
        raise InvalidArgumentError(
            f"feet: could not tell the robot's {count} feet: the bodies within {tolerance} m "
            f"of its lowest point form {len(legs)} leg(s) ({found}); name the feet"
        )
    feet = [min(bodies, key=lambda b: (lowest[b], b)) for bodies in legs.values()]
    if count == 2:
        base = hub if root is None else root
        if root is None and model.njnt and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
            base = int(model.jnt_bodyid[0])
        axis = data.xmat[base].reshape(3, 3)[:, 1]
        feet.sort(key=lambda b: -float(data.xpos[b] @ axis))
    else:
        feet.sort()
    return tuple(f"body:{_name(model, b)}" for b in feet)
