"""Free objects in an arm's scene: find them, or weld them where a keyframe puts them.

A free body that the controller cannot move (a pot on a table next to an arm) adds six
uncontrollable, marginally stable modes to the linearization: an LQR about the arm's goal
then meets an ill-conditioned Riccati equation. An arm task either refuses such a scene with
a clear error or welds each free object to the world at its start pose
(:func:`weld_free_bodies`), which removes its joint from the state.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.core.model import frame_object
from mpcbox.errors import InvalidArgumentError

_FREE = mujoco.mjtJoint.mjJNT_FREE


def chain_bodies(model: mujoco.MjModel, frame: str) -> set[int]:
    """Ids of the bodies from the world down to the body that carries ``frame``.

    Args:
        model: The model.
        frame: Site or body name.
    """
    kind, idx = frame_object(model, frame)
    body = int(model.site_bodyid[idx]) if kind == "site" else int(idx)
    chain = {body}
    while body:
        body = int(model.body_parentid[body])
        chain.add(body)
    return chain


def free_objects(model: mujoco.MjModel, frame: str) -> tuple[str, ...]:
    """Names of the bodies on a free joint that do not carry ``frame`` (objects, not the arm).

    A free joint above ``frame`` (a floating or mobile base) belongs to the arm and is kept.

    Args:
        model: The model.
        frame: Site or body name of the end effector.
    """
    chain = chain_bodies(model, frame)
    out = []
    for j in range(model.njnt):
        body = int(model.jnt_bodyid[j])
        if model.jnt_type[j] == _FREE and body not in chain:
            out.append(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body {body}")
    return tuple(out)


def subtree(model: mujoco.MjModel, root: int) -> set[int]:
    """Ids of ``root`` and every body below it."""
    out = {root}
    for body in range(root + 1, model.nbody):  # children come after their parents
        if int(model.body_parentid[body]) in out:
            out.add(body)
    return out


def weld_free_bodies(
    spec: mujoco.MjSpec, model: mujoco.MjModel, frame: str, start_qpos: np.ndarray
) -> tuple[str, ...]:
    """Weld every free object (see :func:`free_objects`) to the world at its pose in ``start_qpos``.

    The free joints are deleted from ``spec`` and each object's body gets the position and
    orientation that ``start_qpos`` gives it. Joints inside an object (a pot's lid on a slide)
    are deleted too, freezing those parts at the joint's ``qpos0``. The keyframes lose the
    deleted joints' ``qpos`` and ``qvel`` entries.

    Args:
        spec: The model's spec, edited in place.
        model: ``spec`` compiled before the edit.
        frame: Site or body name of the end effector.
        start_qpos: Positions ``(nq,)`` of ``model``.

    Returns:
        The names of the welded bodies.

    Raises:
        InvalidArgumentError: If a free object is not a child of the world body.
    """
    chain = chain_bodies(model, frame)
    roots = [
        int(model.jnt_bodyid[j])
        for j in range(model.njnt)
        if model.jnt_type[j] == _FREE and model.jnt_bodyid[j] not in chain
    ]
    if not roots:
        return ()
    bodies = set().union(*(subtree(model, root) for root in roots))
    joints = [j for j in range(model.njnt) if int(model.jnt_bodyid[j]) in bodies]
    sizes = {int(mujoco.mjtJoint.mjJNT_FREE): (7, 6), int(mujoco.mjtJoint.mjJNT_BALL): (4, 3)}
    drop_q = np.concatenate(
        [
            model.jnt_qposadr[j] + np.arange(sizes.get(int(model.jnt_type[j]), (1, 1))[0])
            for j in joints
        ]
    )
    drop_v = np.concatenate(
        [
            model.jnt_dofadr[j] + np.arange(sizes.get(int(model.jnt_type[j]), (1, 1))[1])
            for j in joints
        ]
    )
    for root in roots:
        if model.body_parentid[root] != 0:
            raise InvalidArgumentError(
                f"free object {model.body(root).name!r} is not a child of the world body; "
                "weld it in the MJCF"
            )
        adr = model.jnt_qposadr[model.body_jntadr[root]]
        body = spec.bodies[root]
        body.pos = start_qpos[adr : adr + 3]
        body.quat = start_qpos[adr + 3 : adr + 7]
    for j in sorted(joints, reverse=True):
        spec.delete(spec.joints[j])
    for key in spec.keys:
        if len(key.qpos) == model.nq:
            key.qpos = np.delete(np.asarray(key.qpos), drop_q)
        if len(key.qvel) == model.nv:
            key.qvel = np.delete(np.asarray(key.qvel), drop_v)
    return tuple(model.body(root).name or f"body {root}" for root in roots)


__all__ = ["chain_bodies", "free_objects", "subtree", "weld_free_bodies"]
