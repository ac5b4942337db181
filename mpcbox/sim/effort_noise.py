r"""A robot-independent actuator-noise recipe: torque, or a fraction of each actuator's range.

:class:`~mpcbox.ActuatorNoise` takes standard deviations in control units, which mean
different things on different robots. :func:`effort_noise` builds one from an amount that
means the same on any robot (:mod:`mpcbox.core.actuator_scales`): a torque through each
actuator's gain (a position servo's set-point noise is the torque divided by ``kp``), or a
fraction of the actuator's range (of its force range when it has one, so a servo with
``forcerange`` ±23.7 N m and a fraction of 2 % gets 0.47 N m of torque noise, as a motor
with that torque limit would). It reads no actuator or joint names.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.core.actuator_scales import actuator_scales, to_control
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.disturbances import ActuatorNoise


def effort_noise(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    fraction: float | np.ndarray | None = None,
    torque: float | np.ndarray | None = None,
    scale: float = 1.0,
    width: float = 0.8,
) -> ActuatorNoise:
    r"""Actuator noise of standard deviation ``torque``, or ``fraction`` of each range.

    The standard deviation of control :math:`i` is :math:`\tau_i / k_i` (``torque``) or
    :math:`f_i h_i` (``fraction``), with :math:`k_i` the generalized force per unit of
    control and :math:`h_i` half the control interval its limits allow, both at ``qpos``
    (see :func:`~mpcbox.core.actuator_scales.actuator_scales`).

    Args:
        model: The model.
        qpos: Posture ``(nq,)`` where the actuators' scales are read (a servo's force range
            maps to set-points about it).
        fraction: Fraction of each actuator's half range, one or ``(nu,)``.
        torque: Torque (N m; N for slides and tendons), one or ``(nu,)``.
        scale: Noise scale (:attr:`ActuatorNoise.scale`).
        width: Smoothing kernel span (s) (:attr:`ActuatorNoise.width`).

    Returns:
        The :class:`~mpcbox.ActuatorNoise` with ``std`` ``(nu,)`` in control units.

    Raises:
        InvalidArgumentError: Unless exactly one of ``fraction`` and ``torque`` is given, or
            if the unit is undefined for an actuator (see
            :func:`~mpcbox.core.actuator_scales.to_control`).
    """
    if (fraction is None) == (torque is None):
        raise InvalidArgumentError("effort_noise: give exactly one of fraction and torque")
    scales = actuator_scales(model, qpos)
    if torque is not None:
        std = to_control(scales, torque, "torque", name="torque")
    else:
        std = to_control(scales, fraction, "range", name="fraction")
    return ActuatorNoise(std=std, scale=scale, width=width)
