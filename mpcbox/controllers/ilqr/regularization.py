r"""Schedules of the Levenberg-Marquardt term :math:`\mu` of iLQR (the ``regularization``).

The backward pass adds :math:`\mu I` to :math:`Q_{uu}`: a large :math:`\mu` gives short,
gradient-like steps that the line search accepts easily, a small one Newton steps that
converge fast near a minimum. A schedule says how :math:`\mu` moves: it always grows after a
failed backward pass (non-definite :math:`Q_{uu}`) or a failed line search
(:meth:`Regularization.increase`); after an accepted step of size :math:`\alpha` the
schedules differ (:meth:`Regularization.accepted`). With ``factor`` :math:`\rho > 1`
(``regularization_factor``) and ``minimum`` :math:`\mu_{min}` (``regularization_min``):

``"mpcbox"`` (the default)
    :math:`\mu \leftarrow \mu / \rho` after a step with :math:`\alpha \ge 0.5` (and to 0 once
    below :math:`\mu_{min}`), :math:`\mu \leftarrow \max(\mu_{min}, \rho \mu)` after a step
    with :math:`\alpha < 0.2`; failures multiply by :math:`\rho`.
``"crocoddyl"``
    As Crocoddyl's DDP/FDDP solvers describe their schedule: :math:`\mu \leftarrow
    \max(\mu_{min}, \mu / \rho)` after a step with :math:`\alpha \ge 0.5`, :math:`\mu
    \leftarrow \rho \mu` after a step with :math:`\alpha \le 0.01` and after failures;
    :math:`\mu` never drops below :math:`\mu_{min}` (Crocoddyl's defaults: :math:`\rho = 10`,
    :math:`\mu_{min} = 10^{-9}`).
``"tassa"``
    The multiplicative schedule of Tassa, Erez and Todorov (IROS 2012): a running factor
    :math:`\delta` that grows while failures repeat and shrinks while steps are accepted,
    :math:`\delta \leftarrow \max(\rho, \delta\rho)`, :math:`\mu \leftarrow \max(\mu_{min},
    \mu\delta)` after a failure; :math:`\delta \leftarrow \min(1/\rho, \delta/\rho)`,
    :math:`\mu \leftarrow \mu\delta` (0 below :math:`\mu_{min}`) after every accepted step,
    whatever its size (the paper's :math:`\rho` is 1.6).

The multiple-shooting phase (defects open) of the ``"mpcbox"`` schedule only decreases
(``feasible=False``): while defects close, a short step is the step size the gaps allowed,
not a sign of a poor quadratic model.
"""

from __future__ import annotations

from typing import Literal

RegularizationSchedule = Literal["mpcbox", "crocoddyl", "tassa"]
#: Valid values of :attr:`~mpcbox.controllers.ilqr.config.ILQRConfig.regularization_schedule`.
REGULARIZATION_SCHEDULES: tuple[str, ...] = ("mpcbox", "crocoddyl", "tassa")


class Regularization:
    r"""The :math:`\mu` of one solve and the schedule that moves it (see the module docstring).

    Args:
        value: Initial :math:`\mu \ge 0`.
        schedule: ``"mpcbox"``, ``"crocoddyl"`` or ``"tassa"``.
        factor: :math:`\rho > 1`.
        minimum: :math:`\mu_{min} > 0`.

    Attributes:
        value: The current :math:`\mu`.
    """

    def __init__(
        self, value: float, schedule: RegularizationSchedule, factor: float, minimum: float
    ) -> None:
        self.value = float(value)
        self.schedule = schedule
        self.factor = factor
        self.minimum = minimum
        self._delta = 1.0

    def increase(self) -> None:
        """After a failed backward pass or line search."""
        if self.schedule == "tassa":
            self._delta = max(self.factor, self._delta * self.factor)
            self.value = max(self.minimum, self.value * self._delta)
        else:
            self.value = max(self.minimum, self.value * self.factor)

    def accepted(self, alpha: float, *, feasible: bool = True) -> None:
        """After an accepted step of size ``alpha`` (``feasible``: no defects were open)."""
        if self.schedule == "tassa":
            self._delta = min(1.0 / self.factor, self._delta / self.factor)
            value = self.value * self._delta
            self.value = value if value >= self.minimum else 0.0
        elif self.schedule == "crocoddyl":
            if alpha >= 0.5:
                self.value = max(self.minimum, self.value / self.factor)
            elif alpha <= 0.01:
                self.value = max(self.minimum, self.value * self.factor)
        elif alpha >= 0.5:
            value = self.value / self.factor
            self.value = value if value >= self.minimum else 0.0
        elif alpha < 0.2 and feasible:
            self.increase()


__all__ = ["REGULARIZATION_SCHEDULES", "Regularization", "RegularizationSchedule"]
