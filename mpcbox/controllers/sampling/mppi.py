"""Model-predictive path integral control (MPPI)."""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.sampling.base import SamplingController
from mpcbox.controllers.sampling.config import MPPIConfig


class MPPI(SamplingController):
    r"""Cost-weighted average of Gaussian perturbations of the nominal spline.

    Candidates are drawn as in predictive sampling (candidate 0 is the nominal). With the
    valid costs :math:`J_n`, their minimum :math:`J^*` and standard deviation :math:`s_J`,

    .. math::
        w_n = \frac{\exp(-(J_n - J^*) / (\lambda s_J))}{\sum_m \exp(-(J_m - J^*) / (\lambda s_J))},
        \qquad \bar U \leftarrow \sum_n w_n U^n ,

    where :math:`\lambda` is ``temperature``; excluded candidates (:math:`J_n = \infty`) get
    zero weight. Normalizing by :math:`s_J` makes :math:`\lambda` independent of the cost's
    scale: small values approach predictive sampling, large values a plain average. With
    ``temperature_mode="absolute"`` the weights are the softmax of :math:`-J_n / \lambda`,
    :math:`\lambda` in cost units (subtracting :math:`J^*` only guards the exponential).

    Args:
        problem: The Problem.
        config: An :class:`~mpcbox.controllers.sampling.MPPIConfig`.
        **options: Config fields to override.
    """

    name = "mppi"
    config_class = MPPIConfig

    def sample(self) -> np.ndarray:
        return self.gaussian_candidates(self.knot_noise)

    def update(self, candidates: np.ndarray, costs: np.ndarray) -> None:
        cfg = self.config
        weights = mppi_weights(costs, cfg.temperature, cfg.temperature_mode == "normalized")
        self.knots = np.einsum("n,nkj->kj", weights, candidates)


def mppi_weights(costs: np.ndarray, temperature: float, normalized: bool = True) -> np.ndarray:
    r"""MPPI weights ``(N,)`` of costs ``(N,)`` (``inf`` gets weight zero; they sum to 1).

    Args:
        costs: Costs :math:`J_n` ``(N,)``, at least one finite.
        temperature: :math:`\lambda`.
        normalized: Divide :math:`\lambda` by the valid costs' standard deviation
            (``temperature_mode="normalized"``); otherwise the weights are
            :math:`\operatorname{softmax}(-J / \lambda)` (``"absolute"``).
    """
    finite = np.isfinite(costs)
    valid = costs[finite]
    spread = 1.0
    if normalized:
        spread = float(valid.std()) if valid.size > 1 else 0.0
        if spread <= 0.0:
            spread = 1.0
    w = np.zeros_like(costs, dtype=np.float64)
    w[finite] = np.exp(-(valid - valid.min()) / (temperature * spread))
    return w / w.sum()
