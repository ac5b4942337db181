r"""A reference to track: states, the controls that realize them, and time-varying LQR gains.

Given reference states :math:`\bar x_k` every planning step (from a quintic
:class:`~mpcbox.controllers.trajectory.quintic.JointTrajectory` or a planned rollout),
:func:`tracking_reference` finds

* the feedforward controls :math:`\bar u_k` that make one step of the planning model (its
  actuator force limits lifted) land on the next reference state (one Gauss-Newton step per
  knot,
  :math:`\bar u_k = u + B_k^{+}\,(\bar x_{k+1} \ominus f(\bar x_k, u))` from the previous
  knot's control :math:`u`, clipped to the control range): inverse dynamics through
  whatever actuators the model has (motors, position servos, tendons);
* the gains of time-varying LQR along the reference, by the backward Riccati recursion

  .. math::
      K_k = (R + B_k^T P_{k+1} B_k)^{-1} B_k^T P_{k+1} A_k, \qquad
      P_k = Q + A_k^T P_{k+1} (A_k - B_k K_k), \qquad P_K = Q
      \text{ (or a given terminal weight)},

  with :math:`Q = \mathrm{diag}(w_q I, w_v I, 0)` on the tangent deviation and
  :math:`R = w_u\,\mathrm{diag}(k_i^2)` (:math:`k_i`: torque per unit of control ``i``, so
  :math:`w_u` weighs torque).

A tracker then applies :math:`u = \bar u_k - K_k (x \ominus \bar x_k)`.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mpcbox.controllers.trajectory.quintic import JointTrajectory
from mpcbox.core.actuator_scales import actuator_scales
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, checked_options, finite_array, non_negative, positive


@checked_options
@dataclass(frozen=True, kw_only=True)
class TrackingWeights:
    r"""Weights of time-varying LQR along a reference.

    Attributes:
        position_weight: :math:`w_q` on joint position errors (per rad or m).
        velocity_weight: :math:`w_v` on joint velocity errors.
        torque_weight: :math:`w_u` on the control deviation expressed as torque (N m).
    """

    position_weight: float = 1e4
    velocity_weight: float = 10.0
    torque_weight: float = 1e-3

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "position_weight", non_negative("position_weight", self.position_weight)
        )
        object.__setattr__(
            self, "velocity_weight", non_negative("velocity_weight", self.velocity_weight)
        )
        object.__setattr__(self, "torque_weight", positive("torque_weight", self.torque_weight))


class TrackingReference(NamedTuple):
    """States to follow, their feedforward controls and the LQR gains (``K`` knots).

    Attributes:
        time: Knot times ``(K,)`` (s), one planning step apart, from 0.
        states: Reference states ``(K, nstate)``.
        ctrls: Feedforward controls ``(K, nu)`` (the last repeats the one before).
        gains: Feedback gains ``(K, nu, nx)``: :math:`u = \\bar u_k - K_k (x \\ominus \\bar x_k)`.
        residual: Largest one-step miss :math:`\\lVert \\bar x_{k+1} \\ominus f(\\bar x_k,
            \\bar u_k) \\rVert_\\infty` of the feedforward controls (0 when the actuators
            can realize the reference exactly).
    """

    time: np.ndarray
    states: np.ndarray
    ctrls: np.ndarray
    gains: np.ndarray
    residual: float


def reference_states(problem: Problem, trajectory: JointTrajectory) -> np.ndarray:
    """States ``(T, nstate)`` ``[qpos, qvel, 0]`` of a joint trajectory over all of ``qpos``.

    Raises:
        InvalidArgumentError: If the model has free or ball joints (``nq != nv``) or the
            trajectory does not cover ``nq`` joints.
    """
    if problem.nq != problem.nv:
        raise InvalidArgumentError(
            f"trajectory: joint-space references need hinge and slide joints only (nq == nv), "
            f"got nq={problem.nq}, nv={problem.nv}; weld free objects first"
        )
    qpos = as_array("trajectory.qpos", trajectory.qpos, (None, problem.nq))
    qvel = as_array("trajectory.qvel", trajectory.qvel, qpos.shape)
    return np.hstack([qpos, qvel, np.zeros((qpos.shape[0], problem.na))])


def unlimited(problem: Problem) -> Problem:
    """A shallow copy of ``problem`` whose planning model has no actuator force limits.

    The feedforward search runs on it: where a reference needs more force than an actuator
    can give, the control asks for it (the plant then saturates) instead of stalling where
    the clamped force no longer responds to the control (a zero column of ``B``).
    """
    clone = copy.copy(problem)
    model = copy.copy(problem.planning_model)
    model.actuator_forcelimited[:] = 0
    model.jnt_actfrclimited[:] = 0
    clone.planning_model = model
    clone.dynamics = clone.make_dynamics(model)
    return clone


def feedforward(
    problem: Problem, states: np.ndarray, ctrl_init: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """Feedforward controls along reference states.

    The search runs on the planning model without actuator force limits (:func:`unlimited`),
    within the control range.

    Args:
        problem: The Problem (its planning model and timestep).
        states: Reference states ``(K, nstate)``, one planning step apart, ``K >= 2``.
        ctrl_init: Control to start the search from ``(nu,)`` (default: the one that holds
            the first posture, :func:`~mpcbox.find_equilibrium`).

    Returns:
        Controls ``(K, nu)`` and their largest one-step miss on the planning model itself,
        force limits included (see :class:`TrackingReference`).
    """
    states = finite_array("states", states, (None, problem.nstate))
    if states.shape[0] < 2:
        raise InvalidArgumentError("states must hold at least two knots")
    if ctrl_init is None:
        model, qpos = problem.planning_model, states[0, : problem.nq]
        ctrl_init = find_equilibrium(model, qpos, on_infeasible="ignore").ctrl
    u = problem.clip_ctrl(as_array("ctrl_init", ctrl_init, (problem.nu,)))
    free = unlimited(problem)
    ctrls = np.empty((states.shape[0], problem.nu))
    try:
        for k in range(states.shape[0] - 1):
            B = free.linearize(states[k], u).B
            error = free.state_difference(states[k + 1], free.step(states[k], u))
            u = free.clip_ctrl(u + np.linalg.lstsq(B, error, rcond=None)[0])
            ctrls[k] = u
    finally:
        free.dynamics.close()
    ctrls[-1] = ctrls[-2]
    return ctrls, _largest_miss(problem, states, ctrls)


def _largest_miss(problem: Problem, states: np.ndarray, ctrls: np.ndarray) -> float:
    """Largest one-step miss ``max |x_{k+1} ⊖ f(x_k, u_k)|`` of controls along states."""
    miss = 0.0
    for k in range(states.shape[0] - 1):
        left = problem.state_difference(states[k + 1], problem.step(states[k], ctrls[k]))
        miss = max(miss, float(np.max(np.abs(left))))
    return miss


def riccati_gains(
    A: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    terminal: np.ndarray | None = None,
) -> np.ndarray:
    """Time-varying LQR gains ``(K, nu, nx)`` by the backward recursion (module docstring).

    Args:
        A: State Jacobians ``(K, nx, nx)``.
        B: Control Jacobians ``(K, nx, nu)``.
        Q: State weight ``(nx, nx)``.
        R: Control weight ``(nu, nu)``, positive definite.
        terminal: Terminal weight :math:`P_K` ``(nx, nx)`` (default ``Q``). The
            infinite-horizon LQR value matrix of the final knot makes the last gain that
            LQR's gain when the reference ends at rest there, so a tracker holding the final
            knot hands over to LQR without a jump.
    """
    P = Q.copy() if terminal is None else finite_array("terminal", terminal, Q.shape).copy()
    gains = np.empty((A.shape[0], B.shape[2], A.shape[1]))
    for k in range(A.shape[0] - 1, -1, -1):
        BtP = B[k].T @ P
        gains[k] = np.linalg.solve(R + BtP @ B[k], BtP @ A[k])
        P = Q + A[k].T @ P @ (A[k] - B[k] @ gains[k])
        P = 0.5 * (P + P.T)
    return gains


def weight_matrices(
    problem: Problem, weights: TrackingWeights, state: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    r"""The LQR weights of the module docstring: :math:`Q = \mathrm{diag}(w_q I, w_v I, 0)`
    ``(nx, nx)`` and :math:`R = w_u\,\mathrm{diag}(k_i^2)` ``(nu, nu)``, with the torque per
    unit of control :math:`k_i` at ``state``'s posture ``(nstate,)``."""
    nv, na = problem.nv, problem.na
    Q = np.diag(
        np.r_[
            np.full(nv, weights.position_weight),
            np.full(nv, weights.velocity_weight),
            np.zeros(na),
        ]
    )
    torque = actuator_scales(problem.planning_model, state[: problem.nq]).torque_per_ctrl
    return Q, weights.torque_weight * np.diag(np.maximum(torque, 1e-9) ** 2)


