"""mpcbox: optimal control and model-predictive control for MuJoCo models.

Heavy or optional pieces (CasADi, MJWarp, OSQP) are imported on first use, so
``import mpcbox`` is fast and works without a GPU or CasADi.
"""

from __future__ import annotations

import importlib
from typing import Any

from mpcbox.errors import (
    BackendUnavailableError,
    CostDefinitionError,
    DivergenceError,
    InvalidArgumentError,
    ModelLoadError,
    ModelNotFoundError,
    MpcboxError,
    NotStabilizableError,
    ShapeError,
    SolverError,
    UnknownNameError,
    UnsupportedModelError,
)

__version__ = "0.1.0"

_LAZY: dict[str, str] = {
    "Problem": "mpcbox.problem",
    "Linearization": "mpcbox.problem",
    "Quadratization": "mpcbox.problem",
    "Rollout": "mpcbox.problem",
    "Cost": "mpcbox.cost",
    "CostTerm": "mpcbox.cost",
    "StateCost": "mpcbox.cost",
    "ControlCost": "mpcbox.cost",
    "ComOverSupport": "mpcbox.cost",
    "FramePosition": "mpcbox.cost",
    "FrameHeight": "mpcbox.cost",
    "Upright": "mpcbox.cost",
    "QuadraticValue": "mpcbox.cost",
    "Controller": "mpcbox.controller",
    "Equilibrium": "mpcbox.equilibrium",
    "find_equilibrium": "mpcbox.equilibrium",
    "LQR": "mpcbox.lqr",
    "ILQR": "mpcbox.ilqr",
    "ILQRResult": "mpcbox.ilqr",
    "QPMPC": "mpcbox.qp_mpc",
    "PredictiveSampling": "mpcbox.sampling",
    "MPPI": "mpcbox.sampling",
    "CEM": "mpcbox.sampling",
    "ActuatorNoise": "mpcbox.disturbances",
    "Push": "mpcbox.disturbances",
    "ModelMismatch": "mpcbox.disturbances",
    "simulate": "mpcbox.simulation",
    "SimulationResult": "mpcbox.simulation",
    "Metrics": "mpcbox.simulation",
    "compare": "mpcbox.comparison",
    "Scenario": "mpcbox.comparison",
    "make_controller": "mpcbox.registry",
}

__all__ = [
    "BackendUnavailableError",
    "CostDefinitionError",
    "DivergenceError",
    "InvalidArgumentError",
    "ModelLoadError",
    "ModelNotFoundError",
    "MpcboxError",
    "NotStabilizableError",
    "ShapeError",
    "SolverError",
    "UnknownNameError",
    "UnsupportedModelError",
    *sorted(_LAZY),
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'mpcbox' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
