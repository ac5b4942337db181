"""Control-limited iLQR, offline and receding-horizon, laid out as a planner folder.

- :mod:`~mpcbox.controllers.ilqr.config`: :class:`ILQRConfig`, the options.
- :mod:`~mpcbox.controllers.ilqr.backward_pass`: the Riccati recursion with box-QP
  feed-forward (:mod:`~mpcbox.controllers.ilqr.boxqp`).
- :mod:`~mpcbox.controllers.ilqr.forward_pass`: closed-loop rollouts and the line search.
- :mod:`~mpcbox.controllers.ilqr.multiple_shooting`: FDDP-style multiple shooting from a
  state-trajectory guess (defects closed during the iterations).
- :mod:`~mpcbox.controllers.ilqr.solver`: :class:`ILQRSolver`, the offline iterations.
- :mod:`~mpcbox.controllers.ilqr.result`: :class:`ILQRResult`, :class:`Timing` and
  :class:`StopReason`.
- :mod:`~mpcbox.controllers.ilqr.controller`: :class:`ILQR`, the receding-horizon controller.
"""

from __future__ import annotations

from mpcbox.controllers.ilqr.backward_pass import (
    BackwardPass,
    backward_pass,
    interpolate_linearization,
)
from mpcbox.controllers.ilqr.boxqp import BoxQPResult, solve_box_qp
from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.multiple_shooting import (
    GappedRollout,
    optimize_multiple_shooting,
    straight_line_states,
)
from mpcbox.controllers.ilqr.result import ILQRResult, StopReason, Timing
from mpcbox.controllers.ilqr.solver import ILQRSolver

__all__ = [
    "ILQR",
    "BackwardPass",
    "BoxQPResult",
    "GappedRollout",
    "ILQRConfig",
    "ILQRResult",
    "ILQRSolver",
    "StopReason",
    "Timing",
    "backward_pass",
    "interpolate_linearization",
    "optimize_multiple_shooting",
    "solve_box_qp",
    "straight_line_states",
]
