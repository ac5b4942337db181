"""Reach: move an arm's end effector to a target position (and orientation), any arm.

The goal posture comes from inverse kinematics with collision avoidance
(:func:`mpcbox.core.posture.reach_posture`), and the control that holds it from the actuator
model (:func:`mpcbox.find_equilibrium`: torque for motors, set-point for position servos), so
LQR about the goal is available out of the box and iLQR starts from a sensible reference.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost import ControlCost, Cost, FramePosition, StateCost
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.model import ModelSource, frame_position, object_id
from mpcbox.core.posture import reach_posture
from mpcbox.core.problem import Problem
from mpcbox.validation import as_array, positive


class ArmReach(Problem):
    r"""Bring ``frame`` to ``target`` from a start posture and hold it there.

    Running cost, with :math:`p` the frame position and :math:`q^\star` the IK goal posture:

    .. math::
        w_p \|p - p^\star\|^2 + w_q \|q - q^\star\|^2 + w_v \|\dot q\|^2
        + w_u \|u - u^\star\|^2

    where :math:`u^\star` holds :math:`q^\star` against gravity through the actuators. The
    terminal cost weighs position and velocity ten times more.

    Args:
        model: The arm's MJCF (path, XML, spec, or ``"menagerie:NAME"``).
        frame: End-effector site or body name.
        target: Target position ``(3,)`` in the world frame (m), or with ``relative=True`` an
            offset from the frame's start position.
        orientation: Target orientation (unit quaternion ``[w, x, y, z]``) for the IK goal
            posture; ``None`` leaves it free.
        relative: Read ``target`` as an offset from the start position.
        keyframe: Start posture (name or index); default: the model's first keyframe, else
            ``qpos0``.
        tolerance: Distance (m) within which the frame counts as arrived.
        position_weight: :math:`w_p`.
        posture_weight: :math:`w_q`.
        velocity_weight: :math:`w_v`.
        ctrl_weight: :math:`w_u`, in the units of the controls.
        avoid_collisions: Keep the IK goal posture free of collisions.
        **kwargs: Passed to :class:`~mpcbox.Problem` (``planning_timestep``, ...).
    """

    name = "arm_reach"

    def __init__(
        self,
        model: ModelSource,
        *,
        frame: str,
        target: np.ndarray,
        orientation: np.ndarray | None = None,
        relative: bool = False,
        keyframe: str | int | None = None,
        tolerance: float = 0.01,
        position_weight: float = 100.0,
        posture_weight: float = 0.1,
        velocity_weight: float = 1.0,
        ctrl_weight: float = 0.01,
        avoid_collisions: bool = True,
        **kwargs: Any,
    ) -> None:
        self.frame = frame
        self.target_input = as_array("target", target, (3,)).copy()
        self.orientation = (
            None if orientation is None else as_array("orientation", orientation, (4,))
        )
        self.relative = bool(relative)
        self.tolerance = positive("tolerance", tolerance)
        self.weights = {
            "position_weight": positive("position_weight", position_weight),
            "posture_weight": float(posture_weight),
            "velocity_weight": float(velocity_weight),
            "ctrl_weight": float(ctrl_weight),
        }
        self.avoid_collisions = bool(avoid_collisions)
        self._start_key = keyframe
        super().__init__(model, **kwargs)

    # ------------------------------------------------------------------ construction
    def prepare(self, model: mujoco.MjModel) -> None:
        if self._start_key is not None:
            key = object_id(model, "keyframe", self._start_key)
            self.start_qpos = model.key_qpos[key].copy()
        elif model.nkey:
            self.start_qpos = model.key_qpos[0].copy()
        else:
            self.start_qpos = model.qpos0.copy()
        data = mujoco.MjData(model)
        data.qpos[:] = self.start_qpos
        mujoco.mj_forward(model, data)
        self.start_position = frame_position(model, data, self.frame)
        self.target = (
            self.start_position + self.target_input if self.relative else self.target_input
        )
        goal = reach_posture(
            model,
            self.start_qpos,
            frame=self.frame,
            position=self.target,
            orientation=self.orientation,
            avoid_collisions=self.avoid_collisions,
        )
        self.goal = goal
        self.qpos_ref = goal.qpos.copy()
        self.ctrl_ref = find_equilibrium(model, goal.qpos).ctrl.copy()

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        w = self.weights
        return Cost(
            [
                FramePosition(self.frame, self.target, weight=w["position_weight"], name="reach"),
                StateCost(
                    self.qpos_ref,
                    weight_qpos=w["posture_weight"],
                    weight_qvel=w["velocity_weight"],
                    name="posture",
                ),
                ControlCost(self.ctrl_ref, weight=w["ctrl_weight"]),
            ],
            [
                FramePosition(
                    self.frame, self.target, weight=10 * w["position_weight"], name="reach_end"
                ),
                StateCost(
                    self.qpos_ref,
                    weight_qpos=w["posture_weight"],
                    weight_qvel=10 * w["velocity_weight"],
                    name="posture_end",
                ),
            ],
        )

    def initial_state(self) -> np.ndarray:
        state = np.zeros(self.nstate)
        state[: self.nq] = self.start_qpos
        return state

    # ------------------------------------------------------------------ measures
    def frame_position(self, state: np.ndarray) -> np.ndarray:
        """The end effector's world position ``(3,)`` at ``state``."""
        data = mujoco.MjData(self.model)
        self.set_state(data, state)
        mujoco.mj_kinematics(self.model, data)
        return frame_position(self.model, data, self.frame)

    def reach_error(self, state: np.ndarray) -> float:
        """Distance (m) from the end effector to the target at ``state``."""
        return float(np.linalg.norm(self.frame_position(state) - self.target))
