r"""Measures of a reach: the end effector's distance to the target, and when it arrived.

:class:`ReachError` samples :math:`e_k = \lVert p_k - p^\star \rVert` after every step. Its
summaries over a run are the final and largest error and the settle time (after which the
error stays within ``tolerance``); :meth:`ReachError.summarize` adds the arrival time (first
within ``tolerance``) and the overshoot, the largest error from then on (:func:`arrival`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import frame_position
from mpcbox.sim.measures import Measure
from mpcbox.validation import as_array, positive


class Arrival(NamedTuple):
    """When an error series first came within a tolerance, and how far it strayed after.

    Attributes:
        time: First time (s) with ``error <= tolerance``; NaN when never.
        overshoot: Largest error (m) from that time on (NaN when never); above the
            tolerance when the frame left the tolerance ball again.
    """

    time: float
    overshoot: float


def arrival(errors: np.ndarray, time: np.ndarray, tolerance: float) -> Arrival:
    """Time to within ``tolerance`` and the overshoot after it.

    Args:
        errors: Errors ``(T,)`` (m).
        time: Their times ``(T,)`` (s).
        tolerance: Arrival distance (m).
    """
    errors = np.asarray(errors, dtype=np.float64)
    inside = np.flatnonzero(errors <= tolerance)
    if inside.size == 0:
        return Arrival(float("nan"), float("nan"))
    first = int(inside[0])
    return Arrival(float(np.asarray(time)[first]), float(np.max(errors[first:])))


@dataclass(frozen=True, kw_only=True)
class ReachError(Measure):
    r"""Distance (m) from an end-effector frame to its target, :math:`\lVert p - p^\star \rVert`.

    Shown in centimeters; ``tolerance`` (m, default 1 cm) is the arrival distance of the
    settle-time summary and of :meth:`summarize`'s arrival time and overshoot.

    Attributes:
        frame: Site or body name of the end effector.
        target: Target position ``(3,)`` in the world frame (m).
    """

    name: str = "reach_error"
    unit: str = "m"
    label: str = "EE error"
    summaries: tuple[str, ...] = ("final", "max", "settle_time")
    display_unit: str = "cm"
    display_scale: float = 100.0
    tolerance: float | None = 0.01
    frame: str = ""
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        target = as_array("target", np.asarray(self.target, dtype=np.float64), (3,))
        object.__setattr__(self, "target", tuple(float(v) for v in target))
        object.__setattr__(self, "tolerance", positive("tolerance", self.tolerance))

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        return float(np.linalg.norm(frame_position(model, data, self.frame) - self.target))

    def summarize(self, samples: np.ndarray, time: np.ndarray) -> dict[str, float]:
        """The declared summaries, plus ``reach_error_arrival_s`` and
        ``reach_error_overshoot_m`` (:func:`arrival`) of the errors ``(T,)`` at ``time``
        ``(T,)`` (s)."""
        out = super().summarize(samples, time)
        hit = arrival(samples, time, float(self.tolerance))
        out[f"{self.name}_arrival_s"] = hit.time
        out[f"{self.name}_overshoot_m"] = hit.overshoot
        return out


__all__ = ["Arrival", "ReachError", "arrival"]
