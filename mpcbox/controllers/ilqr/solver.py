r"""Offline iLQR: iterate backward and forward passes from a start state until a stop criterion.

Each iteration linearizes the planning model and quadratizes the cost along the current
trajectory, runs the :mod:`~mpcbox.controllers.ilqr.backward_pass` and then the line search of
the :mod:`~mpcbox.controllers.ilqr.forward_pass`. The Levenberg-Marquardt term :math:`\mu` (the
``regularization``) grows when the backward pass meets a non-definite :math:`Q_{uu}` or no
step size works, and moves after accepted steps as the config's schedule says
(:mod:`~mpcbox.controllers.ilqr.regularization`); the result says why the iterations
stopped (:class:`~mpcbox.controllers.ilqr.result.StopReason`).
"""

from __future__ import annotations

import time as _time
from typing import Any

import numpy as np

from mpcbox.config import resolve_config
from mpcbox.controllers.base import check_problem
from mpcbox.controllers.ilqr.backward_pass import (
    BackwardPass,
    DynamicsBlocks,
    backward_pass,
    dynamics_blocks,
    interpolate_linearization,
)
from mpcbox.controllers.ilqr.bounds import control_bounds
from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.forward_pass import Candidate, ClosedLoopRollout, line_search
from mpcbox.controllers.ilqr.held_controls import compose_held, held_steps, scale_running
from mpcbox.controllers.ilqr.multiple_shooting import optimize_multiple_shooting
from mpcbox.controllers.ilqr.reference_model import (
    constant_hessians,
    hessians_at_reference,
    linearization_at_reference,
)
from mpcbox.controllers.ilqr.regularization import Regularization
from mpcbox.controllers.ilqr.result import ILQRResult, StopReason, Timing
from mpcbox.controllers.ilqr.riccati_cache import RiccatiCache
from mpcbox.controllers.ilqr.saddle import descent_probe
from mpcbox.controllers.lqr import with_lqr_terminal_value
from mpcbox.core.blas_threads import single_blas_thread
from mpcbox.core.divergence import check_planning_step
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.core.problem import Linearization, Problem, Quadratization
from mpcbox.errors import DivergenceError, InvalidArgumentError, SolverError
from mpcbox.validation import as_array, finite_array, positive_int


