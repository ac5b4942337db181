"""Monte-Carlo sweep on Ray against the same sweep run serially; prints JSON.

The sweep is ``--runs`` closed loops of ``--task`` (seeds x noise scales x controllers), run
three ways in one process: serially (the peer), on a local process pool, and on Ray (a local
Ray started here, or ``--address``). It reports each wall time, the speed-ups over serial, and
whether the three tables agree apart from the timing columns (they must)::

    python benchmarks/ray_sweep.py --runs 200 --json benchmarks/results/ray_sweep.json
    python benchmarks/ray_sweep.py --runs 24 --duration 1   # a quick look on a laptop

Serial time is measured on ``--serial-runs`` of the runs (default: all) and scaled to the
sweep when fewer, which the JSON says. Starting the local Ray is timed on its own
(``ray_start_s``): a sweep sent to a running cluster does not pay it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from mpcbox.comparison.executors import ProcessExecutor, RayExecutor
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import Scenario

TIMING = {"compute_mean_ms", "compute_p50_ms", "compute_p99_ms", "realtime_factor", "offline_ms"}


def _sweep(task: str, controllers: list[str], runs: int, duration: float):
    """Scenarios and seeds giving about ``runs`` closed loops."""
    scales = [0.5, 1.0, 1.5, 2.0]
    seeds = max(1, round(runs / (len(scales) * len(controllers))))
    scenarios = [Scenario(duration=duration, noise_scale=s) for s in scales]
    return scenarios, seeds


def _agree(a, b) -> bool:
    for x, y in zip(a.runs, b.runs, strict=True):
        if (x.controller, x.scenario, x.seed, x.failure) != (
            y.controller,
            y.scenario,
            y.seed,
            y.failure,
        ):
            return False
        for field in x.metrics._fields:
            if field in TIMING:
                continue
            u, v = getattr(x.metrics, field), getattr(y.metrics, field)
            try:
                np.testing.assert_equal(u, v)
            except AssertionError:
                return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid_balance")
    parser.add_argument("--controllers", default="lqr")
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--serial-runs", type=int, default=0, help="0: all")
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--address", default=None)
    parser.add_argument("--workers", type=int, default=0, help="0: one per core")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()

    controllers = args.controllers.split(",")
    scenarios, seeds = _sweep(args.task, controllers, args.runs, args.duration)
    total = len(scenarios) * seeds * len(controllers)
    kwargs = dict(progress=False)
    workers = args.workers or os.cpu_count() or 1

    def timed(executor, n_seeds):
        t0 = time.perf_counter()
        result = compare(args.task, controllers, scenarios, n_seeds, executor=executor, **kwargs)
        return result, time.perf_counter() - t0

    serial_seeds = seeds
    if args.serial_runs:
        serial_seeds = max(1, round(args.serial_runs / (len(scenarios) * len(controllers))))
    serial, serial_wall = timed("serial", serial_seeds)
    serial_scaled = serial_wall * seeds / serial_seeds
    procs, procs_wall = timed(ProcessExecutor(workers=workers), seeds)
    import ray

    t0 = time.perf_counter()
    ray.init(address=args.address, include_dashboard=False, logging_level="ERROR")
    ray_start = time.perf_counter() - t0
    ray_exec = RayExecutor(address=args.address, workers=args.workers or None)
    ray_result, ray_wall = timed(ray_exec, seeds)

    resources = ray.cluster_resources()
    full = serial if serial_seeds == seeds else None
    out = {
        "benchmark": "ray_sweep",
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cores": os.cpu_count(),
            "ray_cluster_cpus": resources.get("CPU"),
            "ray_cluster_gpus": resources.get("GPU", 0),
            "python": sys.version.split()[0],
            "ray": ray.__version__,
        },
        "task": args.task,
        "controllers": controllers,
        "runs": total,
        "run_duration_s": args.duration,
        "serial_runs_measured": len(serial.runs),
        "serial_wall_s": serial_scaled,
        "serial_wall_measured_s": serial_wall,
        "processes_wall_s": procs_wall,
        "ray_start_s": ray_start,
        "ray_wall_s": ray_wall,
        "ray_wall_with_start_s": ray_wall + ray_start,
        "speedup_processes": serial_scaled / procs_wall,
        "speedup_ray": serial_scaled / ray_wall,
        "speedup_ray_with_start": serial_scaled / (ray_wall + ray_start),
        "ray_placement": ray_result.placement,
        "tables_agree_ray_vs_processes": _agree(ray_result, procs),
        "tables_agree_ray_vs_serial": None if full is None else _agree(ray_result, full),
        "success_rate": float(np.mean([r.metrics.success for r in ray_result.runs])),
    }
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
