r"""Linear MPC with explicit contact forces and friction-pyramid constraints (a sparse QP).

The prediction model is the planning model stepped at the QP step ``dt`` **with contacts
disabled**; the ground acts only through explicit contact forces :math:`f_k` at the contact
points. About a linearization point :math:`(\bar x, \bar u)`, with tangent deviations
:math:`\delta x` (``nx = 2 nv + na``) and :math:`\delta u = u - \bar u`:

.. math::

    \delta x_{k+1} = A\,\delta x_k + B\,\delta u_k + B_c\,f_k + c, \qquad
    B_c = \begin{bmatrix} dt\,V \\ V \\ 0 \end{bmatrix},\quad
    V = dt\,\tilde M^{-1} J_c^T ,

where ``A``, ``B`` are ``substeps`` steps (of the planning model's own timestep
``h = dt / substeps``, control and force held) of :func:`mujoco.mjd_transitionFD` on the
contact-free model composed (:math:`A = A_h^n`, :math:`B = \sum_{i<n} A_h^i B_h`, likewise
``B_c``; ``V`` below then uses ``h``),
:math:`c = \mathrm{step}(\bar x, \bar u) \ominus \bar x` is its drift (gravity),
:math:`J_c` ``(3 k, nv)`` the contact Jacobian and :math:`\tilde M = M + dt\,D` the mass
matrix with the implicitly integrated joint damping ``D`` (MuJoCo's Euler and implicitfast
integrators), so that a force enters the velocity update and, through
:math:`q_{k+1} = q_k \oplus dt\,v_{k+1}`, the position update.

Constraints over the horizon ``N``:

* stance: every stance body with three or more points keeps its twist at zero,
  :math:`J_s v_{k+1} = 0` (``J_s`` ``(6, nv)``), with a drift correction
  :math:`J_s v_1 = -\alpha\, e / dt` on the first step (``e``: pose error from the anchor
  taken when the body touched down); bodies with fewer points keep the points still;
* friction: :math:`G f \le 0` per point (:func:`~mpcbox.core.contact.friction_pyramid`),
  :math:`0 \le f_n \le f_{\max}`; points more than ``contact_margin`` above the ground
  carry no force and their bodies have no stance rows;
* ``ctrlrange`` and, optionally, joint limits.

The cost is the Problem's Gauss-Newton quadratization at the reference (``Q``, ``R``, cross
term), the Riccati matrix of the same linear model with the forces as inputs as terminal
cost (``terminal``), and :math:`\tfrac{w_f}{2}\|f/(m g) - \bar\phi\|^2` pulling the forces
toward an even share of the weight. Forces are solved in units of the weight :math:`m g`
(conditioning).

**Soft stance (``stance_model="soft"``, the default).** MuJoCo's contacts are soft, and a foot
held rigidly still mispredicts them (an LQR designed on that rigid model falls where one
designed on the soft model holds). The soft stance therefore predicts with the soft-contact
model, :math:`\delta x_{k+1} = A_s \delta x_k + B_s \delta u_k + B_c s_k + c_s`, and keeps the
forces explicit through the linearized contact-force law of the same model,
:math:`f_k = \bar f + F_x \delta x_k + F_u \delta u_k + s_k` (forward differences of the forces
:func:`mujoco.mj_contactForce` reports, each contact given to the nearest point). The slack
:math:`s_k`, weighted by ``stance_weight``, is a force the soft model does not predict; the
friction pyramid and unilateral bounds above apply to :math:`f_k`, so they constrain the forces
the simulator will produce. The stance rows and the force regularization are replaced by
these force-law rows.

The QP is solved with OSQP's own API on a persistent solver whose sparsity pattern is built
once; each tick updates the vectors (and the matrix values when relinearizing) and warm-starts
from the previous solution shifted by one step. Any ``qpsolvers`` backend can solve the same
QP instead (``solver="clarabel"``, ``"daqp"``, ...).
"""

from __future__ import annotations

import copy
import time as _time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np
import scipy.sparse as sp

from mpcbox.controllers.base import Controller
from mpcbox.controllers.lqr import dlqr, nearest_psd
from mpcbox.core.contact import (
    ContactPoints,
    body_twist_jacobian,
    cone_violation,
    contact_jacobian,
    contact_points,
    friction_pyramid,
    project_to_pyramid,
)
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, SolverError, UnknownNameError
from mpcbox.validation import as_array, one_of, positive, positive_int

_OSQP_DEFAULTS: dict[str, Any] = dict(
    eps_abs=1e-4,
    eps_rel=1e-4,
    # A solve that needs more falls back (to LQR by default) instead. With 400 the push limits
    # match those with 1000 (two-feet grids; one-leg backward 90-110 N), and a failing tick
    # takes about 90 ms instead of 215 ms. With 200 the one-leg controller falls at 100 N
    # backward (its solves there need 200-400 iterations).
    max_iter=400,
    polishing=False,
    verbose=False,
    check_termination=5,
    # A fixed rho: OSQP's adaptive rho moved it to values that needed 250-400 iterations on
    # this problem (with the warm start in place); rho = 3 takes 30-40 (benchmarks/qp_mpc.py).
    adaptive_rho=False,
    rho=3.0,
    scaling=10,
)


class QPData(NamedTuple):
    r"""One tick's QP: minimize :math:`\tfrac12 z^T P z + q^T z` s.t. :math:`l \le A z \le u`.

    Attributes:
        P: Upper triangle of the Hessian, ``(n, n)`` CSC.
        q: Gradient ``(n,)``.
        A: Constraint matrix ``(m, n)`` CSC.
        l: Lower bounds ``(m,)`` (``-inf`` where absent).
        u: Upper bounds ``(m,)`` (``inf`` where absent).
    """

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    l: np.ndarray
    u: np.ndarray


