r"""Plan joint set-points for a torque-driven robot: its motors as servos in the planning model.

A sampling planner draws its controls at random; on a torque-driven arm a random torque
sequence has to hold the arm against gravity as well as move it, and small torque noise
moves nothing (on the Franka FR3 with motors, MPPI ended 10-27 cm from a 40 cm reach's
target). Planning in set-points instead, as most sampling MPC for arms does, needs a
servo between the plan and the motors:

.. math:: \tau_j = \mathrm{clip}\big(k_{p,j} (u_j - q_j) - k_{v,j} \dot q_j,\;
   \tau_{j,\min}, \tau_{j,\max}\big),

with each joint's gains from a bandwidth :math:`\omega` (default :math:`0.1/h`) and damping
ratio :math:`\zeta` on its inertia at the start posture (:math:`I_j`, the diagonal of the
mass matrix, armature included): :math:`k_p = I \omega^2`, :math:`k_v = 2 \zeta I \omega`.
:func:`servo_spec` builds the planning model, each motor replaced by that position servo
with the motor's torque range as its force range; :class:`ServoActions` runs any planner on
a Problem of that model and sends the world the motor controls of the same law at every
simulation step.

The planning model integrates the servo's damping implicitly and the world explicitly; at
:math:`k_v h / I = 2 \zeta \omega h` (0.2 by default) the two agree closely, and the damping
is moderate, so a saturating servo's step hardly jumps (:mod:`~mpcbox.core.saturation_jumps`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller, check_problem
from mpcbox.core.actuation import motor_actuators
from mpcbox.core.model import ModelSource, compile_spec, load_spec
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnsupportedModelError
from mpcbox.validation import as_array, positive

_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class ServoLaw(NamedTuple):
    """The servo that turns set-points into motor controls, for the converted motors.

    Attributes:
        actuators: Indices of the motors replaced ``(k,)``; other controls pass through.
        qpos_adr: Each one's joint position address ``(k,)``.
        dof_adr: Each one's joint velocity address ``(k,)``.
        kp: Stiffness (N m/rad or N/m) ``(k,)``.
        kv: Damping (N m s/rad or N s/m) ``(k,)``.
        gear: The motor's gear ``(k,)`` (torque = gear x control).
        ctrl_low: The motor's lower control bound ``(k,)`` (``-inf`` when unlimited).
        ctrl_high: The motor's upper control bound ``(k,)``.
    """

    actuators: np.ndarray
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    kp: np.ndarray
    kv: np.ndarray
    gear: np.ndarray
    ctrl_low: np.ndarray
    ctrl_high: np.ndarray

    def controls(self, state: np.ndarray, setpoints: np.ndarray, nq: int) -> np.ndarray:
        """The world's controls ``(nu,)`` for ``setpoints`` ``(nu,)`` at ``state``: the
        servo's torque over the gear on the converted motors, the set-point elsewhere."""
        ctrl = np.array(setpoints, dtype=np.float64, copy=True)
        i = self.actuators
        q, qdot = state[self.qpos_adr], state[nq + self.dof_adr]
        torque = self.kp * (setpoints[i] - q) - self.kv * qdot
        ctrl[i] = np.clip(torque / self.gear, self.ctrl_low, self.ctrl_high)
        return ctrl


def motors(model: mujoco.MjModel) -> np.ndarray:
    """Indices of the actuators that are plain motors on a hinge or slide joint (force = gear
    x control): those :func:`servo_spec` replaces."""
    out = []
    motor = motor_actuators(model)
    for i in range(model.nu):
        if (
            motor[i]
            and model.actuator_dyntype[i] == mujoco.mjtDyn.mjDYN_NONE
            and model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT
            and int(model.jnt_type[model.actuator_trnid[i, 0]]) in _SCALAR
            and model.actuator_gear[i, 0] != 0.0
        ):
            out.append(i)
    return np.array(out, dtype=int)


