r"""Infinite-horizon discrete LQR about an operating point.

With the finite-difference model :math:`dx_{t+1} = A\,dx_t + B\,du_t` and the cost
:math:`\sum_t dx_t^T Q\,dx_t + du_t^T R\,du_t + 2\,dx_t^T N du_t`, the gain is
:math:`K = (R + B^T P B)^{-1}(B^T P A + N^T)` with :math:`P` the stabilizing solution of the
discrete algebraic Riccati equation (:func:`scipy.linalg.solve_discrete_are`), and the
controller applies :math:`u = u_0 - K\,(x \ominus x_0)`.

Called every ``period`` seconds with the control held in between (as
:func:`~mpcbox.simulate` and :func:`~mpcbox.sim.realtime.simulate_realtime` do), the gain is
designed for that hold: over :math:`n = \text{period} / \delta t` planning steps from the
operating point (states :math:`x_0, x_1 = f(x_0, u_0), \dots`, Jacobians :math:`A_i, B_i` at
:math:`(x_i, u_0)`) the held step is

.. math::
    A = A_{n-1} \cdots A_0 , \qquad
    B = \sum_{i=0}^{n-1} A_{n-1} \cdots A_{i+1} B_i ,

the exact linearization of :math:`n` steps under one held control (at a fixed point
:math:`A = A_0^n`, :math:`B = \sum_i A_0^i B_0`), with the per-step weights :math:`Q, R`
(scaling both by :math:`n` leaves :math:`K` unchanged).

With ``wrap`` the deviation :math:`\delta q_j` of each hinge joint without a range is taken
modulo a whole turn, :math:`\delta q_j \mapsto \delta q_j - 2\pi \lfloor (\delta q_j + \pi)
/ 2\pi \rfloor \in [-\pi, \pi)`, so the controller regulates to the nearest whole-turn copy
of the operating point (a pendulum upright at :math:`0` is also upright at :math:`2\pi`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import scipy.linalg

from mpcbox.config import resolve_config
from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.uncontrollable import (
    INPUT_GAIN_TOL,
    UncontrollableMode,
    marginal_projector,
    uncontrollable_modes,
)
from mpcbox.core.cost import Cost, QuadraticValue
from mpcbox.core.problem import Problem
from mpcbox.errors import (
    CostDefinitionError,
    InvalidArgumentError,
    NotStabilizableError,
    ShapeError,
    SolverError,
)
from mpcbox.validation import as_array, boolean, checked_options, finite, positive


def check_symmetric(name: str, mat: np.ndarray, rtol: float = 1e-9) -> None:
    """Raise :class:`CostDefinitionError` unless ``mat`` is symmetric to a scale-aware tolerance."""
    if not np.all(np.isfinite(mat)):
        raise CostDefinitionError(f"{name} must be finite")
    scale = max(1.0, float(np.max(np.abs(mat))))
    if np.max(np.abs(mat - mat.T)) > rtol * scale:
        raise CostDefinitionError(
            f"{name} must be symmetric: max |{name} - {name}^T| = {np.max(np.abs(mat - mat.T)):.3g}"
        )


def check_weights(Q: np.ndarray, R: np.ndarray, rtol: float = 1e-9) -> None:
    """Symmetry of Q and R, R positive definite, Q positive semidefinite."""
    check_symmetric("Q", Q, rtol)
    check_symmetric("R", R, rtol)
    try:
        np.linalg.cholesky(0.5 * (R + R.T))
    except np.linalg.LinAlgError:
        raise CostDefinitionError(
            f"R must be positive definite; smallest eigenvalue {np.linalg.eigvalsh(R).min():.3g}"
        ) from None
    qmin = np.linalg.eigvalsh(0.5 * (Q + Q.T)).min() if Q.size else 0.0
    if qmin < -rtol * max(1.0, float(np.max(np.abs(Q)))) * len(Q):
        raise CostDefinitionError(
            f"Q must be positive semidefinite; smallest eigenvalue {qmin:.3g}"
        )


#: Distance from the unit circle within which a mode counts as on it.
_MARGIN = 1e-6
#: Closed-loop eigenvalues within this of the unit circle count as on it (not stabilized).
_UNDAMPED = 1e-9


def check_stabilizable(
    A: np.ndarray, B: np.ndarray, tol: float = INPUT_GAIN_TOL, margin: float = _MARGIN
) -> int:
    r"""Every mode of A with :math:`|\lambda| \ge 1` must be controllable (the PBH
    condition :math:`\operatorname{rank}[A - \lambda I,\ B] = n`, tested on each
    eigenvalue's own coordinates: :func:`~mpcbox.controllers.uncontrollable.uncontrollable_modes`).

    Modes on the unit circle to within ``margin`` that are uncontrollable are tolerated and
    counted: a floating base on a flat floor has them (moving the whole body sideways or
    turning it about the vertical is again an equilibrium); :func:`dlqr` takes them out of
    the cost. Strictly unstable ones raise.

    Returns:
        The number of uncontrollable marginal modes (distinct eigenvalues).

    Raises:
        NotStabilizableError: Naming the uncontrollable unstable eigenvalue.
    """
    return _count_marginal(uncontrollable_modes(A, B, tol, margin), margin)


def _count_marginal(modes: list[UncontrollableMode], margin: float) -> int:
    """How many of the uncontrollable ``modes`` lie on the unit circle; raise on one outside."""
    marginal = 0
    for mode in modes:
        lam = mode.eigenvalue
        if abs(lam) < 1.0 - margin:
            continue
        if abs(lam) <= 1.0 + margin:
            marginal += 1
            continue
        raise NotStabilizableError(
            f"(A, B) is not stabilizable: eigenvalue {lam:.6g} (|λ| = {abs(lam):.6g} > 1) is "
            "uncontrollable: no input reaches it"
        )
    return marginal


def _refuse_partly_reached_blocks(modes: list[UncontrollableMode], margin: float) -> None:
    """Raise on a defective eigenvalue on the unit circle that the inputs reach only in
    part: no projector leaves it out of the cost, and no gain stops its drift."""
    for mode in modes:
        if mode.projector is None and abs(abs(mode.eigenvalue) - 1.0) <= margin:
            raise NotStabilizableError(
                f"(A, B) is not stabilizable: eigenvalue {mode.eigenvalue:.6g} on the unit "
                "circle is a Jordan block (a coordinate and its rate, such as a joint that "
                "turns freely with neither stiffness nor damping) that the inputs reach only "
                "in part: it drifts at a constant rate that no gain can stop. Add an "
                "actuator, damping or stiffness to that joint, or lock it"
            )


def nearest_psd(P: np.ndarray) -> np.ndarray:
    """Nearest positive semidefinite matrix to the symmetric part of ``P`` ``(n, n)``.

    A Riccati solution with marginal modes (the humanoid's free heading, say) carries
    negative eigenvalues of order 1e-6 of its largest from the solver's rounding; quadratic
    forms that must be convex (a QP's Hessian, a terminal value) use this projection.
    """
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    return (V * np.maximum(w, 0.0)) @ V.T


def dlqr(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, N: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    r"""Checked discrete LQR: the gain ``K`` ``(nu, nx)`` and Riccati solution ``P`` ``(nx, nx)``.

    Uncontrollable modes on the unit circle
    (:func:`~mpcbox.controllers.uncontrollable.uncontrollable_marginal_projector`) are left
    out: no gain can change them, and a weight on them would make ``P`` unbounded there. The
    equation is solved on the rest of the state, and ``K`` and ``P`` act on
    :math:`(I - \Pi_u)\,x` (zero along those modes).

    Raises:
        ShapeError: An array has the wrong shape, or ``A`` or ``B`` is not finite.
        CostDefinitionError: ``Q`` or ``R`` is not symmetric, ``R`` is not positive
            definite or ``Q`` is not positive semidefinite.
        NotStabilizableError: No stabilizing gain exists.
        SolverError: The Riccati solver failed.
    """
    A = as_array("A", A, (None, None))
    n = A.shape[0]
    if A.shape != (n, n):
        raise ShapeError(f"A must be a square matrix (n, n), got shape {A.shape}")
    B = as_array("B", B, (n, None))
    m = B.shape[1]
    Q = as_array("Q", Q, (n, n))
    R = as_array("R", R, (m, m))
    if N is not None:
        N = as_array("N", N, (n, m))
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise ShapeError("A and B must be finite")
    check_weights(Q, R)
    modes = uncontrollable_modes(A, B)
    _count_marginal(modes, _MARGIN)  # raises on an uncontrollable unstable mode
    _refuse_partly_reached_blocks(modes, _MARGIN)
    Q, R = 0.5 * (Q + Q.T), 0.5 * (R + R.T)
    # Modes no control reaches and that neither grow nor decay (a floating robot moved
    # sideways or turned as a whole) have no stabilizing Riccati solution where the cost
    # weighs them: weigh only the rest, x_c = (I - Pi_u) x, an invariant complement that
    # holds the range of B, so that K and P act on x_c alone.
    uncontrollable = marginal_projector(modes, _MARGIN)
    if uncontrollable is None:
        return _solve_dare(A, B, Q, R, N)
    keep = np.eye(n) - uncontrollable
    if np.linalg.norm(keep) <= 1e-9 * n:  # no input reaches anything: the gain is zero
        return np.zeros((m, n)), np.zeros((n, n))
    try:
        K, P = _solve_dare(A, B, keep.T @ Q @ keep, R, None if N is None else keep.T @ N, keep)
    except SolverError:
        # SciPy's reordering can fail on the full pencil: solve in an orthonormal basis T
        # of the complement instead (x_c = T z).
        U, sv, _ = np.linalg.svd(keep)
        T = U[:, : int(np.sum(sv > 1e-9 * sv[0]))]
        K, P = _solve_dare(T.T @ A @ T, T.T @ B, T.T @ Q @ T, R, None if N is None else T.T @ N)
        keep = T.T @ keep
    return K @ keep, keep.T @ P @ keep


def _solve_dare(
    A: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    N: np.ndarray | None,
    keep: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``K`` and ``P`` of the discrete Riccati equation (arguments already checked).

    A mode on the unit circle that ``Q`` does not see (a floating robot turning about its
    one stance foot) makes the pencil singular: older SciPy raises, SciPy 1.17 returns a
    solution whose gain leaves the mode on the circle. Either way the equation is solved
    again with every state weighed negligibly (``1e-9`` of ``Q``'s largest diagonal entry;
    only the part ``keep`` ``(n, n)`` that inputs reach when uncontrollable modes are left
    out), which moves such a mode inside without changing the gain elsewhere.
    """
    left_out = 0 if keep is None else len(A) - round(float(np.trace(keep)))
    first: tuple[np.ndarray, np.ndarray] | None = None
    try:
        P = scipy.linalg.solve_discrete_are(A, B, Q, R, s=N)
    except Exception as exc:  # LinAlgError, ValueError, and LAPACK's own error type
        error: Exception | None = exc
    else:
        error = None
        K = _gain(A, B, R, N, P)
        if np.all(np.isfinite(P)):
            if _on_circle(A - B @ K) <= left_out:
                return K, P
            first = (K, P)  # finite, but a mode stays on the circle: the fallback
    delta = 1e-9 * max(1.0, float(np.max(np.abs(np.diag(Q)))))
    weigh = np.eye(len(A)) if keep is None else keep.T @ keep
    try:
        P = scipy.linalg.solve_discrete_are(A, B, Q + delta * weigh, R, s=N)
    except Exception:
        P = None
    if P is None or not np.all(np.isfinite(P)):
        if first is not None:
            return first
        raise SolverError(
            f"the discrete Riccati equation has no stabilizing solution ({error}); "
            "check that every unstable mode is penalized by Q (detectability)"
        ) from error
    return _gain(A, B, R, N, P), P


def _gain(
    A: np.ndarray, B: np.ndarray, R: np.ndarray, N: np.ndarray | None, P: np.ndarray
) -> np.ndarray:
    cross = B.T @ P @ A if N is None else B.T @ P @ A + N.T
    return np.linalg.solve(R + B.T @ P @ B, cross)


def _on_circle(closed: np.ndarray) -> int:
    """How many eigenvalues of the closed-loop matrix ``closed`` lie on or outside the unit
    circle (to within :data:`_UNDAMPED`)."""
    return int(np.sum(np.abs(np.linalg.eigvals(closed)) >= 1.0 - _UNDAMPED))


@checked_options
@dataclass(frozen=True, kw_only=True)
class LQRConfig:
    r"""Options of :class:`LQR`.

    Attributes:
        Q: State weight ``(nx, nx)``; by default the Gauss-Newton Hessian of the Problem's
            running cost at the operating point.
        R: Control weight ``(nu, nu)``; likewise by default.
        state: Operating state ``(nstate,)`` (default: the Problem's reference state).
        ctrl: Operating control ``(nu,)`` (default: the Problem's ``ctrl_ref``).
        eps: Finite-difference step for the linearization (default: the Problem's).
        centered: Centered finite differences (default: the Problem's).
        period: Seconds between calls, a whole number ``n`` of the Problem's planning steps
            (default: one step); the gain is designed for the control held ``n`` steps (see
            the module docstring).
        wrap: Wrap each unlimited hinge joint's deviation onto :math:`[-\pi, \pi)` (see the
            module docstring); off: the deviation is the plain difference.
    """

    Q: np.ndarray | None = None
    R: np.ndarray | None = None
    state: np.ndarray | None = None
    ctrl: np.ndarray | None = None
    eps: float | None = None
    centered: bool | None = None
    period: float | None = None
    wrap: bool = False

    def __post_init__(self) -> None:
        if self.period is not None:
            positive("period", self.period)
        if self.eps is not None:
            positive("eps", self.eps)
        if self.centered is not None:
            boolean("centered", self.centered)
        object.__setattr__(self, "wrap", boolean("wrap", self.wrap))

    def check_sizes(self, problem: Problem) -> dict[str, np.ndarray | None]:
        """The arrays given (``Q``, ``R``, ``state``, ``ctrl``) as arrays of ``problem``'s
        sizes, ``None`` for those not given; the controller builds from these. Raises
        ShapeError naming the option."""
        n, m = problem.nx, problem.nu
        shapes = {"Q": (n, n), "R": (m, m), "state": (problem.nstate,), "ctrl": (m,)}
        return {
            name: None
            if getattr(self, name) is None
            else as_array(name, getattr(self, name), shape)
            for name, shape in shapes.items()
        }


def hold_steps(period: float | None, dt: float) -> int:
    """Planning steps ``n`` of ``dt`` in ``period`` (1 for ``None``).

    Raises:
        InvalidArgumentError: If ``period`` is not a whole multiple of ``dt``.
    """
    if period is None:
        return 1
    n = round(period / dt)
    if n < 1 or abs(n * dt - period) > 1e-9 * max(1.0, period):
        raise InvalidArgumentError(
            f"period must be a whole multiple of the planning timestep {dt:g} s, got {period:g}"
        )
    return n


class LQR(Controller):
    """Infinite-horizon LQR about an operating point of a Problem.

    The linearization is that of the Problem's planning model, so the controller runs at the
    planning timestep (``period``). With no options it regulates about the Problem's
    reference with weights from its running cost.

    Args:
        problem: The Problem.
        config: An :class:`LQRConfig` (default: its defaults).
        **options: Fields of :class:`LQRConfig` that replace those of ``config``, e.g.
            ``LQR(problem, R=0.1 * quad.luu)``.

    Attributes:
        config: The resolved config.
        A, B: The linearization.
        K: Gain ``(nu, nx)``.
        P: Riccati solution ``(nx, nx)``.
        wrapped: Tangent indices ``(k,)`` whose deviation is wrapped (empty without
            ``wrap``).

    Raises:
        InvalidTypeError: If ``problem`` is not a Problem or ``config`` not an LQRConfig.
        UnknownOptionError: For an option that is not a config field; it lists the valid ones.
        ShapeError, CostDefinitionError, NotStabilizableError, SolverError: From :func:`dlqr`.
    """

    name = "lqr"
    config_class = LQRConfig

    def __init__(self, problem: Problem, config: LQRConfig | None = None, **options: Any) -> None:
        problem = check_problem(problem, "LQR")
        cfg = resolve_config(LQRConfig, config, options, "LQR")
        self.problem = problem
        self.config = cfg
        given = cfg.check_sizes(problem)
        state, ctrl = given["state"], given["ctrl"]
        self.state0 = problem.reference_state() if state is None else state
        self.ctrl0 = problem.ctrl_ref.copy() if ctrl is None else ctrl
        steps = hold_steps(cfg.period, problem.dt)
        self.A, self.B = _held_linearization(problem, self.state0, self.ctrl0, steps, cfg)
        Q, R, N = given["Q"], given["R"], None
        if Q is None or R is None:
            quad = problem.quadratize(self.state0, self.ctrl0)
            Q = quad.lxx if Q is None else Q
            R = quad.luu if R is None else R
            if np.any(quad.lux):
                N = quad.lux.T
        self.Q = as_array("Q", Q, (problem.nx, problem.nx))
        self.R = as_array("R", R, (problem.nu, problem.nu))
        self.K, self.P = dlqr(self.A, self.B, self.Q, self.R, N)
        self.period = steps * problem.dt
        hinges = unlimited_hinges(problem.model) if cfg.wrap else np.zeros(0, int)
        self.wrapped = np.asarray(problem.model.jnt_dofadr[hinges], dtype=int)

    @property
    def closed_loop_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of ``A - B K``."""
        return np.linalg.eigvals(self.A - self.B @ self.K)

    @property
    def spectral_radius(self) -> float:
        """Largest closed-loop eigenvalue magnitude (< 1 means locally stable)."""
        return float(np.max(np.abs(self.closed_loop_eigenvalues)))

    def deviation(self, states: np.ndarray) -> np.ndarray:
        """Tangent deviations ``(..., nx)`` of states ``(..., nstate)`` from the operating
        point, the wrapped hinges' taken modulo a whole turn (see ``wrap``)."""
        dx = self.problem.state_difference(states, self.state0)
        if self.wrapped.size:
            dx[..., self.wrapped] = np.mod(dx[..., self.wrapped] + np.pi, 2.0 * np.pi) - np.pi
        return dx

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """``clip(u0 - K (state ⊖ x0))`` ``(nu,)``; a state of another shape is a
        ``ShapeError``, a non-finite one a ``DivergenceError`` (``time`` is not read but
        must be a finite number)."""
        finite("time", time)
        state = self.problem.check_state(state)
        return self.problem.clip_ctrl(self.ctrl0 - self.K @ self.deviation(state))


def unlimited_hinges(model: mujoco.MjModel) -> np.ndarray:
    """Ids ``(k,)`` of the hinge joints without a range in ``model``: the joints whose angle
    is defined modulo a whole turn (their angle at ``jnt_qposadr``, tangent at
    ``jnt_dofadr``)."""
    hinge = (model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE) & (model.jnt_limited == 0)
    return np.flatnonzero(hinge)


def with_lqr_terminal_value(problem: Problem) -> Problem:
    r"""``problem`` with its LQR value function added to the terminal cost.

    The term is :math:`(x \ominus x_{ref})^T P (x \ominus x_{ref})` with the Riccati matrix
    :math:`P` of :class:`LQR` on ``problem``'s planning model at its reference (made positive
    semidefinite by :func:`nearest_psd`): the infinite-horizon cost-to-go of the linearized
    problem, so a short horizon still sees what follows it.

    On a model with activation states (``na > 0``: filters, integrators, muscles) the
    Riccati matrix is ``(2 nv + na, 2 nv + na)`` but a cost term reads only positions and
    velocities, so the term is its leading ``(2 nv, 2 nv)`` block: the cost-to-go with each
    activation at its reference value (a principal block of a positive semidefinite matrix
    is one too). The whole matrix was a ``ShapeError`` when the term was bound, so that
    iLQR-MPC with ``terminal_value="lqr"`` could not be built on dm_control's quadruped,
    whose actuators are first-order filters.
    """
    lqr = LQR(problem)
    nx = 2 * problem.model.nv
    value = QuadraticValue(
        problem.qpos_ref, problem.qvel_ref, P=nearest_psd(lqr.P)[:nx, :nx], name="lqr_value"
    )
    return problem.with_cost(Cost(problem.cost.running, [*problem.cost.terminal, value]))


def _held_linearization(
    problem: Problem, state: np.ndarray, ctrl: np.ndarray, steps: int, cfg: LQRConfig
) -> tuple[np.ndarray, np.ndarray]:
    """``A`` ``(nx, nx)`` and ``B`` ``(nx, nu)`` of ``steps`` planning steps under a held
    ``ctrl`` from ``state`` (the module docstring's products and sums)."""
    A, B = problem.linearize(state, ctrl, eps=cfg.eps, centered=cfg.centered)
    for _ in range(steps - 1):
        state = problem.step(state, ctrl)
        A_i, B_i = problem.linearize(state, ctrl, eps=cfg.eps, centered=cfg.centered)
        A, B = A_i @ A, A_i @ B + B_i
    return np.asarray(A), np.asarray(B)


__all__ = [
    "LQR",
    "LQRConfig",
    "check_stabilizable",
    "check_symmetric",
    "check_weights",
    "dlqr",
    "hold_steps",
    "nearest_psd",
    "unlimited_hinges",
    "with_lqr_terminal_value",
]
