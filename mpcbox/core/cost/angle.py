"""Periodic distance of a hinge angle from a target."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian
from mpcbox.core.cost.rows import AngleRow, Row
from mpcbox.core.model import object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import checked_options, finite


class WrappedAngle(CostTerm):
    r"""Periodic distance of a hinge angle from a target: :math:`r = 2 \sin((\theta -
    \theta_{ref}) / 2)`.

    ``r**2 = 2 (1 - cos(theta - theta_ref))`` is :math:`2\pi`-periodic, zero at the target and
    its turns, and ``|dr/dtheta| = 1`` there. The hanging start of a swing-up is a critical
    point of this cost (as of every smooth periodic one), so optimizers need an initial guess
    that moves.

    Args:
        joint: Hinge joint name.
        target: Target angle (rad).
        weight: Scalar weight.
        name: Short label used in reports.
    """

    stage = "none"

    @checked_options
    def __init__(self, joint: str, target: float, *, weight: float, name: str = "") -> None:
        super().__init__(weight, name or f"angle_{joint}")
        self.joint = joint
        self.target = finite("target", target)
        self._qadr = self._vadr = 0

    def size(self, model: mujoco.MjModel) -> int:
        return 1

    def bind(self, model: mujoco.MjModel) -> None:
        jid = object_id(model, "joint", self.joint)
        if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
            kind = mujoco.mjtJoint(model.jnt_type[jid]).name.removeprefix("mjJNT_").lower()
            raise InvalidArgumentError(
                f"joint: WrappedAngle needs a hinge joint, got the {kind} joint {self.joint!r}"
            )
        self._qadr = int(model.jnt_qposadr[jid])
        self._vadr = int(model.jnt_dofadr[jid])
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        return 2.0 * np.sin(0.5 * (features.qpos[:, self._qadr : self._qadr + 1] - self.target))

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        dq = np.zeros((1, model.nv))
        dq[0, self._vadr] = np.cos(0.5 * (data.qpos[self._qadr] - self.target))
        return Jacobian(dq, np.zeros((1, model.nv)), np.zeros((1, model.nu)))

    def rows(self) -> list[Row]:
        """One wrapped-angle row."""
        return [AngleRow(self._qadr, self.target, self.weight[0])]

    def casadi_residual(self, qpos: Any, qvel: Any, ctrl: Any) -> Any:
        """``2 sin((q - q_ref) / 2)``."""
        import casadi

        return 2.0 * casadi.sin(0.5 * (qpos[self._qadr] - self.target))
