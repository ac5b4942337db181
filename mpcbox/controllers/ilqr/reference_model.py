"""The planning model at the reference: dynamics Jacobians and cost Hessians, once per solver.

``ILQRConfig(linearization="reference")`` plans with the Jacobians at the Problem's reference
state and ``ctrl_ref`` at every knot, and ``cost_hessian="reference"`` with the cost's
Gauss-Newton Hessians there (:class:`~mpcbox.controllers.ilqr.config.ILQRConfig`).
"""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.ilqr.held_controls import compose_held, scale_running
from mpcbox.core.problem import Linearization, Problem


def linearization_at_reference(
    problem: Problem, ctrl: np.ndarray, horizon: int, steps: int, centered: bool | None
) -> Linearization:
    """``A`` ``(T, nx, nx)`` and ``B`` ``(T, nx, nu)``: the planning model's Jacobians at the
    reference state and ``ctrl`` ``(nu,)`` (``ctrl_ref`` within the solver's bounds), composed
    over ``steps`` held steps, the same at each of the ``horizon`` knots (read-only views)."""
    A, B = problem.linearize(problem.reference_state(), ctrl, centered=centered)
    A, B = compose_held(Linearization(A, B), steps)
    return Linearization(
        np.broadcast_to(A, (horizon, *A.shape)), np.broadcast_to(B, (horizon, *B.shape))
    )


def hessians_at_reference(
    problem: Problem, ctrl: np.ndarray, horizon: int, steps: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cost's ``lxx`` ``(T + 1, nx, nx)``, ``luu`` ``(T + 1, nu, nu)`` and ``lux``
    ``(T + 1, nu, nx)`` at the reference state and ``ctrl`` ``(nu,)`` at every knot (the last
    row is the terminal cost's), scaled for ``steps`` held steps as the solver's are."""
    states = np.tile(problem.reference_state(), (horizon + 1, 1))
    quad = problem.quadratize_trajectory(states, np.tile(ctrl, (horizon, 1)))
    quad = scale_running(quad, steps)
    return quad.lxx, quad.luu, quad.lux


def constant_hessians(problem: Problem) -> bool:
    """Whether every cost term of ``problem`` has a constant residual Jacobian, so that its
    Gauss-Newton Hessians are the same at every state."""
    terms = [*problem.cost.running, *problem.cost.terminal]
    return all(term.constant_jacobian for term in terms)


__all__ = ["constant_hessians", "hessians_at_reference", "linearization_at_reference"]
