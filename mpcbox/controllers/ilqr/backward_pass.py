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

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import get_lapack_funcs

from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.controllers.ilqr.riccati_cache import RiccatiCache, RiccatiChain
from mpcbox.core.problem import Linearization, Quadratization
from mpcbox.errors import SolverError

#: LAPACK's Cholesky factorization and solve (``dpotrf``, ``dpotrs``), called directly: the
#: knots' systems are tiny, so the per-call overhead of ``numpy.linalg`` would dominate.
_POTRF, _POTRS = get_lapack_funcs(("potrf", "potrs"), dtype=np.float64)


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


class DynamicsBlocks(NamedTuple):
    """The linearization's per-knot blocks of the recursion (:func:`dynamics_blocks`).

    Attributes:
        FA: ``blockdiag(1, [A_t B_t])`` ``(T, 1 + nx, 1 + nx + nu)``, so that
            ``[V_x | V_xx] @ FA[t] = [V_x | V_xx F_t]``.
        FT: The transpose of ``F_t = [A_t B_t]``, ``(T, nx + nu, nx)``, contiguous.
    """

    FA: np.ndarray
    FT: np.ndarray


def dynamics_blocks(lin: Linearization) -> DynamicsBlocks:
    """The blocks of ``lin`` that every backward pass over it uses.

    A solve builds them once per linearization (once per solver when the dynamics are
    linearized only at the reference) instead of once per backward pass: the retries after
    a failed line search and a receding horizon's replans reuse them.
    """
    A, B = lin
    horizon, nx, nu = B.shape
    F = np.concatenate([A, B], axis=2)
    FA = np.zeros((horizon, 1 + nx, 1 + nx + nu))
    FA[:, 0, 0] = 1.0
    FA[:, 1:, 1:] = F
    return DynamicsBlocks(FA, np.ascontiguousarray(F.transpose(0, 2, 1)))


def _cost_blocks(quad: Quadratization, horizon: int, nx: int, nu: int) -> np.ndarray:
    r"""The cost model ``[\ell_t | \ell_{zz,t}]`` ``(T, n, 1 + n)`` over :math:`z = (x, u)`,
    ``n = nx + nu``: the gradient in column 0, the Hessian
    :math:`\begin{pmatrix} \ell_{xx} & \ell_{ux}^T \\ \ell_{ux} & \ell_{uu}
    \end{pmatrix}` in the rest."""
    LQ = np.empty((horizon, nx + nu, 1 + nx + nu))
    LQ[:, :nx, 0] = quad.lx[:horizon]
    LQ[:, nx:, 0] = quad.lu[:horizon]
    LQ[:, :nx, 1 : 1 + nx] = quad.lxx[:horizon]
    LQ[:, :nx, 1 + nx :] = quad.lux[:horizon].transpose(0, 2, 1)
    LQ[:, nx:, 1 : 1 + nx] = quad.lux[:horizon]
    LQ[:, nx:, 1 + nx :] = quad.luu[:horizon]
    return LQ


def _guessed_active_set(
    gain: np.ndarray,
    quu_reg: np.ndarray,
    qu_qux: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
) -> np.ndarray | None:
    r"""The box QP's solution if the unconstrained step's violated bounds are its active set.

    Clamps every control whose unconstrained step ``gain[:, 0]`` leaves the box at the bound
    it crosses, solves for the others with those held, and accepts the result only if it
    satisfies the box QP's optimality conditions: the free controls inside their bounds, the
    gradient :math:`Q_u + (Q_{uu} + \mu I) k` pointing out of the box at every clamped one.
    Then it is the box QP's unique minimizer, found with one small solve instead of projected
    Newton iterations; this is the common case of a control held at a limit along the whole
    horizon (a gripper kept open at its range's end). On success ``gain = [k | K]`` is
    overwritten as in :func:`_clamped_gain`.

    Returns:
        The mask ``(nu,)`` of free controls, or ``None`` when the guess is not optimal
        (``gain`` is then unchanged).
    """
    step = gain[:, 0]
    at_low, at_high = step < low, step > high
    clamped = at_low | at_high
    free = ~clamped
    k = np.where(at_low, low, np.where(at_high, high, 0.0))
    if free.any():
        h_free = quu_reg[np.ix_(free, free)]
        rhs = qu_qux[free].copy()
        rhs[:, 0] += quu_reg[np.ix_(free, clamped)] @ k[clamped]
        factor, info = _POTRF(h_free, lower=1, clean=1)
        if info != 0:
            return None
        sol, info = _POTRS(factor, rhs, lower=1)
        k[free] = -sol[:, 0]
        if (k[free] < low[free]).any() or (k[free] > high[free]).any():
            return None
    grad = qu_qux[:, 0] + quu_reg @ k
    if (grad[at_low] < 0.0).any() or (grad[at_high] > 0.0).any():
        return None
    gain[:, 0] = k
    gain[clamped, 1:] = 0.0
    if free.any():
        gain[free, 1:] = -sol[:, 1:]
    return free


