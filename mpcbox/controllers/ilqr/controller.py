r"""Time-varying, control-limited iterative LQR, offline and as a receding-horizon controller.

Notation (``T`` knots, states ``x_0 .. x_T``, controls ``u_0 .. u_{T-1}``): the planning model
is linearized along the current trajectory, :math:`dx_{t+1} = A_t dx_t + B_t du_t`, and the
cost quadratized (Gauss-Newton) into :math:`\ell_x, \ell_u, \ell_{xx}, \ell_{uu}, \ell_{ux}`.
The backward pass computes, from :math:`V_x, V_{xx}` at ``t + 1``,

.. math::

    Q_x = \ell_x + A^T V_x, \quad Q_u = \ell_u + B^T V_x, \quad
    Q_{xx} = \ell_{xx} + A^T V_{xx} A, \quad
    Q_{uu} = \ell_{uu} + B^T V_{xx} B, \quad Q_{ux} = \ell_{ux} + B^T V_{xx} A,

then solves the box QP :math:`\min_{du} \tfrac12 du^T (Q_{uu} + \mu I) du + Q_u^T du` with
:math:`u_{lo} - u_t \le du \le u_{hi} - u_t` (:func:`mpcbox.controllers.ilqr.boxqp.solve_box_qp`) for the
feed-forward ``k``, and sets the feedback ``K = -(Q_{uu}+\mu I)_{ff}^{-1} Q_{ux,f}`` on the free
controls only (zero rows on clamped ones), as in control-limited DDP (Tassa et al., 2014).
The forward pass rolls out :math:`u = \mathrm{clip}(u_t + \alpha k_t + K_t (\hat x_t \ominus
x_t))` for a few step sizes :math:`\alpha` and keeps the best one that decreases the cost
enough relative to the model's prediction. The Levenberg-Marquardt term :math:`\mu` grows
when the backward pass meets a non-definite :math:`Q_{uu}` or no step size works, and
shrinks after each accepted step.
"""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.core.problem import Linearization, Problem, Quadratization, Rollout
from mpcbox.errors import DivergenceError, InvalidArgumentError, MpcboxError, SolverError
from mpcbox.validation import as_array, one_of, positive, positive_int


class Timing(NamedTuple):
    """Wall-clock seconds spent per phase of a solve.

    Attributes:
        derivatives: Dynamics linearization and cost quadratization.
        backward: Backward passes (including box QPs and retries).
        rollouts: Initial rollout and line-search rollouts.
        total: The whole solve.
    """

    derivatives: float
    backward: float
    rollouts: float
    total: float


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


class ILQRResult(NamedTuple):
    """Result of :meth:`ILQR.solve`.

    Attributes:
        states: Optimized states ``(T + 1, nstate)``, ``states[0] = x0``.
        ctrls: Optimized controls ``(T, nu)``, inside the control bounds.
        k: Last feed-forward terms ``(T, nu)``.
        K: Last feedback gains ``(T, nu, nx)`` (acting on ``x ⊖ states[t]``).
        cost: Final total cost.
        costs: Cost after each accepted iteration, starting with the initial guess.
        iterations: Iterations performed (backward passes with fresh derivatives).
        converged: Stopped on the relative cost-decrease tolerance rather than the cap.
        regularization: The Levenberg-Marquardt :math:`\\mu` at exit.
        divergences: Rollouts that produced non-finite states or costs.
        timing: Time per phase, a :class:`Timing`.
        status: Why the solver stopped.
    """

    states: np.ndarray
    ctrls: np.ndarray
    k: np.ndarray
    K: np.ndarray
    cost: float
    costs: np.ndarray
    iterations: int
    converged: bool
    regularization: float
    divergences: int
    timing: Timing
    status: str


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


