r"""Objects to grasp, their contact parameters, and random draws of them.

An object is one rigid body of one of three kinds:

* ``"hard"``: a box or an upright cylinder with a stiff contact (1e5-1e6 N/m);
* ``"soft"``: a box or a sphere with a compliant contact (1e3-1e4 N/m);
* ``"irregular"``: an ellipsoid, or a cluster of three capsules whose centre of mass lies
  off the fingers' line, with a contact of 1e4-1e5 N/m.

Its contact with the finger pads has MuJoCo's five friction coefficients (sliding, sliding,
torsional, rolling, rolling; condim 6) and a contact stiffness :math:`K` (N/m): the contact
spring that an object of mass :math:`m` pressed on a rigid surface would feel (penetration
:math:`m g / K` under its weight; see :func:`~mpcbox.tasks.grasp.scene.contact_solref`).

Friction levels (sliding coefficient :math:`\mu`, drawn uniformly in the level's range):
``"low"`` 0.3-0.6, ``"medium"`` 1.0-1.25, ``"high"`` 1.25-1.5; torsional 0.1-0.3 and rolling
0.05-0.15 at every level (MuJoCo's coefficients: lengths, in m).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import one_of, positive

#: The kinds of object.
KINDS: tuple[str, ...] = ("hard", "soft", "irregular")
#: Shapes of each kind.
SHAPES: dict[str, tuple[str, ...]] = {
    "hard": ("box", "cylinder"),
    "soft": ("box", "sphere"),
    "irregular": ("ellipsoid", "capsules"),
}
#: Sliding friction range of each friction level.
FRICTION_LEVELS: dict[str, tuple[float, float]] = {
    "low": (0.3, 0.6),
    "medium": (1.0, 1.25),
    "high": (1.25, 1.5),
}
#: Torsional and rolling friction ranges (m), at every level.
TORSIONAL_RANGE = (0.1, 0.3)
ROLLING_RANGE = (0.05, 0.15)
#: Contact stiffness range (N/m) of each kind; drawn log-uniformly.
STIFFNESS_RANGES: dict[str, tuple[float, float]] = {
    "hard": (1e5, 1e6),
    "soft": (1e3, 1e4),
    "irregular": (1e4, 1e5),
}
#: Object mass range (kg); drawn uniformly.
MASS_RANGE = (0.1, 1.0)


class GraspObject(NamedTuple):
    """One object to grasp.

    Attributes:
        kind: ``"hard"``, ``"soft"`` or ``"irregular"``.
        shape: ``"box"``, ``"cylinder"``, ``"sphere"``, ``"ellipsoid"`` or ``"capsules"``.
        size: Half extents ``(3,)`` (m): along the fingers' closing axis ``x``, along ``y``,
            and the half height along ``z``.
        mass: Mass (kg).
        friction: Sliding, torsional and rolling coefficients ``(3,)`` (torsional and
            rolling in m).
        stiffness: Contact stiffness :math:`K` (N/m).
        damping_ratio: Damping ratio of the contact spring (1 is critical).
    """

    kind: str
    shape: str
    size: np.ndarray
    mass: float
    friction: np.ndarray
    stiffness: float
    damping_ratio: float = 1.0


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(*bounds))


def sample_object(
    rng: np.random.Generator,
    level: str,
    kind: str | None = None,
    *,
    mass_range: tuple[float, float] = MASS_RANGE,
) -> GraspObject:
    """Draw an object of friction level ``level``.

    Args:
        rng: Random generator.
        level: ``"low"``, ``"medium"`` or ``"high"`` (:data:`FRICTION_LEVELS`).
        kind: ``"hard"``, ``"soft"`` or ``"irregular"``, or ``None`` to draw one uniformly.
        mass_range: Bounds of the uniform mass draw (kg).

    Returns:
        A :class:`GraspObject` with shape, size (half widths 2-3 cm along the closing axis,
        half heights 3-4 cm), mass, friction and stiffness (log-uniform in the kind's range)
        drawn. Ellipsoids are flat (half height 1.5-2 cm), so that they rest on the
        table on their own; spheres have one radius of 2.5-3.5 cm.

    Raises:
        InvalidArgumentError: If ``level`` or ``kind`` is unknown or ``mass_range`` is not
            positive and increasing.
    """
    one_of("level", level, tuple(FRICTION_LEVELS))
    if kind is None:
        kind = KINDS[int(rng.integers(len(KINDS)))]
    one_of("kind", kind, KINDS)
    low, high = (positive("mass_range", m) for m in mass_range)
    if high < low:
        raise InvalidArgumentError(f"mass_range must be increasing, got {mass_range!r}")
    shapes = SHAPES[kind]
    shape = shapes[int(rng.integers(len(shapes)))]
    half_x = _uniform(rng, (0.02, 0.03))
    half_y = _uniform(rng, (0.02, 0.03))
    half_z = _uniform(rng, (0.03, 0.04))
    if shape in ("cylinder", "sphere"):
        half_y = half_x
    if shape == "sphere":
        half_x = half_y = half_z = _uniform(rng, (0.025, 0.035))
    if shape == "ellipsoid":  # its shortest axis upright, so that it rests on the table
        half_z = _uniform(rng, (0.015, 0.02))
    friction = np.array(
        [
            _uniform(rng, FRICTION_LEVELS[level]),
            _uniform(rng, TORSIONAL_RANGE),
            _uniform(rng, ROLLING_RANGE),
        ]
    )
    k_low, k_high = STIFFNESS_RANGES[kind]
    stiffness = float(np.exp(rng.uniform(np.log(k_low), np.log(k_high))))
    return GraspObject(
        kind,
        shape,
        np.array([half_x, half_y, half_z]),
        _uniform(rng, (low, high)),
        friction,
        stiffness,
    )
