"""State deviation from a reference, in tangent space."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian
from mpcbox.core.cost.rows import PositionRow, QuaternionRow, Row, VelocityRow
from mpcbox.core.tangent import TangentSpace
from mpcbox.errors import UnsupportedCostTermError
from mpcbox.validation import as_array, as_weights, checked_options, finite_array


class StateCost(CostTerm):
    r"""Deviation from a reference state in tangent space: ``r = [q \ominus q_ref, v - v_ref]``.

    Args:
        qpos_ref: Reference positions ``(nq,)``.
        qvel_ref: Reference velocities ``(nv,)``; zeros by default.
        weight_qpos: Weights on the ``nv`` position differences (scalar or ``(nv,)``).
        weight_qvel: Weights on the ``nv`` velocity differences (scalar or ``(nv,)``).
        name: Short label used in reports.
    """

    constant_jacobian = True
    stage = "none"

    @checked_options
    def __init__(
        self,
        qpos_ref: np.ndarray,
        qvel_ref: np.ndarray | None = None,
        *,
        weight_qpos: float | np.ndarray,
        weight_qvel: float | np.ndarray = 0.0,
        name: str = "state",
    ) -> None:
        super().__init__(0.0, name)
        self.qpos_ref = finite_array("qpos_ref", qpos_ref, (None,))
        self.qvel_ref = None if qvel_ref is None else finite_array("qvel_ref", qvel_ref, (None,))
        self._wq, self._wv = weight_qpos, weight_qvel
        self._tangent: TangentSpace | None = None

    def size(self, model: mujoco.MjModel) -> int:
        return 2 * model.nv

    def bind(self, model: mujoco.MjModel) -> None:
        as_array(f"{self.name}.qpos_ref", self.qpos_ref, (model.nq,))
        if self.qvel_ref is None:
            self.qvel_ref = np.zeros(model.nv)
        as_array(f"{self.name}.qvel_ref", self.qvel_ref, (model.nv,))
        wq = as_weights(f"{self.name}.weight_qpos", self._wq, model.nv)
        wv = as_weights(f"{self.name}.weight_qvel", self._wv, model.nv)
        self._weight_arg = np.concatenate([wq, wv])
        self._tangent = TangentSpace(model)
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        assert self._tangent is not None, "bind() first"
        dq = self._tangent.difference(features.qpos, self.qpos_ref)
        return np.concatenate([dq, features.qvel - self.qvel_ref], axis=-1)

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        # Exact for hinge and slide joints; for quaternions d(log)/dq is the identity at the
        # reference and close to it nearby (the Gauss-Newton approximation).
        nv = model.nv
        eye, zero = np.eye(nv), np.zeros((nv, nv))
        return Jacobian(
            np.vstack([eye, zero]), np.vstack([zero, eye]), np.zeros((2 * nv, model.nu))
        )

    def rows(self) -> list[Row]:
        """Position and quaternion rows for the ``nv`` position differences, then one velocity
        row per dof."""
        assert self._tangent is not None and self.qvel_ref is not None, "bind() first"
        nv = self._tangent.nv
        wq, wv = self.weight[:nv], self.weight[nv:]
        out: list[Row] = []
        for qa, va in zip(*self._tangent.scalar_addresses, strict=True):
            out.append(PositionRow(int(qa), self.qpos_ref[qa], wq[va]))
        for qa, va in zip(*self._tangent.quaternion_addresses, strict=True):
            out.append(QuaternionRow(int(qa), self.qpos_ref[qa : qa + 4], wq[va : va + 3]))
        for j in range(nv):
            out.append(VelocityRow(j, self.qvel_ref[j], wv[j]))
        return out

    def casadi_residual(self, qpos: Any, qvel: Any, ctrl: Any) -> Any:
        """``[q - q_ref, v - v_ref]``, for models without quaternions (``nq == nv``)."""
        assert self._tangent is not None, "bind() first"
        if self._tangent.quaternion_addresses[0].size:
            raise UnsupportedCostTermError(
                f"cost term {self.name!r} of type StateCost has no CasADi form on a model with "
                "free or ball joints; the IPOPT reference needs nq == nv"
            )
        import casadi

        return casadi.vertcat(qpos - self.qpos_ref, qvel - self.qvel_ref)
