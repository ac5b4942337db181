"""CPU backend: :func:`mujoco.rollout` on all cores, scored with the Problem's cost."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from mpcbox.controllers.sampling.backends.interface import RolloutBackend, RolloutCosts
from mpcbox.core.problem import Problem


class CpuBackend(RolloutBackend):
    """Evaluate candidate knots with :meth:`Problem.rollout` and :meth:`Problem.rollout_cost`.

    Args:
        problem: The Problem (its persistent rollout pool is used).
        weights: Interpolation matrix ``(T, K)``.
        models: ``M`` planning models (the nominal one, or randomized copies).
        policy: A state feedback ``policy(states (B, nstate), ctrls (B, nu)) -> (B, nu)``
            that every rollout step goes through (:meth:`Problem.dynamics.rollout_policy
            <mpcbox.core.dynamics.Dynamics.rollout_policy>`), such as
            :meth:`~mpcbox.controllers.sampling.catch.LQRCatch.policy`; ``None``: open loop.
    """

    def __init__(
        self,
        problem: Problem,
        weights: np.ndarray,
        models: Sequence[mujoco.MjModel],
        policy: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.problem = problem
        self.weights = np.asarray(weights, dtype=np.float64)
        self.models = list(models)
        self.policy = policy

    def controls(self, candidates: np.ndarray) -> np.ndarray:
        """Interpolated controls ``(N, T, nu)`` of knots ``(N, K, nu)``."""
        return np.einsum("tk,nkj->ntj", self.weights, candidates)

    def evaluate(self, state: np.ndarray, candidates: np.ndarray) -> RolloutCosts:
        """Costs ``(N, M)`` of candidate knots ``(N, K, nu)`` from ``state``."""
        n, m = candidates.shape[0], len(self.models)
        ctrls = self.problem.clip_ctrl(self.controls(candidates))
        if m > 1:
            ctrls = np.repeat(ctrls, m, axis=0)
        model = None if m == 1 else self.models * n
        if self.policy is None:
            rollout = self.problem.rollout(state, ctrls, model=model)
        else:
            state = self.problem.check_state(state)
            rollout = self.problem.dynamics.rollout_policy(state, ctrls, self.policy, model)
        with np.errstate(all="ignore"):
            costs = self.problem.rollout_cost(rollout).reshape(n, m)
        nonfinite = ~np.all(np.isfinite(rollout.states), axis=(1, 2)).reshape(n, m)
        nonfinite |= ~np.isfinite(costs)
        return RolloutCosts(costs, np.zeros((n, m), dtype=bool), nonfinite)
