r"""Run several controllers on identical seeded scenarios: :func:`compare`.

:func:`compare` runs every controller on every :class:`~mpcbox.comparison.scenario.Scenario`
for every seed, optionally finds each controller's largest survived push
(:class:`~mpcbox.comparison.scenario.PushTest`, by bisection with
:func:`~mpcbox.comparison.push_limits.largest_push`), and returns a
:class:`~mpcbox.comparison.report.Comparison` that prints as a markdown table and writes CSV;
:func:`~mpcbox.comparison.plots.plot_comparison` draws it.

Runs are spread over worker processes when everything needed to rebuild them in a worker is
picklable: the problem given as a task name (see :data:`mpcbox.registry.TASKS`) and the
controllers as names or module-level factories. Each worker rebuilds the problem and each
controller once and reuses them across runs (:func:`mpcbox.simulate` resets the controller
before every run), so a run's numbers depend only on its controller, scenario and seed, not
on which process ran it. Timing columns (compute per tick, real-time factor) naturally vary.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from mpcbox.comparison.push_limits import PushLimit, largest_push
from mpcbox.comparison.report import Comparison, Run, Trace
from mpcbox.comparison.scenario import PushTest, Scenario, check_noise_models
from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.registry import (
    CONTROLLERS,
    TASKS,
    available_controllers,
    make_controller,
    task_class,
)
from mpcbox.sim.measures import Measure
from mpcbox.sim.simulation import simulate
from mpcbox.validation import positive_int

ControllerFactory = Callable[[Problem], Controller]
ControllerSpec = str | Controller | ControllerFactory


@dataclass(frozen=True)
class _Setup:
    """What a worker needs to rebuild the problem and the controllers (picklable)."""

    task: str | None
    task_options: dict[str, Any]
    controllers: dict[str, ControllerSpec]
    overrides: dict[str, dict[str, Any]]
    scenarios: tuple[Scenario, ...]
    push_tests: tuple[PushTest, ...]
    trace_seed: int


@dataclass(frozen=True)
class _Job:
    controller: str
    scenario: int = -1
    seed: int = 0
    push: int = -1


class _Done(NamedTuple):
    """A finished job: its run or push limit, and the task's measures (for the tables)."""

    job: _Job
    result: Run | PushLimit
    measures: tuple[Measure, ...]


class _Runner:
    """Builds the problem and controllers on first use, then runs jobs."""

    def __init__(self, setup: _Setup, problem: Problem | None = None) -> None:
        self.setup = setup
        self._problem = problem
        self._controllers: dict[str, Controller] = {}

    @property
    def problem(self) -> Problem:
        if self._problem is None:
            self._problem = task_class(self.setup.task)(**self.setup.task_options)
        return self._problem

    def controller(self, label: str) -> Controller:
        if label not in self._controllers:
            spec = self.setup.controllers[label]
            if isinstance(spec, str):
                ctrl = make_controller(spec, self.problem, **self.setup.overrides.get(label, {}))
            elif isinstance(spec, Controller):
                ctrl = spec
            else:
                ctrl = spec(self.problem)
            self._controllers[label] = ctrl
        return self._controllers[label]

    def __call__(self, job: _Job) -> _Done:
        problem, controller = self.problem, self.controller(job.controller)
        if job.push >= 0:
            limit = largest_push(problem, controller, self.setup.push_tests[job.push], seed=0)
            return _Done(job, limit, tuple(problem.measures()))
        scenario = self.setup.scenarios[job.scenario]
        res = simulate(
            problem,
            controller,
            scenario.duration,
            noise=scenario.resolve_noise(problem),
            pushes=scenario.pushes,
            mismatch=scenario.mismatch,
            seed=job.seed,
        )
        trace = None
        if job.seed == self.setup.trace_seed:
            trace = Trace(res.time, res.series, res.ctrls, problem.ctrl_ref.copy(), res.states)
        run = Run(
            job.controller,
            job.scenario,
            job.seed,
            res.metrics,
            res.failure,
            res.compute_times,
            trace,
        )
        return _Done(job, run, res.measures)


_WORKER: _Runner | None = None


