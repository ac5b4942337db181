r"""Run several controllers on identical seeded scenarios and tabulate the results.

:func:`compare` runs every controller on every :class:`Scenario` for every seed, optionally
finds each controller's largest survived push (:class:`PushTest`, by bisection with
:func:`mpcbox.comparison.push_limits.largest_push`), and returns a :class:`Comparison` that prints as a
markdown table, writes CSV, and plots PNGs.

Runs are spread over worker processes when everything needed to rebuild them in a worker is
picklable: the problem given as a task name (see :data:`mpcbox.registry.TASKS`) and the
controllers as names or module-level factories. Each worker rebuilds the problem and each
controller once and reuses them across runs (:func:`mpcbox.simulate` resets the controller
before every run), so a run's numbers depend only on its controller, scenario and seed, not
on which process ran it. Timing columns (compute per tick, real-time factor) naturally vary.
"""

from __future__ import annotations

import csv
import io
import math
import os
import pickle
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mpcbox.comparison.push_limits import PushLimit, largest_push
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
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.simulation import Metrics, simulate
from mpcbox.validation import positive, positive_int

ControllerFactory = Callable[[Problem], Controller]
ControllerSpec = str | Controller | ControllerFactory


# ---------------------------------------------------------------------------- configuration
@dataclass(frozen=True, kw_only=True)
class Scenario:
    """One closed-loop test condition, run once per seed.

    The actuator noise is ``noise`` scaled by ``noise_scale`` when ``noise`` is given;
    otherwise the problem's own recipe ``problem.noise(noise_scale)`` when the problem has a
    ``noise`` method (e.g. :meth:`~mpcbox.tasks.humanoid.balance.HumanoidBalance.noise`), and
    no noise when it has none. ``noise_scale = 0`` always means no noise.

    Attributes:
        name: Label in tables and file names (default: built from the settings).
        duration: Simulated time per run (s).
        noise_scale: Multiplier on the noise standard deviation.
        noise: Explicit actuator noise (overrides the problem's recipe).
        pushes: Pushes applied in every run.
        mismatch: Model mismatch of the simulated plant.
    """

    name: str = ""
    duration: float = 10.0
    noise_scale: float = 1.0
    noise: ActuatorNoise | None = None
    pushes: tuple[Push, ...] = ()
    mismatch: ModelMismatch | None = None

    def __post_init__(self) -> None:
        positive("duration", self.duration)
        if not (math.isfinite(self.noise_scale) and self.noise_scale >= 0):
            raise InvalidArgumentError(
                f"noise_scale must be finite and >= 0, got {self.noise_scale!r}"
            )
        object.__setattr__(self, "pushes", tuple(self.pushes))
        for push in self.pushes:
            if not isinstance(push, Push):
                raise InvalidArgumentError(
                    f"pushes must hold mpcbox.Push objects, got {type(push).__name__}"
                )
        if self.noise is not None and not isinstance(self.noise, ActuatorNoise):
            raise InvalidArgumentError(
                f"noise must be an mpcbox.ActuatorNoise, got {type(self.noise).__name__}"
            )
        if self.mismatch is not None and not isinstance(self.mismatch, ModelMismatch):
            raise InvalidArgumentError(
                f"mismatch must be an mpcbox.ModelMismatch, got {type(self.mismatch).__name__}"
            )

    @property
    def label(self) -> str:
        """``name``, or a short description such as ``"noise x1 push 30N mass x1.1"``."""
        if self.name:
            return self.name
        parts = [f"noise x{self.noise_scale:g}"]
        for push in self.pushes:
            parts.append(f"push {np.linalg.norm(push.force):g}N@{push.start:g}s")
        if self.mismatch is not None:
            m = self.mismatch
            if m.mass_scale != 1.0:
                parts.append(f"mass x{m.mass_scale:g}")
            if m.friction_scale != 1.0:
                parts.append(f"friction x{m.friction_scale:g}")
            for body, value in (m.body_mass_scale or {}).items():
                parts.append(f"{body} mass x{value:g}")
        return " ".join(parts)

    def resolve_noise(self, problem: Problem) -> ActuatorNoise | None:
        """The actuator noise of this scenario for ``problem`` (``None`` for none)."""
        if self.noise_scale == 0:
            return None
        if self.noise is not None:
            return replace(self.noise, scale=self.noise.scale * self.noise_scale)
        recipe = getattr(problem, "noise", None)
        return recipe(self.noise_scale) if callable(recipe) else None

    @classmethod
    def noise_sweep(cls, scales: Sequence[float], **kwargs: Any) -> list[Scenario]:
        """One scenario per noise scale, the other settings shared (``kwargs``)."""
        return [cls(noise_scale=float(s), **kwargs) for s in scales]


