r"""iLQR as a receding-horizon controller: replan from the measured state, feedback in between.

Every ``replan_period`` seconds the controller shifts the previous solution in time, runs
``mpc_iterations`` iterations of :class:`~mpcbox.controllers.ilqr.solver.ILQRSolver` from the
measured state (the first from the config's ``states_init`` by multiple shooting when given,
and every one from the shifted plan's states too when ``warm_start_states`` is on), and in
between (when ``feedback`` is on and the simulation calls it every step) applies
:math:`u = u_i + K_i\,(x \ominus \bar x(t))` with the nominal state interpolated at the
time elapsed since the replan.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.multiple_shooting import optimize_multiple_shooting
from mpcbox.controllers.ilqr.policy import FeedbackPolicy
from mpcbox.controllers.ilqr.result import ILQRResult, Timing
from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.core.blas_threads import single_blas_thread
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.core.problem import Problem
from mpcbox.errors import MpcboxError
from mpcbox.validation import finite


class ILQR(ILQRSolver, Controller):
    r"""Control-limited iLQR on a Problem's planning model, also usable as an MPC controller.

    Offline, :meth:`solve` optimizes a ``horizon``-knot trajectory from a start state (see
    :class:`~mpcbox.controllers.ilqr.solver.ILQRSolver`). As a
    :class:`~mpcbox.controllers.base.Controller` it replans every ``replan_period`` seconds
    and applies the feedback law in between (see the module docstring). The options are the
    fields of :class:`~mpcbox.controllers.ilqr.config.ILQRConfig`.

    Each replan starts from the smaller of the configured ``regularization`` and the last
    replan's final :math:`\mu`, and its feedback gains are those of its last linearization
    at that starting :math:`\mu` (:class:`~mpcbox.controllers.ilqr.result.ILQRResult`), so
    a :math:`\mu` raised by failed line searches weakens neither this plan's gains nor the
    next replan's. Carried over, a replan that stalled at ``regularization_max`` left every
    later one to start there and stall too, with gains near zero (on Menagerie's G1 with
    the reference linearization, 107 stalled replans of 192 and a fall within 4 s).

    With ``control_steps > 1`` the feedback law is applied as the plan assumes it: at the
    start of each knot :math:`u = \bar u_k + K_k (x \ominus \bar x_k)`, held for the knot's
    ``control_steps`` model steps. The knot's gain is designed for the held block; applied
    at every model step it acts ``control_steps`` times as often and destabilized Kinova's
    Gen3, whose stiff servos act within a few milliseconds (1.2 m from the target at 2 s).

    Args:
        problem: The Problem; its planning model (timestep ``problem.dt``) is used.
        config: An :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` (default: its
            defaults, which work for any Problem).
        **options: Config fields that replace those of ``config``, e.g.
            ``ILQR(problem, horizon=100, planning_timestep=0.02)``.

    Raises:
        InvalidTypeError: If ``problem`` is not a Problem or ``config`` not an ILQRConfig.
        UnknownOptionError: For an option that is not a config field; it lists the valid ones.
        InvalidArgumentError: Naming the option, for a value out of range.
    """

    name = "ilqr"
    config_class = ILQRConfig

    def __init__(self, problem: Problem, config: ILQRConfig | None = None, **options: Any) -> None:
        super().__init__(problem, config, **options)
        self.replan_period = self.config.replan_period
        plan = self.horizon * self.knot_dt
        if self.replan_period > plan * (1 + 1e-9):
            warnings.warn(
                f"replan_period {self.replan_period:g} s is longer than the plan (horizon "
                f"{self.horizon} x {self.knot_dt:g} s = {plan:g} s): as MPC, the last "
                "knot's control and gain are held until the next replan",
                UserWarning,
                stacklevel=2,
            )
        self.period = None if self.config.feedback else self.replan_period
        self.reset()

    def reset(self) -> None:
        """Forget the warm start, the counters and the backward passes kept, so that a run
        after it repeats the first run after the controller was built."""
        if self.riccati_cache is not None:
            self.riccati_cache.clear()
        self._last_result: ILQRResult | None = None
        self._plan_time = 0.0
        self._regularization = self.config.regularization
        self._counts = {
            "replans": 0,
            "iterations": 0,
            "divergences": 0,
            "fallbacks": 0,
            "stalled": 0,
            "converged": 0,
        }
        self._last_timing = Timing(0.0, 0.0, 0.0, 0.0)
        self._last_ctrl = np.clip(self.problem.ctrl_ref, self.ctrl_low, self.ctrl_high)
        self._policy: FeedbackPolicy | None = None

    @property
    def last_result(self) -> ILQRResult | None:
        """The solve of the last successful replan, the current plan (``None`` before one)."""
        return self._last_result

    @property
    def stats(self) -> dict[str, float]:
        """Counters and the current regularization.

        ``replans``, ``iterations`` and ``divergences`` (diverged rollouts); ``fallbacks``:
        calls that kept the previous plan (a failed replan, a non-finite state, or a replan
        that stalled before accepting a step from an open-loop warm start); ``stalled``:
        replans that stopped on a stall
        (:attr:`~mpcbox.controllers.ilqr.result.StopReason.stalled`), whether or not an
        earlier iteration of theirs improved the plan; ``converged``: converged replans."""
        out = {key: float(val) for key, val in self._counts.items()}
        out["regularization"] = float(self._regularization)
        return out

    def _shifted_ctrls(self, time: float, state: np.ndarray) -> np.ndarray:
        plan, dt = self._last_result, self.knot_dt
        if plan is None:
            return self.default_ctrls(state)
        old_t = self._plan_time + dt * np.arange(self.horizon)
        new_t = time + dt * np.arange(self.horizon)
        out = np.empty_like(plan.ctrls)
        for j in range(plan.ctrls.shape[1]):
            out[:, j] = np.interp(new_t, old_t, plan.ctrls[:, j])
        return out

    def _shifted_indices(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Indices of the plan's knots ``(T,)`` and states ``(T + 1,)`` shifted by the whole
        knots elapsed since it was made, each clamped to the last."""
        shift = round((time - self._plan_time) / self.knot_dt)
        knots = np.minimum(np.arange(self.horizon) + shift, self.horizon - 1)
        nodes = np.minimum(np.arange(self.horizon + 1) + shift, self.horizon)
        return knots, nodes

    def _shifted_states(self, time: float, state: np.ndarray) -> np.ndarray:
        """The plan's states shifted by the whole knots elapsed, padded with its last state;
        the first is the measured ``state``."""
        plan = self._last_result
        assert plan is not None
        out = plan.states[self._shifted_indices(time)[1]].copy()
        out[0] = state
        return out

    def _shifted_policy(self, time: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The plan's controls ``(T, nu)`` and its (states ``(T + 1, nstate)``, gains
        ``(T, nu, nx)``) shifted by the whole knots elapsed since it was made, each padded
        with its last entry: the feedback law the world has been executing, continued."""
        plan = self._last_result
        assert plan is not None
        knots, nodes = self._shifted_indices(time)
        return plan.ctrls[knots], (plan.states[nodes], plan.K[knots])

    def policy(self) -> FeedbackPolicy | None:
        """The feedback law of the current plan, as an object of its own:
        :func:`mpcbox.simulate_realtime` evaluates it in the world's thread at every step
        while the next replan runs (:mod:`~mpcbox.controllers.ilqr.policy`). ``None`` before
        the first plan and with ``feedback=False`` (the replan's control is then held)."""
        return self._policy if self.config.feedback else None

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """MPC step: replan every ``replan_period``, otherwise apply the feedback law.

        A state holding NaN or infinity is a :class:`~mpcbox.DivergenceError` (the world
        diverged; as every controller reports it). Otherwise it never raises on numerical
        trouble in the planner: a failed replan keeps the previous plan (or
        ``ctrl_ref``) and counts a fallback. A replan that stalled
        (``stop_reason.stalled``) is used and counted in ``stats["stalled"]``; it counts a
        fallback too only when it stalled before accepting a step from the previous plan's
        controls rolled out open loop (``warm_start_feedback=False``, the default). From the
        previous plan's feedback law rolled out from the measured state
        (``warm_start_feedback=True``), such a replan keeps that law, as LQR keeps its gain: a
        stall, not a fallback (on
        Menagerie's Robotis OP3 and Talos with position servos most replans find no step
        that improves on it, and the robots stand as LQR stands them, tilt RMS 0.3-0.8
        deg). One that improved the plan in an
        iteration and stalled in the next is not a fallback (with ``mpc_iterations=2`` a
        second iteration stalls on most replans of a standing ANYmal B, whose first
        accepted a step: counted as fallbacks, 124-128 of 150 replans had read as a
        degraded run of a robot that stood).
        """
        cfg = self.config
        state = self.problem.check_state(state)
        time = finite("time", time)
        if self._last_result is not None and time < self._plan_time - 1e-9:
            self.reset()  # a new simulation started
        due = self._last_result is None or time - self._plan_time >= self.replan_period - 1e-9
        self.last_call = "solve" if due else "hold"
        if due:
            warm = self._shifted_ctrls(time, state)
            first = self._last_result is None
            iters = cfg.effective_first_iterations if first else cfg.mpc_iterations
            retries = cfg.max_retries if first else cfg.effective_mpc_max_retries
            if first and iters > cfg.mpc_iterations:
                self.last_call = "offline"  # the warm-up solve a real robot does beforehand
            if first:
                guess = self.states_init
            else:
                guess = self._shifted_states(time, state) if cfg.warm_start_states else None
            # BLAS keeps to one thread (mpcbox.core.blas_threads), entered outside the
            # try: a bad MPCBOX_PLANNER_BLAS_THREADS is the user's error to see, not a
            # failed replan to count as a fallback.
            with single_blas_thread():
                try:
                    # MuJoCo's warnings of diverged rollouts are counted
                    # (result.divergences), not printed.
                    rolled_law = guess is None and not first and cfg.warm_start_feedback
                    with captured_warnings():
                        if rolled_law:
                            warm, policy = self._shifted_policy(time)
                            result = self._optimize(
                                state, warm, iters, self._regularization, None, retries, policy
                            )
                        elif guess is None:
                            result = self._optimize(
                                state, warm, iters, self._regularization, None, retries
                            )
                        else:
                            result = optimize_multiple_shooting(
                                self, state, guess, warm, iters, self._regularization, retries
                            )
                except MpcboxError:
                    result = None
            if result is None:
                self._counts["fallbacks"] += 1
            else:
                if result.stop_reason.stalled:
                    self._counts["stalled"] += 1
                    # Stalled before any step was accepted: the plan is the previous one's
                    # controls (a fallback), or its feedback law rolled out from the
                    # measured state (``warm_start_feedback``: what LQR would do, counted
                    # as a stall only, unless that rollout diverged and the solver
                    # started from the controls after all).
                    if len(result.costs) == 1 and result.start != "policy":
                        self._counts["fallbacks"] += 1
                self._last_result = result
                self._plan_time = float(time)
                self._policy = FeedbackPolicy(
                    result.states,
                    result.ctrls,
                    result.K,
                    self._plan_time,
                    self.knot_dt,
                    self.steps,
                    self.ctrl_low,
                    self.ctrl_high,
                    self._rollout.deviation,
                    self.problem.state_add,
                )
                # A decrease carries over, an increase does not (see the class docstring).
                self._regularization = min(result.regularization, cfg.regularization)
                self._counts["replans"] += 1
                self._counts["iterations"] += result.iterations
                self._counts["divergences"] += result.divergences
                self._counts["converged"] += int(result.converged)
                self._last_timing = result.timing
        if self._policy is None:
            ctrl = self._last_ctrl.copy()
        else:
            ctrl = self._policy(state, time)
        self._last_ctrl = ctrl
        return ctrl


__all__ = ["ILQR"]