def _init_worker(setup: _Setup) -> None:
    global _WORKER
    _WORKER = _Runner(setup)


def _run_in_worker(job: _Job) -> _Done:
    assert _WORKER is not None
    return _WORKER(job)


def _picklable(obj: object) -> bool:
    try:
        pickle.dumps(obj)
    except Exception:  # any failure means "run serially"
        return False
    return True


def _controller_label(spec: ControllerSpec, index: int) -> str:
    if isinstance(spec, str):
        return spec
    name = getattr(spec, "name", None)
    if isinstance(name, str) and name and name != "controller":
        return name
    return getattr(spec, "__name__", None) or f"{type(spec).__name__}{index}"


def resolve_controllers(
    problem: Problem | type, controllers: Sequence[ControllerSpec] | str | None
) -> dict[str, ControllerSpec]:
    """Labels and specs of ``controllers``; unknown names raise :class:`UnknownNameError`.

    Args:
        problem: The Problem (or its class), whose ``controller_options`` give the default.
        controllers: Names (``"lqr"``), Controller instances or factories
            ``problem -> Controller``; a comma-separated string of names; ``None`` for every
            controller tuned for the problem (:func:`mpcbox.registry.available_controllers`).
    """
    if controllers is None:
        controllers = available_controllers(problem)
        if not controllers:
            raise InvalidArgumentError(
                f"problem {getattr(problem, 'name', problem)!r} has no tuned controllers; "
                f"pass controllers explicitly (valid names: {', '.join(CONTROLLERS)})"
            )
    elif isinstance(controllers, str):
        controllers = [c.strip() for c in controllers.split(",") if c.strip()]
    if len(controllers) == 0:
        raise InvalidArgumentError("controllers must hold at least one controller")
    out: dict[str, ControllerSpec] = {}
    for i, spec in enumerate(controllers):
        if isinstance(spec, str):
            if spec not in CONTROLLERS:
                raise UnknownNameError("controller", spec, CONTROLLERS)
        elif not (isinstance(spec, Controller) or callable(spec)):
            raise InvalidArgumentError(
                "controllers must hold names, mpcbox.Controller instances or factories "
                f"problem -> Controller, got {type(spec).__name__}"
            )
        label = _controller_label(spec, i)
        while label in out:
            label += "'"
        out[label] = spec
    return out


