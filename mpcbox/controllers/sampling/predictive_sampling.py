"""Predictive sampling: the best of the nominal spline and Gaussian perturbations of it."""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.sampling.base import SamplingController
from mpcbox.controllers.sampling.config import PredictiveSamplingConfig


class PredictiveSampling(SamplingController):
    r"""Keep the lowest-cost candidate among the nominal and ``N - 1`` perturbations.

    Candidates are :math:`U^0 = \bar U` and :math:`U^n = \bar U + \sigma \odot \varepsilon^n`
    with :math:`\varepsilon^n \sim \mathcal N(0, I)`; the update is
    :math:`\bar U \leftarrow U^{n^*}`, :math:`n^* = \arg\min_n J_n`. Because the nominal is
    always a candidate, the planned cost never increases between iterations from one state.

    Args:
        problem: The Problem.
        config: A :class:`~mpcbox.controllers.sampling.PredictiveSamplingConfig`.
        **options: Config fields to override.
    """

    name = "ps"
    config_class = PredictiveSamplingConfig

    def sample(self) -> np.ndarray:
        return self.gaussian_candidates(self.knot_noise)

    def update(self, candidates: np.ndarray, costs: np.ndarray) -> None:
        self.knots = candidates[int(np.argmin(costs))].copy()