def _clamped_gain(
    gain: np.ndarray,
    quu_reg: np.ndarray,
    qu_qux: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    k_init: np.ndarray | None,
    t: int,
) -> np.ndarray:
    r"""Overwrite ``gain = [k | K]`` when the unconstrained step leaves the box.

    With one control the box QP's solution is the clipped step and the control is clamped
    (gain 0). With several, the active set guessed from the violated bounds is tried first
    (:func:`_guessed_active_set`); if it is not optimal,
    :func:`~mpcbox.controllers.ilqr.boxqp.solve_box_qp` (warm-started at ``k_init[t]``) gives
    ``k`` and the free set, and ``K = -(Q_{uu}+\mu I)_{ff}^{-1} Q_{ux,f}`` on the free rows,
    zero on the clamped ones.

    Returns:
        The mask ``(nu,)`` of free controls.

    Raises:
        SolverError: If the box QP meets a non-definite Hessian.
    """
    nu = gain.shape[0]
    if nu == 1:
        gain[0, 0] = min(max(gain[0, 0], low[0]), high[0])
        gain[0, 1:] = 0.0
        return np.zeros(1, dtype=bool)
    free = _guessed_active_set(gain, quu_reg, qu_qux, low, high)
    if free is not None:
        return free
    res = solve_box_qp(
        quu_reg, qu_qux[:, 0], low, high, None if k_init is None else k_init[t], check=False
    )
    if not res.ok:
        raise SolverError(f"Q_uu is not positive definite at knot {t}")
    gain[:, 0] = res.x
    gain[:, 1:] = 0.0
    if res.factor is not None:
        f = res.free
        gain[f, 1:] = -np.linalg.solve(quu_reg[np.ix_(f, f)], qu_qux[f, 1:])
    return res.free


