r"""Residual cost terms.

A cost term is a weighted least-squares residual,
:math:`\ell(x, u) = \tfrac12 \sum_i w_i \, r_i(x, u)^2`; a :class:`Cost` holds a Problem's
running and terminal terms. One file per concept: the protocol and the :class:`Cost`
(:mod:`~mpcbox.core.cost.base`), the row vocabulary of the GPU kernels
(:mod:`~mpcbox.core.cost.rows`), and the terms (state, control, frames, center of mass
position and velocity, quadratic value, wrapped angle, clearance from a sphere, actuator effort,
total energy).
"""

from mpcbox.core.cost.actuator_force import ActuatorForce
from mpcbox.core.cost.angle import WrappedAngle
from mpcbox.core.cost.base import (
    STAGES,
    Cost,
    CostTerm,
    Features,
    Jacobian,
    SensorRequest,
    forward_stage,
)
from mpcbox.core.cost.clearance import SphereClearance
from mpcbox.core.cost.com import ComOverSupport, ComVelocity
from mpcbox.core.cost.control import ControlCost
from mpcbox.core.cost.energy import Energy, rest_energy
from mpcbox.core.cost.frames import FrameHeight, FramePosition, HeightAbove, Upright
from mpcbox.core.cost.state import StateCost
from mpcbox.core.cost.value import QuadraticValue

__all__ = [
    "STAGES",
    "ActuatorForce",
    "ComOverSupport",
    "ComVelocity",
    "ControlCost",
    "Cost",
    "CostTerm",
    "Energy",
    "Features",
    "FrameHeight",
    "FramePosition",
    "HeightAbove",
    "Jacobian",
    "QuadraticValue",
    "SensorRequest",
    "SphereClearance",
    "StateCost",
    "Upright",
    "WrappedAngle",
    "forward_stage",
    "rest_energy",
]
