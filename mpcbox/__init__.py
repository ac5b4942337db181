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
    InvalidTypeError,
    ModelLoadError,
    ModelNotFoundError,
    ModelWarning,
    MpcboxError,
    MujocoError,
    NoControlAuthorityError,
    NotStabilizableError,
    PeriodWarning,
    PlanningModelWarning,
    PostureWarning,
    RunError,
    ShapeError,
    SolverError,
    UnknownNameError,
    UnknownOptionError,
    UnsupportedCostTermError,
    UnsupportedModelError,
)

__version__ = "0.1.0"

_LAZY: dict[str, str] = {
    "Problem": "mpcbox.core.problem",
    "Linearization": "mpcbox.core.dynamics",
    "Quadratization": "mpcbox.core.derivatives",
    "Rollout": "mpcbox.core.dynamics",
    "Cost": "mpcbox.core.cost",
    "CostTerm": "mpcbox.core.cost",
    "StateCost": "mpcbox.core.cost",
    "ControlCost": "mpcbox.core.cost",
    "ComOverSupport": "mpcbox.core.cost",
    "ComVelocity": "mpcbox.core.cost",
    "Energy": "mpcbox.core.cost",
    "FramePosition": "mpcbox.core.cost",
    "FrameHeight": "mpcbox.core.cost",
    "HeightAbove": "mpcbox.core.cost",
    "Upright": "mpcbox.core.cost",
    "QuadraticValue": "mpcbox.core.cost",
    "WrappedAngle": "mpcbox.core.cost",
    "Controller": "mpcbox.controllers.base",
    "Equilibrium": "mpcbox.core.equilibrium",
    "find_equilibrium": "mpcbox.core.equilibrium",
    "servo_ringing": "mpcbox.core.servo_ringing",
    "ServoRinging": "mpcbox.core.servo_ringing",
    "saturation_jumps": "mpcbox.core.saturation_jumps",
    "SaturationJumps": "mpcbox.core.saturation_jumps",
    "LQR": "mpcbox.controllers.lqr",
    "LQRConfig": "mpcbox.controllers.lqr",
    "ILQR": "mpcbox.controllers.ilqr.controller",
    "ILQRConfig": "mpcbox.controllers.ilqr.config",
    "ILQRResult": "mpcbox.controllers.ilqr.result",
    "QPMPC": "mpcbox.controllers.qp_mpc.controller",
    "QPMPCConfig": "mpcbox.controllers.qp_mpc.config",
    "IpoptController": "mpcbox.controllers.ipopt_controller",
    "IpoptConfig": "mpcbox.controllers.ipopt_controller",
    "SamplingConfig": "mpcbox.controllers.sampling",
    "PredictiveSamplingConfig": "mpcbox.controllers.sampling",
    "MPPIConfig": "mpcbox.controllers.sampling",
    "CEMConfig": "mpcbox.controllers.sampling",
    "PredictiveSampling": "mpcbox.controllers.sampling",
    "MPPI": "mpcbox.controllers.sampling",
    "CEM": "mpcbox.controllers.sampling",
    "PlannerTrace": "mpcbox.controllers.sampling",
    "ActuatorNoise": "mpcbox.sim.disturbances",
    "effort_noise": "mpcbox.sim.effort_noise",
    "Push": "mpcbox.sim.disturbances",
    "ModelMismatch": "mpcbox.sim.disturbances",
    "simulate": "mpcbox.sim.simulation",
    "SimulationResult": "mpcbox.sim.simulation",
    "Metrics": "mpcbox.sim.simulation",
    "simulate_realtime": "mpcbox.sim.realtime",
    "RealtimeStats": "mpcbox.sim.realtime",
    "LiveViewer": "mpcbox.sim.live_viewer",
    "OffscreenViewer": "mpcbox.sim.offscreen_viewer",
    "make_viewer": "mpcbox.sim.viewer_choice",
    "compare": "mpcbox.comparison.runner",
    "Scenario": "mpcbox.comparison.scenario",
    "make_controller": "mpcbox.registry",
}

__all__ = [
    "BackendUnavailableError",
    "CostDefinitionError",
    "DivergenceError",
    "InvalidArgumentError",
    "InvalidTypeError",
    "ModelLoadError",
    "ModelNotFoundError",
    "ModelWarning",
    "MpcboxError",
    "MujocoError",
    "NoControlAuthorityError",
    "NotStabilizableError",
    "PeriodWarning",
    "PlanningModelWarning",
    "PostureWarning",
    "RunError",
    "ShapeError",
    "SolverError",
    "UnknownNameError",
    "UnknownOptionError",
    "UnsupportedCostTermError",
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
