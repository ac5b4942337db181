"""Reach: move an arm's end effector to a target position (and orientation), any arm.

The goal posture comes from inverse kinematics with collision avoidance
(:func:`mpcbox.core.posture.reach_posture`), and the control that holds it from the actuator
model (:func:`mpcbox.find_equilibrium`: torque for motors, set-point for position servos), so
LQR about the goal is available out of the box and iLQR starts from a sensible reference.

Planning step. Menagerie's arms drive their joints with stiff position servos (Panda:
:math:`k_p` up to 4500 N m/rad behind torque limits of 12-87 N m). MuJoCo integrates a
servo's stiffness explicitly, so a planning model coarser than the simulation mispredicts
the arm (on the Panda, 0.5 s of the same controls on a 0.01 s planning model put the hand
10 cm from where the 0.002 s simulation takes it), and iLQR-MPC planned on it wanders. The
tuned controllers therefore plan at the model's own timestep, with a short horizon (25
knots that each hold their control for four steps, 0.2 s on the Panda,
``control_steps=4``; 8 ms knots over 0.2 s on any timestep, :attr:`ArmReach.knot_seconds`)
whose end is priced by the LQR value function at the goal (``terminal_value="lqr"``).
The initial guess is the control that holds the IK goal posture, which on a servo arm
already drives the arm toward the goal, or on an arm whose goal torques let it fall from the
start the control that holds the start (:meth:`ArmReach.initial_ctrls`). Offline iLQR over a
long horizon meets the servos' torque limits (their derivatives vanish once saturated) and
typically stalls (short steps, then the regularization limit); its ``stop_reason`` says so.

Force limits also make the planning model's step discontinuous: MuJoCo's implicit
integrators treat a servo's velocity gain implicitly only while its force is inside
``forcerange``, so the velocity after one step jumps where a servo saturates (on the Panda's
wrist by up to about 0.2 rad/s). The cost along an iLQR search direction is then jagged,
and about half the line searches of the Panda's replans find no step size that lowers it
(``benchmarks/ilqr_servo_saturation.py``: the jumps vanish on a copy without the force
limits). The replans therefore give up after one regularization increase
(``mpc_max_retries=1``) and keep their warm start; such replans count as stalled.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.sampling.config import MPPIConfig
from mpcbox.controllers.servo_actions import ServoActions, servo_spec
from mpcbox.core.actuation import position_servos
from mpcbox.core.cost import ControlCost, Cost, FramePosition, StateCost
from mpcbox.core.end_effector import end_effector
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.free_bodies import free_objects, weld_free_bodies
from mpcbox.core.model import (
    ModelSource,
    compile_spec,
    frame_object,
    frame_position,
    load_spec,
    object_id,
)
from mpcbox.core.posture import reach_posture
from mpcbox.core.problem import Problem
from mpcbox.core.servo_ringing import ServoRinging, servo_ringing
from mpcbox.errors import InvalidArgumentError, ModelWarning, MpcboxError, UnsupportedModelError
from mpcbox.tasks.reach_measures import ReachError
from mpcbox.validation import finite_array, one_of, positive

#: Valid values of ``ArmReach(free_objects=...)``.
FREE_OBJECTS = ("weld", "error")


def _check_moving_frame(model: mujoco.MjModel, frame: str) -> None:
    """The end effector must hang from at least one joint (a frame on the world or a
    static body never moves, and the IK would only report it out of reach)."""
    kind, oid = frame_object(model, frame)
    body = int(model.site_bodyid[oid]) if kind == "site" else oid
    if model.body_weldid[body] == 0:  # welded to the world
        raise InvalidArgumentError(
            f"frame {frame!r} is fixed to the world (no joint moves it): name a site or body on "
            "the arm's moving links"
        )


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
        frame: End-effector site or body name; ``None``: the one
            :func:`~mpcbox.core.end_effector.end_effector` picks (Menagerie's
            ``attachment_site`` on the tool flange, else the tip of the arm).
        target: Target position ``(3,)`` in the world frame (m), or with ``relative=True`` an
            offset from the frame's start position.
        orientation: Target orientation (unit quaternion ``[w, x, y, z]``) for the IK goal
            posture; ``None`` leaves it free.
        relative: Read ``target`` as an offset from the start position.
        keyframe: Start posture (name or index); default: the model's first keyframe, else
            ``qpos0``.
        start_qpos: Start posture ``(nq,)`` replacing the keyframe's (e.g. a perturbed one);
            with welded free objects, of the model after welding.
        tolerance: Distance (m) within which the frame counts as arrived.
        position_weight: :math:`w_p`.
        posture_weight: :math:`w_q`.
        velocity_weight: :math:`w_v`. With 0.1 iLQR-MPC and LQR reach 2-4x sooner on six
            arms, but MPPI holds the target less precisely (2-11 mm against under 1 mm), so
            the default stays 1.0 (results/arm_reach_velocity_weight.json).
        ctrl_weight: :math:`w_u`, in the units of the controls.
        avoid_collisions: Keep the IK goal posture free of collisions.
        servo_check: Step-test the actuators at the start posture
            (:func:`~mpcbox.core.servo_ringing.servo_ringing`) and warn (a
            :class:`~mpcbox.ModelWarning` naming them) about any that ring at the model's
            timestep, as the Unitree Z1's wrist servos do; the report is kept in
            :attr:`servo_report`.
        free_objects: What to do with free bodies that do not carry ``frame`` (a pot on the
            table): ``"weld"`` them to the world at their start pose, which removes their
            uncontrollable joints from the state (LQR's Riccati equation has no stabilizing
            solution with them), or ``"error"``: raise, naming them. Only a model given as
            MJCF or spec can be welded.
        **kwargs: Passed to :class:`~mpcbox.Problem` (``planning_timestep``, ...);
            ``dry_friction`` defaults to ``"drop"`` here.

    Attributes:
        welded: Names of the free objects welded to the world.
        servo_report: The :class:`~mpcbox.core.servo_ringing.ServoRinging` of the start
            posture, or ``None`` (``servo_check=False``, or actuators it cannot rest).

    Raises:
        InvalidArgumentError: For free objects with ``free_objects="error"`` or a compiled
            model; the message names them. Also when ``frame`` is ``None`` and the model
            has no single arm tip (the message lists the candidates).
        SolverError: If the IK goal posture leaves the frame farther than ``tolerance`` from
            the target, is in self-collision or (``avoid_collisions``) goes into the static
            world: the target is out of reach or inside an obstacle.
    """

    name = "arm_reach"
    #: Seconds each iLQR knot holds its control, and seconds the plan covers. The iLQR
    #: config's ``control_steps`` becomes ``round(knot_seconds / dt)`` of the planning
    #: model's timestep and its ``horizon`` ``round(plan_seconds / (control_steps * dt))``
    #: knots: 25 knots of 4 steps at Menagerie's 2 ms, 25 of 8 on Unitree's Z1 at 1 ms
    #: (with 4 steps its plan covered 0.1 s, and in the real-time loop 2 of 3 seeds missed
    #: the 1 cm goal), 20 of 2 at 5 ms. ``knot_seconds=None`` keeps the config as written.
    knot_seconds: ClassVar[float | None] = 0.008
    plan_seconds: ClassVar[float] = 0.2
    controller_configs: ClassVar[dict[str, Any]] = {
        "lqr": LQRConfig(),
        # Planned at the model's own timestep (see the module docstring) over 0.2 s: 25
        # knots that each hold their control for four model steps (control_steps; on other
        # timesteps knot_seconds and plan_seconds set both), the LQR
        # value at the goal as terminal cost, one iteration per 0.02 s replan (five for the
        # first), dynamics derivatives at every fourth knot (interpolated between). A replan
        # whose line search fails at every step size raises the regularization once, not up
        # to 20 times: the servos' force limits make MuJoCo's step jump
        # (ILQRConfig.mpc_max_retries; on the Panda the p99 tick fell from 588-885 to
        # 177-200 ms, results/arm_reach_mpc_retries.json). Before control_steps (100 knots
        # of one step) a replan needed two iterations: with one the KUKA iiwa 14 never came
        # within 1 cm (results/arm_reach_iiwa_one_iteration.json). With the held controls
        # and one iteration, on seven arms (Panda, FR3, iiwa 14, UR5e, Sawyer, Gen3; Z1 at
        # 1 ms) the same arrivals within 1 cm by 2 s, with median ticks of 6-11 ms against
        # 24-56 ms and p99 ticks of 7-23 ms against 37-113 ms on 2 cores, about the 20 ms
        # period (results/arm_reach_control_steps.json).
        "ilqr": ILQRConfig(
            horizon=25,
            control_steps=4,
            terminal_value="lqr",
            first_iterations=5,
            mpc_iterations=1,
            replan_period=0.02,
            linearize_every=4,
            mpc_max_retries=1,
        ),
        # Sampling on the CPU: 32 rollouts of 1 s (six knots) per 0.02 s tick. A 0.3 s
        # horizon of four knots reached on the Panda (0.41 s) and the KUKA iiwa 14 but left
        # the UR5e and the Sawyer 6.9 and 11.3 cm away: over 0.3 s their damped servos make
        # every move toward the goal cost more than staying (38.9 against 62.5 for the
        # UR5e's stalled state); a 0.6 s horizon still left about 2 cm. With 1 s all four
        # settle on the target. No noise on the first knot (``"ramp"``): the knot the arm
        # executes next comes from the shifted plan. With the same noise there, Kinova's
        # Gen3 (stiff servos on links without armature: a set-point moves the joint within a
        # tick) followed each tick's best sample's noise and wandered 2-21 cm from the target
        # over 3 s; with the ramp it arrived in 0.19 s and stayed within 0.3 mm, and the
        # other four arms stayed within 3.6 mm (results/arm_reach_mppi_ramp.json). The
        # goal's set-points are scored at every tick (guess_candidate): the same arrivals on
        # five servo arms, final errors 0.001-0.17 mm against 0.07-0.79 mm (a Gen3 seed had
        # wandered back to 2 cm), and on a torque arm planned through servos
        # (servo_planner) MPPI without it walked 5-6 cm off the target it had reached
        # (results/arm_reach_mppi_guess.json).
        "mppi": MPPIConfig(
            num_samples=32,
            horizon=1.0,
            num_knots=6,
            noise_schedule="ramp",
            noise_scale=0.1,
            temperature=0.1,
            period=0.02,
            guess_candidate=True,
        ),
    }

    def __init__(
        self,
        model: ModelSource,
        *,
        frame: str | None = None,
        target: np.ndarray,
        orientation: np.ndarray | None = None,
        relative: bool = False,
        keyframe: str | int | None = None,
        start_qpos: np.ndarray | None = None,
        tolerance: float = 0.01,
        position_weight: float = 100.0,
        posture_weight: float = 0.1,
        velocity_weight: float = 1.0,
        ctrl_weight: float = 0.01,
        avoid_collisions: bool = True,
        servo_check: bool = True,
        free_objects: str = "weld",
        **kwargs: Any,
    ) -> None:
        self.frame = frame
        self.target_input = finite_array("target", target, (3,)).copy()
        self.orientation = (
            None if orientation is None else finite_array("orientation", orientation, (4,))
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
        self.servo_check = bool(servo_check)
        self.servo_report: ServoRinging | None = None
        self._start_key = keyframe
        self._start_qpos = None if start_qpos is None else np.asarray(start_qpos, dtype=float)
        self.welded: tuple[str, ...] = ()
        one_of("free_objects", free_objects, FREE_OBJECTS)
        model = self._without_free_objects(model, free_objects)
        # A reaching arm's joints slip: linearize without their dry friction, which at rest
        # sticks (Unitree's Z1, 1 N m a joint: LQR drove the arm 23-32 cm from a 20 cm
        # target with it, 0.9-1.5 cm without; results/arm_reach_z1.json).
        kwargs.setdefault("dry_friction", "drop")
        self._source, self._options = model, dict(kwargs)  # for servo_planner's twin
        super().__init__(model, **kwargs)
        ilqr = type(self).controller_configs.get("ilqr")
        if self.knot_seconds is not None and isinstance(ilqr, ILQRConfig):
            steps = max(1, round(self.knot_seconds / self.dt))
            knots = max(2, round(self.plan_seconds / (steps * self.dt)))
            if (steps, knots) != (ilqr.control_steps, ilqr.horizon):
                self.controller_configs = {
                    **type(self).controller_configs,
                    "ilqr": dataclasses.replace(ilqr, control_steps=steps, horizon=knots),
                }

    def _without_free_objects(self, source: ModelSource, mode: str) -> ModelSource:
        """``source`` with its free objects welded (``"weld"``), or an error naming them."""
        spec = None if isinstance(source, mujoco.MjModel) else load_spec(source)
        base = source if spec is None else compile_spec(spec)
        if self.frame is None:
            self.frame = end_effector(base)
        _check_moving_frame(base, self.frame)
        objects = free_objects(base, self.frame)
        if not objects:
            return source if spec is None else spec
        if mode == "error" or spec is None:
            how = (
                "pass free_objects='weld' to weld them to the world at their start pose"
                if spec is not None
                else "pass the MJCF (path, XML or spec) so that they can be welded"
            )
            raise InvalidArgumentError(
                f"ArmReach: free objects {list(objects)} are not part of the arm carrying "
                f"{self.frame!r}; their joints cannot be controlled (LQR would meet an "
                f"ill-conditioned Riccati equation): {how}, or remove them from the model"
            )
        self.welded = weld_free_bodies(spec, base, self.frame, self._key_qpos(base))
        return spec

    def _key_qpos(self, model: mujoco.MjModel) -> np.ndarray:
        """The start keyframe's positions ``(nq,)`` (first keyframe, else ``qpos0``)."""
        if self._start_key is not None:
            return model.key_qpos[object_id(model, "keyframe", self._start_key)].copy()
        return model.key_qpos[0].copy() if model.nkey else model.qpos0.copy()

    # ------------------------------------------------------------------ construction
    def prepare(self, model: mujoco.MjModel) -> None:
        self.start_qpos = self._key_qpos(model)
        if self._start_qpos is not None:
            self.start_qpos = finite_array("start_qpos", self._start_qpos, (model.nq,)).copy()
        if self.servo_check:
            self._check_servos(model)
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
            max_error=self.tolerance,
        )
        self.goal = goal
        self.qpos_ref = goal.qpos.copy()
        self.ctrl_ref = find_equilibrium(model, goal.qpos).ctrl.copy()

    def _check_servos(self, model: mujoco.MjModel) -> None:
        """Keep the start posture's servo step test; warn about actuators that ring."""
        try:
            self.servo_report = servo_ringing(model, self.start_qpos)
        except UnsupportedModelError:  # an actuator without a resting state to step from
            return
        message = self.servo_report.message()
        if message:
            warnings.warn(message, ModelWarning, stacklevel=6)

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

    def initial_ctrls(self, state: np.ndarray, horizon: int) -> np.ndarray:
        """Every planner's first guess ``(horizon, nu)`` from ``state``, per actuator.

        A position servo takes the goal posture's set-point (``ctrl_ref``), which drives its
        joint to the goal. Any other actuator takes the control that holds the posture of
        ``state`` (through the actuator model, :func:`~mpcbox.find_equilibrium`): on a
        torque-driven arm the goal's gravity torques let the arm fall from the start, and
        iLQR from that fall stalled 67-72 cm from a 40 cm target where it converged from
        holding the start (a Franka FR3 with motors).

        The choice goes by actuator, not by the guesses' costs: under the task's cost over a
        sampling controller's 1 s horizon, holding a perturbed start rolled out cheaper on a
        Kinova Gen3 (stiff servos: the move to the goal costs its speed) than the set-points
        that reach the target in 0.3 s, and MPPI started from it ended 8.6 cm away.
        """
        state = self.check_state(state)
        goal = super().initial_ctrls(state, horizon)
        servo = position_servos(self.model)
        if servo.all():
            return goal
        try:
            hold = find_equilibrium(self.model, state[: self.nq], on_infeasible="ignore").ctrl
        except MpcboxError:  # an actuator model find_equilibrium cannot invert
            return goal
        return np.where(servo, goal, self.clip_ctrl(hold))

    def servo_planner(
        self,
        name: str = "mppi",
        *,
        bandwidth: float | None = None,
        damping_ratio: float = 1.0,
        replan_period: float | None = None,
        **options: Any,
    ) -> ServoActions:
        """A planner of joint set-points for a torque-driven arm (its motors as servos).

        Builds this reach again on :func:`~mpcbox.controllers.servo_actions.servo_spec`'s
        model (each motor a position servo of the motor's torque range, gains from
        ``bandwidth`` and ``damping_ratio`` at the start posture; same frame, target, start
        and weights), makes the task's ``name`` controller on it, called every step and
        replanning every ``replan_period`` (default its config's ``period``), and wraps it
        in :class:`~mpcbox.controllers.servo_actions.ServoActions`, which sends this arm the
        motor torques of the same servo law.

        Args:
            name: A registered controller (``"mppi"``, ``"ps"``, ``"cem"``, ...).
            bandwidth: Servo bandwidth (rad/s); default ``0.1 / timestep``.
            damping_ratio: Servo damping ratio.
            replan_period: Seconds between replans.
            **options: The controller's options (e.g. ``num_samples=64``).

        Raises:
            UnsupportedModelError: If the arm has no motor (e.g. already position servos).
        """
        from mpcbox.registry import make_controller

        spec, law = servo_spec(
            self._source, bandwidth=bandwidth, damping_ratio=damping_ratio, qpos=self.start_qpos
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ModelWarning)  # this arm's were shown already
            twin = ArmReach(
                spec,
                frame=self.frame,
                target=self.target,
                orientation=self.orientation,
                start_qpos=self.start_qpos,
                tolerance=self.tolerance,
                avoid_collisions=self.avoid_collisions,
                servo_check=False,
                **self.weights,
                **self._options,
            )
        config = twin.controller_configs.get(name)
        period = getattr(config, "period", None)
        replan = replan_period if replan_period is not None else (period or 0.02)
        options = {"period": None, "replan_period": replan, **options}
        return ServoActions(self, make_controller(name, twin, **options), law)

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

    def measures(self) -> Sequence[ReachError]:
        """The end-effector error: final, max, settle time; arrival time and overshoot."""
        return (ReachError(frame=self.frame, target=tuple(self.target), tolerance=self.tolerance),)

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        """Why a finished run missed the target: the final end-effector error, or ``None``.

        Args:
            time: Times ``(T,)`` of the run (s).
            states: States ``(T, nstate)``.
        """
        states = np.asarray(states)
        error = self.reach_error(states[-1])
        if error <= self.tolerance:
            return None
        return (
            f"end effector {100 * error:.2f} cm from the target at t={float(time[-1]):.2f} s, "
            f"tolerance {100 * self.tolerance:.2f} cm"
        )
