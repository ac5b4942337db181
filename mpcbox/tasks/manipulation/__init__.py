"""Manipulation tasks: scenes written with ``MjSpec`` (a table, objects, an arm attached
through a frame) and the pick-and-place phases that
:class:`~mpcbox.controllers.waypoints.WaypointController` runs on them."""

from __future__ import annotations

from mpcbox.tasks.manipulation.arms import ARMS, ArmSpec, arm_spec
from mpcbox.tasks.manipulation.pick_place import PickPlaceTiming, stacking_controller
from mpcbox.tasks.manipulation.scene import CubeLayout, stacking_model, stacking_scene
from mpcbox.tasks.manipulation.stacking import StackCheck, StackCubes, stack_check

__all__ = [
    "ARMS",
    "ArmSpec",
    "CubeLayout",
    "PickPlaceTiming",
    "StackCheck",
    "StackCubes",
    "arm_spec",
    "stack_check",
    "stacking_controller",
    "stacking_model",
    "stacking_scene",
]
