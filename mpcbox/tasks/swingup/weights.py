"""Cost weights of the generic swing-up, in units that do not depend on the robot."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields

from mpcbox.errors import InvalidArgumentError


@dataclass(frozen=True, kw_only=True)
class SwingupWeights:
    r"""Weights of the swing-up cost :math:`\tfrac12 \sum_i w_i r_i^2` (see :class:`Swingup`).

    Each running weight has a terminal counterpart (``terminal_*``) on the last state. The
    residuals are angles (rad, as :math:`2 \sin(\Delta/2)`), site distances (m), the other
    joints' positions (m or rad), all velocities (m/s or rad/s), and each control as a
    fraction of its half range, :math:`(u - u_{ref}) / ((u_{max} - u_{min}) / 2)`, so that
    ``ctrl = 1`` weighs a control at its limit like a radian of angle error whatever the
    actuator's units (an actuator without a range is weighed in its own units).

    Attributes:
        angle: On each named joint's wrapped angle error.
        site: On each named site's height or position error.
        position: On the position of every joint that is not named (e.g. a cart).
        velocity: On every velocity.
        ctrl: On every control, as a fraction of its half range.
        energy: On the total mechanical energy's distance (J) from the goal posture's at
            rest (:class:`~mpcbox.core.cost.Energy`), running only; 0 (default) leaves the
            term out.
        terminal_angle: Terminal counterpart of ``angle``.
        terminal_site: Terminal counterpart of ``site``.
        terminal_position: Terminal counterpart of ``position``.
        terminal_velocity: Terminal counterpart of ``velocity``.

    Raises:
        InvalidArgumentError: Naming a weight that is negative or not finite.
    """

    angle: float = 10.0
    site: float = 10.0
    position: float = 1.0
    velocity: float = 0.5
    ctrl: float = 1.0
    energy: float = 0.0
    terminal_angle: float = 100.0
    terminal_site: float = 100.0
    terminal_position: float = 10.0
    terminal_velocity: float = 10.0

    def __post_init__(self) -> None:
        for spec in fields(self):
            value = getattr(self, spec.name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise InvalidArgumentError(
                    f"weights.{spec.name} must be a number >= 0, got {value!r}"
                )
            if not (math.isfinite(value) and value >= 0):
                raise InvalidArgumentError(
                    f"weights.{spec.name} must be finite and >= 0, got {value!r}"
                )
            object.__setattr__(self, spec.name, float(value))
