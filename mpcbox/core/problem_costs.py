"""A :class:`~mpcbox.Problem`'s cost: values and Gauss-Newton quadratizations, checked."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mpcbox.core import derivatives, inputs
from mpcbox.core.cost import Features
from mpcbox.core.derivatives import Quadratization
from mpcbox.core.dynamics import Rollout
from mpcbox.errors import DivergenceError
from mpcbox.validation import as_array, boolean, positive_int

if TYPE_CHECKING:
    from mpcbox.core.cost import Cost
    from mpcbox.core.dynamics import Dynamics
    from mpcbox.core.tangent import TangentSpace


class ProblemCosts:
    """The cost methods of :class:`~mpcbox.Problem` (which sets the attributes below)."""

    cost: Cost
    dynamics: Dynamics
    tangent: TangentSpace
    ctrl_ref: np.ndarray
    fd_eps: float
    nq: int
    nv: int
    nu: int
    nstate: int

    def features(self, state: np.ndarray, ctrl: np.ndarray | None = None) -> Features:
        """Cost features of one state (after ``mj_forward`` on the planning model)."""
        state = self.check_state(state)
        ctrl = self.ctrl_ref if ctrl is None else self.check_ctrl(ctrl)
        return derivatives.evaluate_features(self.dynamics, state, ctrl)

    def running_cost(self, state: np.ndarray, ctrl: np.ndarray) -> float:
        """Running cost ``l(x, u)`` of one knot."""
        return float(self.cost.running_value(self.features(state, ctrl))[0])

    def terminal_cost(self, state: np.ndarray) -> float:
        """Terminal cost ``l_T(x)``."""
        return float(self.cost.terminal_value(self.features(state))[0])

    def rollout_cost(self, rollout: Rollout) -> np.ndarray:
        """Total cost ``(B,)`` of each rollout: ``T`` running costs plus the terminal cost."""
        return derivatives.rollout_cost(self.cost, rollout, self.nq, self.nv)

    def quadratize(
        self, state: np.ndarray, ctrl: np.ndarray, *, terminal: bool = False
    ) -> Quadratization:
        r"""Gauss-Newton quadratization of the running (or terminal) cost at one knot.

        :math:`\ell_x = J_x^T W r`, :math:`\ell_{xx} = J_x^T W J_x`, ... with the residual
        Jacobians :math:`J_x, J_u` (see :mod:`mpcbox.core.derivatives`).
        """
        state, ctrl = self.check_state(state), self.check_ctrl(ctrl)
        terms = self.cost.terminal if boolean("terminal", terminal) else self.cost.running
        out = derivatives.quadratize_knots(
            self.dynamics, self.tangent, terms, state[None], ctrl[None], self.fd_eps
        )
        return Quadratization(*(value[0] for value in out))

    def quadratize_trajectory(
        self,
        states: np.ndarray,
        ctrls: np.ndarray,
        *,
        threads: int | None = None,
        hessians: bool = True,
    ) -> Quadratization:
        """Running cost at ``T`` knots and terminal cost at the last of ``T + 1`` states.

        ``states`` ``(T + 1, nstate)`` and ``ctrls`` ``(T, nu)`` give arrays with leading size
        ``T + 1`` (see :func:`~mpcbox.core.derivatives.quadratize_trajectory`); with
        ``hessians=False`` the Hessian blocks are left zero (for a caller with its own).

        Raises:
            ShapeError: For other shapes.
            DivergenceError: If ``states`` or ``ctrls`` hold NaN or infinity.
            InvalidArgumentError: For a control beyond MuJoCo's limit.
        """
        states = as_array("states", states, (None, self.nstate))
        if not np.all(np.isfinite(states)):
            raise DivergenceError("states holds non-finite values (NaN or inf)")
        ctrls = inputs.check_ctrl("ctrls", ctrls, (states.shape[0] - 1, self.nu))
        threads = None if threads is None else positive_int("threads", threads)
        hessians = boolean("hessians", hessians)
        return derivatives.quadratize_trajectory(
            self.dynamics, self.tangent, self.cost, states, ctrls, self.fd_eps, threads, hessians
        )