class QPPlan(NamedTuple):
    """A solved plan.

    Attributes:
        dx: Predicted state deviations from the linearization point, ``(N + 1, nx)``.
        ctrls: Planned controls ``(N, nu)``.
        forces: Planned contact forces in newtons, world frame, ``(N, k, 3)``, projected onto
            the friction pyramid (the projection moves them by at most ``violation``).
        violation: Largest friction/unilateral violation of the raw solver output, in
            newtons.
        status: Solver status string.
        iterations: Solver iterations (0 when the backend does not report them).
        solve_time: Solver wall time (s).
        objective: QP objective value.
    """

    dx: np.ndarray
    ctrls: np.ndarray
    forces: np.ndarray
    violation: float
    status: str
    iterations: int
    solve_time: float
    objective: float


class TickTiming(NamedTuple):
    """Wall times (s) of the parts of the last tick."""

    linearize: float
    update: float
    solve: float


def _available_backends() -> list[str]:
    import qpsolvers

    return list(qpsolvers.available_solvers)


class QPMPC(Controller):
    r"""Contact-force QP-MPC (see the module docstring for the formulation).

    Args:
        problem: The Problem; its planning model is copied with timestep ``dt`` and contacts
            disabled for the prediction.
        horizon: Number of QP steps ``N``.
        dt: QP step (s).
        contacts: Geom, site or body names of the contact points (see
            :func:`~mpcbox.core.contact.contact_points`; prefix ``"geom:"``, ``"body:"`` or
            ``"site:"`` to pick one kind). Default: the Problem's ``contacts`` attribute if
            it has one, else the bodies touching the ground at its reference state.
        mu: Friction coefficient of the pyramid.
        facets: Facets of the friction pyramid (4 or 8).
        f_max: Largest normal force per point (N); default twice the weight.
        relinearize: Relinearize about the measured state and the last control every tick
            (otherwise once, about the reference).
        solver: ``"osqp"`` (persistent OSQP solver) or a ``qpsolvers`` backend name.
        force_weight: Weight :math:`w_f` of the force regularization (forces in weights).
        substeps: Planning-model steps per QP step (default ``round(dt / h)``).
        terminal: ``"stance"`` (Riccati matrix of the prediction model with the forces as
            inputs and the stance constraint as a penalty), ``"lqr"`` (Riccati matrix of the
            soft-contact model at ``dt``, composed of substeps; the default), ``"cost"``
            (the running ``Q``), or ``(nx, nx)``.
        terminal_scale: Multiplier on the terminal matrix.
        drift_gain: Fraction :math:`\alpha` of the stance pose error removed in one step.
        stance_weight: Weight of slack variables that soften the stance rows (keeps the QP
            feasible when the feet cannot be held); ``None`` for hard stance rows.
        contact_margin: A point higher than this above the lowest reference point is lifted (m).
        joint_limits: Add the joints' ranges as constraints.
        cost_gradient: Keep the cost gradient at the reference (default: regulate to the
            reference, dropping it, as LQR does).
        warm_start: Warm-start OSQP from the shifted previous solution (else cold start).
        period: Seconds between calls (default ``dt``).
        fd_centered: Centered finite differences for the linearization.
        stance_model: ``"soft"`` (default): predict with the soft-contact model and tie the
            explicit forces to its linearized contact-force law, :math:`f_k = \bar f + F_x
            \delta x_k + F_u \delta u_k + s_k`, where the slack :math:`s_k` (weight
            ``stance_weight``) is a force the soft model does not predict and enters the
            dynamics through :math:`B_c`; the friction pyramid then constrains the forces the
            simulator will actually produce. ``"rigid"``: contact-free prediction with the
            stance feet held still (the forces are free inputs).
        osqp_settings: OSQP settings overriding the defaults.
        export_dir: When set, every tick's QP is written there as ``tick_00000.npz`` ...
        fallback: What a failed solve (its status counted in :attr:`stats`) does:
            ``"lqr"`` (default) applies the LQR about the reference; ``"plan"`` replays the
            last accepted plan open loop while it lasts, then LQR. On two feet after a
            forward push, ``"plan"`` fell at 97.5 N and 100 N yet survived 105 N, because
            the open-loop replay runs just when the state leaves the plan. ``"lqr"``
            survived every push up to 100 N (``README.md``).

    Attributes:
        points: The :class:`~mpcbox.core.contact.ContactPoints`.
        last_plan: The last accepted :class:`QPPlan` (``None`` before the first solve).
        last_status: Status of the last solve.
        timing: :class:`TickTiming` of the last tick.
    """

    name = "qp"

    def __init__(
        self,
        problem: Problem,
        *,
        horizon: int = 10,
        dt: float = 0.02,
        contacts: Sequence[str] | str | None = None,
        mu: float = 0.7,
        facets: int = 4,
        f_max: float | None = None,
        relinearize: bool = False,
        solver: str = "osqp",
        force_weight: float = 1.0,
        terminal: str | np.ndarray = "lqr",
        terminal_scale: float = 1.0,
        drift_gain: float = 0.2,
        stance_weight: float | None = 1e4,
        contact_margin: float = 0.01,
        joint_limits: bool = False,
        cost_gradient: bool = False,
        warm_start: bool = True,
        period: float | None = None,
        fd_centered: bool = False,
        substeps: int | None = None,
        stance_model: str = "soft",
        osqp_settings: dict[str, Any] | None = None,
        export_dir: str | Path | None = None,
        fallback: str = "lqr",
    ) -> None:
        if not isinstance(problem, Problem):
            raise InvalidArgumentError(
                f"problem must be an mpcbox.Problem, got {type(problem).__name__}"
            )
        self.problem = problem
        self.horizon = positive_int("horizon", horizon)
        self.dt = positive("dt", dt)
        self.mu = positive("mu", mu)
        self.pyramid = friction_pyramid(self.mu, facets)
        self.facets = int(facets)
        self.relinearize = bool(relinearize)
        backends = ["osqp", *(b for b in _available_backends() if b != "osqp")]
        if solver not in backends:
            raise UnknownNameError("solver", solver, backends)
        self.solver = solver
        self.force_weight = positive("force_weight", force_weight)
        self.terminal_scale = positive("terminal_scale", terminal_scale)
        self.stance_weight = (
            None if stance_weight is None else positive("stance_weight", stance_weight)
        )
        self.drift_gain = float(drift_gain)
        if not 0.0 <= self.drift_gain <= 1.0:
            raise InvalidArgumentError(f"drift_gain must be in [0, 1], got {drift_gain!r}")
        self.contact_margin = positive("contact_margin", contact_margin)
        self.joint_limits = bool(joint_limits)
        self.warm_start = bool(warm_start)
        self.period = self.dt if period is None else positive("period", period)
        self.fd_centered = bool(fd_centered)
        if stance_model not in ("soft", "rigid"):
            raise InvalidArgumentError(
                f"stance_model must be 'soft' or 'rigid', got {stance_model!r}"
            )
        self.stance_model = stance_model
        if stance_model == "soft" and self.stance_weight is None:
            raise InvalidArgumentError("stance_model='soft' needs a finite stance_weight")
        self.osqp_settings = {**_OSQP_DEFAULTS, **(osqp_settings or {})}
        self.export_dir = None if export_dir is None else Path(export_dir)
        self.fallback = one_of("fallback", fallback, ("lqr", "plan"))

        # Prediction model: the planning model at the QP step, contacts off.
        # The QP step is composed of ``substeps`` steps of the planning model's own timestep
        # (a single semi-implicit step of 0.02 s mispredicts the 0.005 s simulation badly).
        base_dt = float(problem.planning_model.opt.timestep)
        self.substeps = max(1, round(self.dt / base_dt)) if substeps is None else int(substeps)
        if self.substeps < 1:
            raise InvalidArgumentError(f"substeps must be a positive integer, got {substeps!r}")
        self.model = copy.copy(problem.planning_model)
        self.model.opt.timestep = self.dt / self.substeps
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.data = mujoco.MjData(self.model)
        self._kin = mujoco.MjData(self.model)
        # The soft-contact model (contacts on) at the same substep, for stance_model="soft".
        self.soft_model = copy.copy(problem.planning_model)
        self.soft_model.opt.timestep = self.dt / self.substeps
        self._soft = mujoco.MjData(self.soft_model)

        self.state_ref = problem.reference_state()
        self.ctrl_ref = problem.ctrl_ref.copy()
        if contacts is None:
            contacts = problem.contacts or self._default_contacts()
        self.points: ContactPoints = contact_points(
            self.model, _resolve_kinds(contacts), self.state_ref[: problem.nq]
        )
        self.weight = float(np.sum(self.model.body_mass) * np.linalg.norm(self.model.opt.gravity))
        if self.weight <= 0:
            raise InvalidArgumentError("the model must have mass and gravity for contact forces")
        self.f_max = 2.0 * self.weight if f_max is None else positive("f_max", f_max)
        self._kin.qpos[:] = self.state_ref[: problem.nq]
        mujoco.mj_kinematics(self.model, self._kin)
        self.ground = float(np.min(self.points.world(self._kin)[:, 2]))

        # Cost about the reference.
        quad = problem.quadratize(self.state_ref, self.ctrl_ref)
        self.Q, self.R, self.N_ux = quad.lxx, quad.luu, quad.lux
        # Regulate to the reference like LQR: the gradient of the cost there (non-zero when the
        # reference is not the cost's minimizer) would make the plan drift along the modes the
        # terminal cost does not see.
        self.lx = quad.lx if cost_gradient else np.zeros_like(quad.lx)
        self.lu = quad.lu if cost_gradient else np.zeros_like(quad.lu)
        self._groups = self._stance_rows()
        self.ns = (
            3 * self.points.count
            if self.stance_model == "soft"
            else sum(g[2] for g in self._groups)
        )
        self._linearize(self.state_ref, self.ctrl_ref)
        self.P_terminal = nearest_psd(self._terminal(terminal)) * self.terminal_scale

        self._build_pattern()
        self._A.data[:] = self._matrix_values()[self._A_perm]
        self._lqr = None
        if self.fallback == "lqr":  # built now, not on the first failed (already slow) tick
            self._fallback_lqr()
        self.reset()

    # ------------------------------------------------------------------ setup
    def _default_contacts(self) -> list[str]:
        """Bodies touching the ground at the reference state, as ``body:`` names."""
        m = self.problem.planning_model
        d = mujoco.MjData(m)
        self.problem.set_state(d, self.state_ref)
        mujoco.mj_forward(m, d)
        bodies: list[int] = []
        for c in d.contact[: d.ncon]:
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            for b in (b1, b2):
                if b != 0 and b not in bodies and 0 in (b1, b2):
                    bodies.append(b)
        if not bodies:
            raise InvalidArgumentError(
                "contacts: nothing touches the ground at the reference state; name the "
                "contact geoms, sites or bodies"
            )
        return ["body:" + mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in bodies]

    def _terminal(self, terminal: str | np.ndarray) -> np.ndarray:
        nx = self.problem.nx
        if isinstance(terminal, str):
            if terminal == "cost":
                return self.Q.copy()
            if terminal == "stance":
                return self._stance_riccati()
            if terminal != "lqr":
                raise InvalidArgumentError(
                    "terminal must be 'stance', 'lqr', 'cost' or an (nx, nx) matrix, "
                    f"got {terminal!r}"
                )
            soft = copy.copy(self.problem.planning_model)
            soft.opt.timestep = self.dt / self.substeps
            data = mujoco.MjData(soft)
            self.problem.set_state(data, self.state_ref)
            data.ctrl[:] = self.ctrl_ref
            Ah = np.zeros((nx, nx))
            Bh = np.zeros((nx, self.problem.nu))
            mujoco.mjd_transitionFD(soft, data, self.problem.fd_eps, True, Ah, Bh, None, None)
            A, S = _compose(Ah, self.substeps)
            B = S @ Bh
            N = self.N_ux.T if np.any(self.N_ux) else None
            try:
                _, P = dlqr(A, B, self.Q, self.R, N)
            except (SolverError, InvalidArgumentError):
                return self.Q.copy()
            return 0.5 * (P + P.T)
        P = as_array("terminal", terminal, (nx, nx))
        return 0.5 * (P + P.T)

    def _stance_riccati(self) -> np.ndarray:
        r"""Riccati matrix of the prediction model with the forces as extra inputs.

        The stance constraint becomes the penalty :math:`w_s \|J_s v\|^2` on the state,
        the forces get the weight :math:`w_f`; without friction limits this is the
        infinite-horizon cost of the linear model the QP uses.
        """
        p, lin = self.problem, self._lin
        nv = p.nv
        Sv = np.zeros((lin["Js"].shape[0], p.nx))
        Sv[:, nv : 2 * nv] = lin["Js"]
        ws = 1e4 if self.stance_weight is None else self.stance_weight
        Q = self.Q + ws * Sv.T @ Sv
        Bc = np.zeros((p.nx, lin["Bc"].shape[1]))
        Bc[: 2 * nv] = lin["Bc"]
        B = np.hstack([lin["B"], Bc])
        nf = 3 * self.points.count
        R = np.zeros((p.nu + nf, p.nu + nf))
        R[: p.nu, : p.nu] = self.R
        R[p.nu :, p.nu :] = self.force_weight * np.eye(nf)
        N = np.zeros((p.nx, p.nu + nf))
        N[:, : p.nu] = self.N_ux.T
        try:
            _, P = dlqr(lin["A"], B, Q, R, N)
        except (SolverError, InvalidArgumentError):
            return self.Q.copy()
        return 0.5 * (P + P.T)

    def _stance_rows(self) -> list[tuple[int, np.ndarray, int]]:
        """Per stance group: (body, point indices, number of rows)."""
        out = []
        for idx in self.points.groups():
            rows = 6 if len(idx) >= 3 else 3 * len(idx)
            out.append((int(self.points.body[idx[0]]), idx, rows))
        return out

    def _build_pattern(self) -> None:
        p = self.problem
        N, nx, nu, nv = self.horizon, p.nx, p.nu, p.nv
        k = self.points.count
        nf = 3 * k
        self.nf = nf
        ns = self.ns
        nsl = N * ns if self.stance_weight is not None else 0
        F = self.facets
        # Joint-limit rows.
        lim_q, lim_d, lim_lo, lim_hi = [], [], [], []
        if self.joint_limits:
            m = self.model
            for j in range(m.njnt):
                if m.jnt_limited[j] and m.jnt_type[j] in (
                    mujoco.mjtJoint.mjJNT_HINGE,
                    mujoco.mjtJoint.mjJNT_SLIDE,
                ):
                    lim_q.append(int(m.jnt_qposadr[j]))
                    lim_d.append(int(m.jnt_dofadr[j]))
                    lim_lo.append(m.jnt_range[j, 0])
                    lim_hi.append(m.jnt_range[j, 1])
        self._lim = (np.array(lim_q, int), np.array(lim_d, int), np.array(lim_lo), np.array(lim_hi))
        nl = len(lim_q)

        self.nvar = n = N * (nx + nu + nf) + nsl
        ox, ou, of = 0, N * nx, N * (nx + nu)
        osl = N * (nx + nu + nf)
        self._osl = osl
        self._ox, self._ou, self._of = ox, ou, of

        def xs(i: int) -> int:  # column of x_{i+1}
            return ox + i * nx

        def us(i: int) -> int:
            return ou + i * nu

        def fs(i: int) -> int:
            return of + i * nf

        # Row blocks.
        r_dyn = 0
        r_st = r_dyn + N * nx
        r_fr = r_st + N * ns
        r_fn = r_fr + N * k * F
        r_u = r_fn + N * k
        r_lim = r_u + N * nu
        self.ncon = m_rows = r_lim + N * nl
        self._rows = dict(dyn=r_dyn, st=r_st, fr=r_fr, fn=r_fn, u=r_u, lim=r_lim)
        self._zblocks = [(ox, nx), (ou, nu), (of, nf), (osl, ns if nsl else 0)]
        self._yblocks = [
            (r_dyn, nx),
            (r_st, ns),
            (r_fr, k * F),
            (r_fn, k),
            (r_u, nu),
            (r_lim, nl),
        ]

        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []

        def block(r0: int, c0: int, nr: int, nc: int) -> None:
            rr, cc = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
            rows.append((r0 + rr).ravel())
            cols.append((c0 + cc).ravel())

        def diag(r0: int, c0: int, size: int) -> None:
            rows.append(r0 + np.arange(size))
            cols.append(c0 + np.arange(size))

        # Order of value segments (must match _matrix_values).
        for i in range(N):
            diag(r_dyn + i * nx, xs(i), nx)  # +I on x_{i+1}
        for i in range(1, N):
            block(r_dyn + i * nx, xs(i - 1), nx, nx)  # -A on x_i
        for i in range(N):
            block(r_dyn + i * nx, us(i), nx, nu)  # -B
        soft = self.stance_model == "soft"
        for i in range(N):
            # -Bc (q and v rows) on the forces, or on the unpredicted force for a soft stance.
            block(r_dyn + i * nx, osl + i * ns if soft else fs(i), 2 * nv, nf)
        for i in range(N):
            if soft:  # f_i - F_x x_i - F_u u_i - s_i = fbar
                diag(r_st + i * ns, fs(i), nf)
                if i >= 1:
                    block(r_st + i * ns, xs(i - 1), nf, nx)
                block(r_st + i * ns, us(i), nf, nu)
                diag(r_st + i * ns, osl + i * ns, ns)
                continue
            block(r_st + i * ns, xs(i) + nv, ns, nv)  # J_s on v_{i+1}
            if nsl:
                diag(r_st + i * ns, osl + i * ns, ns)  # -slack
        for i in range(N):
            for j in range(k):
                block(r_fr + (i * k + j) * F, fs(i) + 3 * j, F, 3)  # pyramid
        for i in range(N):
            rows.append(r_fn + i * k + np.arange(k))
            cols.append(fs(i) + 3 * np.arange(k) + 2)
        for i in range(N):
            diag(r_u + i * nu, us(i), nu)
        for i in range(N):
            if nl:
                rows.append(r_lim + i * nl + np.arange(nl))
                cols.append(xs(i) + self._lim[1])
        coo_r = np.concatenate(rows)
        coo_c = np.concatenate(cols)
        nnz = len(coo_r)
        tag = sp.csc_matrix(
            (np.arange(1, nnz + 1, dtype=np.float64), (coo_r, coo_c)), shape=(m_rows, n)
        )
        tag.sort_indices()
        if tag.nnz != nnz:
            raise SolverError("internal error: duplicate entries in the QP constraint pattern")
        self._A_perm = tag.data.astype(np.int64) - 1
        self._A = sp.csc_matrix((np.zeros(nnz), tag.indices.copy(), tag.indptr.copy()), tag.shape)

        # Hessian (upper triangle), constant: Q, P_N, R, cross terms, force weight.
        hp = sp.lil_matrix((n, n))
        Qu = np.triu(self.Q)
        for i in range(N):
            hp[xs(i) : xs(i) + nx, xs(i) : xs(i) + nx] = (
                np.triu(self.P_terminal) if i == N - 1 else Qu
            )
            hp[us(i) : us(i) + nu, us(i) : us(i) + nu] = np.triu(self.R)
            if i >= 1 and np.any(self.N_ux):
                hp[xs(i - 1) : xs(i - 1) + nx, us(i) : us(i) + nu] = self.N_ux.T
            wf = 1e-6 if soft else self.force_weight  # soft: the force law fixes the forces
            hp[fs(i) : fs(i) + nf, fs(i) : fs(i) + nf] = wf * np.eye(nf)
        if nsl:
            hp[osl:, osl:] = self.stance_weight * sp.eye(nsl)
        self._P = sp.csc_matrix(hp)
        self._P.eliminate_zeros()
        self._P.sort_indices()
        self._solver = None

    # ------------------------------------------------------------------ linearization
    def _linearize(self, state: np.ndarray, ctrl: np.ndarray) -> None:
        p, m = self.problem, self.model
        nx, nv = p.nx, p.nv
        Ah, Bh, A, S, drift = self._composed_step(m, self.data, state, ctrl)
        B = S @ Bh
        # Kinematics, mass matrix and Jacobians at the linearization point.
        kin = self._kin
        p.set_state(kin, state)
        mujoco.mj_fwdPosition(m, kin)
        M = np.zeros((nv, nv))
        mujoco.mj_fullM(m, kin, M)
        if m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
            M += m.opt.timestep * np.diag(m.dof_damping)
        Jc = contact_jacobian(m, kin, self.points)
        h = m.opt.timestep
        V = h * np.linalg.solve(M, Jc.T) * self.weight  # per weight unit, one substep
        Bc_h = np.vstack([h * V, V, np.zeros((nx - 2 * nv, V.shape[1]))])
        Bc = (S @ Bc_h)[: 2 * nv]
        world = self.points.world(kin)
        Js = np.vstack(
            [
                body_twist_jacobian(m, kin, body, world[idx[0]])
                if rows == 6
                else contact_jacobian(
                    m,
                    kin,
                    ContactPoints(self.points.body[idx], self.points.local[idx], ()),
                )
                for body, idx, rows in self._groups
            ]
        )
        self._lin = dict(
            state=state.copy(), ctrl=ctrl.copy(), A=A, B=B, c=drift, Bc=Bc, Js=Js, Bh=Bh, Ah=Ah
        )
        if self.stance_model == "soft":
            self._lin.update(self._soft_linearization(state, ctrl))
        if hasattr(self, "_A_perm"):
            self._A.data[:] = self._matrix_values()[self._A_perm]

    def _composed_step(
        self, m: mujoco.MjModel, d: mujoco.MjData, state: np.ndarray, ctrl: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One QP step of ``m`` (``substeps`` steps, control held) about ``(state, ctrl)``.

        Returns:
            ``A_h``, ``B_h`` of one substep (``mjd_transitionFD``), the composed ``A`` and
            the input sum ``S`` (:func:`_compose`), and the drift ``step(x, u) ⊖ x``.
        """
        p = self.problem
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        Ah = np.zeros((p.nx, p.nx))
        Bh = np.zeros((p.nx, p.nu))
        mujoco.mjd_transitionFD(m, d, p.fd_eps, self.fd_centered, Ah, Bh, None, None)
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        mujoco.mj_step(m, d, self.substeps)
        drift = p.state_difference(p.get_state(d), state)
        A, S = _compose(Ah, self.substeps)
        return Ah, Bh, A, S, drift

    def _soft_linearization(self, state: np.ndarray, ctrl: np.ndarray) -> dict[str, np.ndarray]:
        r"""Soft-contact prediction (``A``, ``B``, drift ``c``) and its contact-force law.

        The force law :math:`f \approx \bar f + F_x \delta x + F_u \delta u` (per point,
        world frame, in weights) is differentiated forward in the tangent space.
        """
        p = self.problem
        nx, nu = p.nx, p.nu
        _, Bh, A, S, drift = self._composed_step(self.soft_model, self._soft, state, ctrl)
        fbar = self._point_forces(state, ctrl)
        eps = 1e-6
        Fx = np.zeros((fbar.size, nx))
        Fu = np.zeros((fbar.size, nu))
        for i in range(nx):
            dx = np.zeros(nx)
            dx[i] = eps
            Fx[:, i] = (self._point_forces(p.state_add(state, dx), ctrl) - fbar) / eps
        for i in range(nu):
            du = np.zeros(nu)
            du[i] = eps
            Fu[:, i] = (self._point_forces(state, ctrl + du) - fbar) / eps
        return dict(A=A, B=S @ Bh, c=drift, fbar=fbar, Fx=Fx, Fu=Fu)

    def _point_forces(self, state: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        """Ground forces on the contact points in the soft-contact model, ``(3 k,)`` in weights.

        Each MuJoCo contact on a contact body is given to the nearest point of that body.
        """
        p, m, d = self.problem, self.soft_model, self._soft
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        mujoco.mj_forward(m, d)
        world = self.points.world(d)
        out = np.zeros((self.points.count, 3))
        f6 = np.zeros(6)
        for c in range(d.ncon):
            con = d.contact[c]
            b1, b2 = m.geom_bodyid[con.geom1], m.geom_bodyid[con.geom2]
            for body, sign in ((b2, 1.0), (b1, -1.0)):
                idx = np.flatnonzero(self.points.body == body)
                if idx.size == 0:
                    continue
                mujoco.mj_contactForce(m, d, c, f6)
                force = sign * (con.frame.reshape(3, 3).T @ f6[:3])
                near = idx[np.argmin(np.linalg.norm(world[idx] - con.pos, axis=1))]
                out[near] += force
                break
        return out.ravel() / self.weight

    def _matrix_values(self) -> np.ndarray:
        lin = self._lin
        N, nx, nu = self.horizon, self.problem.nx, self.problem.nu
        k = self.points.count
        nl = len(self._lim[0])
        parts = [
            np.ones(N * nx),
            np.tile(-lin["A"].ravel(), N - 1),
            np.tile(-lin["B"].ravel(), N),
            np.tile(-lin["Bc"].ravel(), N),
            self._stance_values(),
            np.tile(self.pyramid.ravel(), N * k),
            np.ones(N * k),
            np.ones(N * nu),
            np.ones(N * nl),
        ]
        return np.concatenate(parts)

    def _stance_values(self) -> np.ndarray:
        lin, N, ns = self._lin, self.horizon, self.ns
        if self.stance_model == "soft":
            first = [np.ones(ns), -lin["Fu"].ravel(), -np.ones(ns)]
            later = [np.ones(ns), -lin["Fx"].ravel(), -lin["Fu"].ravel(), -np.ones(ns)]
            return np.concatenate(first + later * (N - 1))
        row = (
            np.concatenate([lin["Js"].ravel(), -np.ones(ns)])
            if self.stance_weight is not None
            else lin["Js"].ravel()
        )
        return np.tile(row, N)

    # ------------------------------------------------------------------ per tick
    def reset(self) -> None:
        """Forget the warm start, the last plan, stance anchors and counters."""
        self._prev_z: np.ndarray | None = None
        self._prev_y: np.ndarray | None = None
        self.last_plan: QPPlan | None = None
        self._plan_age = 0
        self._anchors: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._tick = 0
        self._fallbacks = 0
        self._failures: dict[str, int] = {}
        self._iters: list[int] = []
        self.last_status = "unsolved"
        self.timing = TickTiming(0.0, 0.0, 0.0)
        self.qp: QPData | None = None

    @property
    def stats(self) -> dict[str, float]:
        """``fallbacks``, ``solves``, mean OSQP ``iterations`` and failed statuses."""
        out: dict[str, float] = {
            "fallbacks": self._fallbacks,
            "solves": self._tick,
            "iterations": float(np.mean(self._iters)) if self._iters else 0.0,
        }
        for status, count in self._failures.items():
            out[f"failed:{status}"] = count
        return out

    def _activity(self, state: np.ndarray) -> tuple[np.ndarray, mujoco.MjData]:
        kin = mujoco.MjData(self.model) if not hasattr(self, "_act_data") else self._act_data
        self._act_data = kin
        self.problem.set_state(kin, state)
        mujoco.mj_kinematics(self.model, kin)
        z = self.points.world(kin)[:, 2]
        return z < self.ground + self.contact_margin, kin

    def _vectors(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, lin = self.problem, self._lin
        N, nx, nu, nv = self.horizon, p.nx, p.nu, p.nv
        k, ns = self.points.count, self.ns
        x0 = p.state_difference(state, lin["state"])
        d0 = p.state_difference(lin["state"], self.state_ref)
        w0 = lin["ctrl"] - self.ctrl_ref
        active, kin = self._activity(state)
        n_active = max(1, int(active.sum()))

        # Gradient.
        q = np.zeros(self.nvar)
        gx = self.lx + self.Q @ d0 + self.N_ux.T @ w0
        for i in range(N - 1):
            q[self._ox + i * nx : self._ox + (i + 1) * nx] = gx
        q[self._ox + (N - 1) * nx : self._ox + N * nx] = self.P_terminal @ d0
        gu = self.lu + self.R @ w0 + self.N_ux @ d0
        for i in range(N):
            q[self._ou + i * nu : self._ou + (i + 1) * nu] = gu
        q[self._ou : self._ou + nu] += self.N_ux @ x0
        if self.stance_model == "rigid":
            phi = np.zeros((k, 3))
            phi[active, 2] = 1.0 / n_active
            q[self._of : self._osl] = np.tile(-self.force_weight * phi.ravel(), N)

        lo = np.full(self.ncon, -np.inf)
        hi = np.full(self.ncon, np.inf)
        r = self._rows
        dyn = np.tile(lin["c"], N)
        dyn[:nx] += lin["A"] @ x0
        lo[r["dyn"] : r["dyn"] + N * nx] = dyn
        hi[r["dyn"] : r["dyn"] + N * nx] = dyn

        if self.stance_model == "soft":
            law = np.tile(lin["fbar"], N)
            law[:ns] += lin["Fx"] @ x0
            lo[r["st"] : r["st"] + N * ns] = law
            hi[r["st"] : r["st"] + N * ns] = law
            return (q, *self._common_bounds(lo, hi, active))

        # Stance rows: anchors, drift correction.
        Js, v_lin = lin["Js"], lin["state"][p.nq : p.nq + nv]
        base = -Js @ v_lin
        st_lo = np.full(ns, -np.inf)
        st_hi = np.full(ns, np.inf)
        st_first_lo = st_lo.copy()
        st_first_hi = st_hi.copy()
        row = 0
        world = self.points.world(kin)
        for body, idx, rows in self._groups:
            seg = slice(row, row + rows)
            row += rows
            if not np.any(active[idx]):
                self._anchors.pop(body, None)
                continue
            if rows == 6:
                pos, quat = world[idx[0]].copy(), kin.xquat[body].copy()
                if body not in self._anchors:
                    self._anchors[body] = (pos, quat)
                apos, aquat = self._anchors[body]
                rot = np.zeros(3)
                mujoco.mju_subQuat(rot, quat, aquat)
                err = np.concatenate([pos - apos, kin.xmat[body].reshape(3, 3) @ rot])
            else:
                pos = world[idx].ravel()
                if body not in self._anchors:
                    self._anchors[body] = (pos.copy(), np.zeros(4))
                err = pos - self._anchors[body][0]
            st_lo[seg] = st_hi[seg] = base[seg]
            st_first_lo[seg] = st_first_hi[seg] = base[seg] - self.drift_gain * err / self.dt
        s0 = r["st"]
        for i in range(N):
            a, b = (st_first_lo, st_first_hi) if i == 0 else (st_lo, st_hi)
            lo[s0 + i * ns : s0 + (i + 1) * ns] = a
            hi[s0 + i * ns : s0 + (i + 1) * ns] = b

        return (q, *self._common_bounds(lo, hi, active))

    def _common_bounds(self, lo, hi, active) -> tuple[np.ndarray, np.ndarray]:
        """Friction, normal-force, control and joint-limit bounds (in place)."""
        p, lin, r = self.problem, self._lin, self._rows
        N, nu, k, F = self.horizon, p.nu, self.points.count, self.facets
        # Friction pyramid (upper bound 0) and normal force bounds (0 for lifted points).
        hi[r["fr"] : r["fr"] + N * k * F] = 0.0
        fn_hi = np.where(active, self.f_max / self.weight, 0.0)
        lo[r["fn"] : r["fn"] + N * k] = 0.0
        hi[r["fn"] : r["fn"] + N * k] = np.tile(fn_hi, N)

        lo[r["u"] : r["u"] + N * nu] = np.tile(p.ctrl_low - lin["ctrl"], N)
        hi[r["u"] : r["u"] + N * nu] = np.tile(p.ctrl_high - lin["ctrl"], N)
        nl = len(self._lim[0])
        if nl:
            qa, _, jlo, jhi = self._lim
            ql = lin["state"][qa]
            lo[r["lim"] :] = np.tile(jlo - ql, N)
            hi[r["lim"] :] = np.tile(jhi - ql, N)
        return lo, hi

    def _shifted_warm_start(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Previous primal and dual solutions moved ``period / dt`` stages earlier."""
        if self._prev_z is None or self._prev_y is None:
            return None
        shift = max(0, min(self.horizon - 1, round(self.period / self.dt)))
        N = self.horizon
        return (
            _shift(self._prev_z, self._zblocks, N, shift),
            _shift(self._prev_y, self._yblocks, N, shift),
        )

    def _solve_osqp(self, q, lo, hi, matrix_changed: bool):
        import osqp

        if self._solver is None:
            self._solver = osqp.OSQP()
            self._solver.setup(self._P, q, self._A, lo, hi, **self.osqp_settings)
        else:
            kw: dict[str, Any] = dict(q=q, l=lo, u=hi)
            if matrix_changed:
                kw["Ax"] = self._A.data
            self._solver.update(**kw)
        warm = self._shifted_warm_start() if self.warm_start else None
        if warm is not None:
            self._solver.warm_start(x=warm[0], y=warm[1])
        else:
            self._solver.warm_start(x=np.zeros(self.nvar), y=np.zeros(self.ncon))
        res = self._solver.solve(raise_error=False)
        status = str(res.info.status)
        ok = res.info.status_val in (
            osqp.SolverStatus.OSQP_SOLVED,
            osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
        )
        x = res.x if ok else None
        y = res.y if ok else None
        return x, y, status, int(res.info.iter), float(res.info.obj_val)

    def _solve_qpsolvers(self, q, lo, hi):
        import qpsolvers

        qp = to_qpsolvers(QPData(self._P, q, self._A, lo, hi))
        sol = qpsolvers.solve_problem(qp, solver=self.solver)
        ok = bool(sol.found) and sol.x is not None and np.all(np.isfinite(sol.x))
        status = "solved" if ok else "failed"
        obj = float(0.5 * sol.x @ (qp.P @ sol.x) + q @ sol.x) if ok else float("nan")
        iters = 0
        extras = getattr(sol, "extras", {}) or {}
        for key in ("iter", "iterations", "num_iter"):
            if key in extras:
                iters = int(extras[key])
        return (sol.x if ok else None), None, status, iters, obj

    def solve(self, state: np.ndarray) -> QPPlan | None:
        """Build and solve the QP for ``state``; ``None`` (and a counted status) on failure."""
        p = self.problem
        state = p.check_state(state)
        t0 = _time.perf_counter()
        changed = False
        if self.relinearize:
            ctrl = self.ctrl_ref if self.last_plan is None else self._last_ctrl
            self._linearize(state, ctrl)
            changed = True
        t1 = _time.perf_counter()
        q, lo, hi = self._vectors(state)
        self.qp = QPData(self._P, q, self._A, lo, hi)
        t2 = _time.perf_counter()
        if self.solver == "osqp":
            z, y, status, iters, obj = self._solve_osqp(q, lo, hi, changed)
        else:
            z, y, status, iters, obj = self._solve_qpsolvers(q, lo, hi)
        t3 = _time.perf_counter()
        self.timing = TickTiming(t1 - t0, t2 - t1, t3 - t2)
        self.last_status = status
        if self.export_dir is not None:
            self.export(self.export_dir / f"tick_{self._tick:05d}.npz")
        self._tick += 1
        if z is None or not np.all(np.isfinite(z)):
            self._failures[status] = self._failures.get(status, 0) + 1
            return None
        self._iters.append(iters)
        self._prev_z, self._prev_y = z, y
        N, nx, nu = self.horizon, p.nx, p.nu
        dx = np.vstack([p.state_difference(state, self._lin["state"]), z[: N * nx].reshape(N, nx)])
        ctrls = self._lin["ctrl"] + z[self._ou : self._ou + N * nu].reshape(N, nu)
        raw = z[self._of : self._osl].reshape(N, self.points.count, 3) * self.weight
        active, _ = self._activity(state)
        raw_active = raw.copy()
        viol = cone_violation(raw, self.mu, self.facets, self.f_max)
        if np.any(~active):
            viol = max(viol, float(np.max(np.abs(raw[:, ~active]))))
            raw_active[:, ~active] = 0.0
        forces = project_to_pyramid(raw_active, self.mu, self.facets, self.f_max)
        plan = QPPlan(dx, ctrls, forces, viol, status, iters, t3 - t2, obj)
        self.last_plan = plan
        self._plan_age = 0
        return plan

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        plan = self.solve(state)
        if plan is not None:
            ctrl = self.problem.clip_ctrl(plan.ctrls[0])
        else:
            self._fallbacks += 1
            self._plan_age += 1
            step = round(self._plan_age * self.period / self.dt)
            plan = self.last_plan
            if self.fallback == "plan" and plan is not None and step < self.horizon:
                ctrl = self.problem.clip_ctrl(plan.ctrls[step])
            else:
                ctrl = self._fallback_lqr()(state, time)
        self._last_ctrl = ctrl
        return ctrl

    def _fallback_lqr(self):
        if self._lqr is None:
            from mpcbox.controllers.lqr import LQR

            self._lqr = LQR(self.problem)
        return self._lqr

    # ------------------------------------------------------------------ export
    def export(self, path: str | Path) -> Path:
        """Write the last tick's QP to ``path`` (``.npz``: CSC arrays of ``P`` and ``A``,
        ``q``, ``l``, ``u``, and the sizes)."""
        if self.qp is None:
            raise InvalidArgumentError("export: no QP built yet; call the controller first")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        P, A = self.qp.P, self.qp.A
        np.savez(
            path,
            P_data=P.data,
            P_indices=P.indices,
            P_indptr=P.indptr,
            P_shape=np.array(P.shape),
            A_data=A.data,
            A_indices=A.indices,
            A_indptr=A.indptr,
            A_shape=np.array(A.shape),
            q=self.qp.q,
            l=self.qp.l,
            u=self.qp.u,
            horizon=self.horizon,
            dt=self.dt,
            nx=self.problem.nx,
            nu=self.problem.nu,
            nf=self.nf,
        )
        return path


def load_qp(path: str | Path) -> QPData:
    """Read a QP written by :meth:`QPMPC.export`."""
    f = np.load(path)
    P = sp.csc_matrix((f["P_data"], f["P_indices"], f["P_indptr"]), shape=tuple(f["P_shape"]))
    A = sp.csc_matrix((f["A_data"], f["A_indices"], f["A_indptr"]), shape=tuple(f["A_shape"]))
    return QPData(P, f["q"], A, f["l"], f["u"])


def to_qpsolvers(qp: QPData):
    r"""The same QP as a :class:`qpsolvers.Problem`: rows with ``l = u`` become equalities,
    finite upper bounds ``G z <= h`` rows, finite lower bounds negated rows; ``P`` is made
    symmetric from its upper triangle."""
    import qpsolvers

    P = qp.P + sp.triu(qp.P, k=1).T
    A = sp.csr_matrix(qp.A)
    eq = np.isfinite(qp.l) & np.isfinite(qp.u) & (qp.l == qp.u)
    up = np.isfinite(qp.u) & ~eq
    low = np.isfinite(qp.l) & ~eq
    G = sp.vstack([A[up], -A[low]]).tocsc()
    h = np.concatenate([qp.u[up], -qp.l[low]])
    return qpsolvers.Problem(sp.csc_matrix(P), qp.q.copy(), G, h, A[eq].tocsc(), qp.u[eq].copy())


def _shift(vec: np.ndarray, blocks: list[tuple[int, int]], horizon: int, shift: int) -> np.ndarray:
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


def _compose(Ah: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``A = Ah^n`` and ``S = sum_{i<n} Ah^i``: ``n`` steps of ``x+ = Ah x + b`` with ``b``
    held give ``x_n = A x_0 + S b``."""
    A = np.eye(len(Ah))
    S = np.zeros_like(Ah)
    for _ in range(n):
        S += A
        A = Ah @ A
    return A, S


def _resolve_kinds(contacts: Sequence[str] | str) -> list[str]:
    """Pass names through; ``kind:name`` prefixes are handled by :func:`contact_points`."""
    return [contacts] if isinstance(contacts, str) else list(contacts)