def backward_pass(
    lin: Linearization,
    quad: Quadratization,
    ctrls: np.ndarray,
    ctrl_low: np.ndarray,
    ctrl_high: np.ndarray,
    regularization: float,
    k_init: np.ndarray | None = None,
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
        vxx_b = vxx @ Bt
        qx = quad.lx[t] + At.T @ vx
        qu = quad.lu[t] + Bt.T @ vx
        qxx = quad.lxx[t] + At.T @ vxx @ At
        quu = quad.luu[t] + Bt.T @ vxx_b
        qux = quad.lux[t] + vxx_b.T @ At
        quu = 0.5 * (quu + quu.T)
        quu_reg = quu + eye
        if limited:
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


class ILQR(Controller):
    r"""Control-limited iLQR on a Problem's planning model, also usable as an MPC controller.

    Offline, :meth:`solve` optimizes a ``horizon``-knot trajectory from a start state. As a
    :class:`~mpcbox.controllers.base.Controller`, every ``replan_period`` seconds it shifts the
    previous solution in time, runs ``mpc_iterations`` iterations from the measured state,
    and in between (when ``feedback`` is on and the simulation calls it every step) applies
    :math:`u = u_i + K_i\,(x \ominus \bar x(t))` with the nominal state interpolated at the
    time elapsed since the replan.

    Args:
        problem: The Problem; its planning model (timestep ``problem.dt``) is used.
        horizon: Number of knots ``T`` (controls); the plan spans ``T * dt`` seconds with
            ``dt`` the planning timestep.
        max_iterations: Iteration cap of :meth:`solve`.
        tolerance: Stop when an accepted step lowers the cost by less than this fraction.
        mpc_iterations: Iterations per replan in receding-horizon mode.
        first_iterations: Iterations of the first replan after :meth:`reset` (no warm start
            yet); default ``mpc_iterations``.
        replan_period: Seconds between replans in receding-horizon mode.
        feedback: Apply the feedback law between replans (the controller's ``period`` is then
            ``None`` so that the simulation calls it every step); otherwise the control is
            held for ``replan_period``.
        regularization: Initial :math:`\mu`.
        regularization_min: Below this, :math:`\mu` snaps to 0.
        regularization_max: Give up (keep the current trajectory) above this.
        regularization_factor: Multiplicative step of the :math:`\mu` schedule (> 1).
        step_sizes: Line-search step sizes ``alpha`` in decreasing order, each in (0, 1].
        line_search: ``"backtracking"`` (try step sizes in order, stop at the first accepted)
            or ``"parallel"`` (roll all of them out on the Problem's thread pool and keep the
            best).
        armijo: Accept a step when the actual decrease is at least this fraction of the
            predicted one.
        max_retries: Regularization increases (after a failed backward pass or line search)
            allowed per iteration before giving up and keeping the current trajectory.
        linearize_every: Linearize the dynamics at every ``linearize_every``-th knot (and the
            last) and interpolate ``A``, ``B`` in between.
        fd_centered: Centered finite differences for the dynamics (default: the Problem's).
        ctrl_low: Lower control bounds ``(nu,)`` (default and outer limit: the Problem's).
        ctrl_high: Upper control bounds ``(nu,)``.
        ctrls_init: Initial control guess ``(T, nu)`` or ``(nu,)`` (default ``ctrl_ref``).
        threads: Threads for derivatives and parallel line search (default: the Problem's).
        planning_timestep: Plan on a copy of the Problem whose planning model has this
            timestep (:meth:`~mpcbox.Problem.with_planning_timestep`); default: ``problem.dt``.
        terminal_value: ``"lqr"`` adds the infinite-horizon LQR value function of the planning
            model at the reference (:class:`~mpcbox.core.cost.QuadraticValue` with the Riccati
            matrix ``P``) to the terminal cost, so a short horizon still sees the cost-to-go;
            ``None`` keeps the Problem's terminal cost.
    """

    name = "ilqr"

    def __init__(
        self,
        problem: Problem,
        horizon: int,
        *,
        max_iterations: int = 100,
        tolerance: float = 1e-6,
        mpc_iterations: int = 1,
        first_iterations: int | None = None,
        replan_period: float = 0.02,
        feedback: bool = True,
        regularization: float = 1e-6,
        regularization_min: float = 1e-8,
        regularization_max: float = 1e10,
        regularization_factor: float = 4.0,
        step_sizes: Sequence[float] = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01),
        line_search: str = "backtracking",
        armijo: float = 1e-4,
        max_retries: int = 20,
        linearize_every: int = 1,
        fd_centered: bool | None = None,
        ctrl_low: np.ndarray | None = None,
        ctrl_high: np.ndarray | None = None,
        ctrls_init: np.ndarray | None = None,
        threads: int | None = None,
        planning_timestep: float | None = None,
        terminal_value: str | None = None,
    ) -> None:
        if not isinstance(problem, Problem):
            raise InvalidArgumentError(
                f"problem must be an mpcbox.Problem, got {type(problem).__name__}"
            )
        if planning_timestep is not None:
            dt = positive("planning_timestep", planning_timestep)
            if abs(dt - problem.dt) > 1e-12:
                problem = problem.with_planning_timestep(dt)
        if terminal_value is not None:
            if terminal_value != "lqr":
                raise InvalidArgumentError(
                    f"terminal_value must be None or 'lqr', got {terminal_value!r}"
                )
            problem = _with_lqr_terminal_value(problem)
        self.problem = problem
        self.horizon = positive_int("horizon", horizon)
        self.max_iterations = positive_int("max_iterations", max_iterations)
        self.tolerance = positive("tolerance", tolerance)
        self.mpc_iterations = positive_int("mpc_iterations", mpc_iterations)
        self.first_iterations = (
            self.mpc_iterations
            if first_iterations is None
            else positive_int("first_iterations", first_iterations)
        )
        self.replan_period = positive("replan_period", replan_period)
        self.feedback = bool(feedback)
        self.period = None if self.feedback else self.replan_period
        if (
            isinstance(regularization, bool)
            or not np.isfinite(regularization)
            or (regularization < 0)
        ):
            raise InvalidArgumentError(
                f"regularization must be a finite number >= 0, got {regularization!r}"
            )
        self.regularization = float(regularization)
        self.regularization_min = positive("regularization_min", regularization_min)
        self.regularization_max = positive("regularization_max", regularization_max)
        if self.regularization_max <= self.regularization_min:
            raise InvalidArgumentError(
                "regularization_max must exceed regularization_min, got "
                f"{regularization_max} <= {regularization_min}"
            )
        self.regularization_factor = positive("regularization_factor", regularization_factor)
        if self.regularization_factor <= 1.0:
            raise InvalidArgumentError(
                f"regularization_factor must be > 1, got {regularization_factor}"
            )
        steps = np.asarray(step_sizes, dtype=np.float64).ravel()
        if steps.size == 0 or not np.all((steps > 0) & (steps <= 1)):
            raise InvalidArgumentError(
                f"step_sizes must be a non-empty sequence of numbers in (0, 1], got {step_sizes}"
            )
        self.step_sizes = tuple(float(s) for s in steps)
        self.line_search = one_of("line_search", line_search, ("backtracking", "parallel"))
        if not 0.0 <= armijo < 1.0:
            raise InvalidArgumentError(f"armijo must be in [0, 1), got {armijo}")
        self.armijo = float(armijo)
        self.max_retries = positive_int("max_retries", max_retries)
        self.linearize_every = positive_int("linearize_every", linearize_every)
        self.fd_centered = None if fd_centered is None else bool(fd_centered)
        self.threads = problem.threads if threads is None else positive_int("threads", threads)

        nu = problem.nu
        low = problem.ctrl_low if ctrl_low is None else as_array("ctrl_low", ctrl_low, (nu,))
        high = problem.ctrl_high if ctrl_high is None else as_array("ctrl_high", ctrl_high, (nu,))
        if np.any(np.isnan(low)) or np.any(np.isnan(high)):
            raise InvalidArgumentError("ctrl_low and ctrl_high must not hold NaN")
        if np.any(low > high):
            bad = np.flatnonzero(low > high)
            raise InvalidArgumentError(
                f"ctrl_low must be <= ctrl_high; inverted at actuators {bad.tolist()}: "
                f"ctrl_low={low[bad]}, ctrl_high={high[bad]}"
            )
        self.ctrl_low = np.maximum(low, problem.ctrl_low)
        self.ctrl_high = np.minimum(high, problem.ctrl_high)
        if np.any(self.ctrl_low > self.ctrl_high):
            raise InvalidArgumentError(
                "ctrl_low/ctrl_high do not overlap the model's ctrlrange "
                f"[{problem.ctrl_low}, {problem.ctrl_high}]"
            )
        self.ctrls_init = self._initial_ctrls(ctrls_init)

        model = problem.planning_model
        self._model = model
        self._local = threading.local()
        self._knots = np.unique(
            np.r_[np.arange(0, self.horizon, self.linearize_every), self.horizon - 1]
        )
        self.reset()

    # ------------------------------------------------------------------ helpers
    def _initial_ctrls(self, ctrls: np.ndarray | None, name: str = "ctrls_init") -> np.ndarray:
        nu, horizon = self.problem.nu, self.horizon
        if ctrls is None:
            ctrls = np.tile(self.problem.ctrl_ref, (horizon, 1))
        else:
            arr = np.asarray(ctrls, dtype=np.float64)
            ctrls = (
                np.tile(as_array(name, arr, (nu,)), (horizon, 1))
                if arr.ndim == 1
                else as_array(name, arr, (horizon, nu)).copy()
            )
        if not np.all(np.isfinite(ctrls)):
            raise InvalidArgumentError(f"{name} must be finite")
        return np.clip(ctrls, self.ctrl_low, self.ctrl_high)

    def _data(self) -> mujoco.MjData:
        data = getattr(self._local, "data", None)
        if data is None:
            data = mujoco.MjData(self._model)
            self._local.data = data
        return data

    def _deviation(self, state: np.ndarray, nominal: np.ndarray, out: np.ndarray) -> None:
        p = self.problem
        nq, nv = p.nq, p.nv
        mujoco.mj_differentiatePos(self._model, out[:nv], 1.0, nominal[:nq], state[:nq])
        out[nv:] = state[nq:] - nominal[nq:]

    def _forward(
        self,
        x0: np.ndarray,
        states: np.ndarray,
        ctrls: np.ndarray,
        k: np.ndarray,
        K: np.ndarray,
        alpha: float,
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """Closed-loop rollout with the iLQR update; returns (states, ctrls, cost)."""
        p, m = self.problem, self._model
        d = self._data()
        nq, nv, horizon = p.nq, p.nv, self.horizon
        mujoco.mj_resetData(m, d)
        new_states = np.empty_like(states)
        new_ctrls = np.empty_like(ctrls)
        sens = np.empty((1, horizon + 1, m.nsensordata))
        new_states[0] = x0
        dx = np.zeros(p.nx)
        d.qpos[:] = x0[:nq]
        d.qvel[:] = x0[nq : nq + nv]
        d.act[:] = x0[nq + nv :]
        with np.errstate(all="ignore"):
            for t in range(horizon):
                self._deviation(new_states[t], states[t], dx)
                u = np.clip(ctrls[t] + alpha * k[t] + K[t] @ dx, self.ctrl_low, self.ctrl_high)
                new_ctrls[t] = u
                d.ctrl[:] = u
                mujoco.mj_step(m, d)
                sens[0, t] = d.sensordata
                x = new_states[t + 1]
                x[:nq] = d.qpos
                x[nq : nq + nv] = d.qvel
                x[nq + nv :] = d.act
                if not np.all(np.isfinite(x)):
                    return new_states, new_ctrls, np.inf
            mujoco.mj_forward(m, d)
            sens[0, horizon] = d.sensordata
            cost = float(p.rollout_cost(Rollout(new_states[None], sens, new_ctrls[None]))[0])
        return new_states, new_ctrls, cost if np.isfinite(cost) else np.inf

    def _initial_rollout(self, x0: np.ndarray, ctrls: np.ndarray) -> tuple[np.ndarray, float]:
        roll = self.problem.rollout(x0, ctrls)
        with np.errstate(all="ignore"):
            cost = float(self.problem.rollout_cost(roll)[0])
        if not (np.all(np.isfinite(roll.states)) and np.isfinite(cost)):
            return roll.states[0], np.inf
        return roll.states[0], cost

    def _derivatives(
        self, states: np.ndarray, ctrls: np.ndarray
    ) -> tuple[Linearization, Quadratization]:
        p, knots = self.problem, self._knots
        lin = p.linearize_trajectory(
            states[knots], ctrls[knots], centered=self.fd_centered, threads=self.threads
        )
        lin = interpolate_linearization(lin.A, lin.B, knots, self.horizon)
        quad = p.quadratize_trajectory(states, ctrls, threads=self.threads)
        return lin, quad

    def _increase(self, mu: float) -> float:
        return max(self.regularization_min, mu * self.regularization_factor)

    def _decrease(self, mu: float) -> float:
        mu /= self.regularization_factor
        return mu if mu >= self.regularization_min else 0.0

    # ------------------------------------------------------------------ offline solve
    def solve(
        self,
        x0: np.ndarray,
        ctrls_init: np.ndarray | None = None,
        *,
        max_iterations: int | None = None,
        regularization: float | None = None,
    ) -> ILQRResult:
        """Optimize the ``horizon``-knot trajectory starting at ``x0``.

        Args:
            x0: Start state ``(nstate,)``.
            ctrls_init: Initial controls ``(T, nu)`` or ``(nu,)`` (default: the constructor's
                ``ctrls_init``, else ``ctrl_ref``).
            max_iterations: Overrides the iteration cap.
            regularization: Overrides the initial :math:`\\mu`.

        Returns:
            An :class:`ILQRResult`. It is returned (not raised) when the regularization limit
            is hit; ``status`` says so.

        Raises:
            ShapeError: If ``x0`` or ``ctrls_init`` has the wrong shape.
            DivergenceError: If ``x0`` is not finite or even the initial guess and ``ctrl_ref``
                roll out to non-finite states.
        """
        p = self.problem
        x0 = as_array("x0", x0, (p.nstate,))
        if not np.all(np.isfinite(x0)):
            raise DivergenceError("x0 holds non-finite values (NaN or inf)")
        ctrls = self.ctrls_init.copy() if ctrls_init is None else self._initial_ctrls(ctrls_init)
        iters = (
            self.max_iterations
            if max_iterations is None
            else positive_int("max_iterations", max_iterations)
        )
        mu = self.regularization if regularization is None else float(regularization)
        return self._optimize(x0, ctrls, iters, mu, None)

    def _optimize(
        self, x0: np.ndarray, ctrls: np.ndarray, iters: int, mu: float, k_warm: np.ndarray | None
    ) -> ILQRResult:
        p = self.problem
        t_start = _time.perf_counter()
        t_der = t_back = t_roll = 0.0
        divergences = 0

        t0 = _time.perf_counter()
        states, cost = self._initial_rollout(x0, ctrls)
        if not np.isfinite(cost):
            divergences += 1
            ctrls = np.tile(np.clip(p.ctrl_ref, self.ctrl_low, self.ctrl_high), (self.horizon, 1))
            states, cost = self._initial_rollout(x0, ctrls)
            if not np.isfinite(cost):
                raise DivergenceError(
                    "the initial guess and ctrl_ref both roll out to non-finite states or cost"
                )
        t_roll += _time.perf_counter() - t0

        costs = [cost]
        k = np.zeros((self.horizon, p.nu)) if k_warm is None else k_warm
        K = np.zeros((self.horizon, p.nu, p.nx))
        converged = False
        status = "iteration limit"
        iteration = 0
        need_derivatives = True
        lin = quad = None
        retries = 0
        while True:
            if need_derivatives:
                if iteration >= iters:
                    break
                retries = 0
                t0 = _time.perf_counter()
                lin, quad = self._derivatives(states, ctrls)
                t_der += _time.perf_counter() - t0
                need_derivatives = False
                iteration += 1
            t0 = _time.perf_counter()
            try:
                bp = backward_pass(lin, quad, ctrls, self.ctrl_low, self.ctrl_high, mu, k)
            except SolverError:
                t_back += _time.perf_counter() - t0
                mu = self._increase(mu)
                retries += 1
                if mu > self.regularization_max or retries > self.max_retries:
                    status = "regularization limit (backward pass)"
                    break
                continue
            t_back += _time.perf_counter() - t0
            k, K = bp.k, bp.K
            dv1, dv2 = bp.expected
            if -(dv1 + dv2) <= 1e-12 * max(1.0, abs(cost)):
                converged = True
                status = "converged (no predicted decrease)"
                break

            t0 = _time.perf_counter()
            accepted, new, n_div, alpha = self._line_search(x0, states, ctrls, k, K, cost, dv1, dv2)
            t_roll += _time.perf_counter() - t0
            divergences += n_div
            if not accepted:
                mu = self._increase(mu)
                retries += 1
                if mu > self.regularization_max or retries > self.max_retries:
                    status = "regularization limit (line search)"
                    break
                continue
            new_states, new_ctrls, new_cost = new
            decrease = cost - new_cost
            states, ctrls, cost = new_states, new_ctrls, new_cost
            costs.append(cost)
            need_derivatives = True
            # Trust the quadratic model more after full steps and less after short ones.
            if alpha >= 0.5:
                mu = self._decrease(mu)
            elif alpha < 0.2:
                mu = self._increase(mu)
            if decrease < self.tolerance * max(abs(cost), 1e-12):
                converged = True
                status = "converged (relative decrease)"
                break
        total = _time.perf_counter() - t_start
        return ILQRResult(
            states=states,
            ctrls=ctrls,
            k=k,
            K=K,
            cost=float(cost),
            costs=np.asarray(costs),
            iterations=iteration,
            converged=converged,
            regularization=float(mu),
            divergences=divergences,
            timing=Timing(t_der, t_back, t_roll, total),
            status=status,
        )

    def _line_search(self, x0, states, ctrls, k, K, cost, dv1, dv2):
        """(accepted, (states, ctrls, cost) or None, divergent rollouts, step size)."""

        def accept(alpha: float, new_cost: float) -> bool:
            expected = -(alpha * dv1 + alpha**2 * dv2)
            actual = cost - new_cost
            return np.isfinite(new_cost) and actual > 0 and actual >= self.armijo * expected

        n_div = 0
        if self.line_search == "backtracking" or self.threads == 1:
            for alpha in self.step_sizes:
                new = self._forward(x0, states, ctrls, k, K, alpha)
                if not np.isfinite(new[2]):
                    n_div += 1
                    continue
                if accept(alpha, new[2]):
                    return True, new, n_div, alpha
            return False, None, n_div, 0.0
        pool = self.problem.executor()
        outs = list(pool.map(lambda a: self._forward(x0, states, ctrls, k, K, a), self.step_sizes))
        n_div = sum(not np.isfinite(o[2]) for o in outs)
        ok = [(o[2], a, o) for a, o in zip(self.step_sizes, outs) if accept(a, o[2])]
        if not ok:
            return False, None, n_div, 0.0
        _, alpha, best = min(ok, key=lambda item: item[0])
        return True, best, n_div, alpha

    # ------------------------------------------------------------------ receding horizon
    def reset(self) -> None:
        """Forget the warm start and counters."""
        self._plan: ILQRResult | None = None
        self._plan_time = 0.0
        self._mu = self.regularization
        self._counts = {
            "replans": 0,
            "iterations": 0,
            "divergences": 0,
            "fallbacks": 0,
            "converged": 0,
        }
        self._last_timing = Timing(0.0, 0.0, 0.0, 0.0)
        self._last_ctrl = np.clip(self.problem.ctrl_ref, self.ctrl_low, self.ctrl_high)

    @property
    def plan(self) -> ILQRResult | None:
        """The current receding-horizon plan (``None`` before the first call)."""
        return self._plan

    @property
    def stats(self) -> dict[str, float]:
        """Counters: replans, iterations, divergences, fallbacks, and the current mu."""
        out = {key: float(val) for key, val in self._counts.items()}
        out["regularization"] = float(self._mu)
        return out

    def _shifted_ctrls(self, time: float) -> np.ndarray:
        plan, dt = self._plan, self.problem.dt
        if plan is None:
            return self.ctrls_init.copy()
        old_t = self._plan_time + dt * np.arange(self.horizon)
        new_t = time + dt * np.arange(self.horizon)
        out = np.empty_like(plan.ctrls)
        for j in range(plan.ctrls.shape[1]):
            out[:, j] = np.interp(new_t, old_t, plan.ctrls[:, j])
        return out

    def _feedback(self, state: np.ndarray, time: float) -> np.ndarray:
        plan, dt, p = self._plan, self.problem.dt, self.problem
        assert plan is not None
        s = max(0.0, (time - self._plan_time) / dt)
        i = min(int(s), self.horizon - 1)
        frac = min(s - i, 1.0)
        nominal = plan.states[i]
        if frac > 0:
            step = np.zeros(p.nx)
            self._deviation(plan.states[i + 1], nominal, step)
            nominal = p.state_add(nominal, frac * step)
        dx = np.zeros(p.nx)
        self._deviation(state, nominal, dx)
        u = plan.ctrls[i] + plan.K[i] @ dx
        if not np.all(np.isfinite(u)):
            return plan.ctrls[i].copy()
        return np.clip(u, self.ctrl_low, self.ctrl_high)

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """MPC step: replan every ``replan_period``, otherwise apply the feedback law.

        Never raises on numerical trouble: a failed replan keeps the previous plan (or
        ``ctrl_ref``) and counts a fallback.
        """
        state = as_array("state", state, (self.problem.nstate,))
        if self._plan is not None and time < self._plan_time - 1e-9:
            self.reset()  # a new simulation started
        due = self._plan is None or time - self._plan_time >= self.replan_period - 1e-9
        if not np.all(np.isfinite(state)):
            self._counts["fallbacks"] += 1
            return self._last_ctrl.copy()
        if due:
            warm = self._shifted_ctrls(time)
            iters = self.mpc_iterations if self._plan is not None else self.first_iterations
            try:
                result = self._optimize(state, warm, iters, self._mu, None)
            except MpcboxError:
                result = None
            if result is None:
                self._counts["fallbacks"] += 1
                self._mu = min(self._increase(self._mu), self.regularization_max)
            else:
                if result.status.startswith("regularization limit"):
                    self._counts["fallbacks"] += 1
                self._plan = result
                self._plan_time = float(time)
                self._mu = min(result.regularization, self.regularization_max)
                self._counts["replans"] += 1
                self._counts["iterations"] += result.iterations
                self._counts["divergences"] += result.divergences
                self._counts["converged"] += int(result.converged)
                self._last_timing = result.timing
        if self._plan is None:
            ctrl = self._last_ctrl.copy()
        else:
            ctrl = self._feedback(state, time)
        self._last_ctrl = ctrl
        return ctrl


__all__ = [
    "ILQR",
    "BackwardPass",
    "ILQRResult",
    "Timing",
    "backward_pass",
    "interpolate_linearization",
]


def _with_lqr_terminal_value(problem: Problem) -> Problem:
    """``problem`` with the LQR value function at its reference added to the terminal cost."""
    from mpcbox.controllers.lqr import LQR, nearest_psd
    from mpcbox.core.cost import Cost, QuadraticValue

    lqr = LQR(problem)
    value = QuadraticValue(
        problem.qpos_ref, problem.qvel_ref, P=nearest_psd(lqr.P), name="lqr_value"
    )
    return problem.with_cost(Cost(problem.cost.running, [*problem.cost.terminal, value]))
