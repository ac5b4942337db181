"""Sampling-based predictive control: predictive sampling, MPPI and CEM.

The controllers share :class:`~mpcbox.controllers.sampling.base.SamplingController` (splines, warm
starts, noise, cost evaluation, statistics) and two backends: ``"cpu"``
(:func:`mujoco.rollout` on all cores) and ``"warp"`` (MuJoCo Warp, thousands of worlds per
tick, costs computed on the device). MJWarp is imported only when the warp backend is used.
"""

from __future__ import annotations

from mpcbox.controllers.sampling.base import (
    Evaluation,
    SamplingController,
    TickInfo,
    aggregate_risk,
)
from mpcbox.controllers.sampling.cem import CEM
from mpcbox.controllers.sampling.config import (
    CEMConfig,
    MPPIConfig,
    PredictiveSamplingConfig,
    Randomization,
    SamplingConfig,
)
from mpcbox.controllers.sampling.mppi import MPPI, mppi_weights
from mpcbox.controllers.sampling.predictive_sampling import PredictiveSampling
from mpcbox.controllers.sampling.splines import Spline

__all__ = [
    "CEM",
    "MPPI",
    "CEMConfig",
    "Evaluation",
    "MPPIConfig",
    "PredictiveSampling",
    "PredictiveSamplingConfig",
    "Randomization",
    "SamplingConfig",
    "SamplingController",
    "Spline",
    "TickInfo",
    "aggregate_risk",
    "mppi_weights",
]
