"""Warp-backend sampling closed loops on Ray with one GPU against two; prints JSON.

The same sweep (``--runs`` closed loops of ``--task`` with ``--controller`` on the warp
backend) runs on a local Ray that may use one GPU, then on one that may use two; each actor
asks for one GPU, so Ray runs one closed loop per GPU at a time. The kernel cache is warmed
by one short run first, so neither sweep pays the cold compile. Reports both wall times, the
speed-up, the placement of the runs and whether the two tables agree on the outcomes::

    python benchmarks/ray_gpus.py --runs 8 --duration 5 --json benchmarks/results/ray_gpus.json
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time

from mpcbox.comparison.executors import RayExecutor
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import Scenario


def gpu_names() -> list[str]:
    """The GPUs ``nvidia-smi`` lists (empty without one)."""
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except Exception:
        return []
    return [line.strip() for line in out.stdout.splitlines() if line.strip()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid_stand")
    parser.add_argument("--controller", default="mppi")
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()

    import ray

    options = {args.controller: {"backend": "warp"}}
    scenario = Scenario(duration=args.duration, noise_scale=1.0)
    # Warm the kernel cache (shared on disk by every actor) with one short run.
    compare(
        args.task,
        [args.controller],
        Scenario(duration=0.1, noise_scale=1.0),
        1,
        controller_options=options,
        executor="serial",
        progress=False,
    )
    walls, results = {}, {}
    for gpus in (1, 2):
        ray.init(num_gpus=gpus, include_dashboard=False, logging_level="ERROR")
        t0 = time.perf_counter()
        results[gpus] = compare(
            args.task,
            [args.controller],
            scenario,
            args.runs,
            controller_options=options,
            executor=RayExecutor(gpus_per_run=1),
            progress=False,
        )
        walls[gpus] = time.perf_counter() - t0
        ray.shutdown()
    outcomes = {g: [r.metrics.outcome for r in res.runs] for g, res in results.items()}
    out = {
        "benchmark": "ray_gpus",
        "gpus": gpu_names(),
        "platform": platform.platform(),
        "task": args.task,
        "controller": args.controller,
        "runs": args.runs,
        "run_duration_s": args.duration,
        "wall_1_gpu_s": walls[1],
        "wall_2_gpus_s": walls[2],
        "speedup_2_over_1": walls[1] / walls[2],
        "placement_1_gpu": results[1].placement,
        "placement_2_gpus": results[2].placement,
        "outcomes_1_gpu": outcomes[1],
        "outcomes_2_gpus": outcomes[2],
        "note": "GPU sums are not reproducible run to run, so outcomes may differ by seed",
    }
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
