r"""Bimanual lift of ALOHA's pot: both arms grasp the pot's handles and lift it.

The scene is mujoco-warp's ``test_data/aloha_pot/scene.xml`` (two ViperX 300s arms and a
2.1 kg pot with two handle bars) with a ``tcp`` site added to each gripper (as in
:mod:`.arms`). The same :class:`~mpcbox.controllers.waypoints.WaypointController` drives
both arms, one waypoint per arm per phase: approach above the handles, descend onto them,
close, lift, hold. Each handle is grasped top-down at the middle of its bar, fingers
closing across the bar.

**Success**: at the end of the hold, the pot's centre is at least :data:`LIFT_HEIGHT`
above where it started and tilted less than :data:`MAX_TILT` from upright.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.waypoints import ArmDrive, Phase, Waypoint, WaypointController
from mpcbox.core.problem import Problem
from mpcbox.tasks.manipulation.arms import aloha_scene_path
from mpcbox.tasks.manipulation.pick_place import body_yaw, top_down
from mpcbox.validation import as_array

#: Least rise of the pot's centre for a lift (m).
LIFT_HEIGHT = 0.05
#: Largest tilt of a lifted pot from upright (rad).
MAX_TILT = np.deg2rad(15.0)
#: The pot's root body and free joint.
POT = "partnet_100015/"
#: Middle of each handle bar in the pot's frame (m), from its collision meshes: the bars
#: run along the pot's x axis at y = +-0.1755, between posts at x = -0.032 and 0.018.
HANDLES = {"left": (-0.005, 0.1755, 0.0625), "right": (-0.005, -0.1755, 0.0625)}
_JOINTS = ("waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate")
_HOME = (0.0, -0.96, 1.16, 0.0, -0.3, 0.0)
#: The forearm roll limits of :mod:`.arms` that keep the IK on top-down branches.
_IK_RANGES = (None, None, None, (-1.2, 1.2), None, None)


class PotLiftTiming(NamedTuple):
    """Durations (move, hold) of the phases (s) and heights (m).

    Attributes:
        approach: Above the handles.
        descend: Onto the handles.
        close: Grippers closing.
        lift: Up by ``lift``.
        hold: Holding the pot up (the success check is at its end).
        hover: Approach height above the handles (m).
        lift_by: Height the hands rise in the lift (m).
        grasp_depth: How far below the bar's middle the tool centre point goes (m).
    """

    approach: tuple[float, float] = (1.5, 0.2)
    descend: tuple[float, float] = (0.8, 0.3)
    close: tuple[float, float] = (0.4, 0.3)
    lift: tuple[float, float] = (1.2, 0.3)
    hold: tuple[float, float] = (0.0, 1.0)
    hover: float = 0.08
    lift_by: float = 0.10
    grasp_depth: float = 0.0

    @property
    def total(self) -> float:
        """Length of all phases (s)."""
        return float(sum(sum(getattr(self, f)) for f in self._fields[:5]))


def pot_scene() -> mujoco.MjSpec:
    """The ALOHA pot scene as a spec, with a ``tcp`` site on each gripper."""
    spec = mujoco.MjSpec.from_file(str(aloha_scene_path()))
    axes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # see .arms
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.reshape(9))
    for side in ("left", "right"):
        spec.body(f"{side}\\gripper_link").add_site(
            name=f"{side}\\tcp", pos=[0.128, 0.0, 0.0], quat=list(quat), size=[0.005, 0, 0]
        )
    return spec


class PotLift(Problem):
    """Lift ALOHA's pot with both arms (see the module docstring).

    Args:
        seed: Shift the pot's start by up to 2 cm and turn it by up to 10 degrees, drawn
            from this seed (``None``: the scene's pose).
        **kwargs: Passed to :class:`~mpcbox.Problem`.
    """

    name = "pot_lift"

    def __init__(self, *, seed: int | None = None, **kwargs: Any) -> None:
        self.seed = seed
        super().__init__(pot_scene(), keyframe="neutral_pose", **kwargs)

    def prepare(self, model: mujoco.MjModel) -> None:
        self._pot_adr = int(model.jnt_qposadr[model.joint(POT).id])

    def trial_state(self, seed: int | None) -> np.ndarray:
        """Start state: the keyframe, the pot shifted and turned as drawn from ``seed``."""
        state = np.zeros(self.nstate)
        state[: self.nq] = self.qpos_ref
        if seed is not None:
            rng = np.random.default_rng(seed)
            adr = self._pot_adr
            state[adr : adr + 2] += rng.uniform(-0.02, 0.02, size=2)
            yaw = rng.uniform(-np.deg2rad(10), np.deg2rad(10))
            state[adr + 3 : adr + 7] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        return state

    def initial_state(self) -> np.ndarray:
        return self.trial_state(self.seed)

    def pot_height(self, state: np.ndarray) -> float:
        """Height of the pot's frame at ``state`` ``(nstate,)`` (m)."""
        return float(as_array("state", state, (self.nstate,))[self._pot_adr + 2])

    def pot_tilt(self, state: np.ndarray) -> float:
        """Angle between the pot's up axis and the world's (rad), at ``state``
        ``(nstate,)``."""
        state = as_array("state", state, (self.nstate,))
        quat = state[self._pot_adr + 3 : self._pot_adr + 7]
        x, y = quat[1:3] / np.linalg.norm(quat)
        return float(np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)))

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        """Why the pot is not lifted at the end, or ``None``."""
        states = as_array("states", states, (None, self.nstate))
        if len(states) == 0:
            return "no states recorded"
        rise = self.pot_height(states[-1]) - self.pot_height(states[0])
        tilt = self.pot_tilt(states[-1])
        if rise >= LIFT_HEIGHT and tilt <= MAX_TILT:
            return None
        return (
            f"pot rose {1000 * rise:.0f} mm (need {1000 * LIFT_HEIGHT:.0f}), tilted "
            f"{np.rad2deg(tilt):.1f} deg (at most {np.rad2deg(MAX_TILT):.0f})"
        )