@dataclass(frozen=True, kw_only=True)
class PushTest:
    """Largest survived push, found by bisection on the force magnitude.

    Each trial starts from the initial state, pushes ``body`` with a constant force along
    ``direction`` from ``start`` for ``duration`` seconds, and must stay up ``settle``
    seconds after the push (see :func:`mpcbox.comparison.push_limits.largest_push`). It runs once per
    controller (seed 0 of the noise, none by default), not once per seed.

    Attributes:
        direction: Push direction ``(3,)``; ``(1, 0, 0)`` pushes forward.
        duration: How long the force acts (s).
        start: Push start (s).
        settle: Time that must be survived after the push (s).
        body: Pushed body.
        max_force: Upper end of the search (N).
        tolerance: Bracket width at which the bisection stops (N).
        noise_scale: Actuator noise during the trials (0: none).
        name: Column label (default: from the direction, e.g. ``"+x"``).
    """

    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    duration: float = 0.1
    start: float = 1.0
    settle: float = 3.0
    body: str = "torso"
    max_force: float = 2000.0
    tolerance: float = 2.0
    noise_scale: float = 0.0
    name: str = ""

    def __post_init__(self) -> None:
        direction = tuple(float(d) for d in self.direction)
        if len(direction) != 3 or not any(direction):
            raise InvalidArgumentError(f"direction must be a non-zero 3-vector, got {direction}")
        object.__setattr__(self, "direction", direction)
        for name in ("duration", "settle", "max_force", "tolerance"):
            positive(name, getattr(self, name))

    @property
    def label(self) -> str:
        """``name``, or the dominant axis with its sign, e.g. ``"+x"`` or ``"-y"``."""
        if self.name:
            return self.name
        axis = int(np.argmax(np.abs(self.direction)))
        sign = "+" if self.direction[axis] > 0 else "-"
        return f"{sign}{'xyz'[axis]}"


# ---------------------------------------------------------------------------- results
class Trace(NamedTuple):
    """Time series of one run (``T`` simulation steps), kept for plotting.

    Attributes:
        time: Times ``(T,)`` (s).
        com_deviation: Horizontal COM distance from the support point ``(T,)`` (m).
        tilt_deg: Tilt of the problem's tilt body ``(T,)`` (deg).
        ctrls: Applied controls ``(T, nu)``.
        ctrl_ref: The problem's reference control ``(nu,)``.
    """

    time: np.ndarray
    com_deviation: np.ndarray
    tilt_deg: np.ndarray
    ctrls: np.ndarray
    ctrl_ref: np.ndarray


class Run(NamedTuple):
    """One closed-loop run of a comparison.

    Attributes:
        controller: Controller label.
        scenario: Index into :attr:`Comparison.scenarios`.
        seed: Noise seed.
        metrics: The run's :class:`~mpcbox.Metrics`.
        failure: Why it stopped early, or ``None``.
        compute_times: Controller time per call ``(calls,)`` (s).
        trace: Time series (kept for the first seed only), or ``None``.
    """

    controller: str
    scenario: int
    seed: int
    metrics: Metrics
    failure: str | None
    compute_times: np.ndarray
    trace: Trace | None


class Row(NamedTuple):
    """One line of the comparison table: a controller on a scenario, over all seeds.

    Attributes:
        scenario: Scenario label.
        controller: Controller label.
        runs: Number of seeds.
        success_rate: Fraction of runs that did not fail.
        mean_time_to_fall: Mean of the failure times, counting survived runs at the full
            duration (s).
        com_deviation_rms_cm: Mean over runs of the RMS COM deviation (cm).
        tilt_rms_deg: Mean over runs of the RMS tilt (deg).
        control_effort: Mean over runs of the RMS control.
        largest_push: Largest survived force per :class:`PushTest` label (N); empty when
            no push test ran.
        compute_mean_ms: Mean controller time per call over all runs (ms).
        compute_p99_ms: 99th percentile of the controller time per call (ms).
        realtime_factor: Total simulated time over total wall time.
        fallbacks: Controller fallbacks summed over runs.
    """

    scenario: str
    controller: str
    runs: int
    success_rate: float
    mean_time_to_fall: float
    com_deviation_rms_cm: float
    tilt_rms_deg: float
    control_effort: float
    largest_push: dict[str, float]
    compute_mean_ms: float
    compute_p99_ms: float
    realtime_factor: float
    fallbacks: int


