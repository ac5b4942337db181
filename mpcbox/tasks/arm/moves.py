r"""Plans of an :class:`~mpcbox.tasks.arm.track.ArmTrack` move, their figures, and trackers.

* :func:`quintic_move`: the quintic in joint space (closed form, O(n) per sample), with the
  feedforward controls that realize it
  (:func:`~mpcbox.controllers.trajectory.reference.feedforward`);
* :func:`ilqr_move`: control-limited iLQR on the task's cost over the move's :math:`N`
  knots, started from the quintic's feedforward controls; the actuators' force limits hold
  by construction, since the rollouts go through MuJoCo's actuator model.

:func:`move_report` scores a plan: the task's cost, the effort and the largest ratio to the
actuators' limits (:mod:`mpcbox.core.torque_limits`) of its joint torques (the quintic's from
inverse dynamics, ``mj_inverse``: what it needs; iLQR's as its actuators apply them), the
clearance of the checked frames from the obstacle
(m; negative inside it), the end effector's final distance to the target and the compute
time. :func:`move_tracker` builds a time-varying LQR tracker of a plan followed by a hold.
"""

from __future__ import annotations

import time as _time
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.controllers.trajectory.reference import (
    TrackingWeights,
    feedforward,
    reference_states,
    tracking_reference,
)
from mpcbox.controllers.trajectory.tracker import TrajectoryTracker
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.model import frame_position
from mpcbox.core.torque_limits import (
    actuator_torques,
    inverse_dynamics,
    torque_limits,
    torque_ratio,
)
from mpcbox.tasks.arm.track import ArmTrack
from mpcbox.validation import positive_int


class ArmMove(NamedTuple):
    """A planned move of ``K = N + 1`` knots, one planning step apart.

    Attributes:
        method: ``"quintic"``, ``"ilqr"`` or ``"step"``.
        time: Knot times ``(K,)`` (s).
        states: States ``(K, nstate)``.
        ctrls: Controls ``(K, nu)`` (the last repeats the one before).
        torques: Joint torques ``(K, nv)`` of the motion: for the quintic, those it needs
            (inverse dynamics of its exact accelerations, whether or not the actuators can
            supply them); for a plan rolled out through the actuators (iLQR), those they
            apply (``qfrc_actuator``).
        compute_s: Wall time of the plan (s): the polynomial's samples, or the iLQR solve.
        status: ``"closed form"``, or iLQR's stop status.
    """

    method: str
    time: np.ndarray
    states: np.ndarray
    ctrls: np.ndarray
    torques: np.ndarray
    compute_s: float
    status: str


class MoveReport(NamedTuple):
    r"""Figures of a plan (:func:`move_report`).

    Attributes:
        cost: The task's cost of the plan (running over ``N`` knots, terminal at the last).
        effort: :math:`\sum_k \lVert \tau_k \rVert^2 \Delta t` of the plan's torques
            (:attr:`ArmMove.torques`, N² m² s).
        torque_ratio: Largest :math:`|\tau| / \tau^{max}` over the joints and knots; above 1
            the actuators cannot supply the motion.
        clearance: Smallest distance of the checked frames from the obstacle's surface (m;
            ``inf`` without an obstacle, negative inside it).
        final_error: End-effector distance to the target at the last knot (m).
        compute_ms: Compute time of the plan (ms).
    """

    cost: float
    effort: float
    torque_ratio: float
    clearance: float
    final_error: float
    compute_ms: float


def quintic_move(problem: ArmTrack) -> ArmMove:
    """The quintic plan of the move and its feedforward controls."""
    t0 = _time.perf_counter()
    traj = problem.joint_reference(hold=0.0)
    compute = _time.perf_counter() - t0
    states = reference_states(problem, traj)
    ctrls = feedforward(problem, states)[0]
    torques = inverse_dynamics(problem.model, traj.qpos, traj.qvel, traj.qacc)
    return ArmMove("quintic", traj.time, states, ctrls, torques, compute, "closed form")


def step_move(problem: ArmTrack) -> ArmMove:
    """The goal posture at rest from time 0 under its holding control: tracked by
    :func:`move_tracker`, this is LQR about the goal (a step, no planned path)."""
    goal = np.r_[problem.goal_qpos, np.zeros(problem.nv + problem.na)]
    knots = problem.knots + 1
    states = np.tile(goal, (knots, 1))
    ctrls = np.tile(problem.clip_ctrl(problem.ctrl_ref), (knots, 1))
    torques = actuator_torques(problem.model, states, ctrls)
    return ArmMove("step", problem.dt * np.arange(knots), states, ctrls, torques, 0.0, "goal")


