"""Control effort about a reference control."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian
from mpcbox.core.cost.rows import ControlRow, Row
from mpcbox.validation import as_array, checked_options, finite_array


class ControlCost(CostTerm):
    """Control effort about a reference control: ``r = u - u_ref``.

    Args:
        ctrl_ref: Reference control ``(nu,)``; zeros by default.
        weight: Scalar or ``(nu,)`` weights.
        name: Short label used in reports.
    """

    constant_jacobian = True
    stage = "none"

    @checked_options
    def __init__(
        self,
        ctrl_ref: np.ndarray | None = None,
        *,
        weight: float | np.ndarray,
        name: str = "control",
    ) -> None:
        super().__init__(weight, name)
        self.ctrl_ref = None if ctrl_ref is None else finite_array("ctrl_ref", ctrl_ref, (None,))

    def size(self, model: mujoco.MjModel) -> int:
        return model.nu

    def bind(self, model: mujoco.MjModel) -> None:
        if self.ctrl_ref is None:
            self.ctrl_ref = np.zeros(model.nu)
        as_array(f"{self.name}.ctrl_ref", self.ctrl_ref, (model.nu,))
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        return features.ctrl - self.ctrl_ref

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        nv, nu = model.nv, model.nu
        return Jacobian(np.zeros((nu, nv)), np.zeros((nu, nv)), np.eye(nu))

    def rows(self) -> list[Row]:
        """One control row per actuator."""
        assert self.ctrl_ref is not None, "bind() first"
        return [ControlRow(j, self.ctrl_ref[j], self.weight[j]) for j in range(self.ctrl_ref.size)]

    def casadi_residual(self, qpos: Any, qvel: Any, ctrl: Any) -> Any:
        """``u - u_ref``."""
        return ctrl - self.ctrl_ref
