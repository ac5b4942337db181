r"""Task measures: quantities a task declares, sampled at every step of a closed-loop run.

A :class:`Measure` turns the simulation state after each step into one number
:math:`y_k = f(\text{model}, \text{data}_k)`; :func:`~mpcbox.simulate` records the samples
``(T,)`` in :attr:`~mpcbox.SimulationResult.series` and summarizes them over the run in
:attr:`~mpcbox.Metrics.measures`. A task lists its measures in
:meth:`~mpcbox.Problem.measures` (none by default): the humanoid tasks, for example, report
the center of mass over the support and the torso tilt
(:mod:`mpcbox.tasks.legged.measures`). Comparison tables show one column per measure and
summary.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from mpcbox.errors import InvalidArgumentError, UnknownNameError


def _rms(samples: np.ndarray, time: np.ndarray, tolerance: float | None) -> float:
    return float(np.sqrt(np.mean(samples**2)))


def _settle_time(samples: np.ndarray, time: np.ndarray, tolerance: float | None) -> float:
    """First time after which every sample is within ``tolerance`` (NaN when never)."""
    if tolerance is None:
        raise InvalidArgumentError("the 'settle_time' summary needs the measure's tolerance")
    outside = np.flatnonzero(~(np.abs(samples) <= tolerance))
    if outside.size == 0:
        return float(time[0])
    if outside[-1] == samples.size - 1:
        return float("nan")
    return float(time[outside[-1] + 1])


#: Summaries of a measure's samples ``(T,)`` over a run, by name. Each takes the samples, the
#: times ``(T,)`` (s) and the measure's tolerance.
SUMMARIES: dict[str, Callable[[np.ndarray, np.ndarray, float | None], float]] = {
    "rms": _rms,
    "mean": lambda samples, time, tol: float(np.mean(samples)),
    "max": lambda samples, time, tol: float(np.max(samples)),
    "final": lambda samples, time, tol: float(samples[-1]),
    "settle_time": _settle_time,
}

#: How a summary is written in table headers.
_TITLES = {
    "rms": "RMS",
    "mean": "mean",
    "max": "max",
    "final": "final",
    "settle_time": "settle time",
}


@dataclass(frozen=True, kw_only=True)
class Measure(ABC):
    r"""A quantity sampled after every simulation step and summarized over the run.

    Subclasses implement :meth:`sample`. The summary of a run is stored under
    :meth:`key` (``"<name>_<summary>_<unit>"``, e.g. ``"tilt_rms_deg"``) in SI ``unit``;
    tables show it in ``display_unit`` (``display_scale`` times the value) under
    :meth:`display_key`, e.g. ``"com_deviation_rms_cm"``.

    Attributes:
        name: Key of the per-step samples, e.g. ``"tilt"``.
        unit: Unit of the samples, e.g. ``"m"`` or ``"deg"`` (``""`` when unitless).
        label: Short label in table headers and plot axes (default: ``name``).
        summaries: Names of the summaries over a run, from :data:`SUMMARIES`.
        display_unit: Unit in tables and plots (default: ``unit``).
        display_scale: Factor from ``unit`` to ``display_unit``.
        tolerance: Band :math:`|y| \le` ``tolerance`` (in ``unit``) that the
            ``"settle_time"`` summary waits for: the first time after which every sample is
            inside it, in s (NaN when the run ends outside it).
    """

    name: str
    unit: str = ""
    label: str = ""
    summaries: tuple[str, ...] = ("rms",)
    display_unit: str = ""
    display_scale: float = 1.0
    tolerance: float | None = None

    def __post_init__(self) -> None:
        if not self.name or not self.name.isidentifier():
            raise InvalidArgumentError(f"name must be an identifier, got {self.name!r}")
        object.__setattr__(self, "summaries", tuple(self.summaries))
        if not self.summaries:
            raise InvalidArgumentError(f"measure {self.name!r}: summaries must not be empty")
        for summary in self.summaries:
            if summary not in SUMMARIES:
                raise UnknownNameError("summary", summary, SUMMARIES)
        if "settle_time" in self.summaries and not (
            self.tolerance is not None and np.isfinite(self.tolerance) and self.tolerance >= 0
        ):
            raise InvalidArgumentError(
                f"measure {self.name!r}: the 'settle_time' summary needs a finite tolerance "
                f">= 0, got {self.tolerance!r}"
            )

    @abstractmethod
    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        """The measure of ``data`` (after ``mj_forward`` or a step), in ``unit``."""

    @property
    def title(self) -> str:
        """``label``, or ``name`` when it is empty."""
        return self.label or self.name

    @property
    def shown_unit(self) -> str:
        """``display_unit``, or ``unit`` when it is empty."""
        return self.display_unit or self.unit

    def unit_of(self, summary: str) -> str:
        """Unit of a summary's value: seconds for ``"settle_time"``, else ``unit``."""
        return "s" if summary == "settle_time" else self.unit

    def key(self, summary: str) -> str:
        """Key of a summary in :attr:`~mpcbox.Metrics.measures`, e.g. ``"tilt_rms_deg"``."""
        return "_".join(part for part in (self.name, summary, self.unit_of(summary)) if part)

    def scale_of(self, summary: str) -> float:
        """Factor from a summary's unit to its table unit (1 for ``"settle_time"``)."""
        return 1.0 if summary == "settle_time" else self.display_scale

    def display_key(self, summary: str) -> str:
        """Key of a summary in table rows and CSV columns, e.g. ``"com_deviation_rms_cm"``."""
        unit = "s" if summary == "settle_time" else self.shown_unit
        return "_".join(part for part in (self.name, summary, unit) if part)

    def header(self, summary: str) -> str:
        """Markdown column header of a summary, e.g. ``"tilt RMS (deg)"``."""
        shown = "s" if summary == "settle_time" else self.shown_unit
        unit = f" ({shown})" if shown else ""
        return f"{self.title} {_TITLES[summary]}{unit}"

    def summarize(self, samples: np.ndarray, time: np.ndarray) -> dict[str, float]:
        """``{key(summary): value}`` of the samples ``(T,)`` (``T >= 1``) taken at ``time``
        ``(T,)`` (s), in each summary's unit."""
        return {self.key(s): SUMMARIES[s](samples, time, self.tolerance) for s in self.summaries}


def check_measures(measures: Sequence[Measure], owner: str) -> tuple[Measure, ...]:
    """``measures`` as a tuple, checked: :class:`Measure` objects with distinct names.

    Args:
        measures: What a task's :meth:`~mpcbox.Problem.measures` returned.
        owner: Who declared them, for the error message.
    """
    out = tuple(measures)
    for measure in out:
        if not isinstance(measure, Measure):
            raise InvalidArgumentError(
                f"{owner}.measures() must return mpcbox.sim.measures.Measure objects, "
                f"got {type(measure).__name__}"
            )
    names = [m.name for m in out]
    if len(set(names)) != len(names):
        raise InvalidArgumentError(f"{owner}.measures() needs distinct names, got {names}")
    return out
