"""The root of a legged robot: its floating body, and its centre of mass over the support."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.model import frame_position, free_body, names, object_id
from mpcbox.errors import InvalidArgumentError


def support_offsets(
    model: mujoco.MjModel, data: mujoco.MjData, root_id: int, frames: Sequence[str]
) -> np.ndarray:
    """Horizontal offsets ``(n, 2)`` of the root's subtree center of mass from each of the
    support ``frames`` (site or body names) (m), at the posture whose kinematics ``data``
    holds."""
    mujoco.mj_comPos(model, data)
    com = data.subtree_com[root_id, :2]
    return np.array([com - frame_position(model, data, name)[:2] for name in frames])


def root_body(model: mujoco.MjModel, root: str | None) -> int:
    """Id of the body named ``root``, or of the model's free-joint body when ``None``.

    Raises:
        UnknownNameError: For an unknown ``root`` (the message lists the bodies).
        InvalidArgumentError: When ``root`` is ``None`` and no body has a free joint.
    """
    if root is not None:
        return object_id(model, "body", root, "root")
    body = free_body(model)
    if body is None:
        raise InvalidArgumentError(
            "root: the model has no free joint, so it is not a floating (legged) robot and "
            "has no root body to balance; for a robot mounted on a rail or a stand, pass the "
            f"task's root=BODY (bodies: {', '.join(names(model, 'body'))})"
        )
    return body
