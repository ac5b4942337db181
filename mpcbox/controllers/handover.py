r"""A controller that hands control between two controllers by a predicate with hysteresis
(task stages, or a fall-recovery hand-over: a get-up planner until the robot is up, a
standing controller while it stays up).

Phase :math:`p_k \in \{0, 1\}` at call :math:`k`, from the measured state :math:`x_k`:

.. math::
    p_k = \begin{cases} 1 & p_{k-1} = 0 \wedge \mathrm{engage}(x_k) \\
    0 & p_{k-1} = 1 \wedge \mathrm{release}(x_k) \\ p_{k-1} & \text{otherwise,} \end{cases}
    \qquad p_{-1} = 0 ,

and the call returns ``(first, second)[p_k](x_k, t_k)``. With ``engage`` and ``release`` that
cannot both hold near the switching surface (e.g. height above 1.1 m to engage, below 0.9 m
to release) the phase does not chatter.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import boolean, finite

#: A predicate on the measured state ``(nstate,)``.
StatePredicate = Callable[[np.ndarray], bool]


class HandOver(Controller):
    """Delegate to ``first`` or ``second`` by the phase rule of the module docstring.

    On a switch the incoming controller takes over the outgoing one's plan when both are
    spline planners (the sampling controllers): with ``transfer`` the outgoing nominal
    spline, evaluated at the incoming spline's knot times from now, becomes the incoming
    nominal (:meth:`~mpcbox.controllers.sampling.base.SamplingController.warm_start`);
    without it the incoming controller starts cold from its own reference control. Either
    way the incoming controller's algorithm state (e.g. CEM's standard deviation) restarts
    and its random stream goes on. With ``prime`` the first call also runs ``second`` once
    on the initial state (its output unused, its plan then dropped), so that its one-off
    start-up work (compilation, device buffers, graph capture) happens before the clock
    of a real-time run starts rather than at the first switch.

    Args:
        first: The controller of phase 0 (the start).
        second: The controller of phase 1.
        engage: Switch from ``first`` to ``second`` when this holds.
        release: Switch from ``second`` back to ``first`` when this holds.
        transfer: Warm-start the incoming spline planner with the outgoing plan.
        prime: Run ``second`` once on the first call.
        name: Label used in tables.

    Attributes:
        controllers: ``(first, second)``.
        phase: Index of the active controller (0 or 1).
        switches: Switches since :meth:`reset`.
        switch_times: Simulated time of each of those switches (s).

    Raises:
        InvalidTypeError: If a controller is not a Controller or a predicate not callable.
        InvalidArgumentError: If the two controllers' periods differ.
    """

    name = "handover"

    def __init__(
        self,
        first: Controller,
        second: Controller,
        *,
        engage: StatePredicate,
        release: StatePredicate,
        transfer: bool = True,
        prime: bool = True,
        name: str = "handover",
    ) -> None:
        for label, ctrl in (("first", first), ("second", second)):
            if not isinstance(ctrl, Controller):
                raise InvalidTypeError(
                    f"{label} must be an mpcbox Controller, got {type(ctrl).__name__}"
                )
        for label, fn in (("engage", engage), ("release", release)):
            if not callable(fn):
                raise InvalidTypeError(f"{label} must be callable, got {type(fn).__name__}")
        if first.period != second.period:
            raise InvalidArgumentError(
                f"first and second must share one period, got {first.period} and {second.period}"
            )
        self.controllers: tuple[Controller, Controller] = (first, second)
        self.engage, self.release = engage, release
        self.transfer = boolean("transfer", transfer)
        self.prime = boolean("prime", prime)
        self.name = str(name)
        self.period = first.period
        self.reset()

    # ------------------------------------------------------------------ delegation
    @property
    def active(self) -> Controller:
        """The controller of the current phase."""
        return self.controllers[self.phase]

    @property
    def spline(self) -> Any:
        """The active controller's spline (``None`` when it has none)."""
        return getattr(self.active, "spline", None)

    @property
    def knots(self) -> np.ndarray | None:
        """The active controller's nominal knots ``(K, nu)`` (``None`` when it has none)."""
        return getattr(self.active, "knots", None)

    def reset(self) -> None:
        """Reset both controllers and start in phase 0."""
        for ctrl in self.controllers:
            ctrl.reset()
        self.phase = 0
        self.switches = 0
        self.switch_times: list[float] = []
        self.phase_calls = [0, 0]
        self._primed = not self.prime
        self.last_call = "solve"

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        time = finite("time", time)
        if not self._primed:
            self._primed = True
            second = self.controllers[1]
            second(state, time)
            _warm_start(second, None, time)
        rule = self.release if self.phase else self.engage
        if rule(state):
            self._switch(time)
        ctrl = self.active
        out = ctrl(state, time)
        self.last_call = getattr(ctrl, "last_call", "solve")
        self.phase_calls[self.phase] += 1
        return out

    def _switch(self, time: float) -> None:
        outgoing, incoming = self.active, self.controllers[1 - self.phase]
        knots = _plan_on(outgoing, incoming, time) if self.transfer else None
        _warm_start(incoming, knots, time)
        self.phase = 1 - self.phase
        self.switches += 1
        self.switch_times.append(float(time))

    @property
    def stats(self) -> dict[str, float]:
        """``switches``, ``phase``, calls per phase, ``fallbacks`` (both controllers'), and
        each controller's own stats prefixed ``first.`` / ``second.``."""
        out = {
            "switches": float(self.switches),
            "phase": float(self.phase),
            "first_calls": float(self.phase_calls[0]),
            "second_calls": float(self.phase_calls[1]),
            "fallbacks": 0.0,
        }
        for label, ctrl in zip(("first", "second"), self.controllers):
            stats = ctrl.stats
            out["fallbacks"] += float(stats.get("fallbacks", 0.0))
            out.update({f"{label}.{key}": float(value) for key, value in stats.items()})
        return out

    def close(self) -> None:
        """Close both controllers (those that have ``close``)."""
        for ctrl in self.controllers:
            close = getattr(ctrl, "close", None)
            if close is not None:
                close()


def _plan_on(outgoing: Controller, incoming: Controller, time: float) -> np.ndarray | None:
    """The outgoing nominal spline at the incoming knot times from ``time`` ``(K, nu)``, or
    ``None`` when either is not a spline planner with a plan."""
    source, target = getattr(outgoing, "spline", None), getattr(incoming, "spline", None)
    knots, last = getattr(outgoing, "knots", None), getattr(outgoing, "last", None)
    if source is None or target is None or knots is None or last is None:
        return None
    if knots.shape[-1] != getattr(incoming.problem, "nu", None):  # type: ignore[attr-defined]
        return None
    return source.evaluate(knots, target.knot_times + (float(time) - float(last.time)))


def _warm_start(ctrl: Controller, knots: np.ndarray | None, time: float) -> None:
    warm = getattr(ctrl, "warm_start", None)
    if warm is not None:
        warm(knots, time)
