r"""QP solver backends behind one interface, and the QP's file format.

A QP here is :math:`\min_z \tfrac12 z^T P z + q^T z` s.t. :math:`l \le A z \le u`
(:class:`QPData`). :class:`OSQPBackend` keeps one OSQP solver whose sparsity pattern is set
up on the first solve; later solves update the vectors (and the values of ``A`` when the
controller relinearized) and warm-start it. :class:`QPSolversBackend` hands the same QP to any
``qpsolvers`` backend (``"clarabel"``, ``"daqp"``, ...) through :func:`to_qpsolvers`, cold.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from mpcbox.errors import InvalidTypeError, UnknownNameError

#: OSQP settings of the controller (``QPMPCConfig.osqp_settings`` overrides them).
OSQP_DEFAULTS: dict[str, Any] = dict(
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
    # On Menagerie's Go1, A1 and ANYmal C standing under 1 N m torque noise rho = 3 fails no
    # solve either; adaptive rho made the humanoid's ticks 1.2-3.7x slower (median; p99
    # 2.9-3.6x), with 3.6% of the one-leg solves at the cap (benchmarks/qp_robots.py).
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


class QPSolution(NamedTuple):
    r"""What a backend returns.

    Attributes:
        x: Primal solution ``(n,)``, or ``None`` when the solve failed.
        y: Dual solution ``(m,)``, or ``None`` (failed, or not reported by the backend).
        status: Solver status string.
        iterations: Solver iterations (0 when the backend does not report them).
        objective: Objective value (``nan`` when not known).
        inaccurate: The solver accepted ``x`` at a looser tolerance than asked (OSQP's
            ``"solved inaccurate"``).
        truncated: The solver stopped at its time limit and ``x`` is its last iterate
            (OSQP's ``"run time limit reached"``).
        primal_residual: :math:`\|A x - z\|_\infty` of the returned iterate (``nan`` when
            the backend does not report it).
    """

    x: np.ndarray | None
    y: np.ndarray | None
    status: str
    iterations: int
    objective: float
    inaccurate: bool = False
    truncated: bool = False
    primal_residual: float = float("nan")


def constraint_residual(qp: QPData, x: np.ndarray, rows: np.ndarray | None = None) -> float:
    r"""Largest violation :math:`\|A x - \text{clip}(A x, l, u)\|_\infty` of the rows
    ``rows`` (all rows when ``None``) by the primal point ``x`` ``(n,)``."""
    ax, lo, hi = qp.A @ x, qp.l, qp.u  # the full product: slicing rows of CSC costs more
    if rows is not None:
        ax, lo, hi = ax[rows], lo[rows], hi[rows]
    return float(np.max(np.abs(ax - np.clip(ax, lo, hi)), initial=0.0))


class QPBackend(abc.ABC):
    """Solves the controller's QP, tick after tick (same sparsity pattern every tick)."""

    @abc.abstractmethod
    def solve(
        self,
        qp: QPData,
        matrix_changed: bool,
        warm: tuple[np.ndarray, np.ndarray] | None,
    ) -> QPSolution:
        """Solve ``qp``.

        Args:
            qp: The QP; ``P`` and ``A`` keep their sparsity pattern from tick to tick.
            matrix_changed: Whether the values of ``A`` changed since the last solve.
            warm: Primal ``(n,)`` and dual ``(m,)`` initial guesses, or ``None`` (cold start
                from zeros); backends without warm starts ignore it.
        """


class OSQPBackend(QPBackend):
    """OSQP through its own API, on one persistent solver.

    Args:
        settings: OSQP settings overriding :data:`OSQP_DEFAULTS`.
    """

    def __init__(self, settings: dict[str, Any] | None = None) -> None:
        self.settings = {**OSQP_DEFAULTS, **(settings or {})}
        self._solver: Any = None

    def solve(
        self,
        qp: QPData,
        matrix_changed: bool,
        warm: tuple[np.ndarray, np.ndarray] | None,
    ) -> QPSolution:
        import osqp

        if self._solver is None:
            self._solver = osqp.OSQP()
            self._solver.setup(qp.P, qp.q, qp.A, qp.l, qp.u, **self.settings)
        else:
            kw: dict[str, Any] = dict(q=qp.q, l=qp.l, u=qp.u)
            if matrix_changed:
                kw["Ax"] = qp.A.data
            self._solver.update(**kw)
        if warm is not None:
            self._solver.warm_start(x=warm[0], y=warm[1])
        else:
            self._solver.warm_start(x=np.zeros(qp.A.shape[1]), y=np.zeros(qp.A.shape[0]))
        res = self._solver.solve(raise_error=False)
        status = res.info.status_val
        truncated = status == osqp.SolverStatus.OSQP_TIME_LIMIT_REACHED
        ok = truncated or status in (
            osqp.SolverStatus.OSQP_SOLVED,
            osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
        )
        return QPSolution(
            res.x if ok else None,
            res.y if ok else None,
            str(res.info.status),
            int(res.info.iter),
            float(res.info.obj_val),
            status == osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
            truncated,
            float(res.info.prim_res),
        )


class QPSolversBackend(QPBackend):
    """A ``qpsolvers`` backend, solving :func:`to_qpsolvers` of each QP from scratch.

    Args:
        name: The ``qpsolvers`` solver name (see :func:`backend_names`).
    """

    def __init__(self, name: str) -> None:
        self.name = check_backend(name)

    def solve(
        self,
        qp: QPData,
        matrix_changed: bool,
        warm: tuple[np.ndarray, np.ndarray] | None,
    ) -> QPSolution:
        import qpsolvers

        problem = to_qpsolvers(qp)
        sol = qpsolvers.solve_problem(problem, solver=self.name)
        ok = bool(sol.found) and sol.x is not None and np.all(np.isfinite(sol.x))
        obj = float(0.5 * sol.x @ (problem.P @ sol.x) + qp.q @ sol.x) if ok else float("nan")
        iters = 0
        extras = getattr(sol, "extras", {}) or {}
        for key in ("iter", "iterations", "num_iter"):
            if key in extras:
                iters = int(extras[key])
        return QPSolution(sol.x if ok else None, None, "solved" if ok else "failed", iters, obj)


def backend_names() -> list[str]:
    """``"osqp"`` first, then the other installed ``qpsolvers`` backends."""
    import qpsolvers

    return ["osqp", *(b for b in qpsolvers.available_solvers if b != "osqp")]


def check_backend(name: str, argument: str = "solver") -> str:
    """Return ``name`` if it is a backend of :func:`backend_names`.

    Raises:
        UnknownNameError: Otherwise; the message lists the installed backends.
    """
    if not isinstance(name, str):
        raise InvalidTypeError(f"{argument} must be a QP backend name, got {type(name).__name__}")
    if name == "osqp":
        return name
    valid = backend_names()
    if name not in valid:
        raise UnknownNameError("solver", name, valid, argument)
    return name


def make_backend(name: str, osqp_settings: dict[str, Any] | None = None) -> QPBackend:
    """The backend called ``name``: :class:`OSQPBackend` for ``"osqp"``, else
    :class:`QPSolversBackend`."""
    if name == "osqp":
        return OSQPBackend(osqp_settings)
    return QPSolversBackend(name)


def export_qp(path: str | Path, qp: QPData, **sizes: float) -> Path:
    """Write ``qp`` to ``path`` (``.npz``: CSC arrays of ``P`` and ``A``, ``q``, ``l``,
    ``u``) with the scalar entries ``sizes`` (``horizon``, ``dt``, ...); read it back with
    :func:`load_qp`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    P, A = qp.P, qp.A
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
        q=qp.q,
        l=qp.l,
        u=qp.u,
        **sizes,
    )
    return path


def load_qp(path: str | Path) -> QPData:
    """Read a QP written by :func:`export_qp` (or ``QPMPC.export``)."""
    f = np.load(path)
    P = sp.csc_matrix((f["P_data"], f["P_indices"], f["P_indptr"]), shape=tuple(f["P_shape"]))
    A = sp.csc_matrix((f["A_data"], f["A_indices"], f["A_indptr"]), shape=tuple(f["A_shape"]))
    return QPData(P, f["q"], A, f["l"], f["u"])


def to_qpsolvers(qp: QPData) -> Any:
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
