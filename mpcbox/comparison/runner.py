r"""Run several controllers on identical seeded scenarios: :func:`compare`.

:func:`compare` runs every controller on every :class:`~mpcbox.comparison.scenario.Scenario`
for every seed, optionally finds each controller's largest survived push
(:class:`~mpcbox.comparison.scenario.PushTest`, by bisection with
:func:`~mpcbox.comparison.push_limits.largest_push`), and returns a
:class:`~mpcbox.comparison.report.Comparison` that prints as a markdown table and writes CSV;
:func:`~mpcbox.comparison.plots.plot_comparison` draws it.

Runs are spread over worker processes (or a Ray cluster, :mod:`mpcbox.comparison.executors`)
when everything needed to rebuild them in a worker is picklable: the problem given as a task
name (see :data:`mpcbox.registry.TASKS`) and the controllers as names or module-level
factories. Each worker rebuilds the problem and each controller once and reuses them across
runs (:mod:`mpcbox.comparison.jobs`), so a run's numbers depend only on its controller,
scenario and seed, not on where it ran. Timing columns (compute per tick, real-time factor)
naturally vary. With a ``checkpoint`` folder, finished jobs are kept as they finish and a
re-run skips them (:mod:`mpcbox.comparison.checkpoint`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mpcbox.comparison.checkpoint import Checkpoint
from mpcbox.comparison.executors import (
    EXECUTORS,
    Executor,
    ProcessExecutor,
    SerialExecutor,
)
from mpcbox.comparison.jobs import Done, Job, Setup, picklable
from mpcbox.comparison.report import Comparison
from mpcbox.comparison.robustness import PushLimit
from mpcbox.comparison.scenario import PushTest, Scenario, check_noise_models
from mpcbox.config import check_option_names, resolve_config
from mpcbox.controllers.base import Controller
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import (
    InvalidArgumentError,
    InvalidTypeError,
    MpcboxError,
    UnknownNameError,
)
from mpcbox.registry import (
    CONTROLLERS,
    TASKS,
    available_controllers,
    controller_class,
    task_class,
)
from mpcbox.validation import (
    boolean,
    check_class_options,
    checked_keywords,
    positive_int,
)
from mpcbox.validation import instance as instance_of
from mpcbox.validation import seeds as check_seeds

ControllerFactory = Callable[[Problem], Controller]
ControllerSpec = str | Controller | ControllerFactory


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
    elif not isinstance(controllers, Sequence):
        raise InvalidTypeError(
            f"controllers must be a sequence of controllers, got {type(controllers).__name__}"
        )
    if len(controllers) == 0:
        raise InvalidArgumentError("controllers must hold at least one controller")
    out: dict[str, ControllerSpec] = {}
    for i, spec in enumerate(controllers):
        if isinstance(spec, str):
            if spec not in CONTROLLERS:
                raise UnknownNameError("controller", spec, CONTROLLERS, "controllers")
        elif not (isinstance(spec, Controller) or callable(spec)):
            raise InvalidTypeError(
                "controllers must hold names, mpcbox.Controller instances or factories "
                f"problem -> Controller, got {type(spec).__name__}"
            )
        label = _controller_label(spec, i)
        while label in out:
            label += "'"
        out[label] = spec
    return out


def _check_pushed_bodies(
    problem: Problem, scenarios: Sequence[Scenario], tests: Sequence[PushTest]
) -> None:
    """Every pushed body must exist in ``problem``'s model: a name error before any run,
    rather than the same error in every run's row."""
    for scenario in scenarios:
        for push in scenario.pushes:
            object_id(problem.model, "body", push.body, "scenarios: Push body")
    for test in tests:
        object_id(problem.model, "body", test.body, "push_tests: PushTest body")


