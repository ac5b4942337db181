"""Sampling-based predictive control: predictive sampling, MPPI and CEM.

The controllers share :class:`~mpcbox.sampling.base.SamplingController` (splines, warm
starts, noise, cost evaluation, statistics) and two backends: ``"cpu"``
(:func:`mujoco.rollout` on all cores) and ``"warp"`` (MuJoCo Warp, thousands of worlds per
tick, costs computed on the device). MJWarp is imported only when the warp backend is used.
"""

from __future__ import annotations

from mpcbox.sampling.base import Evaluation, SamplingController, TickInfo, aggregate_risk
from mpcbox.sampling.cem import CEM
from mpcbox.sampling.config import (
    CEMConfig,
    MPPIConfig,
    PredictiveSamplingConfig,
    Randomization,
    SamplingConfig,
)
from mpcbox.sampling.mppi import MPPI, mppi_weights
from mpcbox.sampling.predictive_sampling import PredictiveSampling
from mpcbox.sampling.splines import Spline

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