def pot_lift_controller(
    problem: PotLift, *, timing: PotLiftTiming | None = None
) -> WaypointController:
    """The bimanual :class:`~mpcbox.controllers.waypoints.WaypointController` for
    :class:`PotLift`: left arm on the handle at the pot's ``+y``, right arm on ``-y``."""
    t = PotLiftTiming() if timing is None else timing
    sides = ("left", "right")

    def grasps(d: mujoco.MjData, memo: dict, hover: float) -> list[Waypoint]:
        pot = d.body(POT)
        rot = pot.xmat.reshape(3, 3)
        out = []
        for side in sides:
            handle = pot.xpos + rot @ np.asarray(HANDLES[side])
            handle[2] += hover - t.grasp_depth
            if side not in memo:  # the yaw of the grasp, chosen once per run
                base = d.body(f"{side}\\base_link").xpos
                natural = float(np.arctan2(handle[1] - base[1], handle[0] - base[0])) + np.pi / 2
                across = body_yaw(d, POT) + np.pi / 2  # fingers close along the pot's y axis
                memo[side] = min((across, across + np.pi), key=lambda a: -np.cos(a - natural))
            out.append(Waypoint(handle, top_down(memo[side]), 0.037))
        return out

    def approach(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> list[Waypoint]:
        return grasps(d, memo, t.hover)

    def descend(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> list[Waypoint]:
        return grasps(d, memo, 0.0)

    def close(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> list[Waypoint]:
        return [Waypoint(None, None, 0.002)] * 2

    def lift(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> list[Waypoint]:
        return [Waypoint(d.site(f"{s}\\tcp").xpos + np.array([0.0, 0.0, t.lift_by])) for s in sides]

    def hold(m: mujoco.MjModel, d: mujoco.MjData, memo: dict) -> list[Waypoint]:
        return [Waypoint()] * 2

    steps = (("approach", approach, False), ("descend", descend, True), ("close", close, False))
    steps += (("lift", lift, False), ("hold", hold, False))
    phases = [Phase(n, fn, getattr(t, n)[0], getattr(t, n)[1], r) for n, fn, r in steps]
    arms = [
        ArmDrive(
            frame=f"{s}\\tcp",
            joints=tuple(f"{s}\\{j}" for j in _JOINTS),
            actuators=tuple(f"{s}\\{j}" for j in _JOINTS),
            posture=_HOME,
            gripper=f"{s}\\gripper",
            ik_ranges=_IK_RANGES,
        )
        for s in sides
    ]
    return WaypointController(problem, arms=arms, phases=phases)
