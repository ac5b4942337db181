"""The :class:`Controller` interface that :func:`mpcbox.simulate` calls."""

from __future__ import annotations

import abc

import numpy as np


class Controller(abc.ABC):
    """Maps the measured state to a control, at its own rate.

    Subclasses implement :meth:`__call__`; :func:`mpcbox.simulate` calls it every ``period``
    seconds (every simulation step when ``period`` is ``None``) and holds the control in
    between.

    Attributes:
        name: Label used in tables and plots.
        period: Seconds between calls, or ``None`` for every simulation step.
    """

    name: str = "controller"
    period: float | None = None

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget internal state (warm starts, filters) before a new simulation."""

    @abc.abstractmethod
    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """The control ``(nu,)`` for ``state`` ``[qpos, qvel, act]`` at ``time`` (s)."""

    @property
    def stats(self) -> dict[str, float]:
        """Counters reported in metrics, e.g. ``{"fallbacks": 2}`` (default: none)."""
        return {}
