r"""The ``"ipopt"`` controller: an offline IPOPT plan tracked with time-varying LQR feedback.

A reference for comparison tables on small problems (``nq == nv``): the plan comes from
:func:`mpcbox.controllers.ipopt.solve_ipopt` (direct multiple shooting with CasADi), the
tracking gains from the iLQR backward pass along its rollout, and the gain after the plan
ends from :func:`mpcbox.controllers.lqr.dlqr` at the reference.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mpcbox.config import check_option_names, resolve_config
from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.ilqr.backward_pass import backward_pass
from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ipopt import IpoptSolution, require_casadi, solve_ipopt
from mpcbox.controllers.lqr import dlqr
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, MpcboxError, SolverError
from mpcbox.validation import (
    as_array,
    boolean,
    checked_options,
    finite,
    integer,
    positive,
    positive_int,
)


@checked_options
@dataclass(frozen=True, kw_only=True)
class IpoptConfig:
    """Options of :class:`IpoptController`.

    Attributes:
        horizon: Plan length in knots of the planning model (default 50, as
            :class:`~mpcbox.controllers.ilqr.config.ILQRConfig`).
        warm_start_ilqr: Initialize IPOPT with an iLQR solution (more robust on swing-ups,
            whose costs have several local minima).
        ilqr_options: Keyword options of the :class:`~mpcbox.ILQR` used for the warm start
            (``max_iterations`` defaults to 300 there).
        regularization: Added to ``Q_uu`` when computing the tracking gains, and to ``R`` of
            the LQR gain used after the plan ends.
        planning_timestep: Plan on a copy of the Problem with this planning timestep
            (:meth:`~mpcbox.Problem.with_planning_timestep`).
        ctrls_init: Initial controls ``(T, nu)`` or ``(nu,)`` of :func:`solve_ipopt` (and of
            the iLQR warm start); default: the task's first guess from the planned state
            (:meth:`~mpcbox.Problem.initial_ctrls`).
        states_init: Initial states ``(T + 1, nstate)`` of :func:`solve_ipopt`.
        max_iterations: IPOPT iteration cap.
        tolerance: IPOPT's ``tol``.
        lbfgs_history: Pairs kept by the limited-memory Hessian.
        print_level: IPOPT verbosity (0 silent, 5 verbose).
        nlpsol_options: Extra CasADi ``nlpsol`` options (the ``options`` of
            :func:`solve_ipopt`), e.g. ``{"ipopt.acceptable_tol": 1e-6}``.
    """

    horizon: int = 50
    warm_start_ilqr: bool = False
    ilqr_options: Mapping[str, Any] | None = None
    regularization: float = 1e-6
    planning_timestep: float | None = None
    ctrls_init: np.ndarray | None = None
    states_init: np.ndarray | None = None
    max_iterations: int = 3000
    tolerance: float = 1e-9
    lbfgs_history: int = 20
    print_level: int = 0
    nlpsol_options: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        for name in ("horizon", "max_iterations", "lbfgs_history"):
            put(name, positive_int(name, getattr(self, name)))
        put("print_level", integer("print_level", self.print_level))
        put("regularization", positive("regularization", self.regularization))
        put("tolerance", positive("tolerance", self.tolerance))
        put("warm_start_ilqr", boolean("warm_start_ilqr", self.warm_start_ilqr))
        if self.planning_timestep is not None:
            positive("planning_timestep", self.planning_timestep)
        for name in ("ilqr_options", "nlpsol_options"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, Mapping):
                raise InvalidTypeError(
                    f"{name} must be a mapping of options, got {type(value).__name__}"
                )
        if self.ilqr_options:
            check_option_names(ILQRConfig, self.ilqr_options, "ilqr_options (ILQRConfig)")
            if self.ilqr_options.get("control_steps", 1) != 1:
                raise InvalidArgumentError(
                    "ilqr_options: control_steps must be 1 (IPOPT's knots are planning "
                    f"steps), got {self.ilqr_options['control_steps']}"
                )


class IpoptController(Controller):
    """Offline IPOPT plan from the first measured state, tracked with time-varying LQR.

    On the first call (after :meth:`reset`) it solves :func:`solve_ipopt` over ``horizon``
    knots, then computes feedback gains along the plan with the iLQR backward pass
    (:func:`mpcbox.controllers.ilqr.backward_pass.backward_pass`) and applies
    :math:`u_i + K_i (x \\ominus \\bar x_i)` at every call. After the plan ends it regulates
    about the reference state and control (``problem.reference_state()``, ``ctrl_ref``) with
    the infinite-horizon LQR gain there (:func:`~mpcbox.controllers.lqr.dlqr`).

    Args:
        problem: The Problem (``nq == nv``).
        config: An :class:`IpoptConfig` (default: its defaults).
        **options: Fields of :class:`IpoptConfig` that replace those of ``config``.

    Raises:
        BackendUnavailableError: If CasADi is not installed.
        InvalidTypeError: If ``problem`` is not a Problem or ``config`` not an IpoptConfig.
        UnknownOptionError: For an option that is not a config field; it lists the valid ones.
        InvalidArgumentError: For a model with free or ball joints, or a value out of range.
    """

    name = "ipopt"
    period = None
    requires = ("casadi",)
    config_class = IpoptConfig

    def __init__(self, problem: Problem, config: IpoptConfig | None = None, **options: Any) -> None:
        require_casadi()
        problem = check_problem(problem, "IpoptController")
        cfg = resolve_config(IpoptConfig, config, options, "IpoptController")
        if cfg.planning_timestep is not None and abs(cfg.planning_timestep - problem.dt) > 1e-12:
            problem = problem.with_planning_timestep(cfg.planning_timestep)
        if problem.nq != problem.nv:
            raise InvalidArgumentError(
                "problem: IpoptController needs a model without free or ball joints (nq == nv)"
            )
        self.problem = problem
        self.config = cfg
        self.horizon = cfg.horizon
        self.regularization = cfg.regularization
        self.solution: IpoptSolution | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the plan; the next call solves again."""
        self._plan_time = 0.0
        self._K: np.ndarray | None = None
        self._failures = 0
        self.solution = None

    @property
    def stats(self) -> dict[str, float]:
        """IPOPT iterations and solve time of the current plan, and failed solves."""
        out = {"fallbacks": float(self._failures)}
        if self.solution is not None:
            out["ipopt_iterations"] = float(self.solution.iterations)
            out["ipopt_solve_time"] = float(self.solution.solve_time)
        return out

    def plan(self, state: np.ndarray) -> IpoptSolution:
        """Solve from ``state`` and compute the tracking gains."""
        p, cfg = self.problem, self.config
        ctrls_init, states_init = cfg.ctrls_init, cfg.states_init
        if cfg.warm_start_ilqr:
            ilqr_options = {"max_iterations": 300, **(cfg.ilqr_options or {})}
            if ctrls_init is not None:
                ilqr_options.setdefault("ctrls_init", ctrls_init)
            res = ILQR(p, horizon=self.horizon, **ilqr_options).solve(state)
            ctrls_init, states_init = res.ctrls, res.states
        sol = solve_ipopt(
            p,
            state,
            self.horizon,
            ctrls_init=ctrls_init,
            states_init=states_init,
            max_iterations=cfg.max_iterations,
            tolerance=cfg.tolerance,
            lbfgs_history=cfg.lbfgs_history,
            print_level=cfg.print_level,
            options=None if cfg.nlpsol_options is None else dict(cfg.nlpsol_options),
        )
        # Track the dynamically consistent rollout of the plan's controls.
        states = p.rollout(state, sol.ctrls).states[0]
        lin = p.linearize_trajectory(states[:-1], sol.ctrls)
        quad = p.quadratize_trajectory(states, sol.ctrls)
        reg = self.regularization
        for _ in range(30):
            try:
                bp = backward_pass(lin, quad, sol.ctrls, p.ctrl_low, p.ctrl_high, reg)
                break
            except SolverError:
                reg *= 10.0
        else:
            raise SolverError("IpoptController: could not compute tracking gains")
        self._states, self._ctrls, self._K = states, sol.ctrls, bp.K
        self._tail = (p.reference_state(), p.clip_ctrl(p.ctrl_ref))
        self._K_tail = self._tail_gain(*self._tail, bp.K[-1])
        self.solution = sol
        return sol

    def _tail_gain(self, state: np.ndarray, ctrl: np.ndarray, fallback: np.ndarray) -> np.ndarray:
        """Infinite-horizon LQR gain about ``(state, ctrl)`` (used after the plan ends), as
        ``u = ctrl + gain (x ⊖ state)``; ``fallback`` when the Riccati equation fails."""
        p = self.problem
        A, B = p.linearize(state, ctrl)
        q = p.quadratize(state, ctrl)
        Q = q.lxx + 1e-9 * np.eye(p.nx)
        R = q.luu + self.regularization * np.eye(p.nu)
        try:
            K, _ = dlqr(A, B, Q, R, q.lux.T)
        except MpcboxError:
            return fallback
        return -K

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        p = self.problem
        state = as_array("state", state, (p.nstate,))
        time = finite("time", time)
        self.last_call = "solve"
        if self._K is None or time < self._plan_time - 1e-9:
            self.last_call = "offline"
            try:
                self.plan(state)
            except (SolverError, InvalidArgumentError, RuntimeError):
                self._failures += 1
                return p.clip_ctrl(p.ctrl_ref)
            self._plan_time = float(time)
        assert self._K is not None
        s = (time - self._plan_time) / p.dt + 1e-9
        if s >= self.horizon:
            (nominal, ctrl), gain = self._tail, self._K_tail
        else:
            i = max(int(s), 0)
            nominal, ctrl, gain = self._states[i], self._ctrls[i], self._K[i]
        u = ctrl + gain @ p.state_difference(state, nominal)
        if not np.all(np.isfinite(u)):
            return p.clip_ctrl(ctrl)
        return p.clip_ctrl(u)


__all__ = ["IpoptConfig", "IpoptController"]
