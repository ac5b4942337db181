r"""Follow a :class:`~mpcbox.controllers.trajectory.reference.TrackingReference` in closed loop.

At time :math:`t` the tracker takes the knot :math:`k = \mathrm{round}(t / \Delta t)`
(the last one after the reference ends, which holds its final state) and applies

.. math:: u = \mathrm{clip}\big(\bar u_k - K_k\,(x \ominus \bar x_k)\big).

With ``feedback=False`` it plays the feedforward controls alone (open loop).
"""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.trajectory.reference import TrackingReference
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidTypeError
from mpcbox.validation import as_array, boolean


class TrajectoryTracker(Controller):
    """Time-varying LQR (or feedforward only) along a reference, called every step.

    Args:
        problem: The Problem the reference was computed on.
        reference: The reference, from
            :func:`~mpcbox.controllers.trajectory.reference.tracking_reference`.
        feedback: Apply the gains (otherwise the feedforward controls alone).
        name: Label in tables.

    Raises:
        InvalidTypeError: If ``reference`` is not a TrackingReference.
        ShapeError: If its arrays do not match the Problem's sizes.
    """

    def __init__(
        self,
        problem: Problem,
        reference: TrackingReference,
        *,
        feedback: bool = True,
        name: str = "tv-lqr",
    ) -> None:
        self.problem = check_problem(problem, type(self).__name__)
        if not isinstance(reference, TrackingReference):
            raise InvalidTypeError(
                f"reference must be a TrackingReference (tracking_reference), got "
                f"{type(reference).__name__}"
            )
        knots = reference.time.size
        as_array("reference.states", reference.states, (knots, problem.nstate))
        as_array("reference.ctrls", reference.ctrls, (knots, problem.nu))
        as_array("reference.gains", reference.gains, (knots, problem.nu, problem.nx))
        self.reference = reference
        self.feedback = boolean("feedback", feedback)
        self.name = str(name)
        self.period = None
        self.last_call = "hold"
        self._dx = np.zeros(problem.nx)

    def knot(self, time: float) -> int:
        """The reference knot at ``time`` (s): nearest, clamped to the reference."""
        dt = (
            float(self.reference.time[1] - self.reference.time[0])
            if self.reference.time.size > 1
            else 1.0
        )
        return int(np.clip(round(float(time) / dt), 0, self.reference.time.size - 1))

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        ref, k = self.reference, self.knot(time)
        if not self.feedback:
            return ref.ctrls[k].copy()
        self.problem.state_difference(state, ref.states[k], out=self._dx)
        return self.problem.clip_ctrl(ref.ctrls[k] - ref.gains[k] @ self._dx)


__all__ = ["TrajectoryTracker"]