def backward_pass(
    lin: Linearization,
    quad: Quadratization,
    ctrls: np.ndarray,
    ctrl_low: np.ndarray,
    ctrl_high: np.ndarray,
    regularization: float,
    k_init: np.ndarray | None = None,
    gaps: np.ndarray | None = None,
    blocks: DynamicsBlocks | None = None,
    cache: RiccatiCache | None = None,
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
        blocks: :func:`dynamics_blocks` of ``lin``, when the caller keeps them.
        cache: Matrices of earlier passes over the same ``blocks`` (by identity) and cost
            Hessians (:mod:`~mpcbox.controllers.ilqr.riccati_cache`): the knots it holds cost
            matrix-vector products only, and the knots computed in full extend it. The result
            is the same as without it, to rounding.

    Returns:
        A :class:`BackwardPass`.

    Raises:
        SolverError: If a regularized :math:`Q_{uu}` is not positive definite or the
            recursion produced non-finite numbers (raise the regularization and retry).
    """
    horizon, nx, nu = lin.B.shape
    limited = bool(np.any(np.isfinite(ctrl_low)) or np.any(np.isfinite(ctrl_high)))
    if blocks is None:
        blocks = dynamics_blocks(lin)
    low, high = ctrl_low - ctrls, ctrl_high - ctrls
    k = np.zeros((horizon, nu))
    K = np.zeros((horizon, nu, nx))
    free = np.ones((horizon, nu), dtype=bool)
    chain = None if cache is None else cache.chain(blocks, quad, regularization, nu)
    vx = quad.lx[horizon].copy()
    t, dv1, dv2 = horizon - 1, 0.0, 0.0
    if chain is not None:
        t, vx, dv1, dv2 = _chained_knots(chain, blocks.FT, quad, gaps, low, high, limited, k, K)
    if t >= 0:
        record = chain is not None and t == chain.lowest - 1  # ran out, not clamped
        vxx = quad.lxx[horizon] if chain is None else chain.vxx[t + 1]
        dv = _full_knots(
            t,
            vx,
            vxx,
            blocks,
            quad,
            gaps,
            low,
            high,
            limited,
            regularization,
            k_init,
            k,
            K,
            free,
            chain if record else None,
        )
        dv1, dv2 = dv1 + dv[0], dv2 + dv[1]
    elif not (np.all(np.isfinite(vx)) and math.isfinite(dv1 + dv2)):
        raise SolverError("non-finite value function at knot 0")
    return BackwardPass(k, K, (dv1, dv2), free)


def _chained_knots(
    chain: RiccatiChain,
    FT: np.ndarray,
    quad: Quadratization,
    gaps: np.ndarray | None,
    low: np.ndarray,
    high: np.ndarray,
    limited: bool,
    k: np.ndarray,
    K: np.ndarray,
) -> tuple[int, np.ndarray, float, float]:
    """The knots the chain holds, from the last down, by matrix-vector products; stops at
    the chain's end or at a knot whose step leaves the box. Returns the next knot to compute
    in full (``-1``: none), :math:`V_x` after the last one done, and ``(dV1, dV2)``."""
    nx = quad.lx.shape[1]
    t = len(k) - 1
    vx = quad.lx[t + 1].copy()
    dv1 = dv2 = 0.0
    while t >= chain.lowest:
        v = vx if gaps is None else vx + chain.vxx[t + 1] @ gaps[t]
        q = FT[t] @ v
        qu = q[nx:] + quad.lu[t]
        kt = chain.neg_inv[t] @ qu
        if limited and ((kt < low[t]).any() or (kt > high[t]).any()):
            break
        w = chain.quu[t] @ kt
        dv1 += float(kt @ qu)
        dv2 += 0.5 * float(kt @ w)
        Kt = chain.K[t]
        vx = q[:nx] + quad.lx[t] + Kt.T @ (w + qu) + chain.qux[t].T @ kt
        k[t], K[t] = kt, Kt
        t -= 1
    return t, vx, dv1, dv2


def _full_knots(
    start: int,
    vx: np.ndarray,
    vxx: np.ndarray,
    blocks: DynamicsBlocks,
    quad: Quadratization,
    gaps: np.ndarray | None,
    low: np.ndarray,
    high: np.ndarray,
    limited: bool,
    regularization: float,
    k_init: np.ndarray | None,
    k: np.ndarray,
    K: np.ndarray,
    free: np.ndarray,
    chain: RiccatiChain | None,
) -> tuple[float, float]:
    """Knots ``start`` down to 0 by the full recursion from ``[V_x | V_xx]`` at
    ``start + 1``; while no control is clamped, each knot's matrices go into ``chain``.
    Returns ``(dV1, dV2)`` of these knots."""
    _, nu, nx = K.shape
    FA, FT = blocks
    LQ = _cost_blocks(quad, start + 1, nx, nu)
    reg = regularization * np.eye(nu)
    # Work arrays reused at every knot: the value [V_x | V_xx] (nx, 1 + nx), [V_x | V_xx F_t]
    # (nx, 1 + n), the Q-function [q | Q] (n, 1 + n) and the gains [k_t | K_t] (nu, 1 + nx).
    value = np.empty((nx, 1 + nx))
    value[:, 0] = vx
    value[:, 1:] = vxx
    vq = np.empty((nx, 1 + nx + nu))
    qq = np.empty((nx + nu, 1 + nx + nu))
    gain = np.empty((nu, 1 + nx))
    dv1 = dv2 = 0.0
    for t in range(start, -1, -1):
        if gaps is not None:
            value[:, 0] += value[:, 1:] @ gaps[t]
        np.matmul(value, FA[t], out=vq)
        np.matmul(FT[t], vq, out=qq)
        qq += LQ[t]
        qu_qux = qq[nx:, : 1 + nx]  # [Q_u | Q_ux]
        quu = qq[nx:, 1 + nx :]
        quu = 0.5 * (quu + quu.T)
        quu_reg = quu + reg
        factor, info = _POTRF(quu_reg, lower=1, clean=1)
        if info != 0:
            raise SolverError(f"Q_uu is not positive definite at knot {t}")
        sol, info = _POTRS(factor, qu_qux, lower=1)
        np.negative(sol, out=gain)
        kt, Kt = gain[:, 0], gain[:, 1:]
        if limited and ((kt < low[t]).any() or (kt > high[t]).any()):
            chain = None  # the clamped set changes K here and V_xx before
            free[t] = _clamped_gain(gain, quu_reg, qu_qux, low[t], high[t], k_init, t)
        elif chain is not None:
            chain.neg_inv[t] = -_POTRS(factor, np.eye(nu), lower=1)[0]
            chain.quu[t] = quu
            chain.qux[t] = qu_qux[:, 1:]
            chain.K[t] = Kt
        k[t], K[t] = kt, Kt
        w = quu @ gain  # [Q_uu k | Q_uu K]
        dv1 += float(kt @ qu_qux[:, 0])
        dv2 += 0.5 * float(kt @ w[:, 0])
        w += qu_qux
        # [V_x | V_xx] = [q_x | Q_xx] + K^T [Q_uu k + Q_u | Q_uu K + Q_ux] + Q_ux^T [k | K]
        np.matmul(Kt.T, w, out=value)
        value += qq[:nx, : 1 + nx]
        value += qu_qux[:, 1:].T @ gain
        vxx_t = value[:, 1:]
        vxx_t[...] = 0.5 * (vxx_t + vxx_t.T)
        if not math.isfinite(float(value.sum())):
            raise SolverError(f"non-finite value function at knot {t}")
        if chain is not None:
            chain.vxx[t] = vxx_t
            chain.lowest = t
    return dv1, dv2


__all__ = [
    "BackwardPass",
    "DynamicsBlocks",
    "backward_pass",
    "dynamics_blocks",
    "interpolate_linearization",
]