@checked_keywords
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
    executor: str | Executor | None = None,
    checkpoint: str | Path | None = None,
    on_done: Callable[[Done], None] | None = None,
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
            instance or a controller cannot be pickled. Ignored when ``executor`` is given.
        executor: Where the jobs run: ``"serial"``, ``"processes"``, ``"ray"`` (a local Ray;
            pass a :class:`~mpcbox.comparison.executors.RayExecutor` for a cluster
            address) or an :class:`~mpcbox.comparison.executors.Executor`; default from
            ``workers``.
        checkpoint: A folder where each finished job is kept as it finishes; a re-run with
            the same folder and setup skips those jobs.
        on_done: Called with each finished :class:`~mpcbox.comparison.jobs.Done` as it
            finishes (first the jobs loaded from ``checkpoint``), e.g. a
            :class:`~mpcbox.comparison.stream.RunStream` that appends rows to files.
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
        raise InvalidTypeError(
            f"problem must be an mpcbox.Problem or a task name ({', '.join(TASKS)}), "
            f"got {type(problem).__name__}"
        )
    if problem_options is not None:
        instance_of("problem_options", problem_options, Mapping, "a mapping of options")
        check_class_options(problem_class, problem_options, f"problem_options ({problem})")
    specs = resolve_controllers(instance or problem_class, controllers)
    if controller_options is not None:
        instance_of("controller_options", controller_options, Mapping, "a mapping of mappings")
    overrides = {k: dict(v) for k, v in (controller_options or {}).items()}
    changed = []  # configs with options given: their values are checked below
    for name, options in overrides.items():
        if name not in specs:
            raise UnknownNameError("controller in controller_options", name, specs)
        spec = specs[name]
        if isinstance(spec, str) and controller_class(spec).config_class is not None:
            config_class = controller_class(spec).config_class
            owner = f"controller_options[{name!r}]"
            tuned = getattr(instance or problem_class, "controller_configs", {}).get(spec)
            if isinstance(tuned, config_class):  # names and values, before any run starts
                config = resolve_config(config_class, tuned, options, owner)
            else:
                check_option_names(config_class, options, owner)
                try:  # the class's defaults, unless it has required fields
                    config = resolve_config(config_class, None, options, owner)
                except TypeError as exc:  # a missing field; a bad value is an MpcboxError
                    if isinstance(exc, MpcboxError):
                        raise
                    config = None
            if options and config is not None:
                changed.append(config)
    check_sized_values(changed, instance, problem_class, problem_options)

    if scenarios is None:
        scenarios = (Scenario(),)
    elif isinstance(scenarios, Scenario):
        scenarios = (scenarios,)
    elif not isinstance(scenarios, Sequence):
        raise InvalidTypeError(
            f"scenarios must be Scenario objects, got {type(scenarios).__name__}"
        )
    scenarios = tuple(instance_of("scenarios", s, Scenario, "mpcbox.Scenario") for s in scenarios)
    if not scenarios:
        raise InvalidArgumentError("scenarios must hold at least one mpcbox.Scenario")
    seed_list = tuple(
        range(positive_int("seeds", seeds))
        if isinstance(seeds, int | np.integer) and not isinstance(seeds, bool)
        else check_seeds("seeds", seeds)
    )
    repeated = sorted({s for s in seed_list if seed_list.count(s) > 1})
    if repeated:  # a run is identified by its seed (rows, checkpoint)
        raise InvalidArgumentError(f"seeds must be distinct, got {repeated} more than once")
    tests = (push_tests,) if isinstance(push_tests, PushTest) else push_tests
    if not isinstance(tests, Sequence):
        raise InvalidTypeError(f"push_tests must be PushTest objects, got {type(tests).__name__}")
    tests = tuple(instance_of("push_tests", t, PushTest, "mpcbox PushTest objects") for t in tests)
    progress = boolean("progress", progress)
    labels = [t.label for t in tests]
    if len(set(labels)) != len(labels):
        raise InvalidArgumentError(f"push_tests need distinct labels, got {labels}")
    check_noise_models(instance or problem_class, [*scenarios, *tests])
    if instance is not None:  # a task given by name is checked in each run's own instance
        _check_pushed_bodies(instance, scenarios, tests)

    setup = Setup(
        task=task,
        task_options=dict(problem_options or {}),
        controllers=specs,
        overrides=overrides,
        scenarios=scenarios,
        push_tests=tests,
        trace_seed=seed_list[0],
    )
    jobs = [Job(name, push=p) for name in specs for p in range(len(tests))]
    jobs += [
        Job(name, scenario=s, seed=seed)
        for name in specs
        for s in range(len(scenarios))
        for seed in seed_list
    ]
    runner = pick_executor(executor, workers, len(jobs), instance is None and picklable(setup))
    store = None if checkpoint is None else Checkpoint(checkpoint, setup)
    finished = {} if store is None else store.load(jobs)
    todo = [job for job in jobs if job not in finished]

    from tqdm.auto import tqdm

    bar = tqdm(
        total=len(jobs),
        initial=len(finished),
        desc=f"compare {problem_name} ({runner.name})",
        disable=not progress,
    )
    if on_done is not None and not callable(on_done):
        raise InvalidTypeError(f"on_done must be callable, got {type(on_done).__name__}")
    done: list[Done] = [finished[job] for job in jobs if job in finished]
    if on_done is not None:
        for item in done:
            on_done(item)
    try:
        if todo:
            for item in runner.run(setup, todo, instance):
                if store is not None:
                    store.save(item)
                done.append(item)
                if on_done is not None:
                    on_done(item)
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
        measures=next((d.measures for d in done if d.measures), ()),
        wall_time=time.perf_counter() - wall0,
        placement=_placement(done),
    )


