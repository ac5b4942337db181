"""The cross-entropy method (CEM) over spline knots."""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.sampling.base import SamplingController
from mpcbox.controllers.sampling.config import CEMConfig


class CEM(SamplingController):
    r"""Refit a diagonal Gaussian over knots to the lowest-cost candidates.

    Candidates are :math:`U^n = \mu + \sigma \odot \varepsilon^n` (candidate 0 is
    :math:`\mu` itself). With the ``num_elites`` lowest-cost candidates :math:`E` and the
    smoothing weight :math:`\beta`,

    .. math::
        \mu \leftarrow \beta \mu + (1 - \beta) \operatorname{mean}_{n \in E} U^n, \qquad
        \sigma \leftarrow \operatorname{clip}\big(\beta \sigma + (1 - \beta)
        \operatorname{std}_{n \in E} U^n, \sigma_{\min}, \sigma_{\max}\big),

    with :math:`\sigma_0` = ``std_init`` (default ``noise_scale``), the cap
    :math:`\sigma_{\max} = \max(\sigma_0, \text{noise\_scale})` (both times the
    per-knot ``noise_schedule``). The nominal :attr:`knots` is :math:`\mu`; the
    warm start shifts :math:`\mu` and keeps :math:`\sigma`.

    Args:
        problem: The Problem.
        config: A :class:`~mpcbox.controllers.sampling.CEMConfig`.
        **options: Config fields to override.
    """

    name = "cem"
    config_class = CEMConfig

    def reset_algorithm(self) -> None:
        self.std = self.config.initial_std(self.problem.nu)
        self.std_max = np.maximum(self.std, self.knot_noise)

    def sample(self) -> np.ndarray:
        return self.gaussian_candidates(self.std)

    def update(self, candidates: np.ndarray, costs: np.ndarray) -> None:
        cfg = self.config
        finite = np.flatnonzero(np.isfinite(costs))
        order = finite[np.argsort(costs[finite], kind="stable")]
        elites = candidates[order[: cfg.num_elites]]
        beta = cfg.smoothing
        self.knots = beta * self.knots + (1 - beta) * elites.mean(axis=0)
        std = elites.std(axis=0) if len(elites) > 1 else self.std
        self.std = np.clip(beta * self.std + (1 - beta) * std, cfg.std_min, self.std_max)