class ILQRSolver:
    """Control-limited iLQR on a Problem's planning model: offline trajectory optimization.

    Args:
        problem: The Problem; its planning model (timestep ``problem.dt``) is used.
        config: An :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` (default: its
            defaults).
        **options: Fields of :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` that replace
            those of ``config``, e.g. ``horizon=100``.

    Attributes:
        problem: The Problem planned on (a copy with another planning timestep or terminal
            cost when ``planning_timestep`` or ``terminal_value`` ask for one).
        config: The resolved config.
        horizon: Number of knots ``T``.
        ctrl_low: Lower control bounds ``(nu,)``, inside the Problem's.
        ctrl_high: Upper control bounds ``(nu,)``.
        ctrls_init: The config's initial guess ``(T, nu)`` (see :meth:`default_ctrls`).
        states_init: Default state guess ``(T + 1, nstate)`` or ``None`` (single shooting).
        threads: Threads for derivatives and the parallel line search.

    Raises:
        InvalidTypeError: If ``problem`` is not a Problem or ``config`` not an ILQRConfig.
        UnknownOptionError: For an option that is not a config field; it lists the valid ones.
        InvalidArgumentError: Naming the option, for a value out of range.
        ShapeError: If ``ctrl_low``, ``ctrl_high``, ``ctrls_init`` or ``states_init`` has the
            wrong shape.
        PlanningDivergenceError: If the planning model diverges at its timestep
            (:func:`~mpcbox.core.divergence.check_planning_step`).
    """

    #: The config dataclass of the options.
    config_class: type | None = ILQRConfig

    def __init__(self, problem: Problem, config: ILQRConfig | None = None, **options: Any) -> None:
        owner = type(self).__name__
        problem = check_problem(problem, owner)
        cfg = resolve_config(ILQRConfig, config, options, owner)
        if cfg.planning_timestep is not None and abs(cfg.planning_timestep - problem.dt) > 1e-12:
            problem = problem.with_planning_timestep(cfg.planning_timestep)
        else:
            check_planning_step(problem)  # the copy above was checked when it was made
        if cfg.dry_friction is not None:  # before the terminal value, which it changes
            problem = problem.with_dry_friction(cfg.dry_friction)
        if cfg.terminal_value == "lqr":
            problem = with_lqr_terminal_value(problem)
        self.problem = problem
        self.config = cfg
        self.horizon = cfg.horizon
        self.threads = problem.threads if cfg.threads is None else cfg.threads
        self.ctrl_low, self.ctrl_high = control_bounds(problem, cfg)
        self._ctrls_init = self._initial_ctrls(cfg.ctrls_init)
        self._guess_given = cfg.ctrls_init is not None
        self.states_init = (
            None if cfg.states_init is None else self._initial_states(cfg.states_init)
        )
        self.steps = cfg.control_steps
        self._rollout = ClosedLoopRollout(problem, self.ctrl_low, self.ctrl_high, self.steps)
        self._knots = np.unique(
            np.r_[np.arange(0, self.horizon, cfg.linearize_every), self.horizon - 1]
        )
        ctrl_ref = np.clip(problem.ctrl_ref, self.ctrl_low, self.ctrl_high)
        self._reference_lin = (
            None
            if cfg.linearization == "trajectory"
            else linearization_at_reference(
                problem, ctrl_ref, self.horizon, self.steps, cfg.fd_centered
            )
        )
        self._reference_blocks = (
            None if self._reference_lin is None else dynamics_blocks(self._reference_lin)
        )
        self._reference_hessians = (
            hessians_at_reference(problem, ctrl_ref, self.horizon, self.steps)
            if cfg.cost_hessian == "reference"
            else None
        )
        #: The backward pass's matrices, kept when the dynamics and cost Hessians repeat.
        repeat = self._reference_hessians is not None or constant_hessians(problem)
        self.riccati_cache = RiccatiCache() if self._reference_lin is not None and repeat else None

    @property
    def knot_dt(self) -> float:
        """Seconds between knots: ``control_steps`` steps of the planning model."""
        return self.steps * self.problem.dt

    @property
    def ctrls_init(self) -> np.ndarray:
        """The guess ``(T, nu)`` of the config's ``ctrls_init`` (``ctrl_ref`` without one).

        Assigning it makes it the guess of every later solve without one given; otherwise
        :meth:`default_ctrls` asks the Problem for a guess from each start state.
        """
        return self._ctrls_init

    @ctrls_init.setter
    def ctrls_init(self, value: np.ndarray) -> None:
        self._ctrls_init = self._initial_ctrls(value)
        self._guess_given = True

    def default_ctrls(self, x0: np.ndarray) -> np.ndarray:
        """The initial guess ``(T, nu)`` of a solve from ``x0`` that is given none: the
        config's (or an assigned) ``ctrls_init``, else the Problem's
        :meth:`~mpcbox.Problem.initial_ctrls` (``ctrl_ref`` unless the task chooses better),
        within the bounds."""
        if self._guess_given:
            return self._ctrls_init.copy()
        # Asked per model step, read at the knots (a task's guess may vary in time).
        guess = self.problem.initial_ctrls(x0, self.horizon * self.steps)[:: self.steps]
        return self._initial_ctrls(guess)

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

    def _initial_states(self, states: np.ndarray) -> np.ndarray:
        shape = (self.horizon + 1, self.problem.nstate)
        return finite_array("states_init", states, shape).copy()

    def _forward(
        self,
        x0: np.ndarray,
        states: np.ndarray,
        ctrls: np.ndarray,
        k: np.ndarray,
        K: np.ndarray,
        alpha: float,
    ) -> Candidate:
        """Closed-loop rollout with the iLQR update; returns (states, ctrls, cost)."""
        return self._rollout(x0, states, ctrls, k, K, alpha)

    def _initial_rollout(self, x0: np.ndarray, ctrls: np.ndarray) -> tuple[np.ndarray, float]:
        roll = self.problem.rollout(x0, held_steps(ctrls, self.steps))
        with np.errstate(all="ignore"):
            cost = float(self.problem.rollout_cost(roll)[0])
        states = roll.states[0, :: self.steps]
        if not (np.all(np.isfinite(roll.states)) and np.isfinite(cost)):
            return states, np.inf
        return states, cost

    def _derivatives(
        self, states: np.ndarray, ctrls: np.ndarray
    ) -> tuple[Linearization, Quadratization]:
        p, knots = self.problem, self._knots
        if self._reference_lin is not None:
            lin = self._reference_lin
        else:
            lin = p.linearize_trajectory(
                states[knots], ctrls[knots], centered=self.config.fd_centered, threads=self.threads
            )
            lin = compose_held(lin, self.steps)
            lin = interpolate_linearization(lin.A, lin.B, knots, self.horizon)
        own = self._reference_hessians is None  # else the knots' Hessians go unused
        quad = p.quadratize_trajectory(states, ctrls, threads=self.threads, hessians=own)
        quad = scale_running(quad, self.steps)
        if not own:
            lxx, luu, lux = self._reference_hessians
            quad = quad._replace(lxx=lxx, luu=luu, lux=lux)
        return lin, quad

    def _blocks(self, lin: Linearization) -> DynamicsBlocks:
        """The backward pass's blocks of ``lin``: kept for the solver's life when the dynamics
        are linearized only at the reference."""
        if self._reference_blocks is not None and lin is self._reference_lin:
            return self._reference_blocks
        return dynamics_blocks(lin)

    def _backward(
        self,
        lin: Linearization,
        quad: Quadratization,
        ctrls: np.ndarray,
        mu: float,
        k: np.ndarray,
        blocks: DynamicsBlocks | None,
    ) -> BackwardPass:
        """:func:`backward_pass` within the solver's bounds, with its Riccati cache."""
        low, high, cache = self.ctrl_low, self.ctrl_high, self.riccati_cache
        return backward_pass(lin, quad, ctrls, low, high, mu, k, blocks=blocks, cache=cache)

    def _schedule(self, value: float) -> Regularization:
        """The regularization of one solve, starting at ``value``, on the config's schedule."""
        cfg = self.config
        return Regularization(
            value, cfg.regularization_schedule, cfg.regularization_factor, cfg.regularization_min
        )

    # ------------------------------------------------------------------ offline solve
    def solve(
        self,
        x0: np.ndarray,
        ctrls_init: np.ndarray | None = None,
        *,
        states_init: np.ndarray | None = None,
        max_iterations: int | None = None,
        regularization: float | None = None,
    ) -> ILQRResult:
        """Optimize the ``horizon``-knot trajectory starting at ``x0``.

        Args:
            x0: Start state ``(nstate,)``.
            ctrls_init: Initial controls ``(T, nu)`` or ``(nu,)`` (default:
                :meth:`default_ctrls`).
            states_init: State guess ``(T + 1, nstate)`` (default: the config's
                ``states_init``): solve by multiple shooting
                (:func:`~mpcbox.controllers.ilqr.multiple_shooting.optimize_multiple_shooting`);
                ``states_init[0]`` is replaced by ``x0``. ``None``: single shooting.
            max_iterations: Overrides the iteration cap.
            regularization: Overrides the initial :math:`\\mu`.

        Returns:
            An :class:`~mpcbox.controllers.ilqr.result.ILQRResult`. It is returned (not
            raised) when the solver stalls; ``stop_reason`` says why it stopped.

        Raises:
            ShapeError: If ``x0``, ``ctrls_init`` or ``states_init`` has the wrong shape.
            DivergenceError: If ``x0`` is not finite or even the initial guess and ``ctrl_ref``
                roll out to non-finite states.
        """
        p = self.problem
        x0 = as_array("x0", x0, (p.nstate,))
        if not np.all(np.isfinite(x0)):
            raise DivergenceError("x0 holds non-finite values (NaN or inf)")
        ctrls = self.default_ctrls(x0) if ctrls_init is None else self._initial_ctrls(ctrls_init)
        iters = (
            self.config.max_iterations
            if max_iterations is None
            else positive_int("max_iterations", max_iterations)
        )
        reg = self.config.regularization if regularization is None else float(regularization)
        states = self.states_init if states_init is None else self._initial_states(states_init)
        if states is not None and self.steps > 1:
            raise InvalidArgumentError(
                f"states_init: control_steps={self.steps} works with single shooting only"
            )
        # Diverged rollouts are counted (``divergences``); MuJoCo's warnings are not printed.
        # One BLAS thread: the small products compete with the derivative threads otherwise.
        with captured_warnings(), single_blas_thread():
            if states is None:
                return self._optimize(x0, ctrls, iters, reg, None)
            return optimize_multiple_shooting(self, x0, states, ctrls, iters, reg)

    def _optimize(
        self,
        x0: np.ndarray,
        ctrls: np.ndarray,
        iters: int,
        reg: float | Regularization,
        k_warm: np.ndarray | None,
        max_retries: int | None = None,
        policy: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> ILQRResult:
        """The iterations from ``ctrls`` ``(T, nu)``, rolled out open loop, or under the
        feedback law of ``policy`` = (states ``(T + 1, nstate)``, gains ``(T, nu, nx)``)
        around them (the controller's warm start, ``warm_start_feedback``)."""
        p, cfg = self.problem, self.config
        max_retries = cfg.max_retries if max_retries is None else max_retries
        mu = reg if isinstance(reg, Regularization) else self._schedule(reg)
        mu_start, gains_mu, gains_ctrls = mu.value, mu.value, ctrls
        t_start = _time.perf_counter()
        t_der = t_back = t_roll = 0.0
        divergences = 0

        t0 = _time.perf_counter()
        start = "guess"
        if policy is not None:
            states, closed, cost = self._rollout(x0, policy[0], ctrls, 0 * ctrls, policy[1], 0.0)
            if np.isfinite(cost):
                ctrls, start = closed, "policy"
            else:
                divergences += 1
        if policy is None or not np.isfinite(cost):
            states, cost = self._initial_rollout(x0, ctrls)
        if not np.isfinite(cost):
            divergences += 1
            start = "ctrl_ref"
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
        reason, status = StopReason.ITERATION_LIMIT, "iteration limit"
        iteration = 0
        need_derivatives = True
        lin = quad = blocks = None
        retries = 0
        pool = p.executor() if cfg.line_search == "parallel" and self.threads != 1 else None
        full_step = max(cfg.step_sizes)
        while True:
            if need_derivatives:
                if iteration >= iters:
                    break
                retries = 0
                t0 = _time.perf_counter()
                lin, quad = self._derivatives(states, ctrls)
                blocks = self._blocks(lin)
                t_der += _time.perf_counter() - t0
                need_derivatives = False
                iteration += 1
            t0 = _time.perf_counter()
            try:
                bp = self._backward(lin, quad, ctrls, mu.value, k, blocks)
            except SolverError:
                t_back += _time.perf_counter() - t0
                mu.increase()
                retries += 1
                if mu.value > cfg.regularization_max or retries > max_retries:
                    reason = self._stall_reason(mu.value, diverged=False)
                    status = f"{reason.value} (backward pass)"
                    break
                continue
            t_back += _time.perf_counter() - t0
            k, K = bp.k, bp.K
            gains_mu, gains_ctrls = mu.value, ctrls
            dv1, dv2 = bp.expected
            if -(dv1 + dv2) <= 1e-12 * max(1.0, abs(cost)):
                t0 = _time.perf_counter()
                if descent_probe(
                    lambda c: self._initial_rollout(x0, c)[1],
                    ctrls,
                    self.ctrl_low,
                    self.ctrl_high,
                    cost,
                ):
                    reason = StopReason.SADDLE
                    status = (
                        "saddle (no predicted decrease, but a small change of the controls "
                        "lowers the cost: start from an initial guess that moves)"
                    )
                else:
                    reason = StopReason.NO_PREDICTED_DECREASE
                    status = "converged (no predicted decrease)"
                t_roll += _time.perf_counter() - t0
                break

            t0 = _time.perf_counter()
            ls = line_search(
                lambda a: self._forward(x0, states, ctrls, k, K, a),  # noqa: B023
                cfg.step_sizes,
                cost,
                bp.expected,
                cfg.armijo,
                pool,
            )
            t_roll += _time.perf_counter() - t0
            divergences += ls.divergences
            if ls.candidate is None:
                mu.increase()
                retries += 1
                if mu.value > cfg.regularization_max or retries > max_retries:
                    reason = self._stall_reason(mu.value, diverged=ls.all_diverged)
                    status = f"{reason.value} (line search)"
                    break
                continue
            new_states, new_ctrls, new_cost = ls.candidate
            decrease = cost - new_cost
            states, ctrls, cost = new_states, new_ctrls, new_cost
            costs.append(cost)
            need_derivatives = True
            mu.accepted(ls.alpha)  # the schedule (regularization module)
            # Stop on a small decrease only if the model predicts a small one too: a small
            # decrease under a large prediction is a poor model (a kink, a short step).
            small = cfg.tolerance * max(abs(cost), 1e-12)
            if decrease < small and -(dv1 + dv2) < small:
                if ls.alpha >= full_step:
                    reason, status = StopReason.COST_CHANGE, "converged (relative decrease)"
                else:
                    reason = StopReason.SHORT_STEP
                    status = f"short step (relative decrease below tolerance at alpha={ls.alpha})"
                break
        if gains_mu > mu_start and lin is not None and quad is not None:
            K = self._gains_at(lin, quad, gains_ctrls, mu_start, k, K, blocks)
        total = _time.perf_counter() - t_start
        return ILQRResult(
            states=states,
            ctrls=ctrls,
            k=k,
            K=K,
            cost=float(cost),
            costs=np.asarray(costs),
            iterations=iteration,
            converged=reason.converged,
            regularization=float(mu.value),
            divergences=divergences,
            timing=Timing(t_der, t_back, t_roll, total),
            status=status,
            stop_reason=reason,
            start=start,
        )

    def _gains_at(
        self,
        lin: Linearization,
        quad: Quadratization,
        ctrls: np.ndarray,
        regularization: float,
        k: np.ndarray,
        K: np.ndarray,
        blocks: DynamicsBlocks | None = None,
    ) -> np.ndarray:
        r"""Feedback gains ``(T, nu, nx)`` of the last linearization at the solve's starting
        :math:`\mu`, or ``K`` if that backward pass fails.

        The line search raises :math:`\mu` until a step is accepted (or gives up); the
        gains of that backward pass shrink toward zero as :math:`\mu` grows (about
        :math:`-Q_{ux}/\mu`), and a receding-horizon controller applies them until the next
        replan. The feedback law is the Riccati gain of the model, not a step-size device.
        """
        try:
            bp = self._backward(lin, quad, ctrls, regularization, k, blocks)
        except SolverError:
            return K
        return bp.K

    def _stall_reason(self, regularization: float, diverged: bool) -> StopReason:
        if diverged:
            return StopReason.DIVERGED
        if regularization > self.config.regularization_max:
            return StopReason.REGULARIZATION_LIMIT
        return StopReason.RETRY_LIMIT


__all__ = ["ILQRSolver"]