@dataclass
class Comparison:
    """Everything :func:`compare` measured.

    Attributes:
        problem: Problem name.
        controllers: Controller labels, in the order given.
        scenarios: The scenarios.
        seeds: The seeds.
        runs: One :class:`Run` per controller, scenario and seed, in that order.
        push_limits: ``{controller: {push test label: PushLimit}}``.
        wall_time: Seconds the whole comparison took.
    """

    problem: str
    controllers: tuple[str, ...]
    scenarios: tuple[Scenario, ...]
    seeds: tuple[int, ...]
    runs: tuple[Run, ...]
    push_limits: dict[str, dict[str, PushLimit]] = field(default_factory=dict)
    wall_time: float = 0.0

    def runs_of(self, controller: str, scenario: int) -> list[Run]:
        """The runs of one controller on one scenario (by index), in seed order."""
        return [r for r in self.runs if r.controller == controller and r.scenario == scenario]

    def rows(self) -> list[Row]:
        """The table rows: scenarios in order, controllers in order within each."""
        rows = []
        for s, scenario in enumerate(self.scenarios):
            for name in self.controllers:
                runs = self.runs_of(name, s)
                if not runs:
                    continue
                metrics = [r.metrics for r in runs]
                ticks = np.concatenate([r.compute_times for r in runs])
                sim_time = sum(m.time_to_fall for m in metrics)
                wall = sum(
                    m.time_to_fall / m.realtime_factor
                    for m in metrics
                    if m.realtime_factor > 0 and math.isfinite(m.realtime_factor)
                )
                pushes = self.push_limits.get(name, {})
                rows.append(
                    Row(
                        scenario=scenario.label,
                        controller=name,
                        runs=len(runs),
                        success_rate=float(np.mean([m.survived for m in metrics])),
                        mean_time_to_fall=float(np.mean([m.time_to_fall for m in metrics])),
                        com_deviation_rms_cm=100.0
                        * float(np.mean([m.com_deviation_rms for m in metrics])),
                        tilt_rms_deg=float(np.mean([m.tilt_rms_deg for m in metrics])),
                        control_effort=float(np.mean([m.control_effort for m in metrics])),
                        largest_push={k: v.force for k, v in pushes.items()},
                        compute_mean_ms=float(ticks.mean() * 1e3) if ticks.size else 0.0,
                        compute_p99_ms=float(np.percentile(ticks, 99) * 1e3) if ticks.size else 0.0,
                        realtime_factor=sim_time / wall if wall > 0 else float("inf"),
                        fallbacks=int(sum(m.fallbacks for m in metrics)),
                    )
                )
        return rows

    def _push_labels(self) -> list[str]:
        labels: list[str] = []
        for limits in self.push_limits.values():
            labels += [k for k in limits if k not in labels]
        return labels

    def _table(self) -> tuple[list[str], list[list[str]]]:
        labels = self._push_labels()
        header = [
            "scenario",
            "controller",
            "seeds",
            "success",
            "mean time to fall (s)",
            "COM dev RMS (cm)",
            "tilt RMS (deg)",
            "effort",
            *[f"largest push {k} (N)" for k in labels],
            "compute mean (ms)",
            "compute p99 (ms)",
            "real-time factor",
            "fallbacks",
        ]
        body = []
        for row in self.rows():
            pushes = []
            for k in labels:
                force = row.largest_push.get(k)
                pushes.append("-" if force is None else f"{force:.0f}")
            body.append(
                [
                    row.scenario,
                    row.controller,
                    str(row.runs),
                    f"{100 * row.success_rate:.0f}%",
                    f"{row.mean_time_to_fall:.2f}",
                    f"{row.com_deviation_rms_cm:.2f}",
                    f"{row.tilt_rms_deg:.2f}",
                    f"{row.control_effort:.3f}",
                    *pushes,
                    f"{row.compute_mean_ms:.2f}",
                    f"{row.compute_p99_ms:.2f}",
                    f"{row.realtime_factor:.1f}",
                    str(row.fallbacks),
                ]
            )
        return header, body

    def to_markdown(self) -> str:
        """The table as GitHub-flavoured markdown (one row per scenario and controller)."""
        header, body = self._table()
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(cells) + " |" for cells in body]
        return "\n".join(lines)

    def to_csv(self, path: str | Path | None = None) -> str:
        """The rows as CSV with full precision; also written to ``path`` when given.

        Columns: ``scenario, controller, runs, success_rate, mean_time_to_fall,
        com_deviation_rms_cm, tilt_rms_deg, control_effort, largest_push_<label>...,
        compute_mean_ms, compute_p99_ms, realtime_factor, fallbacks``.
        """
        labels = self._push_labels()
        fields = [f for f in Row._fields if f != "largest_push"]
        header = fields[:8] + [f"largest_push_{k}" for k in labels] + fields[8:]
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(header)
        for row in self.rows():
            values = [getattr(row, f) for f in fields]
            pushes = [row.largest_push.get(k, "") for k in labels]
            writer.writerow(values[:8] + pushes + values[8:])
        text = buffer.getvalue()
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        return text

    def plot(self, folder: str | Path) -> list[Path]:
        """Write PNGs into ``folder`` (see :func:`mpcbox.comparison.plots.plot_comparison`)."""
        from mpcbox.comparison.plots import plot_comparison

        return plot_comparison(self, folder)

    def __str__(self) -> str:
        return self.to_markdown()


