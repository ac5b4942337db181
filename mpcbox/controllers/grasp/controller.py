r"""Grasp controllers for a gripper's finger actuators: force-QP (adaptive) and position closing.

Both act on the same fingers, named by their actuators, each acting on the object through
its pad geoms; each call returns the fingers' controls (:class:`GraspCommand`).

:class:`ForceGrasp` closes each finger with ``approach_force`` until all touch the object,
then each tick

1. measures the contacts (:func:`~mpcbox.controllers.grasp.contacts.finger_contacts`);
2. updates the safety factor :math:`s` and friction estimate :math:`\hat\mu` from slip
   (:class:`~mpcbox.controllers.grasp.config.ForceGraspConfig`);
3. solves the grasp-force QP (:mod:`~mpcbox.controllers.grasp.force_qp`) for the force
   :math:`f^\star = \hat m (a - g)` (:math:`a` the object's planned acceleration, e.g. from
   the wrist's plan), with friction :math:`\hat\mu / s`, margin
   :math:`\delta = d \hat m \lVert g \rVert / k` and the moment about the object's centre
   of mass;
4. maps the finger forces :math:`f_i` to generalized forces
   :math:`\tau = \sum_i J_i^T f_i + b` on the finger dofs (:math:`J_i` the translational
   Jacobian of the contact point on finger :math:`i`, :math:`b` the bias forces), adds a
   spring-damper on the fingers' differential mode (``center_stiffness``), and solves
   MuJoCo's actuator model for the controls that supply them within the actuators' limits
   (:func:`~mpcbox.core.actuation.solve_actuation`): a motor gets :math:`\tau / \text{gear}`,
   a position servo the set-point :math:`q + \tau / k_p`.

:class:`PositionGrasp` commands a fixed closing set-point: its squeeze is whatever the servo
gain makes of the gap between the set-point and the object.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.config import resolve_config
from mpcbox.controllers.grasp.config import ForceGraspConfig
from mpcbox.controllers.grasp.contacts import FingerContacts, finger_contacts
from mpcbox.controllers.grasp.force_qp import GraspForces, GraspQP
from mpcbox.core.actuation import ActuationMap, actuation_map, solve_actuation
from mpcbox.core.model import object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, finite_array, positive


class GraspCommand(NamedTuple):
    """What a grasp controller commands at one tick.

    Attributes:
        ctrl: Controls of the finger actuators ``(k,)``, in their order.
        phase: ``"approach"`` (not all fingers touch), ``"hold"`` (QP forces) or
            ``"saturated"`` (QP failed: every finger at ``f_max``); ``"position"`` for
            :class:`PositionGrasp`.
        normal_force: Commanded normal force of each finger ``(k,)`` (N; NaN for position).
        safety: The safety factor :math:`s` (NaN for position).
        friction: The friction estimate :math:`\\hat\\mu` (NaN for position).
        slipping: Whether slip was detected at this tick.
    """

    ctrl: np.ndarray
    phase: str
    normal_force: np.ndarray
    safety: float
    friction: float
    slipping: bool


class _Fingers:
    """Ids of the finger actuators, their dofs, their pad geoms and the object's body."""

    def __init__(
        self,
        model: mujoco.MjModel,
        fingers: Sequence[str],
        pads: Sequence[str | Sequence[str]],
        target: str,
    ) -> None:
        fingers = list(fingers)
        if len(fingers) < 2:
            raise InvalidArgumentError(f"fingers must name at least 2 actuators, got {fingers}")
        if len(pads) != len(fingers):
            raise InvalidArgumentError(
                f"pads must give the pad geoms of each of the {len(fingers)} fingers, "
                f"got {len(pads)} entries"
            )
        self.actuators = np.array([object_id(model, "actuator", a, "fingers") for a in fingers])
        joints = model.actuator_trnid[self.actuators, 0]
        if np.any(model.actuator_trntype[self.actuators] != mujoco.mjtTrn.mjTRN_JOINT):
            raise InvalidArgumentError("fingers must name actuators with joint transmissions")
        self.dofs = np.array([int(model.jnt_dofadr[j]) for j in joints])
        self.qpos = np.array([int(model.jnt_qposadr[j]) for j in joints])
        scalar = (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))
        if any(int(model.jnt_type[j]) not in scalar for j in joints):
            raise InvalidArgumentError("fingers must drive slide or hinge joints")
        self.pads = [
            np.array(
                [object_id(model, "geom", g, "pads") for g in ([p] if isinstance(p, str) else p)]
            )
            for p in pads
        ]
        self.body = object_id(model, "body", target, "target")


