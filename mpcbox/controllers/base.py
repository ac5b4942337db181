"""The :class:`Controller` interface that :func:`mpcbox.simulate` calls."""

from __future__ import annotations

import abc
from typing import Any

import numpy as np

from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidTypeError


def check_problem(problem: Any, owner: str) -> Problem:
    """The preamble every controller shares: ``problem`` must be an :class:`mpcbox.Problem`.

    Args:
        problem: The argument to check.
        owner: The controller's name, used in the message.

    Raises:
        InvalidTypeError: If ``problem`` is not a Problem.
    """
    if not isinstance(problem, Problem):
        raise InvalidTypeError(
            f"problem of {owner} must be an mpcbox.Problem, got {type(problem).__name__}"
        )
    return problem


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
    #: The keyword-only config dataclass the controller takes (``None``: no options).
    config_class: type | None = None
    #: Optional modules the controller imports when built (not when its class is imported);
    #: :func:`mpcbox.registry.available_controllers` leaves it out when one is missing.
    requires: tuple[str, ...] = ()
    #: What the last call did: ``"solve"`` (computed a new control online), ``"hold"``
    #: (followed the current plan without solving: a feedback law or a spline between
    #: replans) or ``"offline"`` (a one-off solve before the loop, e.g. IPOPT's).
    #: :func:`mpcbox.simulate` times only ``"solve"`` calls as ticks and reports the others
    #: on their own.
    last_call: str = "solve"

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget internal state (warm starts, filters) before a new simulation."""

    @abc.abstractmethod
    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """The control ``(nu,)`` for ``state`` ``[qpos, qvel, act]`` at ``time`` (s)."""

    @property
    def stats(self) -> dict[str, float]:
        """Counters reported in metrics, e.g. ``{"fallbacks": 2}`` (default: none)."""
        return {}
