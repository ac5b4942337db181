"""Robustness measures of a controller: survival over seeds and the largest survived push."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from mpcbox.controller import Controller
from mpcbox.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.errors import InvalidArgumentError
from mpcbox.problem import Problem
from mpcbox.simulation import simulate
from mpcbox.validation import as_array, positive


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


class PushLimit(NamedTuple):
    """Largest survived push found by bisection.

    Attributes:
        force: Largest force magnitude that was survived (N).
        impulse: ``force * duration`` (N s).
        smallest_failed: Smallest force that was not survived (N), ``inf`` if none failed.
        simulations: Number of simulations run.
    """

    force: float
    impulse: float
    smallest_failed: float
    simulations: int


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
    seeds = np.asarray(list(seeds), dtype=int)
    if seeds.size == 0:
        raise InvalidArgumentError("seeds must hold at least one seed")
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
        survived.append(res.metrics.survived)
        times.append(res.metrics.time_to_fall)
    surv, t = np.array(survived), np.array(times)
    return SurvivalSummary(seeds, surv, t, float(surv.mean()), float(t.mean()))


def largest_push(
    problem: Problem,
    controller: Controller,
    *,
    direction: Sequence[float] = (1.0, 0.0, 0.0),
    push_duration: float = 0.1,
    start: float = 1.0,
    settle: float = 4.0,
    body: str = "torso",
    max_force: float = 2000.0,
    tolerance: float = 1.0,
    noise: ActuatorNoise | None = None,
    seed: int = 0,
) -> PushLimit:
    """Largest force magnitude along ``direction`` over ``push_duration`` that is survived.

    Bisection on the magnitude, assuming that surviving a force means surviving every
    smaller one. Each trial simulates until ``start + push_duration + settle``.

    Args:
        problem: The Problem.
        controller: The controller.
        direction: Push direction (normalized here); ``(1, 0, 0)`` is sagittal (forward).
        push_duration: How long the force acts (s).
        start: When the push starts (s).
        settle: How long after the push the robot must stay up (s).
        body: Pushed body.
        max_force: Upper end of the search (N).
        tolerance: Stop when the bracket is this narrow (N).
        noise: Optional actuator noise during the trials.
        seed: Noise seed.
    """
    direction = as_array("direction", direction, (3,))
    norm = np.linalg.norm(direction)
    if norm == 0:
        raise InvalidArgumentError("direction must be a non-zero vector")
    direction = direction / norm
    positive("max_force", max_force)
    positive("tolerance", tolerance)
    total = start + positive("push_duration", push_duration) + positive("settle", settle)
    count = 0

    def survives(force: float) -> bool:
        nonlocal count
        count += 1
        push = Push(force=force * direction, start=start, duration=push_duration, body=body)
        return simulate(problem, controller, total, noise=noise, pushes=[push], seed=seed).survived

    if not survives(0.0):
        return PushLimit(0.0, 0.0, 0.0, count)
    if survives(max_force):
        return PushLimit(max_force, max_force * push_duration, float("inf"), count)
    lo, hi = 0.0, max_force
    while hi - lo > tolerance:
        mid = 0.5 * (lo + hi)
        if survives(mid):
            lo = mid
        else:
            hi = mid
    return PushLimit(lo, lo * push_duration, hi, count)
