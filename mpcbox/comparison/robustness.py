"""Robustness of a controller, in this process: survival over seeds, the largest survived
push, and survival over a grid of push forces (which shows whether survival is monotone in
the force). :mod:`mpcbox.comparison.push_limits` is the public API, which also spreads the
runs over an executor (worker processes, a Ray cluster).

The pushes are described by :class:`~mpcbox.comparison.scenario.PushTest`, the same object
that :func:`mpcbox.compare` takes. A run "survives" here when its outcome is ``"success"``
(:data:`mpcbox.sim.simulation.OUTCOMES`): a run that diverged, or whose controller fell back
on most calls, does not count, whatever the state at the end. A push trial with
``PushTest.rest_speed`` must also end with the pushed body slower than that.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.comparison.scenario import PushTest, task_noise
from mpcbox.controllers.base import Controller
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.disturbances import MAX_FORCE, ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.simulation import SimulationResult, simulate
from mpcbox.validation import (
    checked_keywords,
    instance,
    number,
    positive,
)
from mpcbox.validation import seed as check_seed
from mpcbox.validation import seeds as check_seeds

#: The push test used when none is given (every :class:`PushTest` default).
DEFAULT_PUSH = PushTest()


class SurvivalSummary(NamedTuple):
    """Survival over seeds.

    Attributes:
        seeds: The seeds ``(n,)``.
        survived: Whether each run survived ``(n,)``.
        time_to_fall: Failure time, or the duration, per run ``(n,)`` (s).
        rate: Fraction of runs that survived.
        mean_time: Mean of ``time_to_fall`` (s).
    """

    seeds: np.ndarray
    survived: np.ndarray
    time_to_fall: np.ndarray
    rate: float
    mean_time: float


class PushGrid(NamedTuple):
    """Survival of one push at each force of a grid.

    Attributes:
        forces: The force magnitudes, increasing ``(n,)`` (N).
        survived: Whether each push was survived ``(n,)``.
        time_to_fall: Failure time, or the trial's duration, per force ``(n,)`` (s).
        limit: Largest grid force below which every grid force is survived (N): the last
            force before the first failure, ``0`` when the smallest force already fails.
        largest_survived: Largest grid force survived (N), ``0`` when none is.
        monotone: No force is survived above a failed one (the bisection of
            :func:`largest_push` is only meaningful when this holds).
    """

    forces: np.ndarray
    survived: np.ndarray
    time_to_fall: np.ndarray
    limit: float
    largest_survived: float
    monotone: bool


class PushLimit(NamedTuple):
    """Largest survived push found by bisection.

    Attributes:
        force: Largest force magnitude that was survived (N).
        impulse: ``force * duration`` (N s).
        smallest_failed: Smallest force that was not survived (N), ``inf`` if none failed.
        simulations: Number of simulations run.
        failure: Why the search raised (the error's type and text; the numbers are then
            NaN), or ``None``.
        travel: How far (m) the pushed body's centre of mass moved horizontally from the
            push's start to the end of the trial at ``force`` (:func:`travel`): a recovery
            by steps, hops or sliding on the feet shows here. NaN when no push was
            survived.
    """

    force: float
    impulse: float
    smallest_failed: float
    simulations: int
    failure: str | None = None
    travel: float = float("nan")


@checked_keywords
def survival(
    problem: Problem,
    controller: Controller,
    *,
    seeds: Sequence[int],
    duration: float,
    noise: ActuatorNoise | None = None,
    pushes: Sequence[Push] = (),
    mismatch: ModelMismatch | None = None,
    progress: bool = False,
) -> SurvivalSummary:
    """Run one simulation per seed and summarize survival.

    Args:
        problem: The Problem.
        controller: The controller (reset before each run).
        seeds: Noise seeds.
        duration: Simulated time per run (s).
        noise: Actuator noise (seeded per run).
        pushes: Pushes applied in every run.
        mismatch: Model mismatch applied in every run.
        progress: Show a progress bar.
    """
    _check_runner(problem, controller)
    seeds = np.asarray(check_seeds("seeds", seeds), dtype=int)
    positive("duration", duration)
    iterator = seeds
    if progress:
        from tqdm import tqdm

        iterator = tqdm(seeds, desc=f"{getattr(controller, 'name', 'controller')} survival")
    survived, times = [], []
    for seed in iterator:
        res = simulate(
            problem,
            controller,
            duration,
            noise=noise,
            pushes=pushes,
            mismatch=mismatch,
            seed=int(seed),
        )
        survived.append(res.metrics.success)
        times.append(res.metrics.time_to_fall)
    surv, t = np.array(survived), np.array(times)
    return SurvivalSummary(seeds, surv, t, float(surv.mean()), float(t.mean()))


def _check_runner(problem: object, controller: object) -> None:
    """``problem`` must be a Problem and ``controller`` a Controller (or a callable)."""
    instance("problem", problem, Problem, "an mpcbox.Problem")
    if not (isinstance(controller, Controller) or callable(controller)):
        raise InvalidTypeError(
            f"controller must be an mpcbox.Controller, got {type(controller).__name__}"
        )


def _push_trial(
    problem: Problem, controller: Controller, test: PushTest, seed: int
) -> Callable[[float], SimulationResult]:
    """``trial(force) -> SimulationResult`` for the push of ``test`` at a force magnitude."""
    _check_runner(problem, controller)
    instance("test", test, PushTest, "an mpcbox.comparison.scenario.PushTest")
    seed = check_seed("seed", seed)
    noise = task_noise(problem, test.noise_scale)

    def trial(force: float) -> SimulationResult:
        return simulate(
            problem, controller, test.total_time, noise=noise, pushes=[test.push(force)], seed=seed
        )

    return trial


def end_speed(problem: Problem, result: SimulationResult, body: str) -> float:
    """Linear speed (m/s) of ``body``'s centre of mass at the last state of ``result``."""
    model = problem.model
    data = mujoco.MjData(model)
    problem.set_state(data, result.states[-1])
    mujoco.mj_forward(model, data)
    velocity = np.zeros(6)  # angular, then linear
    mujoco.mj_objectVelocity(
        model, data, mujoco.mjtObj.mjOBJ_BODY, object_id(model, "body", body, "body"), velocity, 0
    )
    return float(np.linalg.norm(velocity[3:]))


