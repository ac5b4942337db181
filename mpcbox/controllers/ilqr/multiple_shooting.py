r"""Multiple shooting for iLQR: start from a state-trajectory guess and close its defects.

A guess of the states :math:`x_0 .. x_T` (and controls :math:`u_0 .. u_{T-1}`) is usually not
a trajectory of the planning model: each shooting node leaves a defect (gap)

.. math:: f_t = F(x_t, u_t) \ominus x_{t+1}, \qquad t = 0 .. T-1,

with :math:`F` one planning step and :math:`x_0` the start state. The feasibility-driven
variant of DDP (FDDP, Mastalli et al., ICRA 2020; box-FDDP for control limits) keeps them:

- the **backward pass** uses the linear model :math:`dx_{t+1} = A_t dx_t + B_t du_t + f_t`,
  i.e. the value gradient :math:`V_x + V_{xx} f_t` at each node
  (:func:`~mpcbox.controllers.ilqr.backward_pass.backward_pass` with ``gaps``);
- the **forward pass** with step size :math:`\alpha` rolls out the update law but lands a
  fraction :math:`(1 - \alpha)` of each defect short,
  :math:`\hat x_{t+1} = F(\hat x_t, \hat u_t) \oplus (-(1 - \alpha) f_t)`, so the defects
  shrink by :math:`(1 - \alpha)` per accepted step and vanish after a full step;
- while defects are open, a step is accepted when its rollout stays finite (the cost of an
  infeasible trajectory is no merit: the feasibility gain is what the step buys), trying the
  step sizes in decreasing order.

Once the defects are below ``defect_tolerance`` the trajectory is a rollout of its controls
and the iterations continue as single-shooting iLQR (same line search, regularization and
stop criteria), so a solve reports converged only when the defects are closed *and* a
convergence criterion of :class:`~mpcbox.controllers.ilqr.result.StopReason` holds.

This code is written from the published equations, not from Crocoddyl's sources.
"""

from __future__ import annotations

import time as _time
from typing import Any

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.backward_pass import backward_pass
from mpcbox.controllers.ilqr.forward_pass import Candidate, ClosedLoopRollout
from mpcbox.controllers.ilqr.result import ILQRResult, StopReason, Timing
from mpcbox.core.divergence import diverged
from mpcbox.core.problem import Problem, Rollout
from mpcbox.errors import InvalidArgumentError, SolverError
from mpcbox.validation import positive_int


def straight_line_states(
    problem: Problem,
    start: np.ndarray,
    goal: np.ndarray,
    horizon: int,
    *,
    arrival: int | None = None,
) -> np.ndarray:
    r"""A straight-line state guess from ``start`` to ``goal``, then resting at ``goal``.

    The positions move at constant speed, :math:`q_t = q_s \oplus \tfrac{t}{n} (q_g \ominus
    q_s)` for :math:`0 < t < n` (``n = arrival``, interpolated in the tangent space so that
    quaternions stay unit), with the velocity that this motion has,
    :math:`(q_g \ominus q_s) / (n\,dt)` (``dt = problem.dt``); from knot ``n`` on the guess
    is ``goal``; the first state is ``start``. Activations are interpolated linearly.

    Args:
        problem: The Problem (its state space and planning timestep).
        start: First state ``(nstate,)``.
        goal: Last state ``(nstate,)``.
        horizon: Number of steps ``T``.
        arrival: Knot ``n`` in ``[1, T]`` at which the guess reaches ``goal`` (default ``T``).

    Returns:
        States ``(T + 1, nstate)``.

    Raises:
        InvalidArgumentError: If ``arrival`` is not in ``[1, horizon]``.
    """
    start, goal = problem.check_state(start, "start"), problem.check_state(goal, "goal")
    horizon = positive_int("horizon", horizon)
    n = horizon if arrival is None else positive_int("arrival", arrival)
    if n > horizon:
        raise InvalidArgumentError(f"arrival must be in [1, horizon={horizon}], got {n}")
    nq, nv = problem.nq, problem.nv
    step = problem.state_difference(goal, start)
    out = np.tile(goal, (horizon + 1, 1))
    out[0] = start
    for t in range(1, n):
        x = problem.state_add(start, (t / n) * step)
        x[nq : nq + nv] = step[:nv] / (n * problem.dt)
        out[t] = x
    return out


