r"""Measures of an arm following a point-to-point reference: tracking error, overshoot, settling.

With the end-effector position :math:`p(t)`, its reference :math:`\bar p(t)` (the planned
move's forward kinematics, interpolated in time and held at the end), the start
:math:`p_0` and the target :math:`p^\star`, move length :math:`L = \lVert p^\star - p_0
\rVert` and direction :math:`d = (p^\star - p_0) / L`:

* :class:`TrackingError` samples :math:`\lVert p(t) - \bar p(t) \rVert`; its RMS over the run
  is the tracking RMSE (m);
* :class:`Overshoot` samples :math:`100\,(p(t) - p^\star) \cdot d / L`, the percentage of
  the move by which the hand is past the target along the move (negative before it); the
  overshoot is its largest value, 0 when the hand never passed the target;
* :class:`TargetError` samples :math:`\lVert p(t) - p^\star \rVert`; its settle time (from the
  start) is when it enters the tolerance for good, and :meth:`TargetError.summarize` adds
  the settling time after the reference's end, :math:`\max(0, t_{settle} - T)`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from mpcbox.core.model import frame_position
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.measures import Measure
from mpcbox.validation import as_array, non_negative, positive


def current_position(
    measure: Measure, model: mujoco.MjModel, data: mujoco.MjData, frame: str
) -> np.ndarray:
    """The frame's world position ``(3,)`` at ``data.qpos``.

    After ``mj_step`` the positions in ``data`` are those of the state before the step (the
    step computes kinematics first, then integrates), one step behind ``qpos``; this runs
    ``mj_kinematics`` on the measure's own scratch data so that the sample matches the
    recorded state and time.
    """
    scratch = measure.__dict__.get("_scratch")
    if scratch is None or scratch[0] is not model:
        scratch = (model, mujoco.MjData(model))
        object.__setattr__(measure, "_scratch", scratch)
    work = scratch[1]
    work.qpos[:] = data.qpos
    work.mocap_pos[:], work.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    mujoco.mj_kinematics(model, work)
    return frame_position(model, work, frame)


def _vector(name: str, value: object) -> tuple[float, float, float]:
    arr = as_array(name, np.asarray(value, dtype=np.float64), (3,))
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True, kw_only=True, eq=False)
class TrackingError(Measure):
    r"""Distance (m) from the end effector to its reference position at the same time.

    Attributes:
        frame: Site or body name of the end effector.
        time: Reference times ``(K,)`` (s), increasing.
        positions: Reference positions ``(K, 3)`` (m); held after the last time.
    """

    name: str = "tracking_error"
    unit: str = "m"
    label: str = "tracking error"
    summaries: tuple[str, ...] = ("rms", "max")
    display_unit: str = "mm"
    display_scale: float = 1000.0
    frame: str = ""
    time: np.ndarray = field(default_factory=lambda: np.zeros(1))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))

    def __post_init__(self) -> None:
        super().__post_init__()
        time = as_array("time", self.time, (None,))
        positions = as_array("positions", self.positions, (time.size, 3))
        if time.size == 0 or np.any(np.diff(time) <= 0):
            raise InvalidArgumentError("time must hold increasing reference times")
        object.__setattr__(self, "time", time.copy())
        object.__setattr__(self, "positions", positions.copy())

    def reference(self, t: float) -> np.ndarray:
        """The reference position ``(3,)`` at time ``t`` (s), linearly interpolated."""
        return np.array([np.interp(t, self.time, self.positions[:, i]) for i in range(3)])

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        error = current_position(self, model, data, self.frame) - self.reference(float(data.time))
        return float(np.linalg.norm(error))


@dataclass(frozen=True, kw_only=True, eq=False)
class Overshoot(Measure):
    """How far (% of the move) the end effector is past the target along the move direction.

    Attributes:
        frame: Site or body name of the end effector.
        start: Start position ``(3,)`` of the move (m).
        target: Target position ``(3,)`` (m), distinct from ``start``.
    """

    name: str = "overshoot"
    unit: str = "pct"
    label: str = "overshoot"
    summaries: tuple[str, ...] = ("max",)
    display_unit: str = "%"
    frame: str = ""
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    target: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "start", _vector("start", self.start))
        object.__setattr__(self, "target", _vector("target", self.target))
        if self.length <= 0:
            raise InvalidArgumentError("target must differ from start (a move of length 0)")

    @property
    def length(self) -> float:
        """Move length :math:`L` (m)."""
        return float(np.linalg.norm(np.subtract(self.target, self.start)))

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        direction = np.subtract(self.target, self.start) / self.length
        past = (
            current_position(self, model, data, self.frame) - np.asarray(self.target)
        ) @ direction
        return float(100.0 * past / self.length)

    def summarize(self, samples: np.ndarray, time: np.ndarray) -> dict[str, float]:
        """The largest sample, 0 when the end effector never passed the target."""
        return {self.key("max"): max(0.0, float(np.max(samples)))}


@dataclass(frozen=True, kw_only=True, eq=False)
class TargetError(Measure):
    """Distance (m) from the end effector to the move's target.

    Attributes:
        frame: Site or body name of the end effector.
        target: Target position ``(3,)`` (m).
        end_time: When the reference reaches the target (s); :meth:`summarize` measures the
            settling time from it.
    """

    name: str = "target_error"
    unit: str = "m"
    label: str = "target error"
    summaries: tuple[str, ...] = ("final", "settle_time")
    display_unit: str = "mm"
    display_scale: float = 1000.0
    tolerance: float | None = 0.005
    frame: str = ""
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    end_time: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "target", _vector("target", self.target))
        object.__setattr__(self, "tolerance", positive("tolerance", self.tolerance))
        object.__setattr__(self, "end_time", non_negative("end_time", self.end_time))

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        return float(np.linalg.norm(current_position(self, model, data, self.frame) - self.target))

    def summarize(self, samples: np.ndarray, time: np.ndarray) -> dict[str, float]:
        """The declared summaries, plus ``target_error_settling_s``: the settle time less
        ``end_time``, at least 0 (NaN when the run ends outside the tolerance)."""
        out = super().summarize(samples, time)
        settle = out[self.key("settle_time")]
        out[f"{self.name}_settling_s"] = (
            max(0.0, settle - self.end_time) if np.isfinite(settle) else float("nan")
        )
        return out


__all__ = ["Overshoot", "TargetError", "TrackingError"]
