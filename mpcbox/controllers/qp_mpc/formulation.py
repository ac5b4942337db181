r"""The sparse QP of one tick: pattern, matrix values, vectors, bounds and warm starts.

Over the horizon ``N`` the QP (variables in :mod:`~mpcbox.controllers.qp_mpc.layout`) has

* the dynamics of the prediction model (:mod:`~mpcbox.controllers.qp_mpc.prediction`),
  :math:`\delta x_{k+1} = A\,\delta x_k + B\,\delta u_k + B_c\,(\cdot) + c`, and its stance
  rows;
* friction: :math:`G f \le 0` per point (:func:`~mpcbox.core.contact.friction_pyramid`),
  :math:`0 \le f_n \le f_{\max}`; points more than ``contact_margin`` above the ground carry
  no force (and the rigid stance drops their bodies' stance rows);
* ``ctrlrange`` and, optionally, joint limits.

The cost is the Problem's Gauss-Newton quadratization at the reference (``Q``, ``R``, cross
term, :class:`QuadraticCost`), the terminal matrix of
:func:`~mpcbox.controllers.qp_mpc.terminal.terminal_matrix` on the last state, the prediction
model's force cost and ``stance_weight`` on the slacks.

The constraint matrix keeps one sparsity pattern: :class:`QPFormulation` builds it once, with
the permutation that maps the values (listed block by block) to CSC order, and relinearizing
only rewrites ``A.data``.

Control variables are scaled by their cost (:func:`control_scale`): the QP's variable for
stage ``i`` is :math:`\tilde u_i = S^{-1} \delta u_i` with :math:`S = \mathrm{diag}(s)`, so
:math:`P`, the columns of :math:`A` and :math:`q` of the control block are multiplied by
:math:`s`. A motor's control in newton metres and a servo's set-point in radians then reach the
solver in the same units (one unit of :math:`\tilde u` costs one unit of objective); the
solution is the same. On Menagerie's Go2 (motors, ``R`` about 2e-3 per (N m)^2) under the
noise recipe with :data:`~mpcbox.controllers.qp_mpc.solvers.OSQP_DEFAULTS` at 50 Hz (2 seeds
x 5 s), 409 of 460 solves failed unscaled and 84 of 397 scaled, and with the quadrupeds'
OSQP settings (:class:`~mpcbox.tasks.legged.quadruped.QuadrupedStand`) 30 of 314; on the
Go1 (servos, ``R`` about 18 per rad^2) none failed either way, at 43 and 44 iterations
(``benchmarks/results/go2_stand_250hz.json``, ``qp_settings``; over 12 seeds of 10 s the
Go2's share of failed solves is 92 %, 10 % and 2.6 %, ``go2_stand.json``).
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
import scipy.sparse as sp

from mpcbox.controllers.qp_mpc.dynamics import Linearization
from mpcbox.controllers.qp_mpc.layout import QPLayout, block_pattern, diag_pattern
from mpcbox.controllers.qp_mpc.prediction import PredictionModel
from mpcbox.core.problem import Problem
from mpcbox.errors import SolverError


class QuadraticCost(NamedTuple):
    r"""The running cost about the reference,
    :math:`\tfrac12 \delta x^T Q \delta x + \tfrac12 \delta u^T R \delta u + \delta u^T N
    \delta x + l_x^T \delta x + l_u^T \delta u`.

    Attributes:
        Q: State weight ``(nx, nx)``.
        R: Control weight ``(nu, nu)``.
        N_ux: Cross term ``(nu, nx)``.
        lx: State gradient ``(nx,)`` (zero unless ``cost_gradient``).
        lu: Control gradient ``(nu,)`` (zero unless ``cost_gradient``).
    """

    Q: np.ndarray
    R: np.ndarray
    N_ux: np.ndarray
    lx: np.ndarray
    lu: np.ndarray


def quadratic_cost(
    problem: Problem, state_ref: np.ndarray, ctrl_ref: np.ndarray, keep_gradient: bool
) -> QuadraticCost:
    """The Problem's quadratization at the reference.

    Without ``keep_gradient`` the gradient is dropped, regulating to the reference like LQR:
    the gradient of the cost there (non-zero when the reference is not the cost's minimizer)
    would make the plan drift along the modes the terminal cost does not see.
    """
    quad = problem.quadratize(state_ref, ctrl_ref)
    lx = quad.lx if keep_gradient else np.zeros_like(quad.lx)
    lu = quad.lu if keep_gradient else np.zeros_like(quad.lu)
    return QuadraticCost(quad.lxx, quad.luu, quad.lux, lx, lu)


class JointLimits(NamedTuple):
    """Limited hinge and slide joints.

    Attributes:
        qpos: Their ``qpos`` addresses ``(nl,)``.
        dofs: Their ``qvel`` addresses ``(nl,)``.
        low: Lower limits ``(nl,)``.
        high: Upper limits ``(nl,)``.
    """

    qpos: np.ndarray
    dofs: np.ndarray
    low: np.ndarray
    high: np.ndarray


def joint_limits(model: mujoco.MjModel, enabled: bool) -> JointLimits:
    """The limited hinge and slide joints of ``model`` (none unless ``enabled``)."""
    lim_q, lim_d, lim_lo, lim_hi = [], [], [], []
    # int(): a numpy integer is never ``in`` a tuple of MuJoCo's enum values.
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    if enabled:
        for j in range(model.njnt):
            if model.jnt_limited[j] and int(model.jnt_type[j]) in kinds:
                lim_q.append(int(model.jnt_qposadr[j]))
                lim_d.append(int(model.jnt_dofadr[j]))
                lim_lo.append(model.jnt_range[j, 0])
                lim_hi.append(model.jnt_range[j, 1])
    return JointLimits(
        np.array(lim_q, int), np.array(lim_d, int), np.array(lim_lo), np.array(lim_hi)
    )


def control_scale(R: np.ndarray, enabled: bool = True) -> np.ndarray:
    r"""Scale :math:`s_j = 1 / \sqrt{R_{jj}}` of each control variable ``(nu,)``.

    Controls without a cost (:math:`R_{jj} \le 0`) and all controls when not ``enabled``
    keep :math:`s_j = 1`.

    Args:
        R: Control weight ``(nu, nu)``.
        enabled: Whether to scale at all.
    """
    d = np.diag(R).astype(float)
    scale = np.ones_like(d)
    if enabled:
        pos = d > 0
        scale[pos] = 1.0 / np.sqrt(d[pos])
    return scale


class QPFormulation:
    """Builds the QP's matrices once and its vectors every tick.

    Args:
        problem: The Problem.
        layout: Where the blocks sit.
        prediction: The prediction model (its force input and stance rows).
        cost: The running cost.
        terminal: Terminal matrix ``(nx, nx)``.
        limits: Joint-limit rows.
        pyramid: Friction pyramid rows ``(F, 3)``.
        fn_max: Largest normal force per point, in body weights.
        state_ref: Reference state.
        ctrl_ref: Reference control ``(nu,)``.
        stance_weight: Weight of the stance slacks (``None``: no slacks).
        ctrl_scale: Scale :math:`s` of the control variables ``(nu,)`` (see the module
            docstring; default ones).
        free_first_forces: Leave the first stage's forces of touching points unbounded
            (``QPMPCConfig.first_stage_forces="free"``).

    Attributes:
        A: Constraint matrix ``(m, n)`` CSC; its values follow :meth:`update_matrix`.
        P: Upper triangle of the Hessian ``(n, n)`` CSC (constant).
        ctrl_scale: :math:`s` ``(nu,)``; a solution's controls are ``ctrl_scale * z_u``.
        scale: The variables' scale ``(n,)`` (:math:`s` on the control blocks, else 1).
    """

    def __init__(
        self,
        problem: Problem,
        layout: QPLayout,
        prediction: PredictionModel,
        cost: QuadraticCost,
        terminal: np.ndarray,
        limits: JointLimits,
        pyramid: np.ndarray,
        fn_max: float,
        state_ref: np.ndarray,
        ctrl_ref: np.ndarray,
        stance_weight: float | None,
        ctrl_scale: np.ndarray | None = None,
        free_first_forces: bool = False,
    ) -> None:
        self.problem = problem
        self.layout = layout
        self.prediction = prediction
        self.cost = cost
        self.terminal = terminal
        self.limits = limits
        self.pyramid = pyramid
        self.fn_max = fn_max
        self.state_ref = state_ref
        self.ctrl_ref = ctrl_ref
        self.free_first_forces = free_first_forces
        L = layout
        self.ctrl_scale = np.ones(L.nu) if ctrl_scale is None else np.asarray(ctrl_scale, float)
        self.scale = np.ones(L.nvar)
        self.scale[L.ou : L.ou + L.horizon * L.nu] = np.tile(self.ctrl_scale, L.horizon)
        self.A, self._perm = self._constraint_pattern()
        # The scale of each stored entry of A (CSC order): that of its column.
        self._col_scale = np.repeat(self.scale, np.diff(self.A.indptr))
        self.P = self._hessian(stance_weight)

    # ------------------------------------------------------------------ matrices
    def _constraint_pattern(self) -> tuple[sp.csc_matrix, np.ndarray]:
        """``A`` with zero values, and the CSC position of each entry of the value list."""
        L = self.layout
        N, nx, nu, k, F, nl = L.horizon, L.nx, L.nu, L.points, L.facets, L.nl
        # Order of the blocks (must match _matrix_values).
        blocks = [diag_pattern(L.r_dyn + i * nx, L.x(i), nx) for i in range(N)]  # +I x_{i+1}
        blocks += [block_pattern(L.r_dyn + i * nx, L.x(i - 1), nx, nx) for i in range(1, N)]
        blocks += [block_pattern(L.r_dyn + i * nx, L.u(i), nx, nu) for i in range(N)]  # -B
        blocks += self.prediction.contact_pattern(L)
        blocks += [
            block_pattern(L.r_fr + (i * k + j) * F, L.f(i) + 3 * j, F, 3)  # pyramid
            for i in range(N)
            for j in range(k)
        ]
        blocks += [(L.r_fn + i * k + np.arange(k), L.f(i) + 3 * np.arange(k) + 2) for i in range(N)]
        blocks += [diag_pattern(L.r_u + i * nu, L.u(i), nu) for i in range(N)]
        if nl:
            blocks += [
                (L.r_lim + i * nl + np.arange(nl), L.x(i) + self.limits.dofs) for i in range(N)
            ]
        coo_r = np.concatenate([b[0] for b in blocks])
        coo_c = np.concatenate([b[1] for b in blocks])
        nnz = len(coo_r)
        tag = sp.csc_matrix(
            (np.arange(1, nnz + 1, dtype=np.float64), (coo_r, coo_c)), shape=(L.ncon, L.nvar)
        )
        tag.sort_indices()
        if tag.nnz != nnz:
            raise SolverError("internal error: duplicate entries in the QP constraint pattern")
        perm = tag.data.astype(np.int64) - 1
        A = sp.csc_matrix((np.zeros(nnz), tag.indices.copy(), tag.indptr.copy()), tag.shape)
        return A, perm

    def _hessian(self, stance_weight: float | None) -> sp.csc_matrix:
        """Upper triangle of the constant Hessian: Q, terminal, R, cross terms, forces,
        slacks."""
        L, c = self.layout, self.cost
        N, nx, nu, nf = L.horizon, L.nx, L.nu, L.nf
        hp = sp.lil_matrix((L.nvar, L.nvar))
        Qu = np.triu(c.Q)
        wf = self.prediction.force_cost
        for i in range(N):
            xs, us, fs = L.x(i), L.u(i), L.f(i)
            hp[xs : xs + nx, xs : xs + nx] = np.triu(self.terminal) if i == N - 1 else Qu
            hp[us : us + nu, us : us + nu] = np.triu(c.R)
            if i >= 1 and np.any(c.N_ux):
                hp[L.x(i - 1) : L.x(i - 1) + nx, us : us + nu] = c.N_ux.T
            hp[fs : fs + nf, fs : fs + nf] = wf * np.eye(nf)
        if L.nsl:
            hp[L.osl :, L.osl :] = stance_weight * sp.eye(L.nsl)
        D = sp.diags(self.scale)
        P = sp.csc_matrix(D @ sp.csc_matrix(hp) @ D)
        P.eliminate_zeros()
        P.sort_indices()
        return P

    def _matrix_values(self, lin: Linearization) -> np.ndarray:
        L = self.layout
        N, nx, nu, k, nl = L.horizon, L.nx, L.nu, L.points, L.nl
        parts = [
            np.ones(N * nx),
            np.tile(-lin.A.ravel(), N - 1),
            np.tile(-lin.B.ravel(), N),
            self.prediction.contact_values(lin, L),
            np.tile(self.pyramid.ravel(), N * k),
            np.ones(N * k),
            np.ones(N * nu),
            np.ones(N * nl),
        ]
        return np.concatenate(parts)

    def update_matrix(self, lin: Linearization) -> None:
        """Write the values of ``A`` for the linearization ``lin`` (pattern unchanged)."""
        self.A.data[:] = self._matrix_values(lin)[self._perm] * self._col_scale

    # ------------------------------------------------------------------ vectors
    def vectors(
        self, lin: Linearization, state: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Gradient ``q`` ``(n,)`` and bounds ``l``, ``u`` ``(m,)`` for the measured
        ``state`` about ``lin``."""
        p, L, c = self.problem, self.layout, self.cost
        N, nx, nu = L.horizon, L.nx, L.nu
        x0 = p.state_difference(state, lin.state)
        d0 = p.state_difference(lin.state, self.state_ref)
        w0 = lin.ctrl - self.ctrl_ref
        active, kin = self.prediction.dynamics.activity(state)

        q = np.zeros(L.nvar)
        gx = c.lx + c.Q @ d0 + c.N_ux.T @ w0
        for i in range(N - 1):
            q[L.x(i) : L.x(i) + nx] = gx
        q[L.x(N - 1) : L.x(N - 1) + nx] = self.terminal @ d0
        gu = c.lu + c.R @ w0 + c.N_ux @ d0
        for i in range(N):
            q[L.u(i) : L.u(i) + nu] = gu
        q[L.ou : L.ou + nu] += c.N_ux @ x0
        q_forces, st_lo, st_hi = self.prediction.contact_bounds(lin, x0, kin, active, L)
        if q_forces is not None:
            q[L.of : L.osl] = q_forces

        lo = np.full(L.ncon, -np.inf)
        hi = np.full(L.ncon, np.inf)
        dyn = np.tile(lin.c, N)
        dyn[:nx] += lin.A @ x0
        lo[L.r_dyn : L.r_dyn + N * nx] = dyn
        hi[L.r_dyn : L.r_dyn + N * nx] = dyn
        lo[L.r_st : L.r_st + N * L.ns] = st_lo
        hi[L.r_st : L.r_st + N * L.ns] = st_hi
        # Friction pyramid (upper bound 0) and normal force bounds (0 for lifted points).
        k, F = L.points, L.facets
        hi[L.r_fr : L.r_fr + N * k * F] = 0.0
        lo[L.r_fn : L.r_fn + N * k] = 0.0
        hi[L.r_fn : L.r_fn + N * k] = np.tile(np.where(active, self.fn_max, 0.0), N)
        if self.free_first_forces:  # stage 0 comes first in both row blocks
            hi[L.r_fr : L.r_fr + k * F][np.repeat(active, F)] = np.inf
            lo[L.r_fn : L.r_fn + k][active] = -np.inf
            hi[L.r_fn : L.r_fn + k][active] = np.inf
        lo[L.r_u : L.r_u + N * nu] = np.tile(p.ctrl_low - lin.ctrl, N)
        hi[L.r_u : L.r_u + N * nu] = np.tile(p.ctrl_high - lin.ctrl, N)
        if L.nl:
            ql = lin.state[self.limits.qpos]
            lo[L.r_lim :] = np.tile(self.limits.low - ql, N)
            hi[L.r_lim :] = np.tile(self.limits.high - ql, N)
        return q * self.scale, lo, hi

    # ------------------------------------------------------------------ warm start
    def shifted(self, z: np.ndarray, y: np.ndarray, shift: int) -> tuple[np.ndarray, np.ndarray]:
        """Primal ``z`` and dual ``y`` moved ``shift`` stages earlier, the last stage
        repeated."""
        L = self.layout
        return (
            shift_stages(z, L.variable_blocks, L.horizon, shift),
            shift_stages(y, L.row_blocks, L.horizon, shift),
        )


def shift_stages(
    vec: np.ndarray, blocks: list[tuple[int, int]], horizon: int, shift: int
) -> np.ndarray:
    """Move each per-stage block ``(offset, size)`` (``horizon`` stages of ``size``) of ``vec``
    ``shift`` stages earlier, repeating the last stage at the end."""
    out = vec.copy()
    if shift <= 0:
        return out
    for off, size in blocks:
        if size == 0:
            continue
        stages = out[off : off + horizon * size].reshape(horizon, size)
        stages[:-shift] = vec[off + shift * size : off + horizon * size].reshape(-1, size)
        stages[-shift:] = stages[-shift - 1]
    return out
