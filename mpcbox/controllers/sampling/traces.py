r"""Traces of a sampling controller's best rollouts, for viewers.

After a tick, :class:`TraceRecorder` takes the candidates of the tick's last iteration and
their aggregated costs :math:`J_n`, keeps the ``k`` lowest (finite) ones, and re-rolls them
from the tick's state on the CPU with :meth:`Problem.rollout <mpcbox.Problem.rollout>` on
the nominal planning model. Neither backend keeps the states of its rollouts (the warp
backend reads back only costs), so the re-roll is what makes the traces; it is the same
dynamics the CPU backend scored, and the warp backend's up to float32 rounding.

For each of the ``T + 1`` states of a re-rolled candidate, :func:`mujoco.mj_kinematics`
places the target (a site, or a body's frame origin) in the world:

.. math:: p^{(i)}_t = \operatorname{pos}(q^{(i)}_t), \qquad i = 1..k, \quad t = 0..T,

with :math:`p^{(i)}_0` the target's position in the tick's state.

Cost per tick: ``k`` rollouts of ``T`` planning steps on the CPU plus ``k (T + 1)``
kinematics passes (2.9 ms for ``k = 8``, ``T = 50`` on the cart-pole on a shared 2-core CPU,
``benchmarks/viewer_traces.py``; the rollouts dominate on larger models). Nothing runs while
no recorder is set.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import positive_int


class PlannerTrace(NamedTuple):
    """The best rollouts of one tick, as paths of one point of the model.

    Attributes:
        time: Simulated time of the tick's state (s).
        times: Times of the trace points ``(T + 1,)`` (s): ``time + t * dt`` with the
            planning timestep ``dt``.
        positions: World positions of the target ``(k, T + 1, 3)``, best candidate first;
            NaN from where a rollout diverged.
        costs: Aggregated costs of those candidates ``(k,)``, ascending.
        target: The traced point, ``"site:NAME"`` or ``"body:NAME"``.
    """

    time: float
    times: np.ndarray
    positions: np.ndarray
    costs: np.ndarray
    target: str


def default_target(model: mujoco.MjModel) -> tuple[str, int]:
    """The point traced when none is named: the model's last site, or else its last body.

    Returns:
        ``("site", id)`` or ``("body", id)``.
    """
    if model.nsite > 0:
        return "site", model.nsite - 1
    return "body", model.nbody - 1


class TraceRecorder:
    """Makes a :class:`PlannerTrace` from a tick's scored candidates.

    Args:
        problem: The controller's (planning) Problem.
        count: How many of the lowest-cost candidates to trace (``k >= 1``).
        site: A site to trace, by name or id.
        body: A body whose frame origin to trace, by name or id (not with ``site``).
        policy: The controller's rollout feedback (its catch), so the traces are the paths
            the planner scored; ``None``: open-loop rollouts.

    Attributes:
        rollouts: Candidates re-rolled so far (``k`` per recorded tick).

    Raises:
        InvalidArgumentError: For ``count < 1`` or both ``site`` and ``body``.
        UnknownNameError: For a site or body the planning model does not have.
    """

    def __init__(
        self,
        problem: Problem,
        count: int,
        *,
        site: str | int | None = None,
        body: str | int | None = None,
        policy: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.problem = problem
        self.policy = policy
        self.count = positive_int("count", count)
        model = problem.planning_model
        if site is not None and body is not None:
            raise InvalidArgumentError("trace a site or a body, not both: give site= or body=")
        if site is not None:
            kind, index = "site", object_id(model, "site", site, "site")
        elif body is not None:
            kind, index = "body", object_id(model, "body", body, "body")
        else:
            kind, index = default_target(model)
        name = mujoco.mj_id2name(model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), index)
        self.kind, self.index = kind, index
        self.target = f"{kind}:{name if name else index}"
        self.data = mujoco.MjData(model)
        self.rollouts = 0

    def record(
        self,
        time: float,
        state: np.ndarray,
        candidates: np.ndarray,
        costs: np.ndarray,
        weights: np.ndarray,
    ) -> PlannerTrace | None:
        """The trace of one tick, or ``None`` when no candidate has a finite cost.

        Args:
            time: Simulated time of the tick (s).
            state: The tick's state ``(nstate,)``.
            candidates: Clamped candidate knots ``(N, K, nu)`` of the last iteration.
            costs: Their aggregated costs ``(N,)`` (``+inf`` for excluded ones).
            weights: Interpolation matrix ``(T, K)`` from knots to planning steps.
        """
        finite = np.flatnonzero(np.isfinite(costs))
        if finite.size == 0:
            return None
        order = finite[np.argsort(costs[finite], kind="stable")][: self.count]
        ctrls = np.einsum("tk,nkj->ntj", weights, candidates[order])
        if self.policy is None:
            rollout = self.problem.rollout(state, ctrls)
        else:  # the paths the planner scored: through its catch
            ctrls = self.problem.clip_ctrl(ctrls)
            rollout = self.problem.dynamics.rollout_policy(state, ctrls, self.policy)
        self.rollouts += len(order)
        steps = ctrls.shape[1]
        return PlannerTrace(
            time=float(time),
            times=float(time) + np.arange(steps + 1) * self.problem.dt,
            positions=self.positions(rollout.states),
            costs=np.asarray(costs[order], dtype=np.float64),
            target=self.target,
        )

    def positions(self, states: np.ndarray) -> np.ndarray:
        """World positions ``(..., 3)`` of the target in states ``(..., nstate)``."""
        model, data = self.problem.planning_model, self.data
        nq = model.nq
        flat = states.reshape(-1, states.shape[-1])
        out = np.full((flat.shape[0], 3), np.nan)
        table = data.site_xpos if self.kind == "site" else data.xpos
        for i, x in enumerate(flat):
            if not np.all(np.isfinite(x[:nq])):
                continue
            data.qpos[:] = x[:nq]
            mujoco.mj_kinematics(model, data)
            out[i] = table[self.index]
        return out.reshape(*states.shape[:-1], 3)


__all__ = ["PlannerTrace", "TraceRecorder", "default_target"]
