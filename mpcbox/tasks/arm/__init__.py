"""Arm trajectories: point-to-point moves planned as a quintic or by iLQR, tracked by LQR."""

from mpcbox.tasks.arm.measures import Overshoot, TargetError, TrackingError
from mpcbox.tasks.arm.moves import (
    ArmMove,
    MoveReport,
    ilqr_move,
    move_report,
    move_tracker,
    quintic_move,
    step_move,
)
from mpcbox.tasks.arm.track import ArmTrack, Sphere

__all__ = [
    "ArmMove",
    "ArmTrack",
    "MoveReport",
    "Overshoot",
    "Sphere",
    "TargetError",
    "TrackingError",
    "ilqr_move",
    "move_report",
    "move_tracker",
    "quintic_move",
    "step_move",
]
