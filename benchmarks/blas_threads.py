"""iLQR-MPC's tick with BLAS limited to one thread while it plans, and with BLAS left alone.

:mod:`mpcbox.core.blas_threads` limits NumPy's BLAS to one thread inside iLQR's solves;
``MPCBOX_PLANNER_BLAS_THREADS=0`` turns that off. This script runs, in one process and
alternating, the one-leg humanoid's tuned iLQR-MPC in closed loop (lock-step, no noise) both
ways, then the same in a two-process comparison (``mpcbox.compare`` with two workers on
two seeds), and prints JSON: median and p99 replan tick per setting::

    python benchmarks/blas_threads.py [--duration 4] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

import mpcbox
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import Scenario
from mpcbox.registry import make_controller, task_class

SETTINGS = {"one BLAS thread (default)": "1", "BLAS left alone": "0"}


def closed_loop(duration: float) -> dict:
    problem = task_class("humanoid_balance")()
    controller = make_controller("ilqr", problem)
    sim = mpcbox.simulate(problem, controller, duration)
    return {
        "survived": sim.metrics.survived,
        "tick_p50_ms": sim.metrics.compute_p50_ms,
        "tick_p99_ms": sim.metrics.compute_p99_ms,
    }


def two_processes(duration: float) -> dict:
    result = compare(
        "humanoid_balance",
        ["ilqr"],
        [Scenario(duration=duration, noise_scale=1.0)],
        seeds=[0, 1],
        workers=2,
        progress=False,
    )
    return {
        "survived": [run.metrics.survived for run in result.runs],
        "tick_p50_ms": [run.metrics.compute_p50_ms for run in result.runs],
        "tick_p99_ms": [run.metrics.compute_p99_ms for run in result.runs],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=4.0)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    from threadpoolctl import threadpool_info

    started = time.perf_counter()
    runs = []
    for repeat in range(args.repeats):
        for label, value in SETTINGS.items():
            os.environ["MPCBOX_PLANNER_BLAS_THREADS"] = value  # the workers inherit it
            runs.append(
                {"repeat": repeat, "setting": label, "loop": "one process"}
                | closed_loop(args.duration)
            )
            runs.append(
                {"repeat": repeat, "setting": label, "loop": "two worker processes"}
                | two_processes(min(args.duration, 2.0))
            )
            print(json.dumps(runs[-2]), json.dumps(runs[-1]), file=sys.stderr)
    summary = {}
    for label in SETTINGS:
        for loop in ("one process", "two worker processes"):
            mine = [r for r in runs if r["setting"] == label and r["loop"] == loop]
            summary[f"{label}, {loop}"] = {
                "tick_p50_ms": round(
                    float(np.median(np.hstack([r["tick_p50_ms"] for r in mine]))), 1
                ),
                "tick_p99_ms": round(
                    float(np.median(np.hstack([r["tick_p99_ms"] for r in mine]))), 1
                ),
            }
    out = {
        "task": "humanoid_balance",
        "controller": "ilqr (the task's config)",
        "machine": f"{os.cpu_count()}-core CPU ({platform.machine()})",
        "blas": [
            {k: info.get(k) for k in ("internal_api", "version", "num_threads")}
            for info in threadpool_info()
            if info.get("user_api") == "blas"
        ],
        "python": platform.python_version(),
        "command": "python benchmarks/blas_threads.py " + " ".join(sys.argv[1:]),
        "wall_s": round(time.perf_counter() - started, 1),
        "summary (medians over repeats and seeds)": summary,
        "runs": runs,
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
