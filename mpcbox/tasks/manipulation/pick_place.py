r"""Pick-and-place phases for :class:`~mpcbox.controllers.waypoints.WaypointController`.

The phases of a top-down pick-and-place, each replanned from the measured cube poses:

* approach: above the object, gripper open, yawed to the object's faces (replanned);
* descend: down to grasp height (replanned: follows the object if it moved);
* close: close the gripper;
* lift: straight up;
* move: above the goal, the held object yawed to the goal's faces (replanned);
* place: lower until the held object's centre is at the goal (replanned from the measured
  object: the waypoint is the end effector plus the object's error);
* release: open the gripper;
* retreat: straight up;
* settle: wait (the success check is taken after it).

Top-down grasps are the rotation :math:`R_z(\psi) R_x(\pi)` of the arm's ``tcp`` site
(:mod:`.arms`). Of the four yaws :math:`\psi` that align the fingers with a cube's faces
(cube yaw plus multiples of :math:`\pi/2`), the approach picks the one closest to the
arm's natural yaw there: the yaw the end effector has at the arm's home posture, turned by
the bearing of the cube from the base (ALOHA: fingers closing across the reach direction;
Panda: along it), so the wrist turns at most 45 degrees from its home.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.waypoints import (
    ArmDrive,
    Phase,
    Waypoint,
    WaypointConfig,
    WaypointController,
)
from mpcbox.tasks.manipulation.arms import ArmSpec
from mpcbox.tasks.manipulation.scene import ARM_PREFIX, TCP_SITE
from mpcbox.tasks.manipulation.stacking import StackCubes


class PickPlaceTiming(NamedTuple):
    """Durations (move, hold) of each phase (s) and heights (m).

    Attributes:
        approach: Move and hold above the object.
        descend: Move and hold at grasp height.
        close: Gripper closing and hold.
        lift: Move and hold up.
        move: Move and hold above the goal.
        place: Move and hold at the goal.
        release: Gripper opening and hold.
        retreat: Move and hold up.
        settle: Wait before the success check.
        hover: Height of the approach above the object's centre (m).
        clearance: Gap between the held object's bottom and the goal's top when moving (m).
        drop: Gap left under the held object when it is released (m).
    """

    approach: tuple[float, float] = (1.2, 0.1)
    descend: tuple[float, float] = (0.8, 0.2)
    close: tuple[float, float] = (0.4, 0.2)
    lift: tuple[float, float] = (0.6, 0.1)
    move: tuple[float, float] = (1.0, 0.2)
    place: tuple[float, float] = (0.6, 0.4)
    release: tuple[float, float] = (0.3, 0.1)
    retreat: tuple[float, float] = (0.5, 0.0)
    settle: tuple[float, float] = (0.0, 0.5)
    hover: float = 0.10
    clearance: float = 0.04
    drop: float = 0.003

    @property
    def total(self) -> float:
        """Length of all phases (s): the run time the task needs."""
        return float(sum(sum(getattr(self, f)) for f in self._fields[:9]))


def top_down(yaw: float) -> np.ndarray:
    r"""Quaternion ``[w, x, y, z]`` of :math:`R_z(\psi) R_x(\pi)` (a top-down grasp)."""
    return np.array([0.0, np.cos(yaw / 2), np.sin(yaw / 2), 0.0])


def body_yaw(data: mujoco.MjData, body: str) -> float:
    """Yaw of ``body`` (rad): the heading of its ``x`` axis in the horizontal plane."""
    mat = data.body(body).xmat
    return float(np.arctan2(mat[3], mat[0]))


def frame_yaw(data: mujoco.MjData, site: str) -> float:
    """Yaw of a top-down site: the heading of its ``x`` (closing) axis."""
    mat = data.site(site).xmat
    return float(np.arctan2(mat[3], mat[0]))


def nearest_quarter(angle: float, reference: float) -> float:
    """``angle`` plus the multiple of :math:`\\pi/2` that brings it closest to ``reference``."""
    k = np.round((reference - angle) / (np.pi / 2))
    return float(angle + k * np.pi / 2)


def pick_place_phases(
    arm: ArmSpec,
    *,
    obj: str,
    goal: str,
    size: float,
    timing: PickPlaceTiming | None = None,
    home_yaw: float = np.pi / 2,
) -> tuple[Phase, ...]:
    """The phases that put cube ``obj`` on top of cube ``goal`` (bodies of edge ``size``).

    Args:
        arm: The arm, with the names it has in the scene (prefixed).
        obj: Body of the object to pick.
        goal: Body to stack it on.
        size: Cube edge (m).
        timing: Phase durations and heights.
        home_yaw: Yaw of the end effector (its closing axis) at the arm's home posture,
            relative to the base's heading (rad).
    """
    t = PickPlaceTiming() if timing is None else timing
    tcp = ARM_PREFIX + TCP_SITE
    base = arm.base
    half = size / 2

    def grasp_yaw(d: mujoco.MjData) -> float:
        rel = d.body(obj).xpos - d.body(base).xpos
        natural = float(np.arctan2(rel[1], rel[0])) - arm.mount_yaw + home_yaw
        return nearest_quarter(body_yaw(d, obj), natural)

    def approach(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        # The first plan picks the yaw; replans follow the object without jumping a quarter.
        yaw = memo.get("yaw")
        memo["yaw"] = grasp_yaw(d) if yaw is None else nearest_quarter(body_yaw(d, obj), yaw)
        pos = d.body(obj).xpos + np.array([0.0, 0.0, t.hover])
        return Waypoint(pos, top_down(memo["yaw"]), arm.gripper_open)

    def descend(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        pos = d.body(obj).xpos.copy()
        pos[2] = half
        # Follow the object's yaw too (it may have been turned), without jumping a quarter.
        memo["yaw"] = nearest_quarter(body_yaw(d, obj), memo["yaw"])
        return Waypoint(pos, top_down(memo["yaw"]), arm.gripper_open)

    def close(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return Waypoint(None, None, arm.gripper_closed)

    def lift(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        pos = d.site(tcp).xpos.copy()
        pos[2] = d.body(goal).xpos[2] + half + size + t.clearance + (pos[2] - d.body(obj).xpos[2])
        return Waypoint(pos, None, None)

    def above_goal(d: mujoco.MjData, lift_by: float) -> Waypoint:
        # Move the end effector by the held object's error: the closed loop on the object.
        held = d.body(obj).xpos
        want = d.body(goal).xpos + np.array([0.0, 0.0, size + lift_by])
        yaw_now = frame_yaw(d, tcp)
        turn = nearest_quarter(body_yaw(d, goal), body_yaw(d, obj)) - body_yaw(d, obj)
        return Waypoint(d.site(tcp).xpos + (want - held), top_down(yaw_now + turn), None)

    def move(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return above_goal(d, t.clearance + t.drop)

    def place(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return above_goal(d, t.drop)

    def release(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return Waypoint(None, None, arm.gripper_open)

    def retreat(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return Waypoint(d.site(tcp).xpos + np.array([0.0, 0.0, t.hover]), None, None)

    def settle(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> Waypoint:
        return Waypoint(None, None, None)

    steps = (
        ("approach", approach, True),
        ("descend", descend, True),
        ("close", close, False),
        ("lift", lift, False),
        ("move", move, True),
        ("place", place, True),
        ("release", release, False),
        ("retreat", retreat, False),
        ("settle", settle, False),
    )
    return tuple(
        Phase(name, fn, getattr(t, name)[0], getattr(t, name)[1], replan)
        for name, fn, replan in steps
    )


def arm_drive(arm: ArmSpec) -> ArmDrive:
    """The :class:`ArmDrive` of an arm of a manipulation scene (prefixed names)."""
    return ArmDrive(
        frame=ARM_PREFIX + TCP_SITE,
        joints=arm.joints,
        actuators=arm.actuators,
        posture=arm.home,
        gripper=arm.gripper,
        ik_ranges=arm.ik_ranges,
    )


def stacking_controller(
    problem: StackCubes,
    *,
    timing: PickPlaceTiming | None = None,
    config: WaypointConfig | None = None,
) -> WaypointController:
    """The closed-loop stacking controller for a
    :class:`~mpcbox.tasks.manipulation.stacking.StackCubes` problem: red on blue.

    Args:
        problem: The StackCubes problem.
        timing: Phase durations and heights (run it for at least ``timing.total`` s).
        config: Options of the :class:`~mpcbox.controllers.waypoints.WaypointController`.
    """
    arm = problem.arm
    size = problem.cube_size
    data = mujoco.MjData(problem.model)
    data.qpos[:] = problem.qpos_ref
    mujoco.mj_kinematics(problem.model, data)
    home_yaw = frame_yaw(data, ARM_PREFIX + TCP_SITE) - arm.mount_yaw
    phases = pick_place_phases(
        arm, obj="red_cube", goal="blue_cube", size=size, timing=timing, home_yaw=home_yaw
    )
    return WaypointController(
        problem,
        arms=[arm_drive(arm)],
        phases=phases,
        config=config,
    )