def servo_spec(
    model: ModelSource,
    *,
    bandwidth: float | None = None,
    damping_ratio: float = 1.0,
    qpos: np.ndarray | None = None,
) -> tuple[mujoco.MjSpec, ServoLaw]:
    r"""The planning model with each motor replaced by a position servo, and the servo's law.

    Args:
        model: The torque-driven model (MJCF path, XML, spec or ``"menagerie:NAME"``).
        bandwidth: :math:`\omega` (rad/s) of every servo; default :math:`0.1 / h` for the
            model's timestep :math:`h` (50 rad/s at 2 ms), so that :math:`2 \omega h = 0.2`:
            stiff enough to track, and the world's explicit damping close to the planning
            model's implicit one. On a Franka FR3 with motors (2 ms) MPPI reached with 30 and
            50 rad/s; on dm_control's manipulator (1 ms) it stopped 3.7 cm short with 30 and
            reached with 60 and 100.
        damping_ratio: :math:`\zeta`.
        qpos: Posture ``(nq,)`` whose mass matrix gives the inertias; default the first
            keyframe, else ``qpos0``.

    Returns:
        ``(spec, law)``: the servo model's spec (its controls are set-points, within the
        joint's range when it has one) and the :class:`ServoLaw`.

    Raises:
        InvalidArgumentError: For a non-positive ``bandwidth`` or ``damping_ratio``.
        UnsupportedModelError: If the model has no motor on a hinge or slide joint.
    """
    damping_ratio = positive("damping_ratio", damping_ratio)
    spec = load_spec(model).copy()  # edited below; a caller's spec stays as it was
    compiled = compile_spec(spec.copy())
    if bandwidth is None:
        bandwidth = 0.1 / compiled.opt.timestep
    bandwidth = positive("bandwidth", bandwidth)
    ids = motors(compiled)
    if ids.size == 0:
        raise UnsupportedModelError(
            "servo_spec needs motors (gear x control) on hinge or slide joints; the model has "
            "none (its actuators are servos or act through tendons or activations already)"
        )
    if qpos is None:
        qpos = compiled.key_qpos[0] if compiled.nkey else compiled.qpos0
    data = mujoco.MjData(compiled)
    data.qpos[:] = as_array("qpos", qpos, (compiled.nq,))
    mujoco.mj_forward(compiled, data)
    mass = np.zeros((compiled.nv, compiled.nv))
    mujoco.mj_fullM(compiled, data, mass)
    joints = compiled.actuator_trnid[ids, 0]
    dof = compiled.jnt_dofadr[joints]
    inertia = np.diag(mass)[dof]
    kp = inertia * bandwidth**2
    kv = 2.0 * damping_ratio * inertia * bandwidth
    for name, value in (("kp", kp), ("kv", kv)):
        if not np.all(np.isfinite(value) & (value > 0.0)):
            raise InvalidArgumentError(f"servo {name} must be positive and finite, got {value}")
    gear = compiled.actuator_gear[ids, 0].copy()
    limited = compiled.actuator_ctrllimited[ids].astype(bool)
    low = np.where(limited, compiled.actuator_ctrlrange[ids, 0], -np.inf)
    high = np.where(limited, compiled.actuator_ctrlrange[ids, 1], np.inf)
    for j, i in enumerate(ids):
        act = spec.actuators[int(i)]
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.gainprm[0] = kp[j]
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.biasprm[:3] = [0.0, -kp[j], -kv[j]]
        act.gear[0] = 1.0
        if limited[j]:
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = np.sort(gear[j] * np.array([low[j], high[j]]))
        joint = int(joints[j])
        if compiled.jnt_limited[joint]:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = compiled.jnt_range[joint]
        else:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    law = ServoLaw(
        actuators=ids,
        qpos_adr=compiled.jnt_qposadr[joints].copy(),
        dof_adr=dof.copy(),
        kp=kp,
        kv=kv,
        gear=gear,
        ctrl_low=low,
        ctrl_high=high,
    )
    return spec, law


class ServoActions(Controller):
    """Run a planner on the servo model and send the world the motors' controls.

    Called every simulation step (``period=None``): it asks ``planner`` for its set-points
    (a spline planner built with ``period=None`` and a ``replan_period`` replans when due
    and otherwise returns its plan at the elapsed time) and applies the :class:`ServoLaw`
    at the measured state. Use it in lock-step runs (:func:`mpcbox.simulate`): the law is
    feedback at every step, and in :func:`~mpcbox.sim.realtime.simulate_realtime` the world
    would hold the last published torque while a replan runs.

    Args:
        problem: The world's Problem (torque-driven).
        planner: A controller of a Problem on :func:`servo_spec`'s model, with the same state
            layout.
        law: The :class:`ServoLaw` from :func:`servo_spec`.
        name: Label in tables (default ``"<planner>-servo"``).

    Raises:
        InvalidTypeError: If ``planner`` is not a Controller or ``law`` not a ServoLaw.
        InvalidArgumentError: If the two Problems' states or controls differ in size.
    """

    def __init__(
        self, problem: Problem, planner: Controller, law: ServoLaw, *, name: str | None = None
    ) -> None:
        self.problem = check_problem(problem, "ServoActions")
        if not isinstance(planner, Controller):
            raise InvalidTypeError(
                f"planner must be an mpcbox Controller, got {type(planner).__name__}"
            )
        if not isinstance(law, ServoLaw):
            raise InvalidTypeError(f"law must be a ServoLaw, got {type(law).__name__}")
        inner = getattr(planner, "problem", None)
        if inner is not None and (inner.nstate, inner.nu) != (problem.nstate, problem.nu):
            raise InvalidArgumentError(
                f"planner's Problem has nstate={inner.nstate}, nu={inner.nu}; the world's "
                f"has nstate={problem.nstate}, nu={problem.nu}: plan on servo_spec's model"
            )
        self.planner = planner
        self.law = law
        self.name = name or f"{planner.name}-servo"
        self.period = None

    def reset(self) -> None:
        self.planner.reset()

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        state = self.problem.check_state(state)
        setpoints = np.asarray(self.planner(state, time), dtype=np.float64)
        self.last_call = getattr(self.planner, "last_call", "solve")
        return self.law.controls(state, setpoints, self.problem.nq)

    @property
    def stats(self) -> dict[str, Any]:
        return dict(getattr(self.planner, "stats", {}))


__all__ = ["ServoActions", "ServoLaw", "motors", "servo_spec"]