class GappedRollout(ClosedLoopRollout):
    """The feasibility-driven forward pass (see the module docstring) and defect evaluation."""

    def _write(self, d: mujoco.MjData, x: np.ndarray) -> None:
        nq, nv = self.problem.nq, self.problem.nv
        d.qpos[:] = x[:nq]
        d.qvel[:] = x[nq : nq + nv]
        d.act[:] = x[nq + nv :]

    def _read(self, d: mujoco.MjData, out: np.ndarray) -> None:
        nq, nv = self.problem.nq, self.problem.nv
        out[:nq] = d.qpos
        out[nq : nq + nv] = d.qvel
        out[nq + nv :] = d.act

    def defects(self, states: np.ndarray, ctrls: np.ndarray) -> tuple[np.ndarray, float]:
        """Defects ``(T, nx)`` of a state and control trajectory, and its cost.

        Args:
            states: States ``(T + 1, nstate)``.
            ctrls: Controls ``(T, nu)``.

        Returns:
            ``f_t = F(x_t, u_t) ⊖ x_{t+1}`` ``(T, nx)`` and the total cost of the (gapped)
            trajectory (``inf`` if not finite).
        """
        p, m = self.problem, self._model
        d = p.scratch_data()
        horizon = len(ctrls)
        mujoco.mj_resetData(m, d)
        gaps = np.zeros((horizon, p.nx))
        sens = np.empty((1, horizon + 1, m.nsensordata))
        x = np.empty(p.nstate)
        with np.errstate(all="ignore"):
            for t in range(horizon):
                self._write(d, states[t])
                d.ctrl[:] = ctrls[t]
                mujoco.mj_step(m, d)
                sens[0, t] = d.sensordata
                self._read(d, x)
                self.deviation(x, states[t + 1], gaps[t])
            if diverged(d, gaps, ctrls):  # MuJoCo reset a step: that defect is meaningless
                return gaps, np.inf
            self._write(d, states[horizon])
            mujoco.mj_forward(m, d)
            sens[0, horizon] = d.sensordata
            cost = float(p.rollout_cost(Rollout(states[None], sens, ctrls[None]))[0])
        ok = np.isfinite(cost) and np.all(np.isfinite(gaps))
        return gaps, cost if ok else np.inf

    def gapped(
        self,
        x0: np.ndarray,
        states: np.ndarray,
        ctrls: np.ndarray,
        gaps: np.ndarray,
        k: np.ndarray,
        K: np.ndarray,
        alpha: float,
    ) -> Candidate:
        """Roll out the update law with step ``alpha``, leaving ``(1 - alpha)`` of each defect.

        Args:
            x0: Start state ``(nstate,)``.
            states: Current states ``(T + 1, nstate)``.
            ctrls: Current controls ``(T, nu)``.
            gaps: Current defects ``(T, nx)``.
            k: Feed-forward terms ``(T, nu)``.
            K: Feedback gains ``(T, nu, nx)``.
            alpha: Step size in (0, 1].

        Returns:
            New states, controls and cost (``inf`` if the rollout diverged).
        """
        if alpha >= 1.0:
            return self(x0, states, ctrls, k, K, alpha)
        p, m = self.problem, self._model
        d = p.scratch_data()
        horizon = len(ctrls)
        mujoco.mj_resetData(m, d)
        new_states = np.empty_like(states)
        new_ctrls = np.empty_like(ctrls)
        sens = np.empty((1, horizon + 1, m.nsensordata))
        new_states[0] = x0
        dx = np.zeros(p.nx)
        x = np.empty(p.nstate)
        self._write(d, x0)
        with np.errstate(all="ignore"):
            for t in range(horizon):
                self.deviation(new_states[t], states[t], dx)
                u = np.clip(ctrls[t] + alpha * k[t] + K[t] @ dx, self.ctrl_low, self.ctrl_high)
                new_ctrls[t] = u
                d.ctrl[:] = u
                mujoco.mj_step(m, d)
                sens[0, t] = d.sensordata
                self._read(d, x)
                new_states[t + 1] = p.tangent.state_add(m, x, -(1.0 - alpha) * gaps[t])
                self._write(d, new_states[t + 1])
            if diverged(d, new_states, new_ctrls):
                return new_states, new_ctrls, np.inf
            mujoco.mj_forward(m, d)
            sens[0, horizon] = d.sensordata
            cost = float(p.rollout_cost(Rollout(new_states[None], sens, new_ctrls[None]))[0])
        return new_states, new_ctrls, cost if np.isfinite(cost) else np.inf