# ---------------------------------------------------------------------------- workers
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

    def __call__(self, job: _Job) -> tuple[_Job, Run | PushLimit]:
        problem, controller = self.problem, self.controller(job.controller)
        if job.push >= 0:
            test = self.setup.push_tests[job.push]
            noise = Scenario(noise_scale=test.noise_scale).resolve_noise(problem)
            limit = largest_push(
                problem,
                controller,
                direction=test.direction,
                push_duration=test.duration,
                start=test.start,
                settle=test.settle,
                body=test.body,
                max_force=test.max_force,
                tolerance=test.tolerance,
                noise=noise,
                seed=0,
            )
            return job, limit
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
            trace = Trace(
                res.time, res.com_deviation, res.tilt_deg, res.ctrls, problem.ctrl_ref.copy()
            )
        run = Run(
            job.controller,
            job.scenario,
            job.seed,
            res.metrics,
            res.failure,
            res.compute_times,
            trace,
        )
        return job, run


_WORKER: _Runner | None = None


def _init_worker(setup: _Setup) -> None:
    global _WORKER
    _WORKER = _Runner(setup)


def _run_in_worker(job: _Job) -> tuple[_Job, Run | PushLimit]:
    assert _WORKER is not None
    return _WORKER(job)


def _picklable(obj: object) -> bool:
    try:
        pickle.dumps(obj)
    except Exception:  # any failure means "run serially"
        return False
    return True


# ---------------------------------------------------------------------------- compare
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
    """
    import time

    wall0 = time.perf_counter()
    instance: Problem | None = None
    if isinstance(problem, str):
        if problem not in TASKS:
            raise UnknownNameError("task", problem, TASKS)
        problem_class = task_class(problem)
        problem_name = getattr(problem_class, "name", problem)
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
    labels = [t.label for t in tests]
    if len(set(labels)) != len(labels):
        raise InvalidArgumentError(f"push_tests need distinct labels, got {labels}")

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
    done: list[tuple[_Job, Run | PushLimit]] = []
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
    done.sort(key=lambda item: order[item[0]])
    runs = tuple(out for job, out in done if job.push < 0)
    push_limits: dict[str, dict[str, PushLimit]] = {}
    for job, out in done:
        if job.push >= 0:
            push_limits.setdefault(job.controller, {})[tests[job.push].label] = out
    return Comparison(
        problem=problem_name,
        controllers=tuple(specs),
        scenarios=scenarios,
        seeds=seed_list,
        runs=runs,
        push_limits=push_limits,
        wall_time=time.perf_counter() - wall0,
    )
