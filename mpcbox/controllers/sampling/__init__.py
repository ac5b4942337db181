"""Sampling-based predictive control: predictive sampling, MPPI and CEM.

The controllers share :class:`~mpcbox.controllers.sampling.base.SamplingController` (splines,
warm starts, noise, cost evaluation, statistics); an algorithm implements only ``sample`` and
``update``. Rollouts run on a :class:`RolloutBackend` (:func:`make_backend`): ``"cpu"``
(:func:`mujoco.rollout` on all cores) or ``"warp"`` (MuJoCo Warp, thousands of worlds per
tick, costs computed on the device). MJWarp is imported only when the warp backend is used.
With ``catch="lqr"`` the CPU rollouts step through the reference's LQR inside its basin
(:class:`LQRCatch`).
"""

from __future__ import annotations

from mpcbox.controllers.sampling.backends import (
    AsyncRolloutBackend,
    RolloutBackend,
    RolloutCosts,
    make_backend,
)
from mpcbox.controllers.sampling.base import SamplingController, TickInfo, aggregate_risk
from mpcbox.controllers.sampling.catch import LQRCatch, basin_level
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
from mpcbox.controllers.sampling.traces import PlannerTrace, TraceRecorder

__all__ = [
    "CEM",
    "MPPI",
    "AsyncRolloutBackend",
    "CEMConfig",
    "LQRCatch",
    "MPPIConfig",
    "PlannerTrace",
    "PredictiveSampling",
    "PredictiveSamplingConfig",
    "Randomization",
    "RolloutBackend",
    "RolloutCosts",
    "SamplingConfig",
    "SamplingController",
    "Spline",
    "TickInfo",
    "TraceRecorder",
    "aggregate_risk",
    "basin_level",
    "make_backend",
    "mppi_weights",
]
