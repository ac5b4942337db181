"""The frame an arm task moves when the user names none.

:func:`end_effector` picks, in this order:

1. the site named ``attachment_site`` (or ``<prefix>attachment_site``), which every MuJoCo
   Menagerie arm places on its tool flange;
2. otherwise the tip of the arm: the deepest body that carries a hinge or ball joint driven
   by an actuator (any hinge or ball joint when no actuator drives one through a joint),
   followed down through jointless children while there is exactly one (a hand welded to
   the last link: the Franka Panda's ``hand``, whose fingers slide).

Two arms (ALOHA's bimanual scene) make the choice ambiguous; the error lists the candidates.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.core.joint_limits import driven_joints
from mpcbox.core.model import check_mjmodel, names
from mpcbox.errors import InvalidArgumentError

#: Menagerie's name for the site on an arm's tool flange.
ATTACHMENT_SITE = "attachment_site"

_ROTATIONAL = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_BALL))


def _body_name(model: mujoco.MjModel, body: int) -> str:
    return model.body(body).name or f"body {body}"


def _depths(model: mujoco.MjModel) -> np.ndarray:
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):  # parents come before their children
        depth[b] = depth[model.body_parentid[b]] + 1
    return depth


def _jointed_bodies(model: mujoco.MjModel) -> set[int]:
    """Bodies with a rotational joint an actuator drives (else with any rotational joint)."""
    driven = driven_joints(model)
    rotational = [j for j in range(model.njnt) if int(model.jnt_type[j]) in _ROTATIONAL]
    chosen = [j for j in rotational if j in driven] or rotational
    return {int(model.jnt_bodyid[j]) for j in chosen}


def _tip(model: mujoco.MjModel, body: int) -> int:
    """``body``, then down through its jointless children while there is exactly one."""
    while True:
        children = [c for c in range(1, model.nbody) if model.body_parentid[c] == body]
        if len(children) != 1 or model.body_jntnum[children[0]] != 0:
            return body
        body = children[0]


def end_effector(model: mujoco.MjModel) -> str:
    """The name of the site or body an arm task moves by default (see the module docstring).

    Args:
        model: The compiled arm model.

    Returns:
        A site name (``attachment_site``) or a body name.

    Raises:
        InvalidTypeError: If ``model`` is not a compiled ``mujoco.MjModel``.
        InvalidArgumentError: If the model has no rotational joint, or several arms (the
            message lists the candidates and asks for ``frame``).
    """
    model = check_mjmodel(model)
    sites = [s for s in names(model, "site") if s.endswith(ATTACHMENT_SITE)]
    if len(sites) == 1:
        return sites[0]
    if len(sites) > 1:
        raise InvalidArgumentError(
            f"frame: the model has several attachment sites {sites}; name the end effector "
            "with frame=... (--frame on the command line)"
        )
    bodies = _jointed_bodies(model)
    if not bodies:
        raise InvalidArgumentError(
            "frame: the model has no hinge or ball joint, so it has no arm tip to pick; name "
            "the end effector with frame=... (--frame on the command line)"
        )
    depth = _depths(model)
    deepest = max(depth[b] for b in bodies)
    tips = sorted(b for b in bodies if depth[b] == deepest)
    if len(tips) > 1:
        candidates = [_body_name(model, _tip(model, b)) for b in tips]
        raise InvalidArgumentError(
            f"frame: the model has several arm tips {candidates}; name the end effector "
            "with frame=... (--frame on the command line)"
        )
    tip = _tip(model, tips[0])
    if not model.body(tip).name:
        raise InvalidArgumentError(
            f"frame: the arm's tip is body {tip}, which has no name; name it in the MJCF (or "
            "add a site there) and pass frame=... (--frame on the command line)"
        )
    return _body_name(model, tip)


__all__ = ["ATTACHMENT_SITE", "end_effector"]
