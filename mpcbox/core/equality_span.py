"""The generalized forces that a model's active equality constraints can supply."""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

__all__ = ["EqualitySpan", "equality_span"]


class EqualitySpan(NamedTuple):
    r"""Span of the active equality constraints' force directions at one posture.

    An equality constraint (joint or tendon coupling, connect, weld) with Jacobian rows
    :math:`J_{eq}` ``(m, nv)`` applies generalized forces :math:`J_{eq}^T \lambda` for any
    :math:`\lambda`. ``basis`` is an orthonormal basis of that span.

    Attributes:
        basis: Orthonormal columns ``(nv, r)`` spanning the range of :math:`J_{eq}^T`
            (``r = 0`` without active equality constraints).
    """

    basis: np.ndarray

    def project(self, value: np.ndarray) -> np.ndarray:
        r"""The part of ``value`` (``(nv,)`` or ``(nv, k)``) that the constraints cannot
        supply: :math:`(I - U U^T)\,v` with :math:`U` the basis."""
        if self.basis.shape[1] == 0:
            return value
        return value - self.basis @ (self.basis.T @ value)


def equality_span(model: mujoco.MjModel, data: mujoco.MjData, rtol: float = 1e-10) -> EqualitySpan:
    """The :class:`EqualitySpan` of ``data``'s current constraint rows.

    Args:
        model: The model.
        data: Data after :func:`mujoco.mj_forward` (or ``mj_fwdPosition``) at the posture.
        rtol: Singular values below ``rtol`` times the largest are dropped (redundant rows).

    Returns:
        The span; empty when the model has no active equality constraint.
    """
    rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    if rows.size == 0:
        return EqualitySpan(np.zeros((model.nv, 0)))
    if mujoco.mj_isSparse(model):
        jac = np.zeros((data.nefc, model.nv))
        mujoco.mju_sparse2dense(
            jac,
            data.efc_J,
            data.efc_J_rownnz[: data.nefc],
            data.efc_J_rowadr[: data.nefc],
            data.efc_J_colind,
        )
    else:
        jac = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)
    u, sv, _ = np.linalg.svd(jac[rows].T, full_matrices=False)
    keep = sv > rtol * sv[0] if sv.size and sv[0] > 0 else np.zeros(sv.size, dtype=bool)
    return EqualitySpan(u[:, keep])
