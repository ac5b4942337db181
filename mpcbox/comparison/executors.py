"""Where a comparison's jobs run: this process, a local process pool, or a Ray cluster.

An :class:`Executor` implements one method, :meth:`~Executor.run`, which yields each
:class:`~mpcbox.comparison.jobs.Done` as its job finishes (in any order). Every executor
gives the same runs for the same setup, seeds and scenarios: only the timing columns differ.

- :class:`SerialExecutor`: one worker in this process (needed for Problem instances and
  controllers that do not pickle).
- :class:`ProcessExecutor`: a local pool of spawned processes. The workers end with the
  comparison: when it raises or is interrupted they are terminated, and a worker whose
  parent died (killed by a signal) exits within a second instead of running its job on.
- :class:`RayExecutor`: Ray actors on a local or remote cluster (``pip install
  "mpcbox[ray]"``), each asking Ray for ``cpus_per_run`` CPUs and ``gpus_per_run`` GPUs, so
  a multi-GPU host runs one warp-backend closed loop per GPU at a time. A worker lost
  mid-run is restarted and its job retried by Ray (``max_restarts``, ``max_task_retries``).
"""

from __future__ import annotations

import abc
import os
import socket
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from mpcbox.comparison.jobs import Done, Job, Setup, Worker
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError
from mpcbox.validation import (
    checked_options,
    integer,
    non_negative,
    positive,
    positive_int,
    string,
)


class Executor(abc.ABC):
    """Runs jobs of one comparison setup."""

    #: Label in progress bars and summaries.
    name: str = "executor"

    @abc.abstractmethod
    def run(
        self, setup: Setup, jobs: Sequence[Job], problem: Problem | None = None
    ) -> Iterator[Done]:
        """Yield each finished job.

        Args:
            setup: What a worker needs to rebuild the problem and controllers.
            jobs: The jobs to run.
            problem: A Problem instance (only executors running in this process accept one).
        """


class SerialExecutor(Executor):
    """Runs every job in this process, in order."""

    name = "serial"

    def run(
        self, setup: Setup, jobs: Sequence[Job], problem: Problem | None = None
    ) -> Iterator[Done]:
        worker = Worker(setup, problem)
        for job in jobs:
            yield worker(job)


_WORKER: Worker | None = None


#: Seconds between a worker's checks that the process that spawned it is alive.
PARENT_CHECK_S = 1.0


def _exit_with_parent(parent: int) -> None:
    """Exit this worker once ``parent`` is gone (the process is then re-parented)."""
    while True:
        time.sleep(PARENT_CHECK_S)
        if os.getppid() != parent:
            os._exit(1)


def _init_worker(setup: Setup, parent: int) -> None:
    global _WORKER
    threading.Thread(target=_exit_with_parent, args=(parent,), daemon=True).start()
    _WORKER = Worker(setup)


def _run_in_worker(job: Job) -> Done:
    assert _WORKER is not None
    return _WORKER(job)


@checked_options
@dataclass(frozen=True, kw_only=True)
class ProcessExecutor(Executor):
    """A pool of ``workers`` spawned processes on this machine (default: one per core)."""

    workers: int | None = None
    name = "processes"

    def run(
        self, setup: Setup, jobs: Sequence[Job], problem: Problem | None = None
    ) -> Iterator[Done]:
        if problem is not None:
            raise InvalidArgumentError(
                "a Problem instance runs in this process only: give the task by name to use "
                "worker processes, or use SerialExecutor"
            )
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        count = (os.cpu_count() or 1) if self.workers is None else self.workers
        count = min(positive_int("workers", count), max(len(jobs), 1))
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(
            max_workers=count,
            mp_context=context,
            initializer=_init_worker,
            initargs=(setup, os.getpid()),
        )
        try:
            futures = [pool.submit(_run_in_worker, job) for job in jobs]
            for future in as_completed(futures):
                yield future.result()
        except BaseException:  # an error, Ctrl-C, or the consumer closing this generator
            # shutdown() alone would let every running job finish first (minutes each).
            for process in list(getattr(pool, "_processes", {}).values()):
                process.terminate()
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


class _RayWorker:
    """A Ray actor holding one :class:`~mpcbox.comparison.jobs.Worker`."""

    def __init__(self, setup: Setup) -> None:
        self.worker = Worker(setup)

    def run(self, job: Job) -> Done:
        import ray

        done = self.worker(job)
        node = ray.get_runtime_context().get_node_id()[:8]
        host, _, gpu = done.where.partition(" gpu ")
        return done._replace(where=f"{host} node {node}" + (f" gpu {gpu}" if gpu else ""))