def optimize_multiple_shooting(
    solver: Any,
    x0: np.ndarray,
    states: np.ndarray,
    ctrls: np.ndarray,
    iters: int,
    reg: float,
    max_retries: int | None = None,
) -> ILQRResult:
    """FDDP iterations from a state and control guess, then single shooting once feasible.

    Args:
        solver: The :class:`~mpcbox.controllers.ilqr.solver.ILQRSolver` (problem, config,
            bounds, derivatives and single-shooting iterations; not imported here, which
            would make an import circle).
        x0: Start state ``(nstate,)``; it replaces ``states[0]``.
        states: State guess ``(T + 1, nstate)``.
        ctrls: Control guess ``(T, nu)``, within the bounds.
        iters: Iteration cap of the whole solve.
        reg: Initial regularization.
        max_retries: Regularization increases allowed per iteration (default the config's
            ``max_retries``).

    Returns:
        An :class:`~mpcbox.controllers.ilqr.result.ILQRResult` whose ``defect`` is the
        largest remaining defect (0 once closed); ``converged`` is false while it is above
        ``defect_tolerance``.
    """
    cfg, p = solver.config, solver.problem
    max_retries = cfg.max_retries if max_retries is None else max_retries
    t_start = _time.perf_counter()
    t_der = t_back = t_roll = 0.0
    roll = GappedRollout(p, solver.ctrl_low, solver.ctrl_high)
    states = states.copy()
    states[0] = x0
    t0 = _time.perf_counter()
    gaps, cost = roll.defects(states, ctrls)
    t_roll += _time.perf_counter() - t0
    costs = [cost]
    defect = float(np.max(np.abs(gaps))) if gaps.size else 0.0
    k = np.zeros((solver.horizon, p.nu))
    K = np.zeros((solver.horizon, p.nu, p.nx))
    iteration = divergences = 0
    mu = solver._schedule(reg)
    reason, status = StopReason.ITERATION_LIMIT, "iteration limit (defects open)"
    while defect > cfg.defect_tolerance and iteration < iters and np.isfinite(cost):
        t0 = _time.perf_counter()
        lin, quad = solver._derivatives(states, ctrls)
        blocks = solver._blocks(lin)
        t_der += _time.perf_counter() - t0
        iteration += 1
        candidate, retries = None, 0
        while candidate is None:
            t0 = _time.perf_counter()
            try:
                bp = backward_pass(
                    lin,
                    quad,
                    ctrls,
                    solver.ctrl_low,
                    solver.ctrl_high,
                    mu.value,
                    k,
                    gaps,
                    blocks,
                    solver.riccati_cache,
                )
            except SolverError:
                bp = None
            t_back += _time.perf_counter() - t0
            if bp is not None:
                k, K = bp.k, bp.K
                t0 = _time.perf_counter()
                for alpha in cfg.step_sizes:
                    new = roll.gapped(x0, states, ctrls, gaps, k, K, alpha)
                    if np.isfinite(new[2]):
                        candidate = (new, alpha)
                        break
                    divergences += 1
                t_roll += _time.perf_counter() - t0
            if candidate is None:
                mu.increase()
                retries += 1
                if mu.value > cfg.regularization_max or retries > max_retries:
                    reason = solver._stall_reason(mu.value, diverged=bp is not None)
                    status = f"{reason.value} (defects open)"
                    break
        if candidate is None:
            break
        (states, ctrls, cost), alpha = candidate
        costs.append(cost)
        gaps = (1.0 - alpha) * gaps if alpha < 1.0 else np.zeros_like(gaps)
        defect = float(np.max(np.abs(gaps))) if gaps.size else 0.0
        mu.accepted(alpha, feasible=False)
    elapsed = Timing(t_der, t_back, t_roll, _time.perf_counter() - t_start)
    if defect > cfg.defect_tolerance or not np.isfinite(cost):
        return ILQRResult(
            states=states,
            ctrls=ctrls,
            k=k,
            K=K,
            cost=float(cost),
            costs=np.asarray(costs),
            iterations=iteration,
            converged=False,
            regularization=float(mu.value),
            divergences=divergences,
            timing=elapsed,
            status=f"{status}: largest defect {defect:.3g} > {cfg.defect_tolerance:g}",
            stop_reason=reason,
            defect=defect,
            start="states",
        )
    # Feasible: its controls roll out to its states; continue as single shooting.
    rest = solver._optimize(x0, ctrls, iters - iteration, mu, k, max_retries)
    timing = Timing(*(a + b for a, b in zip(elapsed, rest.timing)))
    return rest._replace(
        costs=np.r_[costs[:-1], rest.costs] if iteration else rest.costs,
        iterations=rest.iterations + iteration,
        divergences=rest.divergences + divergences,
        timing=timing,
        start="states",
    )


__all__ = ["GappedRollout", "optimize_multiple_shooting", "straight_line_states"]
