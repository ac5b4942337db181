r"""Plan once offline by multi-start iLQR from the first measured state, then track the plan.

On its first call (after :meth:`~OfflinePlanTracker.reset`) the controller runs
:class:`~mpcbox.controllers.ilqr.solver.ILQRSolver` from the measured state :math:`x_0` once
per control guess :math:`U^{(g)}` ``(T, nu)`` and keeps the plan of lowest score
:math:`s(\cdot)` (default: the plan's total cost)

.. math:: g^\star = \arg\min_g s\big(\mathrm{iLQR}(x_0, U^{(g)})\big).

The kept plan's controls, each held for one planning step :math:`\Delta t`, are repeated on
the simulation grid (:math:`r = \Delta t / \delta t` steps of the simulation timestep
:math:`\delta t`). The coarser model's plan drifts on the finer grid (an unstable swing
amplifies the discretization error), so with ``polish_iterations`` the plan is first
re-solved on the simulation grid by that many iterations of multiple shooting from its own
states (linearly interpolated) and controls. The controls are rolled out from :math:`x_0`
on the planning model at :math:`\delta t` (the simulated model itself when the Problem
plans in its integrator) and tracked by
time-varying LQR along that rollout
(:func:`~mpcbox.controllers.trajectory.reference.tracking_reference` with the plan's own
controls, :class:`~mpcbox.controllers.trajectory.tracker.TrajectoryTracker`), which holds
the final knot once the plan has ended. The solve call reports ``last_call = "offline"``,
the tracking calls ``"hold"``.

To end the plan where a regulator about the Problem's reference takes over, a second
re-solve on the simulation grid (``refine_iterations``) can start from the rollout of the
first with other solver options (``refine_options``, e.g. ``terminal_value="lqr"``: the
reference's LQR value as terminal cost) on the whole-turn copy of the plan nearest the
reference (``wrap``: each unlimited hinge's angles shifted by
:math:`2\pi\,\mathrm{round}((q_{j,T} - q_j^{ref}) / 2\pi)`, the plan's final angle
:math:`q_{j,T}`; such a shift leaves the dynamics unchanged); the tracking gains' recursion
can start from a given terminal weight (``terminal``: the regulator's Riccati matrix, so the
last gains are nearly its gain).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.ilqr.result import ILQRResult
from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.controllers.lqr import unlimited_hinges
from mpcbox.controllers.trajectory.reference import TrackingWeights, tracking_reference
from mpcbox.controllers.trajectory.tracker import TrajectoryTracker
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import as_array, boolean, finite, finite_array, integer, positive

#: Scores a plan; lower is better.
PlanScore = Callable[[ILQRResult], float]


class OfflinePlanTracker(Controller):
    """Multi-start iLQR plan from the first measured state, tracked by time-varying LQR.

    Args:
        problem: The Problem whose cost and planning model (timestep ``problem.dt``) the
            plan optimizes; ``problem.dt`` must be a whole multiple of the simulation
            timestep.
        guesses: Control guesses, each ``(T, nu)``; ``T`` is the plan's horizon in knots.
        solver_options: Fields of :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` for
            the solver (``horizon`` is taken from the guesses).
        score: Ranks the plans (default: their total cost).
        polish_iterations: Iterations of the re-solve on the simulation grid (0: none).
        weights: Tracking weights (default
            :class:`~mpcbox.controllers.trajectory.reference.TrackingWeights`).
        refine_iterations: Iterations of the second re-solve (0: none).
        refine_options: :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` fields that
            replace ``solver_options`` in the second re-solve (e.g.
            ``{"terminal_value": "lqr"}``).
        wrap: Run the second re-solve on the whole-turn copy of the plan nearest the
            reference (module docstring); the tracked plan stays in the measured angles.
        terminal: Terminal weight ``(nx, nx)`` of the tracking gains' Riccati recursion
            (default: the tracking state weight).
        period: Seconds between calls it declares: ``None`` or the simulation timestep
            (it is called every step either way), so that it pairs in a
            :class:`~mpcbox.controllers.handover.HandOver` with a controller that states
            that period (e.g. an :class:`~mpcbox.controllers.lqr.LQR` at that step).
        name: Label in tables.

    Attributes:
        plans: The solves of the last planning call, one per guess.
        best: Index of the kept plan in :attr:`plans`.
        tracker: The tracker along the kept plan (``None`` before the first call).
        plan_seconds: Wall-clock time of the last planning call (s).

    Raises:
        InvalidTypeError: If ``problem`` is not a Problem or ``score`` not callable.
        InvalidArgumentError: For no guesses, guesses of different lengths, a planning
            step that is not a whole number of simulation steps, or a ``period`` other than
            the simulation timestep.
        ShapeError: If a guess is not ``(T, nu)`` or ``terminal`` not ``(nx, nx)``.
    """

    name = "offline-plan"
    period = None

    def __init__(
        self,
        problem: Problem,
        guesses: Sequence[np.ndarray],
        *,
        solver_options: Mapping[str, Any] | None = None,
        score: PlanScore | None = None,
        polish_iterations: int = 0,
        weights: TrackingWeights | None = None,
        refine_iterations: int = 0,
        refine_options: Mapping[str, Any] | None = None,
        wrap: bool = False,
        terminal: np.ndarray | None = None,
        period: float | None = None,
        name: str = "offline-plan",
    ) -> None:
        problem = check_problem(problem, type(self).__name__)
        if len(guesses) == 0:
            raise InvalidArgumentError("guesses must hold at least one control guess (T, nu)")
        first = finite_array("guesses[0]", guesses[0], (None, problem.nu))
        self.guesses = [
            finite_array(f"guesses[{i}]", g, first.shape) for i, g in enumerate(guesses)
        ]
        if score is not None and not callable(score):
            raise InvalidTypeError(f"score must be callable, got {type(score).__name__}")
        ratio = problem.dt / problem.model.opt.timestep
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise InvalidArgumentError(
                f"problem: the planning step {problem.dt} s must be a whole multiple of the "
                f"simulation timestep {problem.model.opt.timestep} s"
            )
        options = {"threads": 1, **dict(solver_options or {}), "horizon": first.shape[0]}
        if options.get("control_steps", 1) != 1:
            raise InvalidArgumentError(
                "solver_options: control_steps must be 1 here (the plan is re-solved and "
                f"tracked per planning step), got {options['control_steps']}"
            )
        self.solver = ILQRSolver(problem, **options)
        self.problem = self.solver.problem
        self.substeps = round(ratio)
        self.track_problem = (
            self.problem
            if self.substeps == 1
            else self.problem.with_planning_timestep(problem.model.opt.timestep)
        )
        self.score: PlanScore = (lambda result: float(result.cost)) if score is None else score
        self.polish_iterations = integer("polish_iterations", polish_iterations)
        fine_options = {**options, "horizon": first.shape[0] * self.substeps}
        self.polisher = (
            ILQRSolver(self.track_problem, **fine_options)
            if self.polish_iterations > 0 and self.substeps > 1
            else None
        )
        self.refine_iterations = integer("refine_iterations", refine_iterations)
        self.refiner = (
            ILQRSolver(self.track_problem, **{**fine_options, **dict(refine_options or {})})
            if self.refine_iterations > 0
            else None
        )
        self.weights = TrackingWeights() if weights is None else weights
        self.wrap = boolean("wrap", wrap)
        nx = self.problem.nx
        self.terminal = None if terminal is None else finite_array("terminal", terminal, (nx, nx))
        step = problem.model.opt.timestep
        if period is not None and abs(positive("period", period) - step) > 1e-12:
            raise InvalidArgumentError(
                f"period must be None or the simulation timestep {step} s (the plan is tracked "
                f"every step), got {period}"
            )
        self.period = period
        self.name = str(name)
        self.reset()

    def reset(self) -> None:
        """Forget the plan; the next call plans again from its state."""
        self.plans: list[ILQRResult] = []
        self.best = -1
        self.tracker: TrajectoryTracker | None = None
        self.plan_seconds = 0.0
        self._plan_time = 0.0
        self._last_time = 0.0
        self.last_call = "offline"

    @property
    def duration(self) -> float:
        """Length of the plan (s)."""
        return self.solver.horizon * self.problem.dt

    @property
    def stats(self) -> dict[str, float]:
        """The kept plan's index, score and cost, and the planning wall-clock time (s)."""
        if self.best < 0:
            return {}
        plan = self.plans[self.best]
        return {
            "plan_guess": float(self.best),
            "plan_score": float(self.score(plan)),
            "plan_cost": float(plan.cost),
            "plan_seconds": self.plan_seconds,
        }

    def plan(self, state: np.ndarray) -> ILQRResult:
        """Solve from ``state`` from every guess, keep the best and build its tracker.

        Args:
            state: Start state ``(nstate,)``.

        Returns:
            The kept plan (on the planning grid).
        """
        state = as_array("state", state, (self.problem.nstate,))
        wall = _time.perf_counter()
        self.plans = [self.solver.solve(state, guess) for guess in self.guesses]
        self.best = int(np.argmin([self.score(plan) for plan in self.plans]))
        kept = self.plans[self.best]
        fine = np.repeat(kept.ctrls, self.substeps, axis=0)
        if self.polisher is not None:
            grid = np.arange(fine.shape[0] + 1) / self.substeps
            guess = np.stack(
                [np.interp(grid, np.arange(kept.states.shape[0]), s) for s in kept.states.T], 1
            )
            polished = self.polisher.solve(
                state, fine, states_init=guess, max_iterations=self.polish_iterations
            )
            fine = polished.ctrls
        states = self.track_problem.rollout(state, fine).states[0]
        if self.refiner is not None:
            shift = self.turns(states[-1]) if self.wrap else np.zeros_like(state)
            refined = self.refiner.solve(
                state - shift,
                fine,
                states_init=states - shift,
                max_iterations=self.refine_iterations,
            )
            fine = refined.ctrls
            states = self.track_problem.rollout(state, fine).states[0]
        ctrls = np.vstack([fine, fine[-1:]])
        reference = tracking_reference(
            self.track_problem, states, self.weights, ctrls=ctrls, terminal=self.terminal
        )
        self.tracker = TrajectoryTracker(self.track_problem, reference, name=self.name)
        self.plan_seconds = _time.perf_counter() - wall
        return kept

    def turns(self, state: np.ndarray) -> np.ndarray:
        """Whole turns ``(nstate,)`` by which each unlimited hinge angle of ``state``
        ``(nstate,)`` is off the Problem's reference (zero elsewhere): ``state`` minus this is
        the copy of ``state`` nearest the reference."""
        model, out = self.problem.model, np.zeros(self.problem.nstate)
        address = model.jnt_qposadr[unlimited_hinges(model)]
        offset = state[address] - self.problem.qpos_ref[address]
        out[address] = 2.0 * np.pi * np.round(offset / (2.0 * np.pi))
        return out

    def ctrls_ahead(self, knots: int, dt: float) -> np.ndarray:
        """The plan's controls ``(knots, nu)`` at ``dt``-spaced times from the last call on,
        ``ctrl_ref`` after the plan ends: a warm start for a controller taking over.

        Raises:
            InvalidArgumentError: Before the plan is made.
        """
        if self.tracker is None:
            raise InvalidArgumentError("ctrls_ahead: no plan yet (call the controller first)")
        reference, p = self.tracker.reference, self.track_problem
        times = self._last_time - self._plan_time + positive("dt", dt) * np.arange(knots)
        index = np.floor(times / p.dt + 1e-9).astype(int)
        out = np.tile(p.clip_ctrl(p.ctrl_ref), (knots, 1))
        inside = index < reference.time.size - 1
        out[inside] = reference.ctrls[index[inside]]
        return out

    @property
    def finished(self) -> bool:
        """Whether the plan had ended at the last call (``False`` before it is made)."""
        end = self._plan_time + self.duration - 1e-9
        return self.tracker is not None and self._last_time >= end

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        time = finite("time", time)
        if self.tracker is None or time < self._plan_time - 1e-9:
            self.plan(state)
            self._plan_time = float(time)
            self.last_call = "offline"
        else:
            self.last_call = "hold"
        assert self.tracker is not None
        self._last_time = float(time)
        return self.tracker(state, time - self._plan_time)


__all__ = ["OfflinePlanTracker", "PlanScore"]