def ilqr_move(
    problem: ArmTrack,
    *,
    max_iterations: int = 50,
    linearize_every: int = 5,
    ctrls_init: np.ndarray | None = None,
) -> ArmMove:
    """The iLQR-optimal plan of the move.

    Args:
        problem: The task.
        max_iterations: iLQR iteration cap.
        linearize_every: Linearize the dynamics every this many knots (interpolated between).
        ctrls_init: Initial controls ``(N, nu)``; default: the quintic's feedforward.
    """
    if ctrls_init is None:
        ctrls_init = quintic_move(problem).ctrls[:-1]
    solver = ILQRSolver(
        problem,
        horizon=problem.knots,
        linearize_every=positive_int("linearize_every", linearize_every),
        ctrls_init=ctrls_init,
    )
    result = solver.solve(
        problem.initial_state(), max_iterations=positive_int("max_iterations", max_iterations)
    )
    states = result.states
    ctrls = np.vstack([result.ctrls, result.ctrls[-1:]])
    return ArmMove(
        "ilqr",
        problem.dt * np.arange(states.shape[0]),
        states,
        ctrls,
        actuator_torques(problem.model, states, ctrls),
        result.timing.total,
        result.status,
    )


def move_report(problem: ArmTrack, move: ArmMove) -> MoveReport:
    """Score a plan (see :class:`MoveReport`)."""
    states, ctrls, nq, torques = move.states, move.ctrls, problem.nq, move.torques
    running = sum(problem.running_cost(states[k], ctrls[k]) for k in range(len(states) - 1))
    cost = float(running + problem.terminal_cost(states[-1]))
    ratio = torque_ratio(torques, torque_limits(problem.model))
    clearance = float("inf")
    if problem.obstacle is not None:
        data = mujoco.MjData(problem.model)
        for state in states:
            data.qpos[:] = state[:nq]
            mujoco.mj_kinematics(problem.model, data)
            for frame in problem.clearance_frames:
                gap = np.linalg.norm(
                    frame_position(problem.model, data, frame) - problem.obstacle.center
                )
                clearance = min(clearance, float(gap) - problem.obstacle.radius)
    final = problem.reach_error(states[-1])
    effort = float(np.sum(torques[:-1] ** 2) * problem.dt)
    return MoveReport(cost, effort, ratio, clearance, final, 1e3 * move.compute_s)


def held(problem: ArmTrack, move: ArmMove) -> tuple[np.ndarray, np.ndarray]:
    """The plan's states and controls followed by ``problem.hold`` seconds under the control
    that holds its last posture (:func:`~mpcbox.find_equilibrium`), rolled out on the
    planning model: a plan that ends at rest stays there, and one that ends moving (a move
    too fast to stop in time) is continued as the actuators would brake it, so that the
    reference stays one the dynamics can follow.

    Returns:
        States ``(K + H, nstate)`` and controls ``(K + H, nu)``.
    """
    last = move.states[-1]
    hold = problem.clip_ctrl(
        find_equilibrium(problem.model, last[: problem.nq], on_infeasible="ignore").ctrl
    )
    steps = round(problem.hold / problem.dt)
    if steps == 0:
        return move.states.copy(), move.ctrls.copy()
    tail = problem.rollout(last, np.tile(hold, (steps, 1))).states[0, 1:]
    states = np.vstack([move.states, tail])
    ctrls = np.vstack([move.ctrls[:-1], np.tile(hold, (steps + 1, 1))])
    return states, ctrls


def move_tracker(
    problem: ArmTrack,
    move: ArmMove,
    weights: TrackingWeights | None = None,
    *,
    feedback: bool = True,
) -> TrajectoryTracker:
    """A time-varying LQR tracker of ``move`` with its hold (:func:`held`), using the plan's
    own controls as feedforward; the task's measures now compare with this reference
    (:meth:`ArmTrack.set_reference`)."""
    states, ctrls = held(problem, move)
    problem.set_reference(states)
    reference = tracking_reference(problem, states, weights, ctrls=ctrls)
    name = f"{move.method} + {'tv-lqr' if feedback else 'feedforward'}"
    return TrajectoryTracker(problem, reference, feedback=feedback, name=name)


__all__ = [
    "ArmMove",
    "MoveReport",
    "held",
    "ilqr_move",
    "move_report",
    "move_tracker",
    "quintic_move",
    "step_move",
]
