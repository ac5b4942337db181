r"""A phase-aware controller for position-servo arms: IK waypoints, replanned from measurement.

A task is a sequence of :class:`Phase`\ s (approach, descend, close, lift, ...). When a phase
starts, its ``target`` reads the *measured* scene (the model's data at the current state,
after :func:`mujoco.mj_kinematics`) and returns one :class:`Waypoint` per arm: an
end-effector pose and a gripper command. Inverse kinematics (:class:`~mpcbox.core.arm_ik.ArmIK`,
mink) turns the pose into joint angles :math:`q^\star`, and over the phase's ``duration``
the servo set-points move from the previous command :math:`u_0` to the new one
:math:`u^\star` along a minimum-jerk profile

.. math::
    u(t) = u_0 + (u^\star - u_0)\, s(\tau),\quad s(\tau) = 10\tau^3 - 15\tau^4 + 6\tau^5,
    \quad \tau = \min(1, (t - t_0)/T),

then hold for ``hold`` seconds. A phase with ``replan=True`` re-reads the scene every
``replan_period`` and re-solves the IK (warm-started), so the arm follows a cube that moved
or corrects where the held object is relative to its goal: this is the closed loop.

With ``gravity_compensation`` the set-point of a position servo (force
:math:`k_p (u - q) - k_v \dot q`) is raised by the bias force it must hold,
:math:`u^\star = q^\star + \tau_\text{bias}(q^\star)/k_p`, so the arm does not sag below its
waypoints.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.config import resolve_config
from mpcbox.controllers.base import Controller, check_problem
from mpcbox.core.arm_ik import ArmIK
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import non_negative, positive


class ArmDrive(NamedTuple):
    """One arm as the controller drives it.

    Attributes:
        frame: End-effector site (or body) whose pose the waypoints give.
        joints: The arm's joints, each driven by a position servo.
        actuators: The servo of each joint, same order.
        posture: Rest angles ``(n,)`` the IK is lightly pulled toward.
        gripper: The gripper's actuator, or ``None``.
        ik_ranges: Joint ranges the IK keeps to, one ``(low, high)`` or ``None`` per joint
            (see :class:`~mpcbox.core.arm_ik.ArmIK`), or ``None`` for the model's.
    """

    frame: str
    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    posture: tuple[float, ...]
    gripper: str | None = None
    ik_ranges: tuple[tuple[float, float] | None, ...] | None = None


class Waypoint(NamedTuple):
    """Where one arm goes in a phase.

    Attributes:
        position: End-effector position ``(3,)`` (m), or ``None`` to keep the arm's current
            joint command.
        quat: End-effector orientation ``[w, x, y, z]``, or ``None`` to keep the current one.
        gripper: Gripper control, or ``None`` to keep the current one.
    """

    position: np.ndarray | None = None
    quat: np.ndarray | None = None
    gripper: float | None = None


#: ``target(model, data, memo)``: the waypoint (or one per arm) from the measured scene;
#: ``memo`` is a dict that lives for one run (emptied by ``reset``), where a phase can leave
#: what a later phase needs (the yaw of a grasp, say).
Target = Callable[[mujoco.MjModel, mujoco.MjData, dict], "Waypoint | Sequence[Waypoint]"]


class Phase(NamedTuple):
    """One phase of a task.

    Attributes:
        name: Label (``"approach"``, ``"close"``, ...).
        target: Waypoint(s) from the measured scene, see :data:`Target`.
        duration: Time of the minimum-jerk move to the waypoint (s).
        hold: Time to stay after the move (s).
        replan: Re-read the scene and re-solve the IK every ``replan_period`` in the phase.
    """

    name: str
    target: Target
    duration: float
    hold: float = 0.0
    replan: bool = False


@dataclass(frozen=True, kw_only=True)
class WaypointConfig:
    """Options of :class:`WaypointController`.

    Attributes:
        period: Seconds between controller calls.
        replan_period: Seconds between re-plans inside a phase with ``replan=True``.
        ik_iterations: Maximum IK steps per waypoint.
        ik_tolerance: IK position tolerance (m).
        gravity_compensation: Raise position-servo set-points by the bias force they hold.
    """

    period: float = 0.02
    replan_period: float = 0.1
    ik_iterations: int = 40
    ik_tolerance: float = 1e-3
    gravity_compensation: bool = True


class WaypointController(Controller):
    """Drive one or more position-servo arms through ``phases`` (see the module docstring).

    Args:
        problem: The Problem (its simulation model gives the kinematics).
        arms: The arms, as :class:`ArmDrive`; a phase's target returns one waypoint per arm.
        phases: The phases, in order; after the last, the last command is held.
        config: A :class:`WaypointConfig`.
        **options: Fields replacing those of ``config``.

    Raises:
        InvalidArgumentError: Without phases or arms, or for an actuator that is not a
            position servo on its joint.
    """

    name = "waypoints"
    config_class = WaypointConfig

    def __init__(
        self,
        problem: Problem,
        *,
        arms: Sequence[ArmDrive],
        phases: Sequence[Phase],
        config: WaypointConfig | None = None,
        **options: Any,
    ) -> None:
        self.problem = check_problem(problem, "WaypointController")
        self.config = resolve_config(WaypointConfig, config, options, "WaypointController")
        self.period = positive("period", self.config.period)
        positive("replan_period", self.config.replan_period)
        self.arms = tuple(arms)
        self.phases = tuple(phases)
        if not self.arms or not self.phases:
            raise InvalidArgumentError("WaypointController needs at least one arm and one phase")
        model = problem.model
        self.model = model
        self.data = mujoco.MjData(model)
        for phase in self.phases:
            non_negative(f"phase {phase.name!r} duration", phase.duration)
            non_negative(f"phase {phase.name!r} hold", phase.hold)
        self._ik = []
        self._act: list[np.ndarray] = []
        self._dof: list[np.ndarray] = []
        self._grip: list[int | None] = []
        for arm in self.arms:
            self._ik.append(
                ArmIK(
                    model,
                    frame=arm.frame,
                    joints=arm.joints,
                    posture=np.asarray(arm.posture, dtype=float),
                    iterations=self.config.ik_iterations,
                    tolerance=self.config.ik_tolerance,
                    ranges=arm.ik_ranges,
                )
            )
            act = np.array([model.actuator(a).id for a in arm.actuators])
            self._check_servos(act, arm)
            self._act.append(act)
            self._dof.append(np.array([model.jnt_dofadr[model.joint(j).id] for j in arm.joints]))
            self._grip.append(None if arm.gripper is None else model.actuator(arm.gripper).id)
        self.reset()

    def _check_servos(self, act: np.ndarray, arm: ArmDrive) -> None:
        m = self.model
        for a, joint in zip(act, arm.joints, strict=True):
            kp = m.actuator_gainprm[a, 0]
            ok = (
                m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and m.actuator_trnid[a, 0] == m.joint(joint).id
                and kp > 0
                and np.isclose(m.actuator_biasprm[a, 1], -kp)
            )
            if not ok:
                raise InvalidArgumentError(
                    f"WaypointController: actuator {m.actuator(a).name!r} must be a position "
                    f"servo (gain kp > 0, bias -kp) on joint {joint!r}"
                )

    def reset(self) -> None:
        """Start again from the first phase."""
        self.phase = -1
        self._t0 = 0.0
        self._last_replan = 0.0
        self._u0: np.ndarray | None = None
        self._goal: np.ndarray | None = None
        self._q_goal: list[np.ndarray] = []
        self.ik_errors: list[tuple[str, float]] = []
        self.memo: dict = {}
        self.last_call = "hold"

    def fork(self) -> WaypointController:
        """A controller for another run at the same time (another world of a batch): it
        shares the model, the IK solvers and the scratch data (calls must not overlap, as in
        a batch loop on one thread) and has its own phase, plan and memo, reset."""
        twin = copy.copy(self)
        twin.reset()
        return twin

    @property
    def phase_name(self) -> str:
        """Name of the current phase (``""`` before the first call)."""
        return self.phases[self.phase].name if self.phase >= 0 else ""

    # ------------------------------------------------------------------ planning
    def _measure(self, state: np.ndarray) -> None:
        d = self.data
        self.problem.set_state(d, state)
        mujoco.mj_kinematics(self.model, d)

    def _plan(self, state: np.ndarray, phase: Phase) -> None:
        """Solve the IK of ``phase``'s waypoints at the measured ``state`` into ``_goal``."""
        assert self._goal is not None
        self._measure(state)
        m, d = self.model, self.data
        targets = phase.target(m, d, self.memo)
        if isinstance(targets, Waypoint):
            targets = (targets,)
        if len(targets) != len(self.arms):
            raise InvalidArgumentError(
                f"phase {phase.name!r} gave {len(targets)} waypoints for {len(self.arms)} arms"
            )
        qpos = d.qpos.copy()
        for i, (wp, ik) in enumerate(zip(targets, self._ik, strict=True)):
            if wp.position is not None:
                # Warm start from where the arm was last sent, so branches do not switch.
                start = qpos.copy()
                start[ik.qadr] = self._q_goal[i]
                sol = ik.solve(start, np.asarray(wp.position, float), wp.quat)
                self._q_goal[i] = sol.qpos
                self.ik_errors.append((phase.name, sol.position_error))
                self._goal[self._act[i]] = self._servo_setpoint(qpos, i)
            if wp.gripper is not None and self._grip[i] is not None:
                self._goal[self._grip[i]] = float(wp.gripper)

    def _servo_setpoint(self, qpos: np.ndarray, arm: int) -> np.ndarray:
        """Set-points of arm ``arm`` that hold ``_q_goal[arm]`` (gravity-compensated)."""
        q = self._q_goal[arm]
        if not self.config.gravity_compensation:
            return q.copy()
        d = self.data
        qadr = self._ik[arm].qadr
        d.qpos[:] = qpos
        d.qpos[qadr] = q
        d.qvel[:] = 0.0
        mujoco.mj_fwdPosition(self.model, d)
        mujoco.mj_fwdVelocity(self.model, d)
        kp = self.model.actuator_gainprm[self._act[arm], 0]
        return q + d.qfrc_bias[self._dof[arm]] / kp

    # ------------------------------------------------------------------ the call
    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        if self._u0 is None:
            self._start(state)
        assert self._u0 is not None and self._goal is not None
        self.last_call = "hold"
        while self.phase + 1 < len(self.phases) and (
            self.phase < 0 or time >= self._t0 + self._length(self.phase)
        ):
            start = time if self.phase < 0 else self._t0 + self._length(self.phase)
            self._u0 = self._command(start)  # where the last phase's move ended
            self._t0 = start
            self.phase += 1
            self._plan(state, self.phases[self.phase])
            self._last_replan = time
            self.last_call = "solve"
        phase = self.phases[self.phase]
        if phase.replan and time - self._last_replan >= self.config.replan_period - 1e-9:
            self._plan(state, phase)
            self._last_replan = time
            self.last_call = "solve"
        return self._command(time)

    def _length(self, k: int) -> float:
        return self.phases[k].duration + self.phases[k].hold

    def _command(self, time: float) -> np.ndarray:
        assert self._u0 is not None and self._goal is not None
        if self.phase < 0:
            return self._u0.copy()
        duration = self.phases[self.phase].duration
        tau = 1.0 if duration <= 0 else min(1.0, max(0.0, (time - self._t0) / duration))
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        return self.problem.clip_ctrl(self._u0 + (self._goal - self._u0) * s)

    def _start(self, state: np.ndarray) -> None:
        """First call: hold the measured arm posture, the reference gripper command."""
        u = self.problem.ctrl_ref.copy()
        qpos = state[: self.problem.nq]
        self._q_goal = [qpos[ik.qadr].copy() for ik in self._ik]
        for i in range(len(self.arms)):
            u[self._act[i]] = self._servo_setpoint(qpos, i)
        self._u0, self._goal = u, u.copy()

    @property
    def stats(self) -> dict[str, float]:
        """``phase`` (index reached) and ``ik_error_max`` (largest IK position error, m)."""
        worst = max((e for _, e in self.ik_errors), default=0.0)
        return {"phase": float(self.phase), "ik_error_max": float(worst)}
