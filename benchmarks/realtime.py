"""Lock-step vs real-time closed loop for the sampling controllers; prints JSON.

Runs the cart-pole swing-up (``CartpoleSwingup``) with each controller's task defaults
twice per seed: in :func:`mpcbox.simulate` (the world waits for the planner) and in
:func:`mpcbox.sim.realtime.simulate_realtime` (it does not). Reports per controller and
loop: outcomes, success rate, tick latency (p50/p99), state age, share of ticks over the
control period and whether the planner kept up::

    python benchmarks/realtime.py                                  # CPU, ps/mppi/cem, 2 seeds
    python benchmarks/realtime.py --backend warp --seeds 5 --json OUT.json
    python benchmarks/realtime.py --task humanoid_stand --backend warp --loops realtime

``--task`` takes any registered task (default the cart-pole swing-up); ``--period`` defaults
to each controller's tuned period.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.registry import task_class
from mpcbox.sim.realtime import simulate_realtime


def gpu_name() -> str | None:
    """The first GPU's name from ``nvidia-smi``, or ``None``."""
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
        return out.stdout.strip().splitlines()[0]
    except Exception:
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="cartpole_swingup")
    parser.add_argument("--loops", default="lockstep,realtime")
    parser.add_argument("--controllers", default="ps,mppi,cem")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--num-samples", type=int, default=None)
    parser.add_argument("--period", type=float, default=None)
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument(
        "--set",
        default="",
        help="config fields for every controller, e.g. planning_timestep=0.015,horizon=0.48",
    )
    parser.add_argument("--gpu", default=None, help="GPU name to record (default nvidia-smi)")
    parser.add_argument("--machine", default="2-core sandbox CPU, shared")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()

    problem = task_class(args.task)()
    report: dict = {
        "task": args.task,
        "machine": args.machine,
        "gpu": args.gpu or (gpu_name() if args.backend == "warp" else None),
        "set": args.set,
        "platform": platform.platform(),
        "backend": args.backend,
        "duration_s": args.duration,
        "seeds": args.seeds,
        "period_s": args.period,
        "speed": args.speed,
        "results": {},
    }
    for name in args.controllers.split(","):
        options: dict = {"backend": args.backend}
        if args.period is not None:
            options["period"] = args.period
        if args.num_samples is not None:
            options["num_samples"] = args.num_samples
        for pair in filter(None, args.set.split(",")):
            key, _, value = pair.partition("=")
            try:
                options[key.strip()] = json.loads(value)
            except json.JSONDecodeError:
                options[key.strip()] = value.strip()
        ctrl = mpcbox.make_controller(name, problem, **options)
        entry: dict = {}
        entry["period_s"] = ctrl.period
        entry["num_samples"] = ctrl.config.num_samples
        for loop in args.loops.split(","):
            rows = []
            for seed in range(args.seeds):
                init = problem.initial_state()
                if seed:
                    rng = np.random.default_rng(seed)
                    init = init + np.concatenate(
                        [rng.normal(0, 0.05, problem.nq), np.zeros(problem.nv + problem.na)]
                    )
                if loop == "lockstep":
                    res = mpcbox.simulate(problem, ctrl, args.duration, initial_state=init)
                else:
                    res = simulate_realtime(
                        problem, ctrl, args.duration, initial_state=init, speed=args.speed
                    )
                row = {
                    "seed": seed,
                    "outcome": res.metrics.outcome,
                    "tick_p50_ms": res.metrics.compute_p50_ms,
                    "tick_p99_ms": res.metrics.compute_p99_ms,
                }
                if loop == "realtime":
                    rt = res.realtime
                    row.update(
                        kept_up=rt.kept_up,
                        ticks=rt.ticks,
                        over_period_share=rt.over_period_share,
                        state_age_mean_ms=rt.state_age_mean_s * 1e3,
                        world_lag_ms=rt.world_lag_s * 1e3,
                        sim_over_wall=rt.sim_time_s / rt.wall_time_s,
                    )
                rows.append(row)
            entry[loop] = {
                "success_rate": float(np.mean([r["outcome"] == "success" for r in rows])),
                "runs": rows,
            }
            if loop == "realtime":
                entry[loop]["kept_up_rate"] = float(np.mean([r["kept_up"] for r in rows]))
        report["results"][name] = entry
        if hasattr(ctrl, "close"):
            ctrl.close()
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
