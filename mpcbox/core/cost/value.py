"""A quadratic form in the state deviation, typically an LQR value function."""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian
from mpcbox.core.cost.rows import QuadraticFormRow, Row
from mpcbox.core.tangent import TangentSpace
from mpcbox.errors import CostDefinitionError
from mpcbox.validation import as_array, checked_options, finite_array


class QuadraticValue(CostTerm):
    r"""A quadratic form in the tangent-space state deviation: :math:`\tfrac12\,dx^T P\,dx`.

    Typically the infinite-horizon LQR value function used as a terminal cost, so that a
    short-horizon controller knows the cost-to-go beyond its horizon. The residual is
    :math:`r = L^T dx` with :math:`L L^T = P` (from an eigendecomposition; ``P`` must be
    positive semidefinite).

    Args:
        qpos_ref: Reference positions ``(nq,)``.
        qvel_ref: Reference velocities ``(nv,)``; zeros by default.
        P: Matrix ``(2 nv, 2 nv)``, the weight of the form.
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
        P: np.ndarray,
        name: str = "value",
    ) -> None:
        super().__init__(1.0, name)
        self.P = finite_array("P", P, (None, None))
        self.qpos_ref = finite_array("qpos_ref", qpos_ref, (None,))
        self.qvel_ref = None if qvel_ref is None else finite_array("qvel_ref", qvel_ref, (None,))
        self._L = np.zeros((0, 0))
        self._tangent: TangentSpace | None = None

    def size(self, model: mujoco.MjModel) -> int:
        return 2 * model.nv

    def bind(self, model: mujoco.MjModel) -> None:
        nx = 2 * model.nv
        P = as_array(f"{self.name}.P", self.P, (nx, nx))
        if not np.all(np.isfinite(P)):
            raise CostDefinitionError(f"{self.name}.P must be finite")
        P = 0.5 * (P + P.T)
        vals, vecs = np.linalg.eigh(P)
        if vals.min() < -1e-8 * max(1.0, float(np.abs(vals).max())):
            raise CostDefinitionError(
                f"{self.name}.P must be positive semidefinite; smallest eigenvalue {vals.min():.3g}"
            )
        self._L = vecs * np.sqrt(np.clip(vals, 0.0, None))
        as_array(f"{self.name}.qpos_ref", self.qpos_ref, (model.nq,))
        if self.qvel_ref is None:
            self.qvel_ref = np.zeros(model.nv)
        as_array(f"{self.name}.qvel_ref", self.qvel_ref, (model.nv,))
        self._tangent = TangentSpace(model)
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        assert self._tangent is not None, "bind() first"
        dq = self._tangent.difference(features.qpos, self.qpos_ref)
        dx = np.concatenate([dq, features.qvel - self.qvel_ref], axis=-1)
        return dx @ self._L

    def rows(self) -> list[Row]:
        """One :class:`~mpcbox.core.cost.rows.QuadraticFormRow` with the factor ``L``."""
        assert self._tangent is not None and self.qvel_ref is not None, "bind() first"
        return [
            QuadraticFormRow(
                *self._tangent.scalar_addresses,
                *self._tangent.quaternion_addresses,
                self.qpos_ref,
                self.qvel_ref,
                self._L,
                float(np.asarray(self.weight).reshape(-1)[0]),
            )
        ]

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        nv = model.nv
        return Jacobian(self._L[:nv].T.copy(), self._L[nv:].T.copy(), np.zeros((2 * nv, model.nu)))