def travel(problem: Problem, result: SimulationResult, body: str, start: float) -> float:
    """Horizontal distance (m) between ``body``'s centre of mass at time ``start`` (the last
    recorded state before it) and at the last state of ``result``."""
    model = problem.model
    data = mujoco.MjData(model)
    bid = object_id(model, "body", body, "body")
    index = max(int(np.searchsorted(result.time, start, side="right")) - 1, 0)
    points = []
    for state in (result.states[index], result.states[-1]):
        problem.set_state(data, state)
        mujoco.mj_kinematics(model, data)
        points.append(data.xipos[bid, :2].copy())
    return float(np.linalg.norm(points[1] - points[0]))


def recovered(problem: Problem, test: PushTest, result: SimulationResult) -> bool:
    """Whether a push trial counts as survived: outcome ``"success"`` and, with
    ``test.rest_speed``, the pushed body at most that fast at the end."""
    if not result.metrics.success:
        return False
    return test.rest_speed is None or end_speed(problem, result, test.body) <= test.rest_speed


@checked_keywords
def push_grid(
    problem: Problem,
    controller: Controller,
    forces: Sequence[float],
    test: PushTest = DEFAULT_PUSH,
    *,
    seed: int = 0,
    progress: bool = False,
) -> PushGrid:
    """Survival of the push of ``test`` at every force of a grid (its search settings unused).

    Unlike the bisection of :func:`largest_push`, the grid shows when survival is not
    monotone in the force (a controller that falls at 60 N and survives 100 N);
    :attr:`PushGrid.limit` is then the honest figure, the largest force below which nothing
    failed.

    Args:
        problem: The Problem.
        controller: The controller (reset by each simulation).
        forces: Force magnitudes, at least one, in ``[0, MAX_FORCE]`` (N); sorted here.
        test: The push (direction, duration, start, settle, body) and the trials' noise.
        seed: Noise seed.
        progress: Show a progress bar.
    """
    trial = _push_trial(problem, controller, test, seed)
    if isinstance(forces, (str, bytes)) or not isinstance(forces, Sequence | np.ndarray):
        raise InvalidTypeError(f"forces must be a sequence of numbers, got {type(forces).__name__}")
    grid = np.sort(np.array([number("forces", f) for f in np.ravel(forces)], dtype=float))
    if grid.size == 0 or not np.all((grid >= 0) & (grid <= MAX_FORCE)):
        raise InvalidArgumentError(
            f"forces must hold at least one force in [0, {MAX_FORCE:g}] N, got {list(forces)!r}"
        )
    iterator = grid
    if progress:
        from tqdm import tqdm

        iterator = tqdm(grid, desc=f"{getattr(controller, 'name', 'controller')} push grid")
    results = [trial(float(f)) for f in iterator]
    survived = np.array([recovered(problem, test, r) for r in results], dtype=bool)
    times = np.array([r.metrics.time_to_fall for r in results])
    return summarize_push_grid(grid, survived, times)


