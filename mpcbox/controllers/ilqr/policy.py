r"""iLQR-MPC's feedback law between replans, as an object the simulation can call on its own.

A replan publishes a :class:`FeedbackPolicy`: the plan's states, controls and gains and the
time it was planned at. Evaluated at a state :math:`x` and time :math:`t` it gives

.. math:: u = \mathrm{clip}\big(\bar u_i + K_i\,(x \ominus \bar x(t))\big),

with :math:`i` the knot that :math:`t` falls in and :math:`\bar x(t)` the plan's state
interpolated there. With knots that hold their control for several model steps
(``control_steps > 1``) the law is evaluated once at the start of each knot and held, as the
plan assumes.

:class:`~mpcbox.controllers.ilqr.controller.ILQR` applies it between its replans; the
real-time loop (:func:`mpcbox.simulate_realtime`) evaluates the latest one in the world's
thread at every step while the planner thread computes the next, so the feedback does not
stop while a replan runs.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: ``deviation(state, nominal, out)`` writes ``state ⊖ nominal`` ``(nx,)`` into ``out``.
Deviation = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
#: ``add(state, dx)``: a new state, ``state ⊕ dx``.
StateAdd = Callable[[np.ndarray, np.ndarray], np.ndarray]


class FeedbackPolicy:
    """The feedback law of one plan (see the module docstring).

    Args:
        states: The plan's knot states ``(T + 1, nstate)``.
        ctrls: Its controls ``(T, nu)``.
        gains: Its feedback gains ``(T, nu, nx)``.
        plan_time: Simulated time of the state it was planned from (s).
        knot_dt: Seconds between knots.
        steps: Model steps per knot; above 1 the law is held within each knot.
        ctrl_low: Lower control bounds ``(nu,)``.
        ctrl_high: Upper control bounds ``(nu,)``.
        deviation: Tangent-space difference of two states.
        add: Tangent-space step of a state.
    """

    def __init__(
        self,
        states: np.ndarray,
        ctrls: np.ndarray,
        gains: np.ndarray,
        plan_time: float,
        knot_dt: float,
        steps: int,
        ctrl_low: np.ndarray,
        ctrl_high: np.ndarray,
        deviation: Deviation,
        add: StateAdd,
    ) -> None:
        self.states, self.ctrls, self.gains = states, ctrls, gains
        self.plan_time, self.knot_dt, self.steps = float(plan_time), float(knot_dt), steps
        self.ctrl_low, self.ctrl_high = ctrl_low, ctrl_high
        self._deviation, self._add = deviation, add
        # (knot, control) last computed with ``steps > 1``: state of the caller's
        # execution of the plan, so each caller (the world, a prediction) needs its own
        # copy (``copy.copy``; the arrays are only read).
        self._held: tuple[int, np.ndarray] | None = None

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        """The control ``(nu,)`` at ``state`` ``(nstate,)`` and simulated ``time``."""
        horizon, nx = self.gains.shape[0], self.gains.shape[2]
        s = max(0.0, (time - self.plan_time) / self.knot_dt)
        i = min(int(s + 1e-6), horizon - 1)  # the tolerance: a time just short of a knot
        frac = min(max(s - i, 0.0), 1.0)
        if self.steps > 1 and self._held is not None and self._held[0] == i and frac > 1e-6:
            return self._held[1].copy()  # within the knot: its control is held
        nominal = self.states[i]
        if frac > 0:
            step = np.zeros(nx)
            self._deviation(self.states[i + 1], nominal, step)
            nominal = self._add(nominal, frac * step)
        dx = np.zeros(nx)
        self._deviation(state, nominal, dx)
        u = self.ctrls[i] + self.gains[i] @ dx
        if np.all(np.isfinite(u)):
            u = np.clip(u, self.ctrl_low, self.ctrl_high)
        else:
            u = self.ctrls[i].copy()
        if self.steps > 1:
            self._held = (i, u.copy())
        return u


__all__ = ["Deviation", "FeedbackPolicy", "StateAdd"]
