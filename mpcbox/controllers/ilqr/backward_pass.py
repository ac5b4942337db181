r"""The backward pass of control-limited iLQR: a Riccati recursion with box-QP feed-forward.

Notation (``T`` knots, states ``x_0 .. x_T``, controls ``u_0 .. u_{T-1}``): the planning model
is linearized along the current trajectory, :math:`dx_{t+1} = A_t dx_t + B_t du_t`, and the
cost quadratized (Gauss-Newton) into :math:`\ell_x, \ell_u, \ell_{xx}, \ell_{uu}, \ell_{ux}`.
The backward pass computes, from :math:`V_x, V_{xx}` at ``t + 1``,

.. math::

    Q_x = \ell_x + A^T V_x, \quad Q_u = \ell_u + B^T V_x, \quad
    Q_{xx} = \ell_{xx} + A^T V_{xx} A, \quad
    Q_{uu} = \ell_{uu} + B^T V_{xx} B, \quad Q_{ux} = \ell_{ux} + B^T V_{xx} A,

then solves the box QP :math:`\min_{du} \tfrac12 du^T (Q_{uu} + \mu I) du + Q_u^T du` with
:math:`u_{lo} - u_t \le du \le u_{hi} - u_t` (:func:`mpcbox.controllers.ilqr.boxqp.solve_box_qp`)
for the feed-forward ``k``, and sets the feedback ``K = -(Q_{uu}+\mu I)_{ff}^{-1} Q_{ux,f}`` on
the free controls only (zero rows on clamped ones), as in control-limited DDP (Tassa et al.,
2014). The Levenberg-Marquardt term :math:`\mu` is the ``regularization``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.core.problem import Linearization, Quadratization
from mpcbox.errors import SolverError


class BackwardPass(NamedTuple):
    """Output of :func:`backward_pass`.

    Attributes:
        k: Feed-forward control changes ``(T, nu)``.
        K: Feedback gains ``(T, nu, nx)``, zero rows for controls clamped at a bound.
        expected: ``(dV1, dV2)``: a step of size ``alpha`` is predicted to change the cost by
            ``alpha * dV1 + alpha**2 * dV2``.
        free: Masks ``(T, nu)`` of controls not clamped at a bound.
    """

    k: np.ndarray
    K: np.ndarray
    expected: tuple[float, float]
    free: np.ndarray


def interpolate_linearization(
    A: np.ndarray, B: np.ndarray, knots: np.ndarray, horizon: int
) -> Linearization:
    """Fill in Jacobians between linearized knots by linear interpolation.

    Args:
        A: Jacobians ``(m, nx, nx)`` at ``knots``.
        B: Jacobians ``(m, nx, nu)`` at ``knots``.
        knots: Increasing knot indices ``(m,)`` with ``knots[0] = 0`` and
            ``knots[-1] = horizon - 1``.
        horizon: Number of knots ``T``.

    Returns:
        ``A`` ``(T, nx, nx)`` and ``B`` ``(T, nx, nu)``.
    """
    if len(knots) == horizon:
        return Linearization(A, B)
    t = np.arange(horizon)
    seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(knots) - 2)
    t0, t1 = knots[seg], knots[seg + 1]
    w = ((t - t0) / np.maximum(t1 - t0, 1))[:, None, None]
    return Linearization((1 - w) * A[seg] + w * A[seg + 1], (1 - w) * B[seg] + w * B[seg + 1])


def _scalar_box_step(
    quu_reg: np.ndarray,
    qu: np.ndarray,
    qux: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    t: int,
) -> tuple[np.ndarray, np.ndarray, bool]:
    r"""Feed-forward, gain and freedom of one control (``nu = 1``) under box limits.

    The one-dimensional box QP :math:`\min_{dk} \tfrac12 h\,dk^2 + q_u dk` over
    :math:`[lo, hi]` has the solution :math:`\mathrm{clip}(-q_u / h, lo, hi)`; the control is
    free (gain :math:`-Q_{ux} / h`) when the unconstrained minimizer is inside, clamped (gain
    0) otherwise. This is what :func:`~mpcbox.controllers.ilqr.boxqp.solve_box_qp` returns
    for ``n = 1``, computed with the same ``numpy.linalg.solve`` calls (so the same bits)
    but without its general machinery, which dominated the backward pass of single-input
    problems (about 100 us per knot).

    Args:
        quu_reg: Regularized :math:`Q_{uu}` ``(1, 1)``.
        qu: :math:`Q_u` ``(1,)``.
        qux: :math:`Q_{ux}` ``(1, nx)``.
        low: Lower bound of the control change ``(1,)``.
        high: Upper bound ``(1,)``.
        t: Knot index, for the error message.

    Returns:
        ``k`` ``(1,)``, ``K`` ``(1, nx)`` and whether the control is free.

    Raises:
        SolverError: If :math:`Q_{uu} + \mu` is not positive (or not finite).
    """
    h = quu_reg[0, 0]
    if not (np.isfinite(h) and h > 0.0):
        raise SolverError(f"Q_uu is not positive definite at knot {t}")
    k = -np.linalg.solve(quu_reg, qu)
    if low[0] <= k[0] <= high[0]:
        return k, -np.linalg.solve(quu_reg, qux), True
    return np.clip(k, low, high), np.zeros_like(qux), False


def backward_pass(
    lin: Linearization,
    quad: Quadratization,
    ctrls: np.ndarray,
    ctrl_low: np.ndarray,
    ctrl_high: np.ndarray,
    regularization: float,
    k_init: np.ndarray | None = None,
    gaps: np.ndarray | None = None,
) -> BackwardPass:
    r"""Riccati recursion with box-constrained feed-forward (see the module docstring).

    Args:
        lin: ``A`` ``(T, nx, nx)``, ``B`` ``(T, nx, nu)``.
        quad: Cost model with leading size ``T + 1`` (last row: terminal cost).
        ctrls: Nominal controls ``(T, nu)``.
        ctrl_low: Lower control bounds ``(nu,)`` (``-inf`` where unlimited).
        ctrl_high: Upper control bounds ``(nu,)``.
        regularization: :math:`\mu \ge 0` added to the diagonal of :math:`Q_{uu}`.
        k_init: Warm start of the box QPs ``(T, nu)``.
        gaps: Defects ``(T, nx)`` of a multiple-shooting trajectory, ``gaps[t] =
            f(x_t, u_t) ⊖ x_{t+1}``; the linear model is then
            :math:`dx_{t+1} = A_t dx_t + B_t du_t + f_t`, so the value gradient seen from knot
            ``t`` is :math:`V_x + V_{xx} f_t` (FDDP, Mastalli et al. 2020). ``None``: no
            defects (single shooting).

    Returns:
        A :class:`BackwardPass`.

    Raises:
        SolverError: If a regularized :math:`Q_{uu}` is not positive definite or the
            recursion produced non-finite numbers (raise the regularization and retry).
    """
    A, B = lin
    horizon, nx, nu = B.shape
    limited = bool(np.any(np.isfinite(ctrl_low)) or np.any(np.isfinite(ctrl_high)))
    k = np.zeros((horizon, nu))
    K = np.zeros((horizon, nu, nx))
    free = np.ones((horizon, nu), dtype=bool)
    vx = quad.lx[horizon].copy()
    vxx = quad.lxx[horizon].copy()
    dv1 = dv2 = 0.0
    eye = regularization * np.eye(nu)
    for t in range(horizon - 1, -1, -1):
        At, Bt = A[t], B[t]
        if gaps is not None:
            vx = vx + vxx @ gaps[t]
        vxx_b = vxx @ Bt
        qx = quad.lx[t] + At.T @ vx
        qu = quad.lu[t] + Bt.T @ vx
        qxx = quad.lxx[t] + At.T @ vxx @ At
        quu = quad.luu[t] + Bt.T @ vxx_b
        qux = quad.lux[t] + vxx_b.T @ At
        quu = 0.5 * (quu + quu.T)
        quu_reg = quu + eye
        if limited and nu == 1:
            kt, Kt, free[t] = _scalar_box_step(
                quu_reg, qu, qux, ctrl_low - ctrls[t], ctrl_high - ctrls[t], t
            )
        elif limited:
            res = solve_box_qp(
                quu_reg,
                qu,
                ctrl_low - ctrls[t],
                ctrl_high - ctrls[t],
                None if k_init is None else k_init[t],
                check=False,
            )
            if not res.ok:
                raise SolverError(f"Q_uu is not positive definite at knot {t}")
            kt = res.x
            Kt = np.zeros((nu, nx))
            if res.factor is not None:
                f = res.free
                Kt[f] = -np.linalg.solve(quu_reg[np.ix_(f, f)], qux[f])
            free[t] = res.free
        else:
            try:
                np.linalg.cholesky(quu_reg)  # positive-definiteness check
            except np.linalg.LinAlgError:
                raise SolverError(f"Q_uu is not positive definite at knot {t}") from None
            sol = -np.linalg.solve(quu_reg, np.column_stack([qu, qux]))
            kt, Kt = sol[:, 0], sol[:, 1:]
        k[t], K[t] = kt, Kt
        dv1 += float(kt @ qu)
        dv2 += 0.5 * float(kt @ quu @ kt)
        Kquu = Kt.T @ quu
        vx = qx + Kquu @ kt + Kt.T @ qu + qux.T @ kt
        vxx = qxx + Kquu @ Kt + Kt.T @ qux + qux.T @ Kt
        vxx = 0.5 * (vxx + vxx.T)
        if not (np.all(np.isfinite(vxx)) and np.all(np.isfinite(vx))):
            raise SolverError(f"non-finite value function at knot {t}")
    return BackwardPass(k, K, (dv1, dv2), free)


__all__ = ["BackwardPass", "backward_pass", "interpolate_linearization"]
