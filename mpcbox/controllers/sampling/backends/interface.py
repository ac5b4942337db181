"""What a rollout backend returns and the interface the sampling controllers call."""

from __future__ import annotations

import abc
from typing import NamedTuple

import numpy as np


class RolloutCosts(NamedTuple):
    """Backend output for ``N`` candidates on ``M`` models.

    Attributes:
        costs: Total rollout costs ``(N, M)`` (float64).
        overflow: ``(N, M)`` True where the backend ran out of contact/constraint capacity.
        nonfinite: ``(N, M)`` True where the rollout diverged: a NaN or infinite cost or
            state, or a ``qpos``, ``qvel`` or ``qacc`` entry beyond ``1e10`` (MuJoCo's
            ``mjMAXVAL``, where MuJoCo resets and :func:`mujoco.rollout` returns NaN; the
            warp backend checks it after every step).
    """

    costs: np.ndarray
    overflow: np.ndarray
    nonfinite: np.ndarray


class RolloutBackend(abc.ABC):
    r"""Rolls out candidate knots from one state and scores them with the Problem's cost.

    For candidate knots :math:`U^n` ``(N, K, nu)``, the controls of planning step ``t`` are
    :math:`u^n_t = \sum_k W_{tk} U^n_k` with the interpolation matrix ``W`` ``(T, K)``; each
    candidate is rolled out on every one of the ``M`` planning models and scored with
    :math:`J_{nm} = \sum_{t=0}^{T-1} \ell(x^{nm}_t, u^n_t) + \ell_T(x^{nm}_T)`.
    """

    @abc.abstractmethod
    def evaluate(self, state: np.ndarray, candidates: np.ndarray) -> RolloutCosts:
        """Costs ``(N, M)`` of candidate knots ``(N, K, nu)`` from ``state`` ``(nstate,)``."""

    @property
    def stats(self) -> dict[str, float]:
        """Backend counters merged into the controller's ``stats`` (default: none)."""
        return {}

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release resources (default: nothing to release)."""


class AsyncRolloutBackend(RolloutBackend):
    """A backend that computes while the host goes on.

    The controller calls :meth:`submit`, draws the next iteration's noise, then
    :meth:`collect`. (The controller recognizes any backend with a ``submit`` method.)
    """

    @abc.abstractmethod
    def submit(self, state: np.ndarray, candidates: np.ndarray) -> None:
        """Start evaluating candidate knots ``(N, K, nu)`` from ``state``; do not wait."""

    @abc.abstractmethod
    def collect(self) -> RolloutCosts:
        """Wait for the submitted evaluation and return its costs ``(N, M)``."""

    def evaluate(self, state: np.ndarray, candidates: np.ndarray) -> RolloutCosts:
        """:meth:`submit` then :meth:`collect`."""
        self.submit(state, candidates)
        return self.collect()
