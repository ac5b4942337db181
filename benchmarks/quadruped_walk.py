"""A quadruped walking to a target (``quadruped_walk``): success rate and time taken; JSON.

For each controller and seed, :class:`~mpcbox.tasks.legged.walk.QuadrupedWalk` (its target
``--distance`` m ahead, reached within its radius) runs for ``--duration`` s in the
real-time loop (:func:`~mpcbox.sim.realtime.simulate_realtime`: the world does not wait
for the planner) and/or in lock-step (:func:`mpcbox.simulate`), with the task's tuned
controller config. Seed ``s``: joint angles of the standing start perturbed by
N(0, ``--start-perturbation``) rad, controller seed ``s``, and the task's actuator noise
recipe times ``--noise-scale`` drawn with seed ``s``. Reported per run: outcome, time to
target, closest and final distance, tick p50/p99 and whether the planner kept up; per
controller and loop: success rate, mean and median time to target over the successes,
worst p99 tick and the share of runs that kept up::

    python benchmarks/quadruped_walk.py --backend cpu --loops lockstep --seeds 5 \\
        --first-seed 100 --json benchmarks/results/quadruped_walk_cpu.json
    python benchmarks/quadruped_walk.py --backend warp --seeds 10 --first-seed 100 \\
        --controllers ps,mppi,cem --json OUT.json        # 1024 candidates on the GPU
    MENAGERIE_ROOT=... python benchmarks/quadruped_walk.py --model menagerie:unitree_go1

``--num-samples`` defaults to the config's (128) on the CPU and 1024 on ``warp``;
``--set field=value,...`` changes other config fields for every controller, ``--task-set``
options of the task.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.cli.checks import lookahead_option
from mpcbox.comparison.records import cpu_name, gpu_names
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.tasks.legged.walk import QuadrupedWalk

#: Candidates per tick on the GPU unless ``--num-samples`` says otherwise.
WARP_SAMPLES = 1024


def parse_set(text: str) -> dict:
    """``key=value,...`` with each value read as JSON where it parses, else as text (also
    the ``--set``/``--task-set`` reader of ``realtime.py``)."""
    out: dict = {}
    for pair in filter(None, text.split(",")):
        key, _, value = pair.partition("=")
        try:
            out[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            out[key.strip()] = value.strip()
    return out


def run(problem: QuadrupedWalk, ctrl, seed: int, args) -> tuple[dict, dict]:
    # One controller serves every seed (a warp controller compiles and captures its graph
    # once); the run's reset() re-seeds its noise from the config's seed.
    ctrl.config = dataclasses.replace(ctrl.config, seed=seed)
    init = problem.initial_state()
    rng = np.random.default_rng(seed)
    adr = 7 if problem.root_qpos is not None else 0
    init[adr : problem.nq] += rng.normal(0.0, args.start_perturbation, problem.nq - adr)
    noise = problem.noise(args.noise_scale) if args.noise_scale > 0 else None
    common = dict(noise=noise, seed=seed, initial_state=init)
    start = time.perf_counter()
    if args.loop == "realtime":
        res = simulate_realtime(
            problem, ctrl, args.duration, speed=args.speed, lookahead=args.lookahead, **common
        )
    else:
        res = mpcbox.simulate(problem, ctrl, args.duration, **common)
    wall = time.perf_counter() - start
    config = {
        k: getattr(ctrl.config, k)
        for k in ("num_samples", "horizon", "num_knots", "noise_scale", "planning_timestep")
    }
    config["period"] = ctrl.period
    distances = problem.target_distances(res.states)
    row = {
        "seed": seed,
        "outcome": res.metrics.outcome,
        "failure": res.failure,
        "time_to_target_s": problem.time_to_target(res.time, res.states),
        "closest_m": float(distances.min()),
        "final_distance_m": float(distances[-1]),
        "sim_time_s": float(res.time[-1]),
        "wall_s": wall,
    }
    rt = getattr(res, "realtime", None)
    if rt is not None:
        row.update(
            tick_p50_ms=rt.latency_p50_ms,
            tick_p99_ms=rt.latency_p99_ms,
            kept_up=bool(rt.kept_up),
            over_period_share=rt.over_period_share,
            world_lag_s=rt.world_lag_s,
        )
    else:
        row.update(
            tick_p50_ms=res.metrics.compute_p50_ms,
            tick_p99_ms=res.metrics.compute_p99_ms,
            kept_up=None,
        )
    return row, config


def summary(rows: list[dict], period: float) -> dict:
    ok = [r for r in rows if r["outcome"] == "success"]
    times = [r["time_to_target_s"] for r in ok]
    kept = [r["kept_up"] for r in rows if r.get("kept_up") is not None]
    ticks = [r["tick_p99_ms"] for r in rows if np.isfinite(r.get("tick_p99_ms", np.nan))]
    return {
        "successes": len(ok),
        "runs": len(rows),
        "success_rate": len(ok) / len(rows) if rows else float("nan"),
        "mean_time_to_target_s": float(np.mean(times)) if times else None,
        "median_time_to_target_s": float(np.median(times)) if times else None,
        "mean_final_distance_m": float(np.mean([r["final_distance_m"] for r in rows])),
        "tick_p50_ms_median": float(np.median([r["tick_p50_ms"] for r in rows])),
        "tick_p99_ms_max": float(max(ticks)) if ticks else None,
        "period_ms": 1e3 * period,
        "kept_up_rate": float(np.mean(kept)) if kept else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--model", default="dm_control", help="dm_control or menagerie:NAME")
    parser.add_argument("--controllers", default="ps")
    parser.add_argument("--loops", default="realtime", help="realtime, lockstep or both")
    parser.add_argument("--backend", default="cpu", choices=("cpu", "warp"))
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--distance", type=float, default=1.0)
    parser.add_argument("--num-samples", type=int, default=None)
    parser.add_argument("--set", default="", help="config fields, e.g. horizon=0.6,num_knots=5")
    parser.add_argument("--task-set", default="", help="task options, e.g. distance_cost=20")
    parser.add_argument("--noise-scale", type=float, default=1.0)
    parser.add_argument("--start-perturbation", type=float, default=0.02)
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument(
        "--lookahead", default=None, help="real-time loop: seconds or 'auto' (default: none)"
    )
    parser.add_argument("--threads", type=int, default=None, help="CPU rollout threads")
    parser.add_argument("--machine", default=None, help="default: CPU model and core count")
    parser.add_argument("--note", default="")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    args.lookahead = lookahead_option(args.lookahead)  # checked before any run

    model = None if args.model == "dm_control" else args.model
    task_options = parse_set(args.task_set)
    problem = QuadrupedWalk(model, distance=args.distance, threads=args.threads, **task_options)
    options: dict = {"backend": args.backend, **parse_set(args.set)}
    samples = args.num_samples or (WARP_SAMPLES if args.backend == "warp" else None)
    if samples is not None:
        options["num_samples"] = samples
    report: dict = {
        "benchmark": "quadruped_walk",
        "model": args.model,
        "machine": args.machine or f"{cpu_name()}, {os.cpu_count()} cores visible",
        "gpu": next(iter(gpu_names()), None) if args.backend == "warp" else None,
        "platform": platform.platform(),
        "backend": args.backend,
        "target": problem.target.tolist(),
        "radius_m": problem.radius,
        "duration_s": args.duration,
        "first_seed": args.first_seed,
        "seeds": args.seeds,
        "noise_scale": args.noise_scale,
        "start_perturbation_rad": args.start_perturbation,
        "speed": args.speed,
        "task_options": task_options,
        "options": dict(options),
        "note": args.note,
        "results": {},
    }

    def save() -> None:
        if args.json:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(json.dumps(report, indent=1) + "\n")

    for name in args.controllers.split(","):
        ctrl = mpcbox.make_controller(name, problem, **options)
        for loop in args.loops.split(","):
            args.loop = loop
            rows, config = [], {}
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                row, config = run(problem, ctrl, seed, args)
                rows.append(row)
                print(json.dumps({name: {loop: row}}), flush=True)
            entry = {"config": config, "runs": rows}
            entry["summary"] = summary(rows, config["period"])
            report["results"][f"{name}/{loop}"] = entry
            save()
        if hasattr(ctrl, "close"):
            ctrl.close()
    print(json.dumps({k: v["summary"] for k, v in report["results"].items()}, indent=1))


if __name__ == "__main__":
    main()
