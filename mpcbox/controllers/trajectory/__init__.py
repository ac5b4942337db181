"""Joint trajectories: quintic point-to-point moves and time-varying LQR tracking of them."""

from mpcbox.controllers.trajectory.quintic import JointTrajectory, quintic
from mpcbox.controllers.trajectory.reference import (
    TrackingReference,
    TrackingWeights,
    tracking_reference,
)
from mpcbox.controllers.trajectory.tracker import TrajectoryTracker

__all__ = [
    "JointTrajectory",
    "TrackingReference",
    "TrackingWeights",
    "TrajectoryTracker",
    "quintic",
    "tracking_reference",
]
