r"""ArmTrack: a point-to-point arm move in a given time, planned, then tracked in closed loop.

The move goes from the start posture :math:`q_0` to a goal posture :math:`q^\star` (given,
or from inverse kinematics of an end-effector ``target`` as in
:class:`~mpcbox.tasks.reach.ArmReach`) in ``duration`` seconds :math:`T`. Two plans exist:
the quintic in joint space (:meth:`ArmTrack.joint_reference`), and the iLQR-optimal one
(:func:`~mpcbox.tasks.arm.moves.ilqr_move`) of the task's cost over :math:`T`,

.. math::
    \sum_{t < N} \Big( \tfrac12 w_q \lVert q_t - q^\star \rVert^2
      + \tfrac12 w_v \lVert \dot q_t \rVert^2
      + \tfrac12 w_\tau \lVert m \odot (f_t - f^\star) \rVert^2
      + \tfrac12 w_o \sum_i \max(0, \rho - \lVert p_i - c \rVert)^2 \Big)
    + \tfrac12 W \big( \lVert p_N - p^\star \rVert^2 + \lVert q_N - q^\star \rVert^2
      + \lVert \dot q_N \rVert^2 \big),

with :math:`N = T / \Delta t`, :math:`f_t` the actuator forces
(:class:`~mpcbox.core.cost.ActuatorForce`; for a position servo its torque, not its
set-point), :math:`m` their gears (so :math:`w_\tau` weighs joint torque), :math:`f^\star`
the forces holding :math:`q^\star`, and the
obstacle term (:class:`~mpcbox.core.cost.SphereClearance`) only with an ``obstacle``: the
frames ``clearance_frames`` (default: the end effector) keep :math:`\rho` = radius + margin
from its centre. The obstacle is virtual: a cost, not a geom in the model.

A body ``frame`` gets a site (``site``, at ``site_offset`` in the body's frame) so that
saved trajectories (:func:`~mpcbox.save_trajectory`) record the end effector's position.
The measures (:mod:`mpcbox.tasks.arm.measures`) compare the run with the current reference
(:meth:`ArmTrack.set_reference`; the quintic by default).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.trajectory.quintic import JointTrajectory, quintic
from mpcbox.controllers.trajectory.reference import reference_states
from mpcbox.core.actuation import actuator_moment
from mpcbox.core.cost import (
    ActuatorForce,
    Cost,
    FramePosition,
    SphereClearance,
    StateCost,
)
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.model import (
    ModelSource,
    compile_spec,
    frame_object,
    frame_position,
    object_id,
)
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.measures import Measure
from mpcbox.tasks import scene_path
from mpcbox.tasks.arm.measures import Overshoot, TargetError, TrackingError
from mpcbox.tasks.reach import ArmReach
from mpcbox.validation import as_array, finite_array, non_negative, positive


class Sphere(NamedTuple):
    """A spherical (virtual) obstacle.

    Attributes:
        center: Centre ``(3,)`` in the world frame (m).
        radius: Radius (m).
    """

    center: np.ndarray
    radius: float


#: Constructor arguments kept for :meth:`ArmTrack.task_options`.
_OPTIONS = (
    "model",
    "frame",
    "goal_qpos",
    "target",
    "relative",
    "duration",
    "hold",
    "obstacle",
    "margin",
    "clearance_frames",
    "site",
    "site_offset",
    "keyframe",
    "start_qpos",
    "tolerance",
    "posture_weight",
    "velocity_weight",
    "torque_weight",
    "goal_weight",
    "obstacle_weight",
    "avoid_collisions",
    "free_objects",
)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def _options(arguments: dict[str, Any]) -> dict[str, Any] | None:
    """The constructor's arguments as JSON values, or ``None`` when the model is not a path
    or a Menagerie name (an MJCF string, a spec, a compiled model) or a Problem option is
    not a plain number, string or flag."""
    model = arguments["model"]
    if not (isinstance(model, Path) or (isinstance(model, str) and "<" not in model)):
        return None
    extra = arguments.get("kwargs") or {}
    if not all(isinstance(v, (int, float, str, bool, type(None))) for v in extra.values()):
        return None
    return {**{name: _jsonable(arguments[name]) for name in _OPTIONS}, **extra}


class ArmTrack(ArmReach):
    """Move an arm from its start posture to a goal posture in ``duration`` seconds.

    Args:
        model: The arm's MJCF (path, XML, spec, or ``"menagerie:NAME"``); default: the
            three-joint arm shipped with mpcbox (``scenes/arm3.xml``).
        frame: End-effector site or body name.
        goal_qpos: Goal posture ``(nq,)``; or give ``target``; with neither, the model's
            keyframe ``"goal"``.
        target: End-effector target ``(3,)`` (m), reached by IK (see
            :class:`~mpcbox.tasks.reach.ArmReach`); ``relative`` reads it as an offset.
        relative: Read ``target`` as an offset from the start position.
        duration: Move time :math:`T` (s).
        hold: Time the reference rests on the goal after the move (s).
        obstacle: A :class:`Sphere` to keep clear of, or ``None``.
        margin: Safety margin added to the obstacle's radius in the cost (m).
        clearance_frames: Frames kept clear of the obstacle (default: the end effector).
        site: Name of the site added on a body ``frame``.
        site_offset: Its position ``(3,)`` in the body frame (m).
        keyframe: Start posture (name or index); default: the first keyframe, else ``qpos0``.
        start_qpos: Start posture ``(nq,)`` replacing the keyframe's.
        tolerance: Settling band of the end effector around the target (m).
        posture_weight: :math:`w_q`.
        velocity_weight: :math:`w_v`.
        torque_weight: :math:`w_\\tau` (per N m squared).
        goal_weight: :math:`W`.
        obstacle_weight: :math:`w_o`.
        avoid_collisions: Keep the IK goal posture free of collisions (with ``target``).
        free_objects: ``"weld"`` or ``"error"``, as for ArmReach.
        **kwargs: Passed to :class:`~mpcbox.Problem`.

    Raises:
        InvalidArgumentError: For neither or both of ``goal_qpos`` and ``target``, a goal
            whose end effector does not move, or a site name that exists already.
    """

    name = "arm_track"
    #: iLQR-MPC toward the goal posture (ArmReach's tuned config before its knots held their
    #: control: 100 one-step knots, two iterations per replan); the task's trackers of a
    #: planned move come from :func:`~mpcbox.tasks.arm.moves.move_tracker`. LQR about the
    #: goal on this cost is sluggish (it weighs effort against a small posture weight);
    #: track :func:`~mpcbox.tasks.arm.moves.step_move` for a stiffer one. Neither MPC config
    #: reaches the goal on this cost (0/8 moves of ``benchmarks/arm_trajectories.py``); with
    #: ArmReach's held knots the final error grew from 7.5 to 26.8 cm (mean), so this one stays.
    knot_seconds: ClassVar[float | None] = None  # one model step per knot on any timestep
    controller_configs: ClassVar[dict[str, Any]] = {
        "ilqr": dataclasses.replace(
            ArmReach.controller_configs["ilqr"], horizon=100, control_steps=1, mpc_iterations=2
        )
    }

    def __init__(
        self,
        model: ModelSource | None = None,
        *,
        frame: str = "ee",
        goal_qpos: np.ndarray | None = None,
        target: np.ndarray | None = None,
        relative: bool = False,
        duration: float = 1.0,
        hold: float = 0.5,
        obstacle: Sphere | None = None,
        margin: float = 0.02,
        clearance_frames: Sequence[str] | None = None,
        site: str = "ee",
        site_offset: np.ndarray | None = None,
        keyframe: str | int | None = None,
        start_qpos: np.ndarray | None = None,
        tolerance: float = 0.005,
        posture_weight: float = 1.0,
        velocity_weight: float = 0.1,
        torque_weight: float = 1e-3,
        goal_weight: float = 1e5,
        obstacle_weight: float = 1e5,
        avoid_collisions: bool = True,
        free_objects: str = "weld",
        **kwargs: Any,
    ) -> None:
        if model is None:
            model = scene_path("arm3.xml")
        self._options = _options(locals())
        if goal_qpos is not None and target is not None:
            raise InvalidArgumentError("ArmTrack takes one of goal_qpos and target, not both")
        self._goal_key = goal_qpos is None and target is None
        self._goal_arg = (
            None if goal_qpos is None else finite_array("goal_qpos", goal_qpos, (None,))
        )
        self.duration = positive("duration", duration)
        self.hold = non_negative("hold", hold)
        self.obstacle = None
        if obstacle is not None:
            self.obstacle = Sphere(
                finite_array("obstacle.center", obstacle[0], (3,)),
                positive("obstacle.radius", obstacle[1]),
            )
        self.margin = non_negative("margin", margin)
        self._clearance_frames = None if clearance_frames is None else tuple(clearance_frames)
        self.site = str(site)
        self.site_offset = (
            np.zeros(3) if site_offset is None else finite_array("site_offset", site_offset, (3,))
        )
        self.track_weights = {
            "posture_weight": non_negative("posture_weight", posture_weight),
            "velocity_weight": non_negative("velocity_weight", velocity_weight),
            "torque_weight": positive("torque_weight", torque_weight),
            "goal_weight": positive("goal_weight", goal_weight),
            "obstacle_weight": positive("obstacle_weight", obstacle_weight),
        }
        self._reference: np.ndarray | None = None
        super().__init__(
            model,
            frame=frame,
            target=np.zeros(3) if target is None else target,
            relative=relative,
            keyframe=keyframe,
            start_qpos=start_qpos,
            tolerance=tolerance,
            avoid_collisions=avoid_collisions,
            free_objects=free_objects,
            **kwargs,
        )

    def _without_free_objects(self, source: ModelSource, mode: str) -> ModelSource:
        """ArmReach's welding, then a site on a body ``frame``."""
        out = super()._without_free_objects(source, mode)
        if not isinstance(out, mujoco.MjSpec):
            return out
        base = compile_spec(out)
        if frame_object(base, self.frame)[0] == "body":
            if mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, self.site) >= 0:
                raise InvalidArgumentError(
                    f"site: the model already has a site {self.site!r}; pass another name"
                )
            body = out.body(self.frame)
            body.add_site(name=self.site, pos=self.site_offset, size=[0.01, 0.01, 0.01])
            self.frame = self.site
        return out

    def task_options(self) -> dict[str, Any]:
        """The constructor's arguments as JSON values: ``ArmTrack(**task_options())``
        rebuilds the task (for ``mpcbox replay``; save them as the trajectory's
        ``task_options``).

        Raises:
            InvalidArgumentError: For a model given as XML text, spec or compiled model, or
                Problem options other than numbers, strings and flags, which do not
                round-trip through JSON.
        """
        if self._options is None:
            raise InvalidArgumentError(
                "ArmTrack.task_options: only a task built from an MJCF path or a Menagerie "
                "name, with plain Problem options, can be rebuilt from JSON"
            )
        return dict(self._options)

    # ------------------------------------------------------------------ construction
    def prepare(self, model: mujoco.MjModel) -> None:
        if self._goal_key:
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "goal") < 0:
                raise InvalidArgumentError(
                    "ArmTrack needs goal_qpos or target (the model has no keyframe 'goal')"
                )
            self._goal_arg = model.key_qpos[object_id(model, "keyframe", "goal")].copy()
        if self._goal_arg is None:
            super().prepare(model)  # IK goal posture for the target
        else:
            self.start_qpos = self._key_qpos(model)
            if self._start_qpos is not None:
                self.start_qpos = as_array("start_qpos", self._start_qpos, (model.nq,)).copy()
            self.qpos_ref = as_array("goal_qpos", self._goal_arg, (model.nq,)).copy()
            self.ctrl_ref = find_equilibrium(model, self.qpos_ref).ctrl.copy()
            self.goal = None
            data = mujoco.MjData(model)
            for qpos, attr in ((self.start_qpos, "start_position"), (self.qpos_ref, "target")):
                data.qpos[:] = qpos
                mujoco.mj_kinematics(model, data)
                setattr(self, attr, frame_position(model, data, self.frame))
        self.goal_qpos = self.qpos_ref.copy()
        if np.linalg.norm(self.target - self.start_position) < 1e-6:
            raise InvalidArgumentError(
                "goal_qpos/target: the end effector does not move between start and goal"
            )
        self.clearance_frames = self._clearance_frames or (self.frame,)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        w = self.track_weights
        data = mujoco.MjData(model)
        data.qpos[:], data.ctrl[:] = self.goal_qpos, self.ctrl_ref
        mujoco.mj_forward(model, data)
        holding = data.actuator_force.copy()  # the forces that hold the goal posture
        lever = np.max(np.abs(actuator_moment(model, data)), axis=1)  # gear of joint actuators
        running = [
            StateCost(
                self.goal_qpos,
                weight_qpos=w["posture_weight"],
                weight_qvel=w["velocity_weight"],
                name="posture",
            ),
            ActuatorForce(holding, weight=w["torque_weight"] * lever**2, name="effort"),
        ]
        if self.obstacle is not None:
            running.append(
                SphereClearance(
                    self.clearance_frames,
                    self.obstacle.center,
                    self.obstacle.radius + self.margin,
                    weight=w["obstacle_weight"],
                    name="obstacle",
                )
            )
        terminal = [
            FramePosition(self.frame, self.target, weight=w["goal_weight"], name="goal_position"),
            StateCost(
                self.goal_qpos,
                weight_qpos=w["goal_weight"],
                weight_qvel=w["goal_weight"],
                name="goal",
            ),
        ]
        return Cost(running, terminal)

    # ------------------------------------------------------------------ references
    @property
    def knots(self) -> int:
        """Knots :math:`N = T / \\Delta t` of the move at the planning step."""
        return max(1, round(self.duration / self.dt))

    def joint_reference(self, hold: float | None = None) -> JointTrajectory:
        """The quintic from the start to the goal posture, every planning step, with
        ``hold`` seconds at rest after it (default: the task's ``hold``)."""
        hold = self.hold if hold is None else hold
        return quintic(self.start_qpos, self.goal_qpos, self.knots * self.dt, self.dt, hold=hold)

    @property
    def reference(self) -> np.ndarray:
        """The reference states ``(K, nstate)`` the measures compare with (default: the
        quintic with its hold)."""
        if self._reference is None:
            self._reference = reference_states(self, self.joint_reference())
        return self._reference

    def set_reference(self, states: np.ndarray) -> None:
        """Compare the measures with these reference states ``(K, nstate)``, one planning
        step apart from time 0 (e.g. an iLQR plan followed by a hold)."""
        self._reference = finite_array("states", states, (None, self.nstate)).copy()

    def frame_path(self, states: np.ndarray) -> np.ndarray:
        """End-effector positions ``(K, 3)`` of states ``(K, nstate)`` (forward kinematics)."""
        states = as_array("states", states, (None, self.nstate))
        data = mujoco.MjData(self.model)
        out = np.empty((states.shape[0], 3))
        for k, state in enumerate(states):
            data.qpos[:] = state[: self.nq]
            mujoco.mj_kinematics(self.model, data)
            out[k] = frame_position(self.model, data, self.frame)
        return out

    # ------------------------------------------------------------------ measures
    def measures(self) -> Sequence[Measure]:
        """Tracking error against the reference, overshoot along the move, settling."""
        ref = self.reference
        time = self.dt * np.arange(ref.shape[0])
        return (
            TrackingError(frame=self.frame, time=time, positions=self.frame_path(ref)),
            Overshoot(
                frame=self.frame, start=tuple(self.start_position), target=tuple(self.target)
            ),
            TargetError(
                frame=self.frame,
                target=tuple(self.target),
                tolerance=self.tolerance,
                end_time=self.knots * self.dt,
            ),
        )


__all__ = ["ArmTrack", "Sphere"]
