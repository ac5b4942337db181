"""Measures of legged robots: the center of mass over the support, the root's tilt, and its
distance from a target."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mpcbox.core.model import frame_position, object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.measures import Measure


def _check_body(measure: ComDeviation | Tilt | TargetDistance) -> None:
    if not isinstance(measure.body, str) or not measure.body:
        raise InvalidArgumentError(
            f"measure {measure.name!r}: body must name a body (the robot's root), "
            f"got {measure.body!r}"
        )


@dataclass(frozen=True, kw_only=True)
class ComDeviation(Measure):
    r"""Horizontal distance of a subtree's center of mass from the support point (m).

    .. math:: y = \lVert c_{xy} - \bar p_{xy} \rVert ,

    where :math:`c` is the center of mass of ``body``'s subtree (the whole robot for the
    root body) and :math:`\bar p` the mean position of the ``support`` frames (sites, or
    bodies when no site has the name). Shown in centimeters.

    Attributes:
        body: Body whose subtree's center of mass is measured.
        support: Names of the frames whose mean horizontal position is the support point.
    """

    name: str = "com_deviation"
    unit: str = "m"
    label: str = "COM dev"
    display_unit: str = "cm"
    display_scale: float = 100.0
    body: str = ""
    support: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_body(self)
        object.__setattr__(self, "support", tuple(self.support))
        if not self.support:
            raise InvalidArgumentError("support must name at least one site or body")

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        com = data.subtree_com[object_id(model, "body", self.body)][:2]
        points = [frame_position(model, data, name)[:2] for name in self.support]
        support = points[0] if len(points) == 1 else np.mean(points, axis=0)
        return float(np.linalg.norm(com - support))


@dataclass(frozen=True, kw_only=True)
class Tilt(Measure):
    """Angle between a body's z axis and the vertical (deg).

    Attributes:
        body: The body.
    """

    name: str = "tilt"
    unit: str = "deg"
    label: str = "tilt"
    body: str = ""

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_body(self)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        zaxis = data.xmat[object_id(model, "body", self.body)].reshape(3, 3)[:, 2]
        return float(np.degrees(np.arccos(np.clip(zaxis[2], -1.0, 1.0))))


@dataclass(frozen=True, kw_only=True)
class TargetDistance(Measure):
    r"""Horizontal distance of a body from a target point (m).

    .. math:: y = \lVert p_{xy} - g \rVert .

    Summarized by its final value and, with a ``tolerance`` (the target's radius), the time
    after which it stays within it.

    Attributes:
        body: The body (the robot's root).
        target: The target ``(x, y)`` in world coordinates (m).
    """

    name: str = "target_distance"
    unit: str = "m"
    label: str = "target dist"
    summaries: tuple[str, ...] = ("final", "settle_time")
    body: str = ""
    target: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_body(self)
        if len(self.target) != 2 or not np.all(np.isfinite(self.target)):
            raise InvalidArgumentError(f"target must be finite (x, y), got {self.target!r}")

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        position = data.xpos[object_id(model, "body", self.body)][:2]
        return float(np.linalg.norm(position - np.asarray(self.target)))


def balance_measures(
    support: tuple[str, ...], body: str, *, recovery_tilt: float | None = None
) -> tuple[Measure, ...]:
    """The legged tasks' measures: :class:`ComDeviation` over ``support`` and :class:`Tilt`.

    Args:
        support: Frames whose mean horizontal position is the support point.
        body: Root body (its subtree's center of mass and its tilt are measured).
        recovery_tilt: With a tilt (deg), the tilt also reports its ``"settle_time"``: the
            recovery time, after which the tilt stays within ``recovery_tilt`` (NaN when it
            never does).
    """
    if recovery_tilt is None:
        tilt = Tilt(body=body)
    else:
        tilt = Tilt(body=body, summaries=("rms", "settle_time"), tolerance=float(recovery_tilt))
    return (ComDeviation(body=body, support=support), tilt)