def summarize_push_grid(
    forces: np.ndarray, survived: np.ndarray, time_to_fall: np.ndarray | None = None
) -> PushGrid:
    """:class:`PushGrid` of survival outcomes at increasing ``forces`` ``(n,)``.

    Args:
        forces: Increasing force magnitudes ``(n,)`` (N).
        survived: Outcome per force ``(n,)``.
        time_to_fall: Failure time per force ``(n,)`` (s); NaN when not given.
    """
    forces = np.asarray(forces, dtype=float)
    survived = np.asarray(survived, dtype=bool)
    if forces.ndim != 1 or survived.shape != forces.shape:
        raise InvalidArgumentError(
            f"forces and survived must be 1-D of one length, got {forces.shape} and "
            f"{survived.shape}"
        )
    if np.any(np.diff(forces) <= 0):
        raise InvalidArgumentError("forces must be strictly increasing")
    times = (
        np.full(forces.shape, np.nan) if time_to_fall is None else np.asarray(time_to_fall, float)
    )
    failed = np.flatnonzero(~survived)
    first_fail = failed[0] if failed.size else forces.size
    limit = float(forces[first_fail - 1]) if first_fail > 0 else 0.0
    largest = float(forces[survived].max()) if survived.any() else 0.0
    monotone = not bool(survived[first_fail:].any())
    return PushGrid(forces, survived, times, limit, largest, monotone)


@checked_keywords
def largest_push(
    problem: Problem, controller: Controller, test: PushTest = DEFAULT_PUSH, *, seed: int = 0
) -> PushLimit:
    """Largest force magnitude of the push of ``test`` that is survived.

    Bisection on the magnitude over ``[0, test.max_force]`` until the bracket is narrower
    than ``test.tolerance``, assuming that surviving a force means surviving every smaller
    one; :func:`push_grid` checks that assumption, and ``test.scan_step`` walks up to the
    first failure before bisecting below it. Each trial simulates ``test.total_time``
    seconds.

    Args:
        problem: The Problem.
        controller: The controller.
        test: The push, the search settings and the trials' noise
            (:class:`~mpcbox.comparison.scenario.PushTest`).
        seed: Noise seed.
    """
    trial = _push_trial(problem, controller, test, seed)
    max_force, count = test.max_force, 0
    last: SimulationResult | None = None  # the last survived trial: the largest force so far

    def survives(force: float) -> bool:
        nonlocal count, last
        count += 1
        result = trial(force)
        if not recovered(problem, test, result):
            return False
        last = result
        return True

    def moved() -> float:
        assert last is not None  # the push of 0 N was survived
        return travel(problem, last, test.body, test.start)

    if not survives(0.0):
        return PushLimit(0.0, 0.0, 0.0, count)
    lo, hi = 0.0, max_force
    # With scan_step, walk up to the first failure (test.scan_step's docstring).
    while test.scan_step is not None and lo + test.scan_step < max_force:
        if not survives(lo + test.scan_step):
            hi = lo + test.scan_step
            break
        lo += test.scan_step
    if hi == max_force and survives(max_force):
        limit = PushLimit(max_force, max_force * test.duration, float("inf"), count)
        return limit._replace(travel=moved())
    while hi - lo > test.tolerance:
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:  # the bracket is at float resolution: a smaller tolerance
            break  # cannot be met, and the loop would never end
        if survives(mid):
            lo = mid
        else:
            hi = mid
    return PushLimit(lo, lo * test.duration, hi, count, travel=moved())
