"""Robustness of a controller: survival over seeds, the largest survived push, and survival
over a grid of push forces (which shows whether survival is monotone in the force).

The pushes are described by :class:`~mpcbox.comparison.scenario.PushTest`, the same object
that :func:`mpcbox.compare` takes. A run "survives" here when its outcome is ``"success"``
(:data:`mpcbox.sim.simulation.OUTCOMES`): a run that diverged, or whose controller fell back
on most calls, does not count, whatever the state at the end.

Each sweep runs in this process by default. Given the problem as a task name
(:data:`mpcbox.registry.TASKS`, with ``problem_options``) and the controller as a name or a
module-level factory ``problem -> Controller``, it can also spread its closed loops over an
``executor`` (``"processes"``, ``"ray"`` or an
:class:`~mpcbox.comparison.executors.Executor`): each run becomes a
:class:`~mpcbox.comparison.jobs.Job` of a :class:`~mpcbox.comparison.jobs.Setup`, exactly as
in :func:`mpcbox.compare`, so the results equal the serial ones (a run depends only on its
controller, scenario and seed). The bisection of :func:`largest_push` is sequential: an
executor runs the whole search as one job (on a GPU worker, say).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from mpcbox.comparison import robustness as _here
from mpcbox.comparison.executors import Executor
from mpcbox.comparison.jobs import Done, Job, Setup, picklable
from mpcbox.comparison.robustness import (
    DEFAULT_PUSH,
    PushGrid,
    PushLimit,
    SurvivalSummary,
    summarize_push_grid,
)
from mpcbox.comparison.runner import ControllerSpec, pick_executor, resolve_controllers
from mpcbox.comparison.scenario import PushTest, Scenario, check_noise_models
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, RunError, UnknownNameError
from mpcbox.registry import TASKS, task_class
from mpcbox.sim.disturbances import MAX_FORCE, ActuatorNoise, ModelMismatch, Push
from mpcbox.validation import (
    checked_keywords,
    instance,
    number,
    positive,
)
from mpcbox.validation import seed as check_seed
from mpcbox.validation import seeds as check_seeds


def _local(problem: object, controller: object, executor: object) -> bool:
    """Whether the sweep runs in this process the classic way (no executor, built objects)."""
    return executor is None and isinstance(problem, Problem) and not isinstance(controller, str)


def _run(
    problem: Problem | str,
    controller: ControllerSpec,
    jobs_of: Any,
    *,
    scenarios: Sequence[Scenario] = (),
    push_tests: Sequence[PushTest] = (),
    problem_options: Mapping[str, Any] | None,
    controller_options: Mapping[str, Any] | None,
    executor: str | Executor | None,
    progress: bool,
    desc: str,
) -> list[Done]:
    """Run the jobs ``jobs_of(label)`` of one controller on ``executor``, in job order."""
    built: Problem | None = None
    if isinstance(problem, str):
        if problem not in TASKS:
            raise UnknownNameError("task", problem, TASKS, "problem")
        problem_class: Any = task_class(problem)
        task: str | None = problem
    else:
        instance("problem", problem, Problem, "an mpcbox.Problem or a task name")
        if problem_options:
            raise InvalidArgumentError("problem_options only applies when problem is a task name")
        built, task, problem_class = problem, None, type(problem)
    specs = resolve_controllers(built or problem_class, [controller])
    label = next(iter(specs))
    if controller_options is not None:
        instance("controller_options", controller_options, Mapping, "a mapping of options")
    check_noise_models(built or problem_class, [*scenarios, *push_tests])
    setup = Setup(
        task=task,
        task_options=dict(problem_options or {}),
        controllers=specs,
        overrides={label: dict(controller_options)} if controller_options else {},
        scenarios=tuple(scenarios),
        push_tests=tuple(push_tests),
        trace_seed=-(2**62),  # no run keeps its time series
    )
    jobs: list[Job] = jobs_of(label)
    portable = built is None and picklable(setup)
    runner = pick_executor(executor or "serial", None, len(jobs), portable)
    from tqdm.auto import tqdm

    order = {job: i for i, job in enumerate(jobs)}
    done: list[Done] = []
    with tqdm(total=len(jobs), desc=f"{label} {desc} ({runner.name})", disable=not progress) as bar:
        for item in runner.run(setup, jobs, built):
            done.append(item)
            bar.update()
    _raise_errors(label, desc, done)
    return sorted(done, key=lambda item: order[item.job])


def _raise_errors(label: str, desc: str, done: list[Done]) -> None:
    """A job that raised outside the closed loop measured nothing: counting it as a fall
    would report a setup error as the controller's failure, so it raises here.

    Raises:
        RunError: Naming how many jobs raised and the first error.
    """
    errors = [
        item.result.failure
        for item in done
        if isinstance(item.result.failure, str)
        and item.result.failure.startswith(("error in run:", "error in push search:"))
    ]
    if errors:
        raise RunError(
            f"{len(errors)} of {len(done)} runs of the {desc} of {label!r} raised before or "
            f"outside the closed loop, so they measured nothing; the first: {errors[0]}"
        )


@checked_keywords
def survival(
    problem: Problem | str,
    controller: ControllerSpec,
    *,
    seeds: Sequence[int],
    duration: float,
    noise: ActuatorNoise | None = None,
    pushes: Sequence[Push] = (),
    mismatch: ModelMismatch | None = None,
    progress: bool = False,
    problem_options: Mapping[str, Any] | None = None,
    controller_options: Mapping[str, Any] | None = None,
    executor: str | Executor | None = None,
) -> SurvivalSummary:
    """Run one simulation per seed and summarize survival.

    Args:
        problem: The Problem, or a task name (:data:`mpcbox.registry.TASKS`).
        controller: The controller (reset before each run), a controller name or a factory
            ``problem -> Controller``.
        seeds: Noise seeds.
        duration: Simulated time per run (s).
        noise: Actuator noise (seeded per run).
        pushes: Pushes applied in every run.
        mismatch: Model mismatch applied in every run.
        progress: Show a progress bar.
        problem_options: Keyword arguments of the task class when ``problem`` is a name.
        controller_options: Keyword overrides of a controller given by name.
        executor: Where the runs go (``"serial"``, ``"processes"``, ``"ray"`` or an
            :class:`~mpcbox.comparison.executors.Executor`); a Problem instance or a
            controller that does not pickle runs in this process.
    """
    if _local(problem, controller, executor) and not (problem_options or controller_options):
        return _here.survival(
            problem,
            controller,
            seeds=seeds,
            duration=duration,
            noise=noise,
            pushes=pushes,
            mismatch=mismatch,
            progress=progress,
        )
    seed_list = check_seeds("seeds", seeds)
    positive("duration", duration)
    scenario = Scenario(
        name="survival",
        duration=duration,
        noise_scale=0.0 if noise is None else 1.0,
        noise=noise,
        pushes=tuple(pushes),
        mismatch=mismatch,
    )
    done = _run(
        problem,
        controller,
        lambda label: [Job(label, scenario=0, seed=s) for s in seed_list],
        scenarios=(scenario,),
        problem_options=problem_options,
        controller_options=controller_options,
        executor=executor,
        progress=progress,
        desc="survival",
    )
    surv = np.array([d.result.metrics.success for d in done], dtype=bool)
    times = np.array([d.result.metrics.time_to_fall for d in done], dtype=float)
    return SurvivalSummary(
        np.asarray(seed_list, dtype=int), surv, times, float(surv.mean()), float(times.mean())
    )


def _grid(forces: Sequence[float]) -> np.ndarray:
    if isinstance(forces, (str, bytes)) or not isinstance(forces, Sequence | np.ndarray):
        raise InvalidTypeError(f"forces must be a sequence of numbers, got {type(forces).__name__}")
    grid = np.sort(np.array([number("forces", f) for f in np.ravel(forces)], dtype=float))
    if grid.size == 0 or not np.all((grid >= 0) & (grid <= MAX_FORCE)):
        raise InvalidArgumentError(
            f"forces must hold at least one force in [0, {MAX_FORCE:g}] N, got {list(forces)!r}"
        )
    return grid


@checked_keywords
def push_grid(
    problem: Problem | str,
    controller: ControllerSpec,
    forces: Sequence[float],
    test: PushTest = DEFAULT_PUSH,
    *,
    seed: int = 0,
    progress: bool = False,
    problem_options: Mapping[str, Any] | None = None,
    controller_options: Mapping[str, Any] | None = None,
    executor: str | Executor | None = None,
) -> PushGrid:
    """Survival of the push of ``test`` at every force of a grid (its search settings unused).

    Unlike the bisection of :func:`largest_push`, the grid shows when survival is not
    monotone in the force (a controller that falls at 60 N and survives 100 N);
    :attr:`PushGrid.limit` is then the honest figure, the largest force below which nothing
    failed. The forces are independent runs, so an ``executor`` runs them in parallel.

    Args:
        problem: The Problem, or a task name (:data:`mpcbox.registry.TASKS`).
        controller: The controller (reset by each simulation), a name or a factory.
        forces: Force magnitudes, at least one, in ``[0, MAX_FORCE]`` (N); sorted here.
        test: The push (direction, duration, start, settle, body) and the trials' noise.
        seed: Noise seed.
        progress: Show a progress bar.
        problem_options: Keyword arguments of the task class when ``problem`` is a name.
        controller_options: Keyword overrides of a controller given by name.
        executor: Where the runs go (see :func:`survival`).
    """
    if _local(problem, controller, executor) and not (problem_options or controller_options):
        return _here.push_grid(problem, controller, forces, test, seed=seed, progress=progress)
    instance("test", test, PushTest, "an mpcbox.comparison.scenario.PushTest")
    if test.rest_speed is not None:
        raise InvalidArgumentError(
            "test.rest_speed needs each trial's last state, which runs on an executor do not "
            "keep: give a built Problem and controller without executor, problem_options or "
            "controller_options, or use largest_push"
        )
    seed = check_seed("seed", seed)
    grid = _grid(forces)
    scenarios = [
        Scenario(
            name=f"{test.label} {f:g}N",
            duration=test.total_time,
            noise_scale=test.noise_scale,
            pushes=(test.push(float(f)),),
        )
        for f in grid
    ]
    done = _run(
        problem,
        controller,
        lambda label: [Job(label, scenario=i, seed=seed) for i in range(len(grid))],
        scenarios=scenarios,
        problem_options=problem_options,
        controller_options=controller_options,
        executor=executor,
        progress=progress,
        desc="push grid",
    )
    survived = np.array([d.result.metrics.success for d in done], dtype=bool)
    times = np.array([d.result.metrics.time_to_fall for d in done], dtype=float)
    return summarize_push_grid(grid, survived, times)


@checked_keywords
def largest_push(
    problem: Problem | str,
    controller: ControllerSpec,
    test: PushTest = DEFAULT_PUSH,
    *,
    seed: int = 0,
    problem_options: Mapping[str, Any] | None = None,
    controller_options: Mapping[str, Any] | None = None,
    executor: str | Executor | None = None,
) -> PushLimit:
    """Largest force magnitude of the push of ``test`` that is survived.

    Bisection on the magnitude over ``[0, test.max_force]`` until the bracket is narrower
    than ``test.tolerance``, assuming that surviving a force means surviving every smaller
    one; :func:`push_grid` checks that assumption. Each trial simulates
    ``test.total_time`` seconds. With an ``executor`` the whole search is one job; to search
    several controllers or directions at once, give them to :func:`mpcbox.compare`
    (``push_tests``), whose searches are jobs of the same executors.

    Args:
        problem: The Problem, or a task name (:data:`mpcbox.registry.TASKS`).
        controller: The controller, a name or a factory.
        test: The push, the search settings and the trials' noise
            (:class:`~mpcbox.comparison.scenario.PushTest`).
        seed: Noise seed.
        problem_options: Keyword arguments of the task class when ``problem`` is a name.
        controller_options: Keyword overrides of a controller given by name.
        executor: Where the search runs (see :func:`survival`).
    """
    if _local(problem, controller, executor) and not (problem_options or controller_options):
        return _here.largest_push(problem, controller, test, seed=seed)
    instance("test", test, PushTest, "an mpcbox.comparison.scenario.PushTest")
    seed = check_seed("seed", seed)
    (done,) = _run(
        problem,
        controller,
        lambda label: [Job(label, push=0, seed=seed)],
        push_tests=(test,),
        problem_options=problem_options,
        controller_options=controller_options,
        executor=executor,
        progress=False,
        desc="largest push",
    )
    return done.result


__all__ = [
    "DEFAULT_PUSH",
    "PushGrid",
    "PushLimit",
    "SurvivalSummary",
    "largest_push",
    "push_grid",
    "summarize_push_grid",
    "survival",
]