def pick_executor(
    executor: str | Executor | None, workers: int | None, jobs: int, portable: bool
) -> Executor:
    """The executor to use: the one asked for, or processes when ``workers`` allows it.

    Args:
        executor: A name of :data:`~mpcbox.comparison.executors.EXECUTORS`, an
            :class:`~mpcbox.comparison.executors.Executor`, or ``None`` (from ``workers``).
        workers: Worker processes (``None``: one per core).
        jobs: Number of jobs (no more workers than jobs).
        portable: Whether the setup can leave this process; when not, the serial executor.
    """
    if isinstance(executor, Executor):
        return executor if portable else SerialExecutor()
    if executor is not None:
        if not isinstance(executor, str):
            raise InvalidTypeError(
                f"executor must be a name ({', '.join(EXECUTORS)}) or an Executor, got "
                f"{type(executor).__name__}"
            )
        if executor not in EXECUTORS:
            raise UnknownNameError("executor", executor, EXECUTORS)
        if executor == "serial" or not portable:
            return SerialExecutor()
        if executor == "processes":
            return ProcessExecutor(workers=workers)
        return EXECUTORS[executor]()
    count = (os.cpu_count() or 1) if workers is None else positive_int("workers", workers)
    if min(count, jobs) > 1 and portable:
        return ProcessExecutor(workers=min(count, jobs))
    return SerialExecutor()


def _placement(done: list[Done]) -> dict[str, int]:
    """Jobs per place (host, Ray node, GPUs) they ran on."""
    out: dict[str, int] = {}
    for item in done:
        out[item.where] = out.get(item.where, 0) + 1
    return out


def check_sized_values(
    configs: Sequence[Any],
    instance: Problem | None,
    problem_class: type,
    problem_options: Mapping[str, Any] | None,
) -> None:
    """Check option values that need the Problem's sizes before any run starts: each
    sampling config (its ``validate(nu, dt)``) and LQR config (the shapes of its arrays)
    against ``instance``, or a Problem built once from the task. A task that cannot be
    built here is left to its runs, which report that error each. ``compare`` and the
    ``mpcbox compare`` command (before it makes ``--out``) both call it.

    Raises:
        MpcboxError: The config's own error naming the option (an ``InvalidArgumentError``
            for a value out of range).
    """
    from mpcbox.controllers.lqr import LQRConfig
    from mpcbox.controllers.sampling.config import SamplingConfig

    sized = [c for c in configs if isinstance(c, SamplingConfig | LQRConfig)]
    if not sized:
        return
    if instance is None:
        try:
            instance = problem_class(**dict(problem_options or {}))
        except MpcboxError:
            return
    for config in sized:
        if isinstance(config, LQRConfig):
            config.check_sizes(instance)  # Q, R, state, ctrl against the Problem's sizes
        else:
            config.validate(instance.nu, instance.dt)
