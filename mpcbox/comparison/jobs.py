"""The unit of work of a comparison: a :class:`Job`, the :class:`Setup` to rebuild it
anywhere, and the :class:`Worker` that runs jobs.

A worker, in this process, a child process or a Ray actor on another machine, rebuilds the
problem and each controller once from the picklable :class:`Setup` and reuses them across
jobs (:func:`mpcbox.simulate` resets the controller before every run), so a run's numbers
depend only on its controller, scenario and seed, never on where it ran. An exception inside
one job is recorded as that run's failure (outcome ``"controller error"``) and does not end
the comparison.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import socket
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from mpcbox.comparison.report import Run, Trace
from mpcbox.comparison.robustness import PushLimit, largest_push
from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.errors import NotAControllerError
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.measures import Measure
from mpcbox.sim.simulation import Metrics


@dataclass(frozen=True)
class Setup:
    """What a worker needs to rebuild the problem and the controllers (picklable).

    Attributes:
        task: Task name (:data:`mpcbox.registry.TASKS`), or ``None`` for a Problem instance
            that only runs in the calling process.
        task_options: Keyword arguments of the task class.
        controllers: Controller specs (names, instances or factories) by label.
        overrides: Per-label keyword overrides of controllers built by name.
        scenarios: The closed-loop scenarios.
        push_tests: The largest-push searches.
        trace_seed: The seed whose runs keep their time series.
    """

    task: str | None
    task_options: dict[str, Any]
    controllers: dict[str, Any]
    overrides: dict[str, dict[str, Any]]
    scenarios: tuple[Scenario, ...]
    push_tests: tuple[PushTest, ...]
    trace_seed: int

    def fingerprint(self) -> str:
        """A digest of everything that decides the results (not the controller objects
        themselves, only their labels), for checkpoints of finished jobs."""
        key = (
            self.task,
            sorted(self.task_options.items()),
            [
                (label, spec if isinstance(spec, str) else repr(type(spec)))
                for label, spec in self.controllers.items()
            ],
            sorted((k, sorted(v.items())) for k, v in self.overrides.items()),
            self.scenarios,
            self.push_tests,
            self.trace_seed,
        )
        return hashlib.sha256(repr(key).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Job:
    """One closed-loop run (``scenario`` and ``seed``) or one push search (``push``, with
    the noise of ``seed``)."""

    controller: str
    scenario: int = -1
    seed: int = 0
    push: int = -1

    @property
    def key(self) -> str:
        """A file-name-safe identifier of the job."""
        label = "".join(c if c.isalnum() or c in "-_." else "_" for c in self.controller)
        if self.push >= 0:
            return f"{label}__push{self.push}" + (f"__seed{self.seed}" if self.seed else "")
        return f"{label}__scenario{self.scenario}__seed{self.seed}"


class Done(NamedTuple):
    """A finished job: its run or push limit, the task's measures, and where it ran.

    Attributes:
        job: The job.
        result: A :class:`~mpcbox.comparison.report.Run` or a
            :class:`~mpcbox.comparison.push_limits.PushLimit`.
        measures: The task's measures (for the table columns).
        where: The host (and Ray node), plus ``" gpu <ids>"`` when the worker had GPUs.
    """

    job: Job
    result: Run | PushLimit
    measures: tuple[Measure, ...]
    where: str


def _where() -> str:
    gpus = os.environ.get("CUDA_VISIBLE_DEVICES", "")
    host = socket.gethostname()
    return f"{host} gpu {gpus}" if gpus else host


def failed_run(job: Job, error: BaseException) -> Run:
    """The record of a run that raised before or outside :func:`~mpcbox.simulate`."""
    nan = float("nan")
    metrics = Metrics(
        survived=False,
        time_to_fall=0.0,
        cost=nan,
        control_effort=nan,
        compute_mean_ms=nan,
        compute_p50_ms=nan,
        compute_p99_ms=nan,
        realtime_factor=nan,
        fallbacks=0,
        measures={},
        success=False,
        outcome="controller error",
    )
    reason = f"error in run: {type(error).__name__}: {error}"
    return Run(job.controller, job.scenario, job.seed, metrics, reason, np.zeros(0), None)


class Worker:
    """Builds the problem and controllers on first use, then runs jobs.

    Args:
        setup: The comparison's setup.
        problem: An already built problem (serial runs of a Problem instance).
    """

    def __init__(self, setup: Setup, problem: Problem | None = None) -> None:
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
                if not isinstance(ctrl, Controller):
                    raise NotAControllerError(
                        f"controllers: the factory for {label!r} returned "
                        f"{type(ctrl).__name__}, not an mpcbox.Controller"
                    )
            self._controllers[label] = ctrl
        return self._controllers[label]

    def __call__(self, job: Job) -> Done:
        """Run ``job``; a closed-loop run that raises is recorded as a failed run."""
        if job.push >= 0:
            try:
                problem, controller = self.problem, self.controller(job.controller)
                test = self.setup.push_tests[job.push]
                limit = largest_push(problem, controller, test, seed=job.seed)
            except NotAControllerError:
                raise
            except Exception as exc:  # one broken search must not end the sweep: NaN
                nan = float("nan")
                reason = f"error in push search: {type(exc).__name__}: {exc}"
                return Done(job, PushLimit(nan, nan, nan, 0, reason), (), _where())
            return Done(job, limit, tuple(problem.measures()), _where())
        try:
            problem, controller = self.problem, self.controller(job.controller)
            measures = tuple(problem.measures())
            res = self.setup.scenarios[job.scenario].run(problem, controller, job.seed)
        except NotAControllerError:
            raise  # the same in every run: the caller's mistake, not the run's
        except Exception as exc:  # one broken run must not end the sweep
            return Done(job, failed_run(job, exc), (), _where())
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
        return Done(job, run, measures, _where())


def picklable(obj: object) -> bool:
    """Whether ``obj`` pickles (what runs outside this process must)."""
    try:
        pickle.dumps(obj)
    except Exception:  # any failure means "run in this process"
        return False
    return True


__all__ = ["Done", "Job", "Setup", "Worker", "failed_run", "picklable"]
