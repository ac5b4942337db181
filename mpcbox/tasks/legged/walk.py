r"""A quadruped walking its root to a target point on the ground."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.sampling.config import CEMConfig, MPPIConfig, PredictiveSamplingConfig
from mpcbox.core.cost import ControlCost, Cost, CostTerm, FrameHeight, FramePosition, StateCost
from mpcbox.core.model import ModelSource, dof_weights
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.measures import Measure
from mpcbox.tasks.legged.measures import TargetDistance, Tilt
from mpcbox.tasks.legged.quadruped import DM_CONTROL_FEET, QuadrupedStand, dm_control_quadruped
from mpcbox.validation import finite_array, non_negative_weights, optional_positive, positive

#: Config shared by the walk's sampling controllers, sized for the CPU backend: 128
#: candidates, a 0.5 s horizon of 50 planning steps of 0.01 s and four cubic knots, noise
#: 0.3 (control units: a fraction of the dm_control quadruped's unit range, radians of the
#: Go1's servo targets), replanning at 50 Hz. Chosen on seeds 0 and 1 of both robots in
#: lock-step (benchmarks/quadruped_walk.py). With distance and height weights of 10 and
#: 100 the Go1 stood still for 2-3 s before hopping off; with 30 and 300 and a 0.02 s
#: planning step it reached the target on both seeds and fell after it on seed 1, while
#: dm_control's quadruped walked in every setting; with 0.01 s PS, MPPI and CEM reached it
#: on both robots and both seeds, standing (CEM once its floor on the standard deviation
#: went from 0.05, where it missed one seed on dm_control's quadruped by 5 cm, to 0.15).
#: On the warp backend pass ``num_samples=1024``.
_COMMON: dict[str, Any] = dict(
    num_samples=128,
    horizon=0.5,
    num_knots=4,
    noise_scale=0.3,
    planning_timestep=0.01,
    period=0.02,
    headroom=4.0,
)


def _yaw_quaternion(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(4)
    mujoco.mju_mulQuat(out, a, b)
    return out


class QuadrupedWalk(QuadrupedStand):
    r"""Walk a quadruped's root to a point on the ground and stand there.

    By default dm_control's quadruped (:func:`~mpcbox.tasks.legged.quadruped.dm_control_quadruped`:
    Euler at 0.005 s, 12 filtered actuators on tendons); ``"menagerie:unitree_go1"`` and the other
    robots of :data:`~mpcbox.tasks.legged.quadruped.MENAGERIE_FEET` need no feet named, any
    other quadruped names its ``feet`` (and ``root`` when it is not the free body). The robot
    starts standing in its reference posture (:class:`~mpcbox.tasks.legged.balance.LeggedBalance`:
    the keyframe, settled on its feet) and the target is ``target`` (m, world x and y), by
    default ``distance`` straight ahead of the root along its x axis.

    Running cost (``terminal_scale`` times heavier at the end of the horizon), with
    :math:`p` the root's position, :math:`g` the target, :math:`z_{ref}` the root's height
    standing, :math:`R \ominus R_{ref}` the root's rotation from the reference posture turned
    to face the target (uprightness and heading at once):

    .. math::
        \tfrac12 w_d \|p_{xy} - g\|^2 + \tfrac12 w_h (p_z - z_{ref})^2
        + \tfrac12 w_o \|R \ominus R_{ref}\|^2 + \tfrac12 w_q \|q_j - q_{j,ref}\|^2
        + \tfrac12 w_v \|v\|^2 + \tfrac12 \|u - u_{ref}\|^2_{W_u} ,

    with :math:`q_j` the joint angles and :math:`W_u` ``ctrl_cost`` in ``ctrl_units``
    (LeggedBalance's robot-independent control units). Every term has the row form of the
    GPU cost kernels, so the warp backend plans with the same cost. A linear pull
    (:math:`w_d \|p_{xy} - g\|`) or a walking speed held toward the target would be the
    same near the goal and gentler far from it; the quadratic one is kept because both
    backends evaluate it, and the default distance (1 m) keeps the pull moderate.

    A run fails when the root falls below ``fall_height`` (by default 0.6 times its height
    standing) or tilts past ``fall_tilt``; it misses its goal (:meth:`goal_failure`) when the
    root never comes within ``radius`` of the target by ``time_limit`` (default: the end of
    the run). :meth:`time_to_target` is the first time it does; the measure
    ``target_distance`` reports the final distance.

    Args:
        model: The robot (default: dm_control's quadruped).
        feet: Its feet (default: the toes of dm_control's quadruped, or those of a known
            Menagerie robot).
        target: Target ``(2,)`` in world x and y (m); default ``distance`` ahead.
        distance: See ``target`` (m).
        radius: The target is reached within this horizontal distance of the root (m).
        time_limit: The target must be reached by this time (s; ``None``: the run's end).
        distance_cost: :math:`w_d` (per m²).
        height_cost: :math:`w_h` (per m²).
        orientation_cost: :math:`w_o` (per rad²).
        posture_cost: :math:`w_q` (per rad²).
        velocity_cost: :math:`w_v`.
        ctrl_cost: Weight of the control deviations, in ``ctrl_units`` (LeggedBalance).
        terminal_scale: Multiplier of the terminal cost.
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance`
            (``root``, ``keyframe``, ``fall_height``, ``ctrl_units``, ...).

    Raises:
        InvalidArgumentError: If an option is out of range, or the feet of a robot are
            unknown.
    """

    name = "quadruped_walk"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "ps": PredictiveSamplingConfig(**_COMMON),
        "mppi": MPPIConfig(temperature=0.1, **_COMMON),
        "cem": CEMConfig(num_elites=16, std_min=0.15, **_COMMON),
    }

    def __init__(
        self,
        model: ModelSource | None = None,
        *,
        feet: Sequence[str] | None = None,
        target: Sequence[float] | np.ndarray | None = None,
        distance: float = 1.0,
        radius: float = 0.2,
        time_limit: float | None = None,
        distance_cost: float = 30.0,
        height_cost: float = 300.0,
        orientation_cost: float = 10.0,
        posture_cost: float = 0.1,
        velocity_cost: float = 0.01,
        ctrl_cost: float = 0.1,
        terminal_scale: float = 5.0,
        **kwargs: Any,
    ) -> None:
        if model is None:
            model = dm_control_quadruped()
            feet = DM_CONTROL_FEET if feet is None else feet
        self.target_arg = None if target is None else finite_array("target", target, (2,))
        self.distance = positive("distance", distance)
        self.radius = positive("radius", radius)
        self.time_limit = optional_positive("time_limit", time_limit)
        self.walk_weights = non_negative_weights(
            distance_cost=distance_cost,
            height_cost=height_cost,
            orientation_cost=orientation_cost,
            posture_cost=posture_cost,
            velocity_cost=velocity_cost,
            terminal_scale=terminal_scale,
        )
        kwargs.setdefault("recovery_tilt", None)
        super().__init__(model, feet=feet, ctrl_cost=ctrl_cost, **kwargs)

    # ------------------------------------------------------------------ construction
    def prepare(self, model: mujoco.MjModel) -> None:
        super().prepare(model)
        data = mujoco.MjData(model)
        data.qpos[:] = self.qpos_ref
        mujoco.mj_kinematics(model, data)
        start = data.xpos[self.root_id].copy()
        #: The root's position standing at the start ``(3,)`` (m).
        self.start = start
        #: The root's height standing (m).
        self.root_height = float(start[2])
        forward = data.xmat[self.root_id].reshape(3, 3)[:2, 0]
        if self.target_arg is None:
            heading = forward / max(float(np.linalg.norm(forward)), 1e-9)
            #: The target ``(2,)`` (m, world x and y).
            self.target = start[:2] + self.distance * heading
        else:
            self.target = self.target_arg.copy()
        to_target = self.target - start[:2]
        if np.linalg.norm(to_target) <= self.radius:
            raise InvalidArgumentError(
                f"target: {self.target.tolist()} is within radius {self.radius:g} m of the "
                f"root's start {start[:2].tolist()}; nothing to walk"
            )
        turn = np.arctan2(to_target[1], to_target[0]) - np.arctan2(forward[1], forward[0])
        self.goal_qpos = self.qpos_ref.copy()
        #: ``qpos`` address of the root's free joint (``None`` when the root has none).
        self.root_qpos = self._free_root_qpos(model)
        if self.root_qpos is not None:
            adr = self.root_qpos
            self.goal_qpos[adr + 3 : adr + 7] = _quat_multiply(
                _yaw_quaternion(float(turn)), self.qpos_ref[adr + 3 : adr + 7]
            )

    def _free_root_qpos(self, model: mujoco.MjModel) -> int | None:
        """``qpos`` address of the root's free joint (None if the root has none)."""
        for j in range(model.body_jntnum[self.root_id]):
            joint = model.body_jntadr[self.root_id] + j
            if model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_FREE:
                return int(model.jnt_qposadr[joint])
        return None

    def _terms(self, model: mujoco.MjModel, scale: float, suffix: str) -> list[CostTerm]:
        w = self.walk_weights
        wq = dof_weights(model, w["posture"], free=(0.0, 0.0, 0.0, *[w["orientation"]] * 3))
        goal = np.array([*self.target, 0.0])
        return [
            FramePosition(
                self.root,
                goal,
                weight=scale * w["distance"] * np.array([1.0, 1.0, 0.0]),
                name="target" + suffix,
            ),
            FrameHeight(
                self.root, self.root_height, weight=scale * w["height"], name="height" + suffix
            ),
            StateCost(
                self.goal_qpos,
                weight_qpos=scale * wq,
                weight_qvel=scale * w["velocity"],
                name="posture" + suffix,
            ),
        ]

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        control = ControlCost(self.ctrl_ref, weight=self.ctrl_weights(model))
        running = [*self._terms(model, 1.0, ""), control]
        return Cost(running, self._terms(model, self.walk_weights["terminal"], "_terminal"))

    # ------------------------------------------------------------------ monitoring
    def root_positions(self, states: np.ndarray) -> np.ndarray:
        """The root's position ``(T, 3)`` in states ``(T, nstate)`` (m)."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        if self.root_qpos is not None:
            return states[:, self.root_qpos : self.root_qpos + 3].copy()
        data = mujoco.MjData(self.model)
        out = np.empty((len(states), 3))
        for i, state in enumerate(states):
            data.qpos[:] = state[: self.nq]
            mujoco.mj_kinematics(self.model, data)
            out[i] = data.xpos[self.root_id]
        return out

    def target_distances(self, states: np.ndarray) -> np.ndarray:
        """Horizontal distance ``(T,)`` of the root from the target in states ``(T, nstate)``."""
        return np.linalg.norm(self.root_positions(states)[:, :2] - self.target, axis=1)

    def time_to_target(self, time: np.ndarray, states: np.ndarray) -> float:
        """First time ``time[k]`` the root is within ``radius`` of the target (s; NaN when
        it never is, or only after ``time_limit``)."""
        time = np.asarray(time, dtype=float)
        inside = np.flatnonzero(self.target_distances(states) <= self.radius)
        if inside.size == 0:
            return float("nan")
        first = float(time[inside[0]])
        if self.time_limit is not None and first > self.time_limit + 1e-9:
            return float("nan")
        return first

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        time = np.asarray(time, dtype=float)
        if time.size == 0:
            return "no states recorded"
        if np.isnan(self.time_to_target(time, states)):
            distances = self.target_distances(states)
            limit = "" if self.time_limit is None else f" by {self.time_limit:g} s"
            return (
                f"missed the target{limit}: closest {distances.min():.2f} m, final "
                f"{distances[-1]:.2f} m (within {self.radius:g} m counts)"
            )
        return None

    def measures(self) -> tuple[Measure, ...]:
        """The root's distance from the target (m; final, and the time it stays within
        ``radius`` for good) and its tilt (deg)."""
        return (
            TargetDistance(body=self.root, target=tuple(self.target), tolerance=self.radius),
            Tilt(body=self.root),
        )
