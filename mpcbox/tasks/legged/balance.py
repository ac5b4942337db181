"""Balance of any legged robot on the feet it is given, by name."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from types import MappingProxyType
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.core.actuator_scales import UNITS, actuator_scales, to_control
from mpcbox.core.contact import contact_points
from mpcbox.core.cost import ComOverSupport, ControlCost, Cost, CostTerm, StateCost
from mpcbox.core.equilibrium import Equilibrium, find_equilibrium
from mpcbox.core.model import (
    ModelSource,
    compile_spec,
    dof_weights,
    load_spec,
    object_id,
)
from mpcbox.core.problem import Problem
from mpcbox.core.root_support import ROOT_ADJUSTMENTS
from mpcbox.core.sole_boxes import box_soles
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.sim.disturbances import ActuatorNoise
from mpcbox.sim.effort_noise import effort_noise
from mpcbox.sim.measures import Measure
from mpcbox.tasks.legged.feet import Foot, find_feet
from mpcbox.tasks.legged.measures import Tilt, balance_measures
from mpcbox.tasks.legged.root import root_body, support_offsets
from mpcbox.validation import (
    as_array,
    as_weights,
    finite,
    finite_array,
    in_range,
    non_negative,
    one_of,
    optional_positive,
)

#: Name of the world site added at the middle of several feet (``support="center"``).
FEET_CENTER = "feet_center"
#: Where the center of mass is kept (see :class:`LeggedBalance`).
SUPPORTS: tuple[str, ...] = ("center", "feet")
#: Where the balance term wants the center of mass (see :class:`LeggedBalance`).
BALANCE_TARGETS: tuple[str, ...] = ("reference", "support")
#: How flat mesh soles are planned on (``mesh_soles``).
MESH_SOLES: tuple[str, ...] = ("box", "mesh")


def _weight(name: str, value: object) -> float | np.ndarray:
    """A non-negative weight, or a 1-D array of them (its length is checked later)."""
    if np.ndim(value) == 0 or isinstance(value, (str, bytes)):
        return non_negative(name, value)
    weights = finite_array(name, value, (None,))
    if np.any(weights < 0):
        raise InvalidArgumentError(f"{name} must be >= 0, got {weights.tolist()}")
    return weights


def _unique_name(
    model: mujoco.MjModel, kind: mujoco.mjtObj, name: str, taken: Sequence[str] = ()
) -> str:
    candidate, i = name, 1
    while mujoco.mj_name2id(model, kind, candidate) >= 0 or candidate in taken:
        candidate, i = f"{name}_{i}", i + 1
    return candidate


#: OSQP settings of LeggedBalance's QP-MPC and of all its presets, the humanoid ones included
#: since stop 25 (over :data:`~mpcbox.controllers.qp_mpc.solvers.OSQP_DEFAULTS`).
#: With the duality-gap test off and ``rho = 0.3`` the mean iterations under the noise recipe
#: fell from 40 to 25 (Go1), 64 to 25 (A1), 59 to 33 (ANYmal C), 376 to 34 (Go2) and 92 to
#: 25 (G1), 1.5 s, seed 0 (with it on, solves ran a hundred iterations past 1e-5 residuals).
QP_OSQP_SETTINGS: MappingProxyType[str, Any] = MappingProxyType(
    {"rho": 0.3, "check_dualgap": False}
)

#: QP-MPC's replanning period (s) on a robot driven by torque alone, which gets the LQR
#: gain about the plan in between (``between_ticks="lqr"``; see :class:`LeggedBalance`).
TORQUE_QP_PERIOD = 0.01


def position_feedback(model: mujoco.MjModel) -> bool:
    """Whether any actuator's force depends on its length (a bias on it, such as a position
    servo's :math:`-k_p`), so that it holds a position between two controller calls."""
    return bool(np.any(model.actuator_biasprm[:, 1] != 0))


