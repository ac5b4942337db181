r"""Point-to-point joint trajectories by quintic interpolation: O(n) samples, closed form.

Between a start :math:`q_0` and a goal :math:`q_1` in :math:`T` seconds every joint follows

.. math::
    q(t) = q_0 + (q_1 - q_0)\, s(\tau), \qquad
    s(\tau) = 10 \tau^3 - 15 \tau^4 + 6 \tau^5, \qquad \tau = t / T \in [0, 1],

the unique fifth-order polynomial with zero velocity and acceleration at both ends. Its
velocity peaks at mid-move, :math:`\dot q(T/2) = \tfrac{15}{8} (q_1 - q_0) / T`, and its
acceleration at :math:`\tau = \tfrac12 \mp \tfrac{\sqrt 3}{6}`, where
:math:`|\ddot q| = \tfrac{10 \sqrt 3}{3} |q_1 - q_0| / T^2`. After :math:`T` the trajectory
holds the goal.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, finite_array, non_negative, positive

#: Peak speed of the quintic over the mean speed :math:`|q_1 - q_0| / T`.
PEAK_VELOCITY_RATIO = 15.0 / 8.0
#: Peak acceleration of the quintic, in units of :math:`|q_1 - q_0| / T^2`.
PEAK_ACCELERATION_RATIO = 10.0 * np.sqrt(3.0) / 3.0


class JointTrajectory(NamedTuple):
    """Joint positions, velocities and accelerations sampled at ``T`` times.

    Attributes:
        time: Sample times ``(T,)`` (s), from 0.
        qpos: Positions ``(T, n)``.
        qvel: Velocities ``(T, n)``.
        qacc: Accelerations ``(T, n)``.
    """

    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc: np.ndarray


def quintic_profile(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""The normalized quintic :math:`s(\tau)` and its first two derivatives in :math:`\tau`.

    Args:
        tau: Normalized times ``(T,)``; values outside ``[0, 1]`` are clamped (rest before
            and after the move).

    Returns:
        :math:`s`, :math:`s'` and :math:`s''`, each ``(T,)``.
    """
    t = np.clip(np.asarray(tau, dtype=np.float64), 0.0, 1.0)
    s = t**3 * (10.0 - 15.0 * t + 6.0 * t**2)
    ds = 30.0 * t**2 * (1.0 - t) ** 2
    dds = 60.0 * t * (1.0 - t) * (1.0 - 2.0 * t)
    return s, ds, dds


def quintic(
    start: np.ndarray,
    goal: np.ndarray,
    duration: float,
    dt: float,
    *,
    hold: float = 0.0,
) -> JointTrajectory:
    r"""Sample the quintic move from ``start`` to ``goal`` every ``dt`` seconds.

    The samples run from :math:`t = 0` to :math:`T + ` ``hold`` (the last sample within half a
    step of it); after :math:`T` they rest at the goal. The cost is O(n) per sample for
    ``n`` joints.

    Args:
        start: Start positions ``(n,)``.
        goal: Goal positions ``(n,)``.
        duration: Move time :math:`T` (s).
        dt: Sampling step (s), typically the model's timestep.
        hold: Time at rest on the goal after the move (s).

    Returns:
        A :class:`JointTrajectory` of ``round((T + hold) / dt) + 1`` samples.

    Raises:
        InvalidArgumentError: For a non-positive ``duration`` or ``dt``, a negative ``hold``,
            a ``dt`` longer than the move, or non-finite positions.
        ShapeError: If ``start`` and ``goal`` are not vectors of one length.
    """
    start = finite_array("start", start, (None,))
    goal = finite_array("goal", goal, (start.size,))
    duration = positive("duration", duration)
    dt = positive("dt", dt)
    hold = non_negative("hold", hold)
    if dt > duration:
        raise InvalidArgumentError(f"dt must not exceed duration, got dt={dt} > {duration}")
    steps = round((duration + hold) / dt)
    time = dt * np.arange(steps + 1)
    s, ds, dds = quintic_profile(time / duration)
    delta = goal - start
    qpos = start + s[:, None] * delta
    qvel = (ds / duration)[:, None] * delta
    qacc = (dds / duration**2)[:, None] * delta
    return JointTrajectory(time, qpos, qvel, qacc)


def joint_trajectory(time: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> JointTrajectory:
    """A :class:`JointTrajectory` from sampled positions and velocities (accelerations by
    finite differences of the velocities, the last repeated).

    Args:
        time: Uniform sample times ``(T,)`` (s), ``T >= 2``.
        qpos: Positions ``(T, n)``.
        qvel: Velocities ``(T, n)``.
    """
    time = finite_array("time", time, (None,))
    if time.size < 2 or not np.all(np.diff(time) > 0):
        raise InvalidArgumentError("time must hold at least two increasing samples")
    qpos = finite_array("qpos", qpos, (time.size, None))
    qvel = as_array("qvel", qvel, qpos.shape)
    qacc = np.diff(qvel, axis=0) / np.diff(time)[:, None]
    return JointTrajectory(time, qpos, qvel, np.vstack([qacc, qacc[-1:]]))


__all__ = [
    "PEAK_ACCELERATION_RATIO",
    "PEAK_VELOCITY_RATIO",
    "JointTrajectory",
    "joint_trajectory",
    "quintic",
    "quintic_profile",
]