def _host_port(address: str) -> tuple[str, int]:
    """``(host, port)`` of ``"HOST:PORT"`` or ``"ray://HOST:PORT"``; raises
    InvalidArgumentError naming ``address`` otherwise."""
    rest = address.removeprefix("ray://")
    host, _, port = rest.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InvalidArgumentError(
            f"address must be 'auto', 'HOST:PORT', 'ray://HOST:PORT' or None, got {address!r}"
        )
    return host.strip("[]"), int(port)


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Raise BackendUnavailableError unless something accepts a connection at ``address``
    within ``timeout`` seconds (``ray.init`` itself would keep retrying an address where
    nothing listens)."""
    host, port = _host_port(address)
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise BackendUnavailableError(
            f"address: no Ray cluster answers at {address!r} ({exc}); start one there "
            "(`ray start --head`) or leave the address out for a local Ray"
        ) from exc


@checked_options
@dataclass(frozen=True, kw_only=True)
class RayExecutor(Executor):
    """Ray actors, one job at a time each, on a local or remote Ray cluster.

    Attributes:
        address: Cluster address (``"auto"``, ``"HOST:PORT"``, ``"ray://HOST:PORT"``);
            ``None`` starts a local Ray (or joins the one this process already started).
        workers: Number of actors (default: as many as the cluster's resources hold).
        cpus_per_run: CPUs each actor asks Ray for (its closed loop's threads).
        gpus_per_run: GPUs each actor asks for; ``None``: one when a controller of the
            setup uses the warp backend, else none.
        max_restarts: Times Ray restarts an actor whose process died.
        max_task_retries: Times Ray retries a job whose actor died while running it.
    """

    address: str | None = None
    workers: int | None = None
    cpus_per_run: float = 1.0
    gpus_per_run: float | None = None
    max_restarts: int = 3
    max_task_retries: int = 3
    name = "ray"

    def __post_init__(self) -> None:
        if self.address is not None and string("address", self.address) != "auto":
            _host_port(self.address)  # '' too: it names the forms an address takes
        positive("cpus_per_run", self.cpus_per_run)
        if self.gpus_per_run is not None:
            non_negative("gpus_per_run", self.gpus_per_run)
        if self.workers is not None:
            positive_int("workers", self.workers)
        for name in ("max_restarts", "max_task_retries"):
            integer(name, getattr(self, name))

    def run(
        self, setup: Setup, jobs: Sequence[Job], problem: Problem | None = None
    ) -> Iterator[Done]:
        if problem is not None:
            raise InvalidArgumentError(
                "a Problem instance runs in this process only: give the task by name to run on Ray"
            )
        ray = _import_ray()
        if not ray.is_initialized():
            if self.address not in (None, "auto"):
                _check_reachable(self.address)
            ray.init(
                address=self.address,
                ignore_reinit_error=True,
                include_dashboard=False,
                logging_level="ERROR",
            )
        count, options = self.actor_options(setup, ray.cluster_resources(), len(jobs))
        actor_class = ray.remote(_RayWorker).options(**options)
        actors = [actor_class.remote(setup) for _ in range(count)]
        try:
            pool = ray.util.ActorPool(actors)
            yield from pool.map_unordered(lambda actor, job: actor.run.remote(job), list(jobs))
        finally:
            for actor in actors:
                ray.kill(actor)

    def actor_options(
        self, setup: Setup, resources: dict[str, float], jobs: int
    ) -> tuple[int, dict[str, float | int]]:
        """How many actors to start and the Ray options of each.

        Each actor asks for ``cpus_per_run`` CPUs and, for a setup whose controllers use the
        warp backend (:func:`uses_warp`, unless ``gpus_per_run`` says otherwise), one GPU:
        Ray then places at most one closed loop per GPU at a time, so a host with ``g``
        GPUs runs ``g`` warp loops in parallel. The default count is what the cluster holds
        (``CPU // cpus_per_run``, and ``GPU // gpus`` for GPU runs), at most one per job.

        Args:
            setup: The comparison's setup.
            resources: The cluster's resources (``ray.cluster_resources()``), e.g.
                ``{"CPU": 16.0, "GPU": 2.0}``.
            jobs: Number of jobs.

        Raises:
            BackendUnavailableError: If the runs need GPUs and the cluster has none.
        """
        gpus = float(uses_warp(setup) if self.gpus_per_run is None else self.gpus_per_run)
        fit = int(resources.get("CPU", 1) // self.cpus_per_run)
        if gpus > 0:
            fit = min(fit, int(resources.get("GPU", 0) // gpus))
            if fit == 0:
                raise BackendUnavailableError(
                    f"the Ray cluster has no GPU for runs that ask for {gpus:g} (resources: "
                    f"{resources})"
                )
        count = self.workers if self.workers is not None else max(fit, 1)
        options = {
            "num_cpus": self.cpus_per_run,
            "num_gpus": gpus,
            "max_restarts": self.max_restarts,
            "max_task_retries": self.max_task_retries,
        }
        return min(count, max(jobs, 1)), options


def uses_warp(setup: Setup) -> bool:
    """Whether a controller of ``setup`` (by name) plans with the warp backend."""
    from mpcbox.registry import task_class

    configs = {}
    if setup.task is not None:
        configs = dict(getattr(task_class(setup.task), "controller_configs", {}))
    for label, spec in setup.controllers.items():
        backend = setup.overrides.get(label, {}).get("backend")
        if backend is None and isinstance(spec, str):
            backend = getattr(configs.get(spec), "backend", None)
        if backend is None:
            backend = getattr(getattr(spec, "config", None), "backend", None)
        if backend == "warp":
            return True
    return False


def _import_ray():
    try:
        import ray
        import ray.util
    except ImportError as exc:
        raise BackendUnavailableError(
            'executor "ray" needs Ray: pip install "mpcbox[ray]"'
        ) from exc
    return ray


#: Executors by the name ``compare(executor=...)`` and ``--executor`` take.
EXECUTORS: dict[str, type[Executor]] = {
    "serial": SerialExecutor,
    "processes": ProcessExecutor,
    "ray": RayExecutor,
}


__all__ = [
    "EXECUTORS",
    "Executor",
    "ProcessExecutor",
    "RayExecutor",
    "SerialExecutor",
    "uses_warp",
]
