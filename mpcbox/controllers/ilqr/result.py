"""What an iLQR solve returns: the trajectory, its gains, the time per phase and why it stopped."""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np


class StopReason(enum.Enum):
    """Why :meth:`~mpcbox.controllers.ilqr.solver.ILQRSolver.solve` stopped.

    Two reasons are convergence (:attr:`converged`); three are stalls, where the solver gave
    up improving and kept its current trajectory (:attr:`stalled`); the others are neither.

    Attributes:
        COST_CHANGE: Converged: a full step (the largest step size) lowered the cost by less
            than ``tolerance`` times the cost, and the backward pass predicted a full-step
            decrease :math:`-(\\Delta V_1 + \\Delta V_2)` below that as well.
        NO_PREDICTED_DECREASE: Converged: the backward pass predicts no decrease of the cost
            (:math:`-(\\Delta V_1 + \\Delta V_2) \\le 10^{-12} \\max(1, |J|)`): a stationary
            point of the control-limited problem.
        SHORT_STEP: Not converged: the cost changed by less than ``tolerance`` times the cost,
            and so did the predicted full-step decrease, but only along a shortened step
            (``alpha`` below the largest step size), so the small change says that the
            quadratic model is poor, not that the solution is optimal. A small change while
            the predicted decrease is still larger (after a short step or a full one) stops
            nothing: the iterations go on.
        SADDLE: Not converged: the backward pass predicts no decrease, but a small random
            change of the controls lowers the cost: a saddle or maximum of the cost that the
            (convex) Gauss-Newton model cannot see, such as a swing-up's pendulum at rest
            hanging down under a cost periodic in the angle. Start from a guess that moves.
        ITERATION_LIMIT: The iteration cap was reached.
        REGULARIZATION_LIMIT: Stalled: the regularization grew past ``regularization_max``
            after failed backward passes or line searches.
        RETRY_LIMIT: Stalled: ``max_retries`` regularization increases within one iteration
            did not produce a backward pass or an accepted step.
        DIVERGED: Stalled: as the two above, with the last line search's rollouts all
            diverging (non-finite states or cost) at every step size.
    """

    COST_CHANGE = "cost change"
    NO_PREDICTED_DECREASE = "no predicted decrease"
    SHORT_STEP = "short step"
    SADDLE = "saddle"
    ITERATION_LIMIT = "iteration limit"
    REGULARIZATION_LIMIT = "regularization limit"
    RETRY_LIMIT = "retry limit"
    DIVERGED = "diverged"

    @property
    def converged(self) -> bool:
        """Whether the reason is a convergence criterion."""
        return self in (StopReason.COST_CHANGE, StopReason.NO_PREDICTED_DECREASE)

    @property
    def stalled(self) -> bool:
        """Whether the solver gave up improving (regularization or retry limit, divergence)."""
        stalls = (StopReason.REGULARIZATION_LIMIT, StopReason.RETRY_LIMIT, StopReason.DIVERGED)
        return self in stalls


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


class ILQRResult(NamedTuple):
    """Result of :meth:`~mpcbox.controllers.ilqr.solver.ILQRSolver.solve`.

    Attributes:
        states: Optimized states ``(T + 1, nstate)``, ``states[0] = x0``.
        ctrls: Optimized controls ``(T, nu)``, inside the control bounds.
        k: Last feed-forward terms ``(T, nu)``.
        K: Last feedback gains ``(T, nu, nx)`` (acting on ``x ⊖ states[t]``): those of the
            last linearization at the solve's starting regularization, even when its line
            search had to raise the regularization (unless that backward pass fails).
        cost: Final total cost.
        costs: Cost after each accepted iteration, starting with the initial guess.
        iterations: Iterations performed (backward passes with fresh derivatives).
        converged: Whether the solve stopped on a convergence criterion
            (``stop_reason.converged``); false at the iteration cap, on a stall, and when a
            small cost change came from a shortened step.
        regularization: The Levenberg-Marquardt :math:`\\mu` at exit.
        divergences: Rollouts that produced non-finite states or costs.
        timing: Time per phase, a :class:`Timing`.
        status: Why the solver stopped, in words (for example ``"converged (relative
            decrease)"`` or ``"regularization limit (line search)"``).
        stop_reason: Why the solver stopped, a :class:`StopReason`.
        defect: Largest defect ``max |F(x_t, u_t) ⊖ x_{t+1}|`` left between shooting nodes
            of a multiple-shooting solve (a ``states_init`` guess); 0 for a feasible
            trajectory. A solve with defects above ``defect_tolerance`` is not converged.
        start: What the first trajectory was, one of :data:`STARTS`: ``"guess"``, the
            given controls rolled out open loop; ``"policy"``, a feedback law rolled out
            from ``x0`` (the controller's ``warm_start_feedback``); ``"ctrl_ref"``, the
            reference control held, after the guess (and the law) rolled out to
            non-finite states or cost; ``"states"``, a multiple-shooting guess.
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
    stop_reason: StopReason
    defect: float = 0.0
    start: str = "guess"


#: The values of :attr:`ILQRResult.start`.
STARTS = ("guess", "policy", "ctrl_ref", "states")

__all__ = ["STARTS", "ILQRResult", "StopReason", "Timing"]