def compare(
    problem: Problem | str,
    controllers: Sequence[ControllerSpec] | str | None = None,
    scenarios: Scenario | Sequence[Scenario] | None = None,
    seeds: int | Sequence[int] = 5,
    *,
    push_tests: PushTest | Sequence[PushTest] = (),
    problem_options: Mapping[str, Any] | None = None,
    controller_options: Mapping[str, Mapping[str, Any]] | None = None,
    workers: int | None = None,
    progress: bool = True,
) -> Comparison:
    """Run each controller on identical seeded scenarios and collect the metrics.

    Every controller sees exactly the same noise sequence for a given scenario and seed (the
    noise depends only on the seed), the same pushes and the same model mismatch.

    Args:
        problem: A :class:`~mpcbox.Problem`, or a task name from
            :data:`mpcbox.registry.TASKS` (e.g. ``"humanoid_balance"``).
        controllers: Controller names, instances, or factories ``problem -> Controller``
            (default: every controller tuned for the problem).
        scenarios: One or several :class:`Scenario` (default: ``Scenario()``).
        seeds: Number of seeds (``0 .. n-1``) or the seeds themselves.
        push_tests: Largest-push searches to run once per controller.
        problem_options: Keyword arguments of the task class when ``problem`` is a name
            (e.g. ``{"leg": "right"}``).
        controller_options: Per-name keyword overrides for controllers built by name, e.g.
            ``{"ilqr": {"horizon": 0.5}}``.
        workers: Worker processes (default: ``os.cpu_count()``, at most one per job); ``1``
            runs everything in this process. Runs are also serial when the problem is an
            instance or a controller cannot be pickled.
        progress: Show a tqdm progress bar.

    Returns:
        A :class:`Comparison`.

    Raises:
        UnknownNameError: For an unknown task or controller name; the message lists the
            valid names.
        InvalidArgumentError: For a scenario or push test that asks for the task's noise
            when the task has no noise model (:meth:`~mpcbox.Problem.noise`).
    """
    import time

    wall0 = time.perf_counter()
    instance: Problem | None = None
    if isinstance(problem, str):
        if problem not in TASKS:
            raise UnknownNameError("task", problem, TASKS)
        problem_class = task_class(problem)
        problem_name = problem_class.name
        task: str | None = problem
    elif isinstance(problem, Problem):
        if problem_options:
            raise InvalidArgumentError("problem_options only applies when problem is a task name")
        instance, task, problem_class, problem_name = problem, None, type(problem), problem.name
    else:
        raise InvalidArgumentError(
            f"problem must be an mpcbox.Problem or a task name ({', '.join(TASKS)}), "
            f"got {type(problem).__name__}"
        )
    specs = resolve_controllers(instance or problem_class, controllers)
    overrides = {k: dict(v) for k, v in (controller_options or {}).items()}
    for name in overrides:
        if name not in specs:
            raise UnknownNameError("controller in controller_options", name, specs)

    if scenarios is None:
        scenarios = (Scenario(),)
    elif isinstance(scenarios, Scenario):
        scenarios = (scenarios,)
    scenarios = tuple(scenarios)
    if not scenarios or not all(isinstance(s, Scenario) for s in scenarios):
        raise InvalidArgumentError("scenarios must hold at least one mpcbox.Scenario")
    seed_list = (
        tuple(range(positive_int("seeds", seeds)))
        if isinstance(seeds, int | np.integer)
        else tuple(int(s) for s in seeds)
    )
    if not seed_list:
        raise InvalidArgumentError("seeds must hold at least one seed")
    tests = (push_tests,) if isinstance(push_tests, PushTest) else tuple(push_tests)
    if not all(isinstance(t, PushTest) for t in tests):
        raise InvalidArgumentError("push_tests must hold mpcbox.comparison.scenario.PushTest")
    labels = [t.label for t in tests]
    if len(set(labels)) != len(labels):
        raise InvalidArgumentError(f"push_tests need distinct labels, got {labels}")
    check_noise_models(instance or problem_class, [*scenarios, *tests])

    setup = _Setup(
        task=task,
        task_options=dict(problem_options or {}),
        controllers=specs,
        overrides=overrides,
        scenarios=scenarios,
        push_tests=tests,
        trace_seed=seed_list[0],
    )
    jobs = [_Job(name, push=p) for name in specs for p in range(len(tests))]
    jobs += [
        _Job(name, scenario=s, seed=seed)
        for name in specs
        for s in range(len(scenarios))
        for seed in seed_list
    ]
    workers = (os.cpu_count() or 1) if workers is None else positive_int("workers", workers)
    workers = min(workers, len(jobs))
    parallel = workers > 1 and instance is None and _picklable(setup)

    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs), desc=f"compare {problem_name}", disable=not progress)
    done: list[_Done] = []
    try:
        if parallel:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor, as_completed

            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(
                max_workers=workers, mp_context=context, initializer=_init_worker, initargs=(setup,)
            ) as pool:
                futures = [pool.submit(_run_in_worker, job) for job in jobs]
                for future in as_completed(futures):
                    done.append(future.result())
                    bar.update()
        else:
            runner = _Runner(setup, instance)
            for job in jobs:
                done.append(runner(job))
                bar.update()
    finally:
        bar.close()

    order = {job: i for i, job in enumerate(jobs)}
    done.sort(key=lambda item: order[item.job])
    runs = tuple(d.result for d in done if d.job.push < 0)
    push_limits: dict[str, dict[str, PushLimit]] = {}
    for d in done:
        if d.job.push >= 0:
            push_limits.setdefault(d.job.controller, {})[tests[d.job.push].label] = d.result
    return Comparison(
        problem=problem_name,
        controllers=tuple(specs),
        scenarios=scenarios,
        seeds=seed_list,
        runs=runs,
        push_limits=push_limits,
        measures=done[0].measures,
        wall_time=time.perf_counter() - wall0,
    )
