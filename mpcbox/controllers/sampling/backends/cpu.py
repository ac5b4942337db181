"""CPU backend: :func:`mujoco.rollout` on all cores, scored with the Problem's cost."""

from __future__ import annotations

from collections.abc import Sequence

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
    """

    def __init__(
        self, problem: Problem, weights: np.ndarray, models: Sequence[mujoco.MjModel]
    ) -> None:
        self.problem = problem
        self.weights = np.asarray(weights, dtype=np.float64)
        self.models = list(models)

    def controls(self, candidates: np.ndarray) -> np.ndarray:
        """Interpolated controls ``(N, T, nu)`` of knots ``(N, K, nu)``."""
        return np.einsum("tk,nkj->ntj", self.weights, candidates)

    def evaluate(self, state: np.ndarray, candidates: np.ndarray) -> RolloutCosts:
        """Costs ``(N, M)`` of candidate knots ``(N, K, nu)`` from ``state``."""
        n, m = candidates.shape[0], len(self.models)
        ctrls = self.controls(candidates)
        if m == 1:
            rollout = self.problem.rollout(state, ctrls)
        else:
            rollout = self.problem.rollout(
                state, np.repeat(ctrls, m, axis=0), model=self.models * n
            )
        with np.errstate(all="ignore"):
            costs = self.problem.rollout_cost(rollout).reshape(n, m)
        nonfinite = ~np.all(np.isfinite(rollout.states), axis=(1, 2)).reshape(n, m)
        nonfinite |= ~np.isfinite(costs)
        return RolloutCosts(costs, np.zeros((n, m), dtype=bool), nonfinite)
