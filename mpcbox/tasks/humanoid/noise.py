"""The published one-leg balance recipe of actuator noise, for the humanoid tasks."""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.disturbances import ActuatorNoise


def balance_noise(
    model: mujoco.MjModel,
    *,
    stance: str = "left",
    scale: float = 1.0,
    low: float = 0.01,
    high: float = 0.08,
) -> ActuatorNoise:
    """The published one-leg balance recipe's per-actuator noise.

    Actuators on the abdomen and stance-leg joints (hip, knee, ankle) whose names contain
    no ``"z"`` get the standard deviation ``low``; every other actuator gets ``high``. The
    joint names are those of the classic MuJoCo humanoid (``hip_x_left``, ``abdomen_y``...).

    Args:
        model: The model whose actuator (joint) names are read.
        stance: ``"left"`` or ``"right"``.
        scale: Noise scale (:attr:`ActuatorNoise.scale`).
        low: Standard deviation on the balance joints.
        high: Standard deviation on the others.

    Returns:
        The :class:`~mpcbox.ActuatorNoise` with ``std`` of shape ``(nu,)``.
    """
    if stance not in ("left", "right"):
        raise InvalidArgumentError(f"stance must be 'left' or 'right', got {stance!r}")
    std = np.full(model.nu, high)
    for i in range(model.nu):
        jnt = model.actuator_trnid[i, 0]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, jnt) or ""
        leg = stance in name and any(k in name for k in ("hip", "knee", "ankle"))
        if ("abdomen" in name or leg) and "z" not in name:
            std[i] = low
    return ActuatorNoise(std=std, scale=scale)