class LeggedBalance(Problem):
    r"""Keep any legged robot standing on the feet it is given.

    The feet are sites, bodies or geoms, in any mix (:func:`~mpcbox.tasks.legged.feet.find_feet`:
    a body or geom stands on the lowest points of its collision geoms, and a site is added
    there so the cost and measures can follow it). The reference posture is the keyframe with
    the root's height and tilt adjusted until the contacts carry the weight and balance its
    moments (``root_adjust``); the control that holds it
    comes through each actuator's model (:func:`~mpcbox.find_equilibrium`: torques for
    motors, set-points for position servos).

    Running cost, with :math:`c` the whole-body center of mass (the root's subtree) and
    :math:`p` the support point:

    .. math::
        \tfrac12 w_b \|c_{xy} - p_{xy} - o\|^2 + \tfrac12 \|q \ominus q_{ref}\|^2_{W_q}
        + \tfrac12 w_v \|v\|^2 + \tfrac12 \|u - u_{ref}\|^2_{W_u} ,

    where :math:`W_q` is ``joint_cost`` on the joints and zero on the free root, and
    :math:`W_u` is ``ctrl_cost`` in ``ctrl_units``: with ``"range"`` (the default) a control
    deviation is measured as a fraction of the actuator's half range
    (:mod:`mpcbox.core.actuator_scales`), so the same weight means the same on motors and
    on position servos of any gain. With ``support="center"`` the support point is a
    world-fixed site ``feet_center`` at the middle of the feet's soles in the keyframe (the
    foot itself for one foot); with ``"feet"`` the cost keeps the center of mass over each
    foot (weight ``w_b / n`` each, the same as over their moving mean up to a constant).
    The offset :math:`o` is, with ``balance_target="reference"`` (the default), where the
    equilibrium holds the center of mass relative to :math:`p`, so that the whole cost is
    zero and stationary at the reference, the state LQR and QP-MPC regulate to; with
    ``"support"`` it is zero: a pull off the equilibrium, a gradient that LQR and QP-MPC
    drop and iLQR follows (iLQR-MPC leant off and fell, without noise too, on the Unitree H1
    and PNDbotics Adam Lite, which stand with it 10-17 cm behind the soles' middle).

    A run fails when the root body drops below ``fall_height`` or tilts by more than
    ``fall_tilt``. The measures are the center
    of mass over the support and the root's tilt
    (:func:`~mpcbox.tasks.legged.measures.balance_measures`), and :meth:`noise` is the
    robot-independent recipe :func:`~mpcbox.sim.effort_noise.effort_noise`.

    Args:
        model: The robot's MJCF with a floor (path, XML, spec, or ``"menagerie:NAME"``).
        feet: Stance feet: site, body or geom names (prefix ``"site:"``, ``"body:"`` or
            ``"geom:"`` to pick one kind); a subclass's :meth:`standing_feet` may fill in
            ``None``.
        root: Root body (default: the body of the free joint).
        keyframe: Name or index of the standing keyframe (default: the first keyframe,
            else ``qpos0``).
        fall_height: The run fails when the root is lower than this (m, between the floor
            and the root's reference height); default ``fall_fraction`` times that height.
        fall_fraction: See ``fall_height``.
        fall_tilt: The run also fails when the root tilts more than this many degrees from
            its reference tilt (a robot thrown onto its side or back may keep its root
            high); ``None``: height only.
        support: ``"center"`` or ``"feet"`` (see above).
        balance_target: ``"reference"`` or ``"support"``: the offset :math:`o` (see above).
        contacts: Contact geoms, bodies or sites for QP-MPC (default: each foot as given,
            except a body foot standing on one point, such as a sphere: its sole site).
        balance_cost: :math:`w_b` (per m²).
        joint_cost: Weight of the joint deviations (per rad²), one or ``(nv,)`` per dof.
        velocity_cost: :math:`w_v`.
        ctrl_cost: Weight of the control deviations, one or ``(nu,)``, in ``ctrl_units``.
        ctrl_units: ``"range"``, ``"torque"`` (per (N m)²) or ``"control"``.
        noise_fraction: Noise standard deviation of :meth:`noise`, as a fraction of each
            actuator's half range.
        noise_torque: Instead, a torque (N m), one or ``(nu,)``.
        recovery_tilt: The tilt measure also reports the recovery time (its
            ``"settle_time"``): when the root's tilt is back within this many degrees of its
            reference tilt for good. ``None`` leaves it out.
        mesh_soles: ``"box"`` plans (and linearizes) on a copy of the model where each foot's
            flat mesh sole resting on the floor is the box spanning its lowest part
            (:func:`~mpcbox.core.sole_boxes.box_soles`; MuJoCo's contact set on a flat mesh
            jumps with tilts of 1e-13 rad); the simulation keeps the mesh. ``"mesh"`` plans
            on the mesh.
        root_adjust: How the reference posture is put on the floor
            (:func:`~mpcbox.find_equilibrium`): ``"pose"`` moves the root's height and tilts
            it until the contacts carry the weight and balance its moments; ``"height"``
            moves its height only, leaving any moment in the equilibrium's
            ``residual_wrench``.
        **kwargs: Passed to :class:`~mpcbox.Problem` (``planning_timestep``, ``qpos_ref``...).

    QP-MPC runs with OSQP at ``rho = 0.3`` and without OSQP 1.x's duality-gap test
    (:data:`QP_OSQP_SETTINGS`). It replans at 50 Hz, holding the plan's first control, on
    robots whose actuators hold a position between two ticks (position servos: Go1, A1,
    ANYmal C). On robots driven by torque alone (motors: the Go2), which get no feedback
    from their actuators, it replans at 100 Hz (:data:`TORQUE_QP_PERIOD`) and adds the LQR
    gain about the plan at every step in between (``between_ticks="lqr"``). On the Go2
    under the noise recipe, with the control held: at 50 Hz one of two 3 s runs fell (the
    root height swinging by 8 cm, the knee torques at their limits), at 100 Hz over 15 steps
    2 of 20 seeds of 10 s fell, and 250 Hz stood 20/20 with 15 % of ticks over its 4 ms
    period on one core. With the feedback, 100 Hz stands 20/20 with no fallback, 0.7 % of
    ticks over the period and a larger push limit (184 N against 146 N); at 50 Hz some
    seeds still fall (``benchmarks/go2_stand.py``, ``benchmarks/results/go2_stand*.json``).
    The servo robots keep the held control: with the feedback their push limits moved both
    ways (A1 305 N to 153 N, Go1 98 N to 112 N,
    ``benchmarks/results/quadruped_stand_qp_feedback.json``).

    The first stage's point forces are left unbounded (``first_stage_forces="free"``):
    bounding each point's linearized force at the measured state made the QP bend its first
    control, and on held-out seeds 100-119 at x1.5 and x2 of the noise recipe it then stood
    fewer seeds than LQR on every Menagerie robot (G1 on two feet 5/20 and 0/20). Free, it
    stands 20/20 at every level on the Go1, A1, ANYmal C and the G1 on one or two feet, and
    the Go2 20, 20 and 13 of 20 (``benchmarks/legged_noise_sweep.py``,
    ``benchmarks/results/legged_noise_sweep.json``). On one seed the smaller of the forward
    and backward push limits rose on every quadruped
    (``benchmarks/results/legged_push_first_stage.json``). On the Go2 and the Go1 the
    outcome of a push is not monotone in its force with either setting (Go2: 60-100 N fall
    where 150-300 N stand; Go1: 200-250 N fall where 300 N stands), so check a bisected
    limit with :func:`~mpcbox.comparison.push_limits.push_grid`
    (``benchmarks/qp_push_window.py``, ``benchmarks/results/qp_push_window_*.json``).

    The humanoid presets keep their own measured QP settings (50 Hz, their stance weight and
    lifted-force law) with these OSQP settings.

    Raises:
        UnknownNameError: If a foot, the root or the keyframe does not exist (lists those
            that do).
        InvalidArgumentError: If the model has no free joint and no ``root`` is named, or an
            option is out of range.
    """

    name = "legged_balance"
    #: LQR, and QP-MPC with friction cones at the task's :attr:`contacts` (50 Hz, OSQP at
    #: :data:`QP_OSQP_SETTINGS`; an instance whose actuators have no position feedback
    #: replans every :attr:`torque_qp_period` s with LQR feedback in between).
    controller_configs: ClassVar[dict[str, Any]] = {
        "lqr": LQRConfig(),
        "qp": QPMPCConfig(
            period=0.02,
            stance_weight=1e5,
            osqp_settings=QP_OSQP_SETTINGS,
            first_stage_forces="free",
        ),
    }
    #: QP-MPC's replanning period on a robot driven by torque alone (no actuator holds a
    #: position between two ticks, :func:`position_feedback`), which also gets
    #: ``between_ticks="lqr"``; ``None`` keeps the config as it is.
    torque_qp_period: ClassVar[float | None] = TORQUE_QP_PERIOD
    equilibrium: Equilibrium | None = None

    def __init__(
        self,
        model: ModelSource,
        *,
        feet: Sequence[str] | str | None,
        root: str | None = None,
        keyframe: str | int | None = None,
        fall_height: float | None = None,
        fall_fraction: float = 0.6,
        fall_tilt: float | None = 60.0,
        support: str = "center",
        balance_target: str = "reference",
        contacts: Sequence[str] | None = None,
        balance_cost: float = 1000.0,
        joint_cost: float | np.ndarray = 1.0,
        velocity_cost: float = 0.0,
        ctrl_cost: float | np.ndarray = 1.0,
        ctrl_units: str = "range",
        noise_fraction: float | np.ndarray | None = 0.05,
        noise_torque: float | np.ndarray | None = None,
        recovery_tilt: float | None = 2.0,
        root_adjust: str = "pose",
        mesh_soles: str = "box",
        **kwargs: Any,
    ) -> None:
        self.root_adjust = one_of("root_adjust", root_adjust, ROOT_ADJUSTMENTS)
        self.mesh_soles = one_of("mesh_soles", mesh_soles, MESH_SOLES)
        self.support = one_of("support", support, SUPPORTS)
        self.balance_target = one_of("balance_target", balance_target, BALANCE_TARGETS)
        self.ctrl_units = one_of("ctrl_units", ctrl_units, UNITS)
        self.fall_fraction = in_range(
            "fall_fraction", fall_fraction, 0.0, 1.0, low_open=True, high_open=True
        )
        self.fall_height = None if fall_height is None else finite("fall_height", fall_height)
        self.fall_tilt = (
            None
            if fall_tilt is None
            else in_range("fall_tilt", fall_tilt, 0.0, 180.0, low_open=True, high_open=False)
        )
        self.weights = dict(
            balance=non_negative("balance_cost", balance_cost),
            joint=_weight("joint_cost", joint_cost),
            velocity=non_negative("velocity_cost", velocity_cost),
            ctrl=_weight("ctrl_cost", ctrl_cost),
        )
        if noise_torque is not None:
            noise_fraction = None
        self.noise_fraction, self.noise_torque = noise_fraction, noise_torque
        self.recovery_tilt = optional_positive("recovery_tilt", recovery_tilt)

        spec = load_spec(model)
        base = compile_spec(spec)
        if keyframe is None and base.nkey:
            keyframe = 0
        key = None if keyframe is None else object_id(base, "keyframe", keyframe, "keyframe")
        qpos = base.qpos0 if key is None else base.key_qpos[key]
        if kwargs.get("qpos_ref") is not None:
            qpos = as_array("qpos_ref", kwargs["qpos_ref"], (base.nq,))
        self.root_id = root_body(base, root)
        self.root = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, self.root_id) or ""
        if not self.root:
            raise InvalidArgumentError("root: the root body needs a name for the cost sensors")
        feet = self.standing_feet(base, qpos, feet)
        self.feet: tuple[Foot, ...] = find_feet(base, feet, qpos)
        self.foot_frames = self.add_sole_sites(spec, base)
        if contacts is None:
            self.contacts = self._contacts()
        else:
            self.contacts = (contacts,) if isinstance(contacts, str) else tuple(contacts)
        self.support_points = self._add_support(spec, base, qpos)
        super().__init__(spec, keyframe=key, **kwargs)
        if self.mesh_soles == "box":
            bodies = sorted({foot.body for foot in self.feet})
            boxed = box_soles(self.planning_model, self.qpos_ref, bodies)
            if boxed.geoms:
                self.replace_planning_model(boxed.model, f"box soles {list(boxed.geoms)}")
        if contacts is not None:  # QP-MPC reads them later: check the names now
            try:
                contact_points(self.model, self.contacts, self.qpos_ref)
            except UnknownNameError as exc:
                raise UnknownNameError(exc.kind, exc.name, exc.valid, "contacts") from None
        qp = type(self).controller_configs.get("qp")
        period = type(self).torque_qp_period
        if isinstance(qp, QPMPCConfig) and period and not position_feedback(self.model):
            self.controller_configs = {
                **type(self).controller_configs,
                "qp": dataclasses.replace(qp, period=period, between_ticks="lqr"),
            }

    # ------------------------------------------------------------------ construction
    def standing_feet(
        self, model: mujoco.MjModel, qpos: np.ndarray, feet: Sequence[str] | str | None
    ) -> Sequence[str] | str:
        """The feet the task stands on, from the ``feet`` argument (``None`` when omitted),
        given the compiled ``model`` and the standing posture ``qpos`` ``(nq,)`` (the
        keyframe or ``qpos_ref``). Subclasses find omitted feet
        (:func:`~mpcbox.tasks.legged.ground_feet.ground_feet`) or choose among them; here
        they are returned as given (:func:`~mpcbox.tasks.legged.feet.find_feet` refuses
        ``None`` with an ``InvalidTypeError``)."""
        return feet

    def add_sole_sites(self, spec: mujoco.MjSpec, base: mujoco.MjModel) -> tuple[str, ...]:
        """Add a site ``<name>_sole`` at each body or geom foot's sole to ``spec``.

        Args:
            spec: The spec the Problem is built from (changed in place).
            base: ``spec`` compiled before the change.

        Returns:
            The frame (site or body name) of each foot that the cost and measures follow.
        """
        frames: list[str] = []
        for foot in self.feet:
            if foot.kind == "site":
                frames.append(foot.name)
                continue
            name = _unique_name(base, mujoco.mjtObj.mjOBJ_SITE, f"{foot.name}_sole", frames)
            body = spec.bodies[foot.body]  # the spec lists bodies in the model's order
            body.add_site(name=name, pos=foot.sole.tolist())
            frames.append(name)
        return tuple(frames)

    def _contacts(self) -> tuple[str, ...]:
        """Each foot's contact: a site or geom foot itself; a body foot's sole site when
        the sole is one point (a sphere), else all of the body's collision geoms."""
        out = []
        for foot, frame in zip(self.feet, self.foot_frames):
            if foot.kind == "body" and foot.point and frame != foot.name:
                out.append(f"site:{frame}")
            else:
                out.append(foot.contact)
        return tuple(out)

    def _add_support(
        self, spec: mujoco.MjSpec, base: mujoco.MjModel, qpos: np.ndarray
    ) -> tuple[str, ...]:
        """The frames the center of mass is kept over (adds ``feet_center`` if needed)."""
        if self.support == "feet" or len(self.feet) == 1:
            return self.foot_frames
        data = mujoco.MjData(base)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(base, data)
        soles = [foot.world(data) for foot in self.feet]
        center = sum(soles[1:], soles[0]) / len(soles)
        name = _unique_name(base, mujoco.mjtObj.mjOBJ_SITE, FEET_CENTER)
        spec.worldbody.add_site(name=name, pos=[center[0], center[1], 0.0])
        return (name,)

    def prepare(self, model: mujoco.MjModel) -> None:
        self.equilibrium = find_equilibrium(model, self.qpos_ref, root_adjust=self.root_adjust)
        self.qpos_ref = self.equilibrium.qpos
        self.ctrl_ref = self.equilibrium.ctrl
        data = mujoco.MjData(model)
        data.qpos[:] = self.qpos_ref
        mujoco.mj_kinematics(model, data)
        height = float(data.xpos[self.root_id, 2])
        if self.fall_height is None:
            self.fall_height = self.fall_fraction * height
        elif self.fall_height >= height or self.fall_height < min(0.0, height):
            raise InvalidArgumentError(  # above it all runs "fall", below the floor none can
                f"fall_height must lie between the floor (0 m) and the {self.root!r} body's "
                f"reference height ({height:.3g} m), got {self.fall_height:g}"
            )
        #: The root's tilt in the reference posture (deg).
        self.reference_tilt = Tilt(body=self.root).sample(model, data)
        #: Horizontal offset of the center of mass from each support point in the
        #: reference posture ``(n, 2)`` (m), for ``balance_target="reference"``.
        self.balance_offsets = support_offsets(model, data, self.root_id, self.support_points)

    def joint_weights(self, model: mujoco.MjModel) -> np.ndarray:
        """Per-dof posture weights ``(nv,)``: ``joint_cost``, zero on free joints (the root)."""
        return dof_weights(model, as_weights("joint_cost", self.weights["joint"], model.nv))

    def ctrl_weights(self, model: mujoco.MjModel) -> np.ndarray:
        """Per-actuator control weights ``(nu,)`` in control units (from ``ctrl_units``)."""
        scales = actuator_scales(model, self.qpos_ref)
        return to_control(scales, self.weights["ctrl"], self.ctrl_units, power=-2, name="ctrl_cost")

    def balance_terms(self) -> list[CostTerm]:
        """The center of mass over the support point (or over each foot)."""
        w, frames = self.weights["balance"], self.support_points
        offsets = (
            self.balance_offsets
            if self.balance_target == "reference"
            else np.zeros((len(frames), 2))
        )
        if len(frames) == 1:
            return [
                ComOverSupport(
                    frames[0], weight=w, root=self.root, offset=offsets[0], name="balance"
                )
            ]
        return [
            ComOverSupport(
                frame,
                weight=w / len(frames),
                root=self.root,
                offset=offset,
                name=f"balance_{i}",
            )
            for i, (frame, offset) in enumerate(zip(frames, offsets, strict=True))
        ]

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        w = self.weights
        return Cost(
            [
                *self.balance_terms(),
                StateCost(
                    self.qpos_ref, weight_qpos=self.joint_weights(model), weight_qvel=w["velocity"]
                ),
                ControlCost(self.ctrl_ref, weight=self.ctrl_weights(model)),
            ]
        )

    # ------------------------------------------------------------------ monitoring
    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        reason = super().failure(model, data)
        if reason is None and data.xpos[self.root_id, 2] < self.fall_height:
            reason = f"fell: {self.root} below {self.fall_height:.3g} m"
        if reason is None and self.fall_tilt is not None:
            tilt = float(np.degrees(np.arccos(np.clip(data.xmat[self.root_id, 8], -1.0, 1.0))))
            if abs(tilt - self.reference_tilt) > self.fall_tilt:
                reason = f"fell: {self.root} tilted {tilt:.0f} deg"
        return reason

    def support_frames(self) -> tuple[str, ...]:
        """Sites or bodies whose mean horizontal position is the support point."""
        return self.support_points

    def measures(self) -> tuple[Measure, ...]:
        """COM deviation from the support point (m) and the root's tilt (deg), with its
        recovery time when ``recovery_tilt`` is set."""
        recovery = None if self.recovery_tilt is None else self.reference_tilt + self.recovery_tilt
        return balance_measures(self.support_frames(), body=self.root, recovery_tilt=recovery)

    def noise(self, scale: float = 1.0) -> ActuatorNoise:
        """The robot-independent noise recipe: ``noise_fraction`` of each actuator's half
        range, or ``noise_torque``, read at the reference posture
        (:func:`~mpcbox.sim.effort_noise.effort_noise`)."""
        return effort_noise(
            self.model,
            self.qpos_ref,
            fraction=self.noise_fraction,
            torque=self.noise_torque,
            scale=scale,
        )
