"""Joint trajectories: quintic point-to-point moves, offline plans, and time-varying LQR
tracking of them."""

from mpcbox.controllers.trajectory.offline_plan import OfflinePlanTracker
from mpcbox.controllers.trajectory.quintic import JointTrajectory, quintic
from mpcbox.controllers.trajectory.reference import (
    TrackingReference,
    TrackingWeights,
    tracking_reference,
)
from mpcbox.controllers.trajectory.tracker import TrajectoryTracker

__all__ = [
    "JointTrajectory",
    "OfflinePlanTracker",
    "TrackingReference",
    "TrackingWeights",
    "TrajectoryTracker",
    "quintic",
    "tracking_reference",
]