class ForceGrasp:
    """Adaptive force-controlled grasp through the grasp-force QP (see the module docstring).

    Args:
        model: The model.
        mass: Estimated object mass :math:`\\hat m` (kg).
        fingers: Names of the finger actuators (joint transmissions, one dof each).
        pads: Pad geom name(s) of each finger.
        target: Name of the object's body.
        config: Options (default :class:`ForceGraspConfig`); ``**options`` override fields.

    Raises:
        InvalidArgumentError: On a non-positive mass, fewer than two fingers or a pads list
            of another length.
        UnknownNameError: If a name is not in the model (the message lists those that are).
    """

    name = "force QP"

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        mass: float,
        fingers: Sequence[str],
        pads: Sequence[str | Sequence[str]],
        target: str,
        config: ForceGraspConfig | None = None,
        **options: Any,
    ) -> None:
        self.config = resolve_config(ForceGraspConfig, config, options, "ForceGrasp")
        self.model = model
        self.mass = positive("mass", mass)
        self.ids = _Fingers(model, fingers, pads, target)
        self.qp = GraspQP(len(self.ids.actuators), facets=self.config.facets)
        self.last_forces: GraspForces | None = None
        self.last_contacts: FingerContacts | None = None
        self.reset()

    def reset(self) -> None:
        """Start a new grasp: prior friction, resting safety factor, cold QP."""
        self.safety = self.config.safety
        self.friction = self.config.friction
        self._time: float | None = None
        self._map: ActuationMap | None = None
        self._map_q = np.zeros(len(self.ids.dofs))
        self.qp.reset()

    def _adapt(self, contacts: FingerContacts, dt: float) -> bool:
        cfg = self.config
        sliding = contacts.slip_speed > cfg.slip_speed
        ratio = contacts.friction_ratio
        slipping = bool(np.any(sliding) or np.any(ratio > cfg.slip_ratio * self.friction))
        if np.any(sliding):
            seen = float(np.max(ratio[sliding]))
            if 0.0 < seen < self.friction:
                self.friction = max(seen, cfg.friction_floor)
        if slipping:
            self.safety = min(cfg.safety_max, self.safety + cfg.safety_rate * dt)
        else:
            decay = np.exp(-dt / cfg.safety_decay)
            self.safety = cfg.safety + (self.safety - cfg.safety) * decay
        return slipping

    def _controls(self, data: mujoco.MjData, points: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """Controls whose actuator forces push with ``forces`` ``(k, 3)`` at ``points``."""
        model, ids = self.model, self.ids
        cfg = self.config
        qfrc = data.qfrc_bias[ids.dofs] - data.qfrc_passive[ids.dofs]
        jac = np.zeros((3, model.nv))
        for i, pad in enumerate(ids.pads):
            mujoco.mj_jac(model, data, jac, None, points[i], int(model.geom_bodyid[pad[0]]))
            qfrc += jac[:, ids.dofs].T @ forces[i]
        q, qd = data.qpos[ids.qpos], data.qvel[ids.dofs]
        qfrc -= cfg.center_stiffness * (q - q.mean()) + cfg.center_damping * (qd - qd.mean())
        if self._map is None or np.max(np.abs(q - self._map_q)) > cfg.map_tolerance:
            amap = actuation_map(model, data)
            self._map = amap._replace(
                matrix=amap.matrix[np.ix_(ids.dofs, ids.actuators)],
                offset=amap.offset[ids.dofs],
                lower=amap.lower[ids.actuators],
                upper=amap.upper[ids.actuators],
            )
            self._map_q = q.copy()
        return solve_actuation(self._map, qfrc)

    def __call__(self, data: mujoco.MjData, accel: np.ndarray | None = None) -> GraspCommand:
        """The fingers' controls now.

        Args:
            data: The simulation's data, after a step or ``mj_forward`` (contacts, forces).
            accel: Planned acceleration of the object ``(3,)`` (m/s^2), default zero.

        Returns:
            The :class:`GraspCommand`.
        """
        cfg, ids, model = self.config, self.ids, self.model
        accel = np.zeros(3) if accel is None else finite_array("accel", accel, (3,))
        dt = 0.0 if self._time is None else max(float(data.time) - self._time, 0.0)
        self._time = float(data.time)
        contacts = finger_contacts(model, data, ids.pads, ids.body)
        self.last_contacts = contacts
        k = len(ids.pads)
        if not np.all(contacts.touching):
            points, forces = np.zeros((k, 3)), np.zeros((k, 3))
            jac = np.zeros((3, model.nv))
            for i, pad in enumerate(ids.pads):
                points[i] = data.geom_xpos[pad[0]]
                mujoco.mj_jac(model, data, jac, None, points[i], int(model.geom_bodyid[pad[0]]))
                closing = jac[:, ids.dofs[i]]
                forces[i] = cfg.approach_force * closing / max(np.linalg.norm(closing), 1e-12)
            ctrl = self._controls(data, points, forces)
            nan = float("nan")
            return GraspCommand(ctrl, "approach", np.full(k, cfg.approach_force), nan, nan, False)
        slipping = self._adapt(contacts, dt)
        gravity = model.opt.gravity
        weight = self.mass * float(np.linalg.norm(gravity))
        sol = self.qp.solve(
            contacts.position,
            contacts.normal,
            data.xipos[ids.body],
            self.mass * (accel - gravity),
            np.zeros(3),
            friction=self.friction / self.safety,
            torsion=cfg.torsion,
            margin=cfg.disturbance * weight / k,
            f_min=cfg.f_min,
            f_max=cfg.f_max,
        )
        self.last_forces = sol
        if sol.solved:
            forces, phase = sol.forces, "hold"
        else:
            forces, phase = cfg.f_max * contacts.normal, "saturated"
        ctrl = self._controls(data, contacts.position, forces)
        normal = np.einsum("ki,ki->k", forces, contacts.normal)
        return GraspCommand(ctrl, phase, normal, self.safety, self.friction, slipping)


class PositionGrasp:
    """Fingers commanded to a fixed closing set-point (the plain grasp).

    Args:
        model: The model.
        fingers: Names of the finger actuators.
        closed: Set-point of each finger ``(k,)``, or one for all (control units: for a
            position servo, the joint value).

    Raises:
        UnknownNameError: If a finger is not an actuator of the model.
    """

    name = "position"

    def __init__(
        self, model: mujoco.MjModel, *, fingers: Sequence[str], closed: float | np.ndarray
    ) -> None:
        self.actuators = np.array([object_id(model, "actuator", a, "fingers") for a in fingers])
        closed_arr = as_array("closed", closed, (None,) * np.ndim(closed))
        self.closed = np.broadcast_to(closed_arr, self.actuators.shape).astype(float)

    def reset(self) -> None:
        """Nothing to forget."""

    def __call__(self, data: mujoco.MjData, accel: np.ndarray | None = None) -> GraspCommand:
        """The fixed set-points (``accel`` is ignored)."""
        k = len(self.actuators)
        nan = float("nan")
        return GraspCommand(self.closed.copy(), "position", np.full(k, nan), nan, nan, False)
