r"""Humanoid get-up: from lying on its back on the floor to standing (the showcase of
MJPC and hydrax), on the humanoid scene shipped with mpcbox or any humanoid named by its
torso, feet and standing keyframe."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.handover import HandOver
from mpcbox.controllers.sampling.config import CEMConfig, MPPIConfig, PredictiveSamplingConfig
from mpcbox.core.cost import (
    ComOverSupport,
    ComVelocity,
    ControlCost,
    Cost,
    FrameHeight,
    HeightAbove,
    StateCost,
    Upright,
)
from mpcbox.core.model import ModelSource, dof_weights, frame_object, object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.getup_handover import getup_handover
from mpcbox.tasks.humanoid.stand import HumanoidStand
from mpcbox.validation import (
    as_array,
    boolean,
    in_range,
    non_negative,
    non_negative_weights,
    optional_positive,
    positive,
)

#: Config shared by the get-up's sampling controllers, the best of a small screen on an
#: H100 (benchmarks/humanoid_getup.py; results/rt17_h100_run2_getup_screen.json): 1024
#: candidates, a 0.8 s horizon of 40 Euler steps of 0.02 s with two solver iterations,
#: noise 0.4, replanning at 50 Hz. Ticks take about 26 ms (p99 33-46 ms), so the planner
#: does not keep the 20 ms period. With the task's cost (the centre of mass's velocity
#: and the torso's height above the feet, both on by default) MPPI gets up within
#: 5 s in 17 of 20 held-out seeds in the real-time loop (results/getup_both30_*_h100.json);
#: PS and CEM do worse (0-2 of 3 in the screen, results/getup_cv_feet_h100.json).
_COMMON: dict[str, Any] = dict(
    num_samples=1024,
    horizon=0.8,
    num_knots=6,
    noise_scale=0.4,
    planning_timestep=0.02,
    planning_integrator="euler",
    solver_iterations=2,
    period=0.02,
    headroom=4.0,
)


class HumanoidGetup(Problem):
    r"""Get the humanoid up from lying on its back to standing, and keep it standing.

    The run starts from the humanoid lying supine on the floor (the keyframe's joint
    angles, the root rotated by -90 degrees about its y axis so that a robot facing +x
    faces up, dropped from 0.3 m and settled for ``settle`` seconds at the keyframe's
    control: no control on the classic torque-driven humanoid, the keyframe's joint
    targets on position servos). The reference posture and control are the keyframe's
    (default ``stand``; ``keyframe=...`` picks another). The running cost
    (``terminal_scale`` times heavier at the end of the horizon) is

    .. math::
        \tfrac12 w_h (z_{torso} - z_{stand})^2 + \tfrac12 w_u \|e_{z,xy}\|^2
        + \tfrac12 w_b \sum_f \|c_{xy} - p_{f,xy}\|^2
        + \tfrac12 w_q \|q_j - q_{j,ref}\|^2 + \tfrac12 w_v \|v\|^2
        + \tfrac12 w_{cv} \|\dot c_{xy}\|^2 + \tfrac12 w_c \|u - u_{ref}\|^2 ,

    with :math:`z_{stand}` the torso height of the keyframe, :math:`e_{z,xy}` the horizontal
    part of the torso's z axis, :math:`c` the centre of mass of the ``root``'s subtree (the
    whole body) and :math:`p_f` the feet (pulling the feet under the body is the first move
    of getting up), :math:`q_j` the joint angles only (not the root), :math:`u_{ref}` the
    keyframe's control in :math:`w_c \|u - u_{ref}\|^2`. With ``height_above_feet`` the
    height term is :math:`\tfrac14 w_h \sum_f (z_{torso} - z_f - (z_{stand} - z_{f,stand}))^2`
    instead, the torso's height above each foot (as MJPC's humanoid measures the head above
    the feet), so that standing on one foot with the other lifted costs height.

    Any humanoid works by name: ``torso`` (the body whose height and tilt count),
    ``root`` (the floating base whose subtree's centre of mass is balanced) and ``feet``
    (site or body names); the defaults are the classic humanoid's. See
    :class:`~mpcbox.tasks.humanoid.g1_getup.G1Getup` for Unitree's G1.

    Success (:meth:`goal_failure`): the torso is at least ``stand_height`` high for the last
    ``hold`` seconds of the run. :meth:`getup_time` gives when it got up for good.

    Task stages (:meth:`handover_controller`): once up, the standing problem
    (:meth:`stand_problem`, :class:`~mpcbox.tasks.humanoid.stand.HumanoidStand` on the same
    model) and its tuned controller take over, and the get-up planner takes back control if
    the torso drops again (:meth:`is_up`, :meth:`is_down`).

    Args:
        model: MJCF of the humanoid (default ``mpcbox/tasks/scenes/humanoid.xml``).
        torso: Body whose height and uprightness are costed and measured.
        root: Body whose subtree's centre of mass is held over the feet (default
            ``torso``; the floating base when the torso is not the root).
        feet: The (left, right) feet: site or body names.
        height_cost: :math:`w_h`.
        upright_cost: :math:`w_u`.
        balance_cost: :math:`w_b`.
        posture_cost: :math:`w_q`.
        velocity_cost: :math:`w_v`.
        com_velocity_cost: :math:`w_{cv}`, on the horizontal velocity of the ``root``'s
            subtree's centre of mass (0: no such term).
        ctrl_cost: :math:`w_c`.
        height_above_feet: Measure the torso's height above each foot instead of above
            the floor. With this and :math:`w_{cv} = 30` (the defaults) MPPI got up and
            stood in 10 of 10 seeds (100-109) and 17 of 20 held-out ones (110-129) on an
            H100 in the real-time loop; without both terms it stood 1 of 3 in the same
            screen, with :math:`w_{cv} = 10` 7 of 10 (``benchmarks/humanoid_getup.py``,
            ``benchmarks/results/getup_cv_feet_h100.json``, ``getup_both30_*_h100.json``).
        terminal_scale: Multiplier of the terminal cost.
        stand_height: Torso height that counts as standing (m); ``None``: ``stand_fraction``
            of the keyframe's torso height.
        stand_fraction: See ``stand_height``, in ``(0, 1]``.
        hold: Seconds the torso must stay at ``stand_height`` at the end of a run.
        settle: Seconds the lying body settles before the run starts.
        handover_height: Torso height at or above which :meth:`is_up` holds (m; default
            ``stand_height``).
        handover_tilt: Largest tilt of the torso's z axis from vertical (rad) at which
            :meth:`is_up` holds.
        handover_speed: Largest speed :math:`\|\dot c\|` of the centre of mass (m/s) at
            which :meth:`is_up` holds; ``None``: any speed.
        handover_offset: Largest horizontal distance :math:`\|c_{xy} - \bar p_{xy}\|` (m)
            of the centre of mass from the feet's midpoint at which :meth:`is_up` holds;
            ``None``: any.
        handover_posture: Largest distance :math:`\|q_j \ominus q_{j,ref}\|_2` (rad) of
            the joint angles (all but the floating root's) from the keyframe's at which
            :meth:`is_up` holds; ``None``: any. With these three, a local feedback law
            (LQR, QP-MPC) takes over only near the standing equilibrium it was designed
            about.
        release_height: Torso height below which :meth:`is_down` holds (m); ``None``:
            ``release_fraction`` of the standing height.
        release_fraction: See ``release_height``, in ``(0, 1)``.
        **kwargs: Passed to :class:`~mpcbox.Problem` (e.g. ``planning_timestep``,
            ``keyframe``, default ``"stand"``).

    Raises:
        UnknownNameError: If ``torso``, ``root``, a foot or the keyframe is not in the
            model (lists the names that are).
        InvalidArgumentError: For a non-positive height, ``feet`` not naming two feet, or
            ``release_height`` not below ``handover_height``.
    """

    name = "humanoid_getup"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "ps": PredictiveSamplingConfig(**_COMMON),
        "mppi": MPPIConfig(temperature=0.1, **_COMMON),
        "cem": CEMConfig(num_elites=64, std_min=0.05, **_COMMON),
    }

    def __init__(
        self,
        *,
        model: ModelSource | None = None,
        torso: str = "torso",
        root: str | None = None,
        feet: Sequence[str] = ("foot_left", "foot_right"),
        height_cost: float = 100.0,
        upright_cost: float = 30.0,
        balance_cost: float = 100.0,
        posture_cost: float = 0.3,
        velocity_cost: float = 0.01,
        com_velocity_cost: float = 30.0,
        ctrl_cost: float = 0.1,
        height_above_feet: bool = True,
        terminal_scale: float = 5.0,
        stand_height: float | None = 1.1,
        stand_fraction: float = 0.8,
        hold: float = 0.5,
        settle: float = 1.0,
        handover_height: float | None = None,
        handover_tilt: float = 0.5,
        handover_speed: float | None = None,
        handover_offset: float | None = None,
        handover_posture: float | None = None,
        release_height: float | None = 0.9,
        release_fraction: float = 0.8,
        **kwargs: Any,
    ) -> None:
        self.getup_weights = non_negative_weights(
            height_cost=height_cost,
            upright_cost=upright_cost,
            balance_cost=balance_cost,
            posture_cost=posture_cost,
            velocity_cost=velocity_cost,
            com_velocity_cost=com_velocity_cost,
            ctrl_cost=ctrl_cost,
            terminal_scale=terminal_scale,
        )
        for label, value in (("torso", torso), ("root", root)):
            if value is not None and not isinstance(value, str):
                raise InvalidTypeError(f"{label} must be a body name, got {value!r}")
        if isinstance(feet, str) or len(feet) != 2 or not all(isinstance(f, str) for f in feet):
            raise InvalidArgumentError(f"feet must name the (left, right) feet, got {feet!r}")
        self.height_above_feet = boolean("height_above_feet", height_above_feet)
        self.torso, self.root = torso, torso if root is None else root
        self.feet = tuple(feet)
        self._heights = {
            "stand_height": optional_positive("stand_height", stand_height),
            "stand_fraction": in_range(
                "stand_fraction", stand_fraction, 0.0, 1.0, low_open=True, high_open=False
            ),
            "handover_height": optional_positive("handover_height", handover_height),
            "release_height": optional_positive("release_height", release_height),
            "release_fraction": in_range(
                "release_fraction", release_fraction, 0.0, 1.0, low_open=True, high_open=True
            ),
        }
        self.hold = non_negative("hold", hold)
        self.settle = non_negative("settle", settle)
        self.handover_tilt = positive("handover_tilt", handover_tilt)
        self.handover_speed = optional_positive("handover_speed", handover_speed)
        self.handover_offset = optional_positive("handover_offset", handover_offset)
        self.handover_posture = optional_positive("handover_posture", handover_posture)
        self._model_source = model
        kwargs.setdefault("keyframe", "stand")
        super().__init__(scene_path("humanoid.xml") if model is None else model, **kwargs)
        if self.release_height >= self.handover_height:
            raise InvalidArgumentError(
                f"release_height must be below handover_height ({self.handover_height:g} m) "
                f"for hysteresis, got {self.release_height:g}"
            )
        self._lying = self._lying_state()

    def prepare(self, model: mujoco.MjModel) -> None:
        """Check the names, take the keyframe's torso height and derive the heights."""
        self.torso_id = object_id(model, "body", self.torso, "torso")
        self.root_id = object_id(model, "body", self.root, "root")
        self._feet = [frame_object(model, foot, "feet") for foot in self.feet]
        data = mujoco.MjData(model)
        data.qpos[:] = self.qpos_ref
        mujoco.mj_kinematics(model, data)
        self.torso_height = float(data.xpos[self.torso_id, 2])
        self._feet_heights = [
            float((data.site_xpos if kind == "site" else data.xpos)[i, 2]) for kind, i in self._feet
        ]
        h = self._heights
        self.stand_height = h["stand_height"] or h["stand_fraction"] * self.torso_height
        self.handover_height = h["handover_height"] or self.stand_height
        self.release_height = h["release_height"] or h["release_fraction"] * self.stand_height
        #: Dofs of the joints other than free ones (the posture of :meth:`is_up`).
        self._joint_dofs = np.flatnonzero(
            model.jnt_type[model.dof_jntid] != mujoco.mjtJoint.mjJNT_FREE
        )
        #: Scratch data of :meth:`is_up` and :meth:`is_down` (kinematics only).
        self._stage_data = mujoco.MjData(model)

    def _terms(self, model: mujoco.MjModel, scale: float, suffix: str) -> list:
        w = self.getup_weights
        wq = dof_weights(model, w["posture"])
        return [
            *(
                ComOverSupport(
                    foot,
                    weight=scale * w["balance"],
                    root=self.root,
                    name=f"com_{side}{suffix}",
                )
                for side, foot in zip(("left", "right"), self.feet)
            ),
            *self._height_terms(scale, suffix),
            Upright(self.torso, weight=scale * w["upright"], name="upright" + suffix),
            StateCost(
                self.qpos_ref,
                weight_qpos=scale * wq,
                weight_qvel=scale * w["velocity"],
                name="posture" + suffix,
            ),
            *(
                [
                    ComVelocity(
                        weight=scale * w["com_velocity"], root=self.root, name="com_vel" + suffix
                    )
                ]
                if w["com_velocity"] > 0
                else []
            ),
        ]

    def _height_terms(self, scale: float, suffix: str) -> list:
        weight = scale * self.getup_weights["height"]
        if not self.height_above_feet:
            return [
                FrameHeight(self.torso, self.torso_height, weight=weight, name="height" + suffix)
            ]
        return [
            HeightAbove(
                self.torso,
                foot,
                self.torso_height - foot_height,
                weight=0.5 * weight,
                name=f"height_{side}{suffix}",
            )
            for side, foot, foot_height in zip(("left", "right"), self.feet, self._feet_heights)
        ]

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        control = ControlCost(self.ctrl_ref, weight=self.getup_weights["ctrl"])
        running = [*self._terms(model, 1.0, ""), control]
        return Cost(running, self._terms(model, self.getup_weights["terminal"], "_terminal"))

    def _lying_state(self) -> np.ndarray:
        """The keyframe's joints, torso facing up just above the floor, settled at the
        keyframe's control."""
        model = self.model
        data = mujoco.MjData(model)
        data.ctrl[:] = self.clip_ctrl(self.ctrl_ref)
        data.qpos[:] = self.qpos_ref
        data.qpos[:3] = [0.0, 0.0, 0.3]
        half = -np.pi / 4  # -90 deg about y: the chest faces up, the head points to -x
        data.qpos[3:7] = [np.cos(half), 0.0, np.sin(half), 0.0]
        for _ in range(round(self.settle / model.opt.timestep)):
            mujoco.mj_step(model, data)
        data.qvel[:] = 0.0
        return self.get_state(data)

    def initial_state(self) -> np.ndarray:
        """Lying on the back, at rest, ``(nstate,)``."""
        return self._lying.copy()

    def torso_heights(self, states: np.ndarray) -> np.ndarray:
        """Torso height ``(T,)`` of states ``(T, nstate)`` (m)."""
        states = as_array("states", states, (None, self.nstate))
        data = mujoco.MjData(self.model)
        out = np.empty(len(states))
        for i, state in enumerate(states):
            data.qpos[:] = state[: self.nq]
            mujoco.mj_kinematics(self.model, data)
            out[i] = data.xpos[self.torso_id, 2]
        return out

    def getup_time(self, time: np.ndarray, states: np.ndarray) -> float:
        """Start of the final interval with the torso at ``stand_height`` (s; NaN if the run
        ends below it)."""
        up = self.torso_heights(states) >= self.stand_height
        time = as_array("time", time, (len(up),))
        if not up.size or not up[-1]:
            return float("nan")
        down = np.flatnonzero(~up)
        first = 0 if down.size == 0 else int(down[-1]) + 1
        return float(np.asarray(time)[first])

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        time = np.asarray(time)
        if time.size == 0:
            return "no states recorded"
        since = self.getup_time(time, states)
        if np.isnan(since) or time[-1] - since < self.hold - 1e-9:
            z = self.torso_heights(states[-1:])[0]
            return (
                f"not standing for the last {self.hold:g} s (torso {z:.2f} m at the end, "
                f"standing is >= {self.stand_height:g} m)"
            )
        return None

    # ------------------------------------------------------------------ task stages
    def _torso(self, state: np.ndarray) -> tuple[float, float]:
        """Torso height (m) and the z component of its z axis for one state."""
        data = self._stage_data
        data.qpos[:] = self.check_state(state)[: self.nq]
        mujoco.mj_kinematics(self.model, data)
        return float(data.xpos[self.torso_id, 2]), float(data.xmat[self.torso_id, 8])

    def balance_state(self, state: np.ndarray) -> tuple[float, float]:
        r"""Speed :math:`\|\dot c\|` (m/s) of the centre of mass of the ``root``'s subtree
        and the horizontal distance :math:`\|c_{xy} - \bar p_{xy}\|` (m) of :math:`c` from
        the midpoint :math:`\bar p` of the feet, for a state ``(nstate,)``."""
        model, data = self.model, self._stage_data
        state = self.check_state(state)
        data.qpos[:] = state[: self.nq]
        data.qvel[:] = state[self.nq : self.nq + self.nv]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_subtreeVel(model, data)
        feet = [(data.site_xpos if kind == "site" else data.xpos)[i] for kind, i in self._feet]
        offset = data.subtree_com[self.root_id, :2] - 0.5 * (feet[0][:2] + feet[1][:2])
        speed = float(np.linalg.norm(data.subtree_linvel[self.root_id]))
        return speed, float(np.linalg.norm(offset))

    def posture_distance(self, state: np.ndarray) -> float:
        r"""Distance :math:`\|q_j \ominus q_{j,ref}\|_2` (rad) of the joint angles of a
        state ``(nstate,)`` from the keyframe's (the floating root left out)."""
        dq = self.state_difference(self.check_state(state), self.reference_state())[: self.nv]
        return float(np.linalg.norm(dq[self._joint_dofs]))

    def is_up(self, state: np.ndarray) -> bool:
        """For a state ``(nstate,)``: the torso is at least ``handover_height`` high and
        tilted at most ``handover_tilt`` from vertical, and (when set) the centre of mass
        moves at most ``handover_speed`` and lies at most ``handover_offset`` from the
        feet's midpoint (:meth:`balance_state`), and the joints are at most
        ``handover_posture`` from the keyframe's (:meth:`posture_distance`)."""
        height, up = self._torso(state)
        if height < self.handover_height or up < np.cos(self.handover_tilt):
            return False
        limit = self.handover_posture
        if limit is not None and self.posture_distance(state) > limit:
            return False
        if self.handover_speed is None and self.handover_offset is None:
            return True
        speed, offset = self.balance_state(state)
        return (self.handover_speed is None or speed <= self.handover_speed) and (
            self.handover_offset is None or offset <= self.handover_offset
        )

    def is_down(self, state: np.ndarray) -> bool:
        """The torso is lower than ``release_height``, for a state ``(nstate,)``."""
        return self._torso(state)[0] < self.release_height

    def stand_problem(self, **kwargs: Any) -> Problem:
        """The standing stage: :class:`~mpcbox.tasks.humanoid.stand.HumanoidStand` (its own
        costs and tuned controller configs) on this task's model.

        Args:
            **kwargs: Passed to :class:`~mpcbox.tasks.humanoid.stand.HumanoidStand`.
        """
        kwargs.setdefault("model", self._model_source)
        return HumanoidStand(**kwargs)

    def handover_controller(
        self,
        name: str,
        *,
        stand: str | None = None,
        transfer: bool = True,
        stand_options: dict[str, Any] | None = None,
        stand_task: dict[str, Any] | None = None,
        stand_on: str = "stand",
        **overrides: Any,
    ) -> HandOver:
        """Get-up controller ``name`` until :meth:`is_up`, then the standing stage's tuned
        controller ``stand`` until :meth:`is_down`, and so on
        (:class:`~mpcbox.controllers.handover.HandOver`).

        With the earlier cost (torso height above the floor, no velocity term of the
        centre of mass) neither a sampling standing stage nor a feedback law (``"lqr"``,
        ``"qp"``, run at the get-up period with LQR designed for that hold) did better than
        the get-up planner alone; the measurements are in the task's page of the docs
        (``docs/api/tasks.md``, "Task stages"). ``handover_posture`` (with
        ``handover_speed`` and ``handover_offset``) keeps a local law out unless the body
        is near the equilibrium it was designed about.

        Args:
            name: The get-up controller (a key of :attr:`controller_configs`).
            stand: The standing controller (a key of ``HumanoidStand.controller_configs``;
                default ``name``).
            transfer: Warm-start each incoming planner with the outgoing plan (else a cold
                start from its reference control).
            stand_options: Overrides of the standing controller's config (its ``period``,
                or iLQR-MPC's ``replan_period``, defaults to the get-up controller's; iLQR-MPC
                needs ``feedback=False`` here).
            stand_task: Options of :meth:`stand_problem` (the standing costs).
            stand_on: The standing stage's problem: ``"stand"`` :meth:`stand_problem`, or
                ``"getup"`` this task itself (its costs, and its config of ``stand`` as the
                base of ``stand_options``; e.g. the same planner with smaller noise once
                up). ``stand_task`` is then not allowed.
            **overrides: Overrides of the get-up controller's config; ``backend``,
                ``device`` and ``seed`` apply to both when the standing controller has
                them (LQR and QP-MPC have none).

        Raises:
            UnknownNameError: If ``name`` or ``stand`` is not a registered controller.
            UnknownOptionError: For an option that its controller does not have.
            InvalidArgumentError: For ``stand_on`` not one of its choices,
                ``stand_task`` with ``stand_on="getup"``, or a standing iLQR-MPC whose
                feedback law would run between the planner's ticks.
        """
        return getup_handover(
            self,
            name,
            stand=stand,
            transfer=transfer,
            stand_options=stand_options,
            stand_task=stand_task,
            stand_on=stand_on,
            **overrides,
        )
