r"""Task measures: quantities a task declares, sampled at every step of a closed-loop run.

A :class:`Measure` turns the simulation state after each step into one number
:math:`y_k = f(\text{model}, \text{data}_k)`; :func:`~mpcbox.simulate` records the samples
``(T,)`` in :attr:`~mpcbox.SimulationResult.series` and summarizes them over the run in
:attr:`~mpcbox.Metrics.measures`. A task lists its measures in
:meth:`~mpcbox.Problem.measures` (none by default): the humanoid tasks, for example, report
the center of mass over the support and the torso tilt
(:mod:`mpcbox.tasks.humanoid.measures`). Comparison tables show one column per measure and
summary.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from mpcbox.errors import InvalidArgumentError, UnknownNameError


def _rms(samples: np.ndarray) -> float:
    return float(np.sqrt(np.mean(samples**2)))


#: Summaries of a measure's samples ``(T,)`` over a run, by name.
SUMMARIES: dict[str, Callable[[np.ndarray], float]] = {
    "rms": _rms,
    "mean": lambda samples: float(np.mean(samples)),
    "max": lambda samples: float(np.max(samples)),
    "final": lambda samples: float(samples[-1]),
}

#: How a summary is written in table headers.
_TITLES = {"rms": "RMS", "mean": "mean", "max": "max", "final": "final"}


@dataclass(frozen=True, kw_only=True)
class Measure(ABC):
    """A quantity sampled after every simulation step and summarized over the run.

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
    """

    name: str
    unit: str = ""
    label: str = ""
    summaries: tuple[str, ...] = ("rms",)
    display_unit: str = ""
    display_scale: float = 1.0

    def __post_init__(self) -> None:
        if not self.name or not self.name.isidentifier():
            raise InvalidArgumentError(f"name must be an identifier, got {self.name!r}")
        object.__setattr__(self, "summaries", tuple(self.summaries))
        if not self.summaries:
            raise InvalidArgumentError(f"measure {self.name!r}: summaries must not be empty")
        for summary in self.summaries:
            if summary not in SUMMARIES:
                raise UnknownNameError("summary", summary, SUMMARIES)

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

    def key(self, summary: str) -> str:
        """Key of a summary in :attr:`~mpcbox.Metrics.measures`, e.g. ``"tilt_rms_deg"``."""
        return "_".join(part for part in (self.name, summary, self.unit) if part)

    def display_key(self, summary: str) -> str:
        """Key of a summary in table rows and CSV columns, e.g. ``"com_deviation_rms_cm"``."""
        return "_".join(part for part in (self.name, summary, self.shown_unit) if part)

    def header(self, summary: str) -> str:
        """Markdown column header of a summary, e.g. ``"tilt RMS (deg)"``."""
        unit = f" ({self.shown_unit})" if self.shown_unit else ""
        return f"{self.title} {_TITLES[summary]}{unit}"

    def summarize(self, samples: np.ndarray) -> dict[str, float]:
        """``{key(summary): value}`` of the samples ``(T,)`` (``T >= 1``), in ``unit``."""
        return {self.key(s): SUMMARIES[s](samples) for s in self.summaries}


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