def tracking_reference(
    problem: Problem,
    states: np.ndarray | JointTrajectory,
    weights: TrackingWeights | None = None,
    *,
    ctrls: np.ndarray | None = None,
    ctrl_init: np.ndarray | None = None,
    terminal: np.ndarray | None = None,
) -> TrackingReference:
    """Feedforward controls and time-varying LQR gains along reference states.

    Args:
        problem: The Problem; the knots are ``problem.dt`` apart.
        states: Reference states ``(K, nstate)``, or a
            :class:`~mpcbox.controllers.trajectory.quintic.JointTrajectory` over all of
            ``qpos`` sampled every ``problem.dt``.
        weights: The LQR weights (default :class:`TrackingWeights`).
        ctrls: Feedforward controls ``(K, nu)`` known to realize the states (a plan's own,
            e.g. iLQR's); by default they are searched for (:func:`feedforward`).
        ctrl_init: Start of the feedforward search (see :func:`feedforward`).
        terminal: Terminal weight :math:`P_K` ``(nx, nx)`` of the gains' recursion (default
            :math:`Q`; see :func:`riccati_gains`).

    Returns:
        A :class:`TrackingReference`.
    """
    if isinstance(states, JointTrajectory):
        step = np.diff(states.time)
        if step.size and np.max(np.abs(step - problem.dt)) > 1e-9:
            raise InvalidArgumentError(
                f"states: the trajectory must be sampled every problem.dt = {problem.dt} s"
            )
        states = reference_states(problem, states)
    states = finite_array("states", states, (None, problem.nstate))
    weights = TrackingWeights() if weights is None else weights
    if ctrls is None:
        ctrls, miss = feedforward(problem, states, ctrl_init)
    else:
        ctrls = problem.clip_ctrl(finite_array("ctrls", ctrls, (states.shape[0], problem.nu)))
        miss = _largest_miss(problem, states, ctrls)
    lin = problem.linearize_trajectory(states, ctrls)
    Q, R = weight_matrices(problem, weights, states[0])
    gains = riccati_gains(lin.A, lin.B, Q, R, terminal=terminal)
    time = problem.dt * np.arange(states.shape[0])
    return TrackingReference(time, states.copy(), ctrls, gains, miss)


__all__ = [
    "TrackingReference",
    "TrackingWeights",
    "feedforward",
    "reference_states",
    "riccati_gains",
    "tracking_reference",
    "unlimited",
    "weight_matrices",
]
