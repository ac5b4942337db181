r"""Robot-independent units for controls: torque through each actuator, or a fraction of its range.

A control's own unit depends on the actuator: a motor's control is a torque divided by its
gear, a position servo's is a joint angle set-point. Noise levels and control-cost weights
written in control units therefore mean different things on different robots (0.08 of a
servo set-point through ``kp = 500`` is 40 N m). This module reads, from MuJoCo's actuator
model at a posture (:func:`~mpcbox.core.actuation.actuation_map`), two scales per actuator:

* :math:`k_i`, the generalized force per unit of control :math:`i` (for a joint actuator,
  gear times gain: a motor's gear, a position servo's ``kp``), so a torque :math:`\tau`
  corresponds to the control :math:`\tau / k_i`;
* :math:`h_i`, half the width of the interval the control may span, after its control range,
  force range and joint actuator-force range are all applied (a motor with
  ``ctrlrange="-1 1"``: 1; a servo with ``forcerange="-23.7 23.7"`` and ``kp = 100``: 0.237 rad
  about the posture, unless the control range is tighter).

A standard deviation or a weight is then given as a torque (``units="torque"``) or as a
fraction of :math:`h_i` (``units="range"``), and converted to control units.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.actuation import actuation_map, actuator_name
from mpcbox.core.model import check_mjmodel
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, finite_array, one_of

#: Units a control weight or standard deviation may be given in.
UNITS: tuple[str, ...] = ("control", "torque", "range")


class ActuatorScales(NamedTuple):
    """Per-actuator scales at one posture (see the module docstring).

    Attributes:
        torque_per_ctrl: :math:`k_i` ``(nu,)``: the largest generalized force (N m for a
            hinge, N for a slide or tendon) that one unit of control :math:`i` makes on any
            dof, at zero velocity.
        half_range: :math:`h_i` ``(nu,)``: half the width of the control interval allowed by
            all of the actuator's limits, in control units (``inf`` when unlimited).
        names: Actuator names ``(nu,)``.
    """

    torque_per_ctrl: np.ndarray
    half_range: np.ndarray
    names: tuple[str, ...]


def actuator_scales(model: mujoco.MjModel, qpos: np.ndarray) -> ActuatorScales:
    """The :class:`ActuatorScales` of ``model``'s actuators at posture ``qpos`` ``(nq,)``.

    Raises:
        UnsupportedModelError: If :func:`~mpcbox.core.actuation.actuation_map` cannot model an
            actuator (delays, or forces that are not affine in the control).
    """
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,))
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    amap = actuation_map(model, data)
    torque = np.max(np.abs(amap.matrix), axis=0) if model.nv else np.zeros(model.nu)
    half = 0.5 * (amap.upper - amap.lower)
    names = tuple(actuator_name(model, i) for i in range(model.nu))
    return ActuatorScales(torque, half, names)


def _per_actuator(name: str, value: float | np.ndarray, nu: int) -> np.ndarray:
    values = as_array(name, value, (None,) * np.ndim(value))
    values = np.full(nu, float(values)) if values.ndim == 0 else as_array(name, values, (nu,))
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise InvalidArgumentError(f"{name} must be finite and non-negative, got {values}")
    return values


def _check_finite(scales: ActuatorScales, scale: np.ndarray, what: str, hint: str) -> None:
    bad = [scales.names[i] for i in np.flatnonzero(~np.isfinite(scale) | (scale <= 0))]
    if bad:
        raise InvalidArgumentError(f"{what} is undefined for actuators {bad}: {hint}")


def to_control(
    scales: ActuatorScales,
    value: float | np.ndarray,
    units: str,
    *,
    power: int = 1,
    name: str = "value",
) -> np.ndarray:
    r"""Convert per-actuator amounts to control units.

    With ``power=1`` (a standard deviation or an amplitude) ``value`` is divided by the
    control's scale :math:`s_i` (:math:`1`, :math:`1/k_i` or :math:`1/h_i` for ``"control"``,
    ``"torque"`` and ``"range"``): a torque :math:`\tau` becomes :math:`\tau / k_i`, a
    fraction :math:`f` of the range becomes :math:`f h_i`. With ``power=-2`` (a weight on a
    squared deviation) it is multiplied by :math:`k_i^2` or divided by :math:`h_i^2`, so
    that :math:`w_\text{ctrl} \, \delta u^2 = w \, (k_i \delta u)^2` or
    :math:`w \, (\delta u / h_i)^2`.

    Args:
        scales: The actuators' scales.
        value: One non-negative amount for all actuators, or one per actuator ``(nu,)``.
        units: ``"control"`` (returned as is), ``"torque"`` or ``"range"``.
        power: ``1`` for amounts, ``-2`` for weights on squared deviations.
        name: The argument that gave ``value``, for error messages.

    Returns:
        The amounts in control units ``(nu,)``.

    Raises:
        InvalidArgumentError: If ``units`` is unknown, ``value`` negative or not finite, or
            the unit is undefined for an actuator (no force at this posture for
            ``"torque"``, an unlimited range for ``"range"``); the message names them.
    """
    one_of("units", units, UNITS)
    if power not in (1, -2):
        raise InvalidArgumentError(f"power must be 1 or -2, got {power!r}")
    nu = len(scales.names)
    values = _per_actuator(name, value, nu)
    if units == "control":
        return values
    if units == "torque":
        k = scales.torque_per_ctrl
        _check_finite(scales, k, f"{name}: a torque unit", "they exert no force at this posture")
        return values / k if power == 1 else values * k**2
    h = scales.half_range
    _check_finite(
        scales,
        h,
        f"{name}: a fraction of the range",
        "they have no control or force range; use torque",
    )
    return values * h if power == 1 else values / h**2
