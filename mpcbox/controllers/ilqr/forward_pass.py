r"""The forward pass of iLQR: closed-loop rollouts of the update law and the line search.

A step of size :math:`\alpha` rolls the planning model out under

.. math:: u_t = \mathrm{clip}(\bar u_t + \alpha k_t + K_t (x_t \ominus \bar x_t)),

from the same start state, with :math:`(\bar x, \bar u)` the current trajectory. The line
search tries several step sizes and accepts one whose actual decrease of the cost is at
least ``armijo`` times the decrease that the backward pass predicts,
:math:`-(\alpha \Delta V_1 + \alpha^2 \Delta V_2)`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.held_controls import held_steps
from mpcbox.core.divergence import diverged
from mpcbox.core.problem import Problem, Rollout

#: A rolled-out candidate: states ``(T + 1, nstate)``, controls ``(T, nu)`` and the total
#: cost (``inf`` when the rollout diverged).
Candidate = tuple[np.ndarray, np.ndarray, float]


class ClosedLoopRollout:
    """Rollouts of the planning model under the iLQR update law.

    :meth:`mpcbox.Problem.rollout` rolls out open-loop control sequences; here every control
    depends on the state just reached, so the steps are taken one by one on a scratch
    ``MjData`` of the planning model (:meth:`~mpcbox.Problem.scratch_data`, one per thread: the
    parallel line search rolls out several step sizes at once), with the tangent deviation
    written into a preallocated buffer in the inner loop (``mj_differentiatePos``, which
    allocates nothing, where :meth:`~mpcbox.Problem.state_difference` is vectorized for
    batches; a plain subtraction when the model has no ball or free joint).

    A rollout that diverges is scored ``inf``: non-finite states or controls, or MuJoCo's
    own reset after a bad position, velocity or acceleration (its warning counters,
    :func:`~mpcbox.core.divergence.diverged`), which would otherwise continue from
    the model's reference pose with a finite cost.

    Args:
        problem: The Problem whose planning model is rolled out.
        ctrl_low: Lower control bounds ``(nu,)``.
        ctrl_high: Upper control bounds ``(nu,)``.
        steps: Model steps per knot, each knot's control held for all of them
            (:mod:`~mpcbox.controllers.ilqr.held_controls`); the cost sums every step.
    """

    def __init__(
        self, problem: Problem, ctrl_low: np.ndarray, ctrl_high: np.ndarray, steps: int = 1
    ) -> None:
        self.problem = problem
        self.ctrl_low = ctrl_low
        self.ctrl_high = ctrl_high
        self.steps = steps
        self._model = problem.planning_model
        # Without ball or free joints every position difference is a subtraction.
        self._plain = problem.nq == problem.nv

    def deviation(self, state: np.ndarray, nominal: np.ndarray, out: np.ndarray) -> None:
        """Write ``state ⊖ nominal`` ``(nx,)`` into ``out``.

        The same as :meth:`mpcbox.Problem.state_difference` for one state, without
        allocating: it runs once per knot of every rollout.
        """
        if self._plain:
            np.subtract(state, nominal, out=out)
            return
        nq, nv = self.problem.nq, self.problem.nv
        mujoco.mj_differentiatePos(self._model, out[:nv], 1.0, nominal[:nq], state[:nq])
        np.subtract(state[nq:], nominal[nq:], out=out[nv:])

    def __call__(
        self,
        x0: np.ndarray,
        states: np.ndarray,
        ctrls: np.ndarray,
        k: np.ndarray,
        K: np.ndarray,
        alpha: float,
    ) -> Candidate:
        """Roll out the update law with step size ``alpha`` from ``x0``.

        Args:
            x0: Start state ``(nstate,)``.
            states: Current states ``(T + 1, nstate)``.
            ctrls: Current controls ``(T, nu)``.
            k: Feed-forward terms ``(T, nu)``.
            K: Feedback gains ``(T, nu, nx)``.
            alpha: Step size.

        Returns:
            New states, controls and cost; the cost is ``inf`` if the rollout diverged.
        """
        p, m, steps = self.problem, self._model, self.steps
        d = p.scratch_data()  # the thread's own MjData, reset below
        nq, nv, horizon = p.nq, p.nv, len(ctrls)
        low, high = self.ctrl_low, self.ctrl_high
        mujoco.mj_resetData(m, d)
        fine = np.empty((horizon * steps + 1, states.shape[1]))
        new_ctrls = np.empty_like(ctrls)
        sens = np.empty((1, len(fine), m.nsensordata))
        fine[0] = x0
        dx = np.zeros(p.nx)
        d.qpos[:] = x0[:nq]
        d.qvel[:] = x0[nq : nq + nv]
        d.act[:] = x0[nq + nv :]
        with np.errstate(all="ignore"):
            feedforward = ctrls + alpha * k
            for t in range(horizon):
                self.deviation(fine[t * steps], states[t], dx)
                u = new_ctrls[t]
                np.matmul(K[t], dx, out=u)
                u += feedforward[t]
                np.minimum(u, high, out=u)
                np.maximum(u, low, out=u)
                d.ctrl[:] = u
                for j in range(t * steps, (t + 1) * steps):
                    mujoco.mj_step(m, d)
                    sens[0, j] = d.sensordata
                    x = fine[j + 1]
                    x[:nq] = d.qpos
                    x[nq : nq + nv] = d.qvel
                    x[nq + nv :] = d.act
            new_states = fine[::steps]
            if diverged(d, fine, new_ctrls):
                return new_states, new_ctrls, np.inf
            mujoco.mj_forward(m, d)
            sens[0, -1] = d.sensordata
            played = held_steps(new_ctrls, steps)
            cost = float(p.rollout_cost(Rollout(fine[None], sens, played[None]))[0])
        return new_states, new_ctrls, cost if np.isfinite(cost) else np.inf


class LineSearchResult(NamedTuple):
    """Outcome of :func:`line_search`.

    Attributes:
        candidate: The accepted ``(states, ctrls, cost)``, or ``None`` if no step size was
            accepted.
        alpha: The accepted step size (0 when none was).
        divergences: Rollouts that diverged.
        all_diverged: Whether every step size's rollout diverged.
    """

    candidate: Candidate | None
    alpha: float
    divergences: int
    all_diverged: bool

    @property
    def accepted(self) -> bool:
        """Whether a step size was accepted."""
        return self.candidate is not None


def line_search(
    forward: Callable[[float], Candidate],
    step_sizes: Sequence[float],
    cost: float,
    expected: tuple[float, float],
    armijo: float,
    executor: Executor | None = None,
) -> LineSearchResult:
    """Try step sizes and keep one that lowers the cost enough.

    Args:
        forward: Rolls out the update law with a given step size.
        step_sizes: Step sizes ``alpha`` in decreasing order.
        cost: Cost of the current trajectory.
        expected: ``(dV1, dV2)`` of the backward pass.
        armijo: Fraction of the predicted decrease that the actual one must reach.
        executor: Backtracking when ``None`` (try the step sizes in order, stop at the first
            accepted); otherwise roll all of them out on this pool and keep the lowest cost.

    Returns:
        A :class:`LineSearchResult`.
    """
    dv1, dv2 = expected

    def accept(alpha: float, new_cost: float) -> bool:
        predicted = -(alpha * dv1 + alpha**2 * dv2)
        actual = cost - new_cost
        return bool(np.isfinite(new_cost) and actual > 0 and actual >= armijo * predicted)

    n_all = len(step_sizes)
    if executor is None:
        n_div = 0
        for alpha in step_sizes:
            new = forward(alpha)
            if not np.isfinite(new[2]):
                n_div += 1
                continue
            if accept(alpha, new[2]):
                return LineSearchResult(new, alpha, n_div, False)
        return LineSearchResult(None, 0.0, n_div, n_div == n_all)
    outs = list(executor.map(forward, step_sizes))
    n_div = sum(not np.isfinite(o[2]) for o in outs)
    ok = [(o[2], a, o) for a, o in zip(step_sizes, outs) if accept(a, o[2])]
    if not ok:
        return LineSearchResult(None, 0.0, n_div, n_div == n_all)
    _, alpha, best = min(ok, key=lambda item: item[0])
    return LineSearchResult(best, alpha, n_div, False)


__all__ = ["Candidate", "ClosedLoopRollout", "LineSearchResult", "line_search"]
