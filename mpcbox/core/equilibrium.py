"""Controls that hold a posture, from inverse dynamics."""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
from scipy.optimize import brentq

from mpcbox.errors import SolverError
from mpcbox.validation import as_array, positive


class Equilibrium(NamedTuple):
    """A posture and the control that holds it.

    Attributes:
        qpos: Posture ``(nq,)`` with the root height adjusted so the contacts carry the weight.
        ctrl: Control ``(nu,)``: least-squares solution of ``moment^T ctrl = qfrc_inverse``.
        qfrc: Generalized force ``(nv,)`` needed to hold the posture (``qfrc_inverse``).
        residual_wrench: What the actuators cannot supply on the unactuated root dofs, ``(6,)``
            for a free root (zeros for a fixed base): ``qfrc - moment^T ctrl`` there.
        height_offset: How far the root was moved vertically (m).
        vertical_residual: Remaining vertical root force after the root-find (N).
    """

    qpos: np.ndarray
    ctrl: np.ndarray
    qfrc: np.ndarray
    residual_wrench: np.ndarray
    height_offset: float
    vertical_residual: float


def _free_root(model: mujoco.MjModel) -> tuple[int, int] | None:
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and model.jnt_bodyid[j] != 0:
            return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
    return None


def actuator_moment(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Dense actuator moment matrix ``(nu, nv)`` (``qfrc_actuator = moment^T ctrl``)."""
    dense = np.zeros((model.nu, model.nv))
    mujoco.mju_sparse2dense(
        dense, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind
    )
    return dense


def find_equilibrium(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    tolerance: float = 1e-3,
    search_range: float = 0.2,
) -> Equilibrium:
    """Adjust the root height until the contacts carry the weight, then solve for the control.

    For a floating base the vertical root force from inverse dynamics,
    :math:`f_z(h)` (with :math:`\\ddot q = 0`), decreases as the body is lowered by :math:`h`
    into the soft contacts. A bracketing root-find (Brent) solves :math:`f_z(h) = 0` to
    ``tolerance`` newtons. The control then solves :math:`M_a^T u = \\tau` in the
    least-squares sense with the dense actuator moment :math:`M_a` (``mju_sparse2dense``).

    Args:
        model: The model.
        qpos: Posture ``(nq,)``.
        tolerance: Target vertical residual force (N).
        search_range: Largest height change tried in either direction (m).

    Returns:
        An :class:`Equilibrium`.

    Raises:
        SolverError: If no height within ``search_range`` brings the vertical force to zero.
    """
    qpos = as_array("qpos", qpos, (model.nq,)).copy()
    tolerance = positive("tolerance", tolerance)
    search_range = positive("search_range", search_range)
    data = mujoco.MjData(model)
    root = _free_root(model)

    def inverse(offset: float) -> np.ndarray:
        data.qpos[:] = qpos
        if root is not None:
            data.qpos[root[0] + 2] += offset
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        data.qacc[:] = 0
        mujoco.mj_inverse(model, data)
        return data.qfrc_inverse.copy()

    offset, vertical = 0.0, 0.0
    if root is not None:
        zdof = root[1] + 2

        def f(h: float) -> float:
            return float(inverse(h)[zdof])

        f0 = f(0.0)
        if abs(f0) > tolerance:
            # Walk away from 0 in growing steps until the sign changes, then bracket-solve.
            direction = -1.0 if f0 > 0 else 1.0
            lo, flo, step = 0.0, f0, 1e-4
            hi, fhi = lo, flo
            while abs(hi) < search_range:
                hi = direction * min(abs(hi) + step, search_range)
                fhi = f(hi)
                if np.sign(fhi) != np.sign(flo):
                    break
                lo, flo, step = hi, fhi, step * 2.0
            if np.sign(fhi) == np.sign(flo):
                raise SolverError(
                    f"find_equilibrium: the vertical root force stays {fhi:+.3g} N within "
                    f"±{search_range} m of the given height; is the body touching the floor?"
                )
            offset = brentq(f, min(lo, hi), max(lo, hi), xtol=1e-14, rtol=1e-15, maxiter=200)
            vertical = f(offset)
        else:
            vertical = f0
    qfrc = inverse(offset)
    moment = actuator_moment(model, data)
    ctrl = np.linalg.lstsq(moment.T, qfrc, rcond=None)[0]
    residual = qfrc - moment.T @ ctrl
    wrench = residual[root[1] : root[1] + 6].copy() if root is not None else np.zeros(6)
    qpos_eq = data.qpos.copy()
    return Equilibrium(qpos_eq, ctrl, qfrc, wrench, float(offset), float(vertical))
