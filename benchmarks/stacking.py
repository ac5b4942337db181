"""Cube stacking over randomized trials: the CPU closed loop, and the same trials in MJWarp.

Trial ``s`` draws the cube layout (positions and yaws) from seed ``s``
(:meth:`StackCubes.trial_state`) and runs the closed-loop pick-and-place controller
(:func:`stacking_controller`: IK waypoints with mink, replanned from the measured cubes)
under :func:`mpcbox.simulate`; success is the issue's check (xy_err <= 15 mm,
35 <= dz <= 55 mm, cubes settled). With ``--worlds N`` the first ``N`` trials also run as
``N`` parallel MuJoCo Warp worlds (:func:`simulate_batch_warp`, one controller per world,
the same period), judged by the same check; a world whose contacts or constraints overflow
counts as failed. JSON with per-trial outcomes and failure reasons goes to
``benchmarks/results/stacking[_SUFFIX].json``.

    python benchmarks/stacking.py [--trials 100] [--arm aloha]
    python benchmarks/stacking.py --trials 100 --worlds 2048 --device cuda --suffix gpu

(``--trials 0`` skips the CPU trials; with both, ``agree_with_cpu`` counts the seeds where
the CPU and MJWarp outcomes agree.)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.tasks.manipulation.pick_place import PickPlaceTiming, stacking_controller
from mpcbox.tasks.manipulation.stacking import StackCubes


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95% Wilson score interval of a success rate."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (float(centre - half), float(centre + half))


def cpu_trials(problem: StackCubes, seeds: range, duration: float) -> dict:
    """The trials on the CPU, one :func:`mpcbox.simulate` each."""
    controller = stacking_controller(problem)
    rows = []
    wall0 = time.perf_counter()
    for seed in seeds:
        t0 = time.perf_counter()
        sim = mpcbox.simulate(
            problem, controller, duration, initial_state=problem.trial_state(seed)
        )
        check = problem.check(sim.states[-1])
        rows.append(
            {
                "seed": seed,
                "success": bool(sim.metrics.success),
                "outcome": sim.metrics.outcome,
                "failure": sim.failure,
                "xy_err_mm": round(1000 * check.xy_err, 2),
                "dz_mm": round(1000 * check.dz, 2),
                "ik_error_max_mm": round(1000 * controller.stats["ik_error_max"], 2),
                "wall_s": round(time.perf_counter() - t0, 2),
            }
        )
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    wins = sum(r["success"] for r in rows)
    return {
        "trials": len(rows),
        "successes": wins,
        "success_rate": wins / len(rows) if rows else float("nan"),
        "success_rate_95ci": wilson(wins, len(rows)),
        "wall_s": round(time.perf_counter() - wall0, 1),
        "failures": [r for r in rows if not r["success"]],
        "per_trial": rows,
    }


def warp_trials(
    problem: StackCubes, worlds: int, duration: float, device: str, calibration_worlds: int
) -> dict:
    """Trials ``0 .. worlds-1`` as parallel MJWarp worlds."""
    from mpcbox.sim.batch_warp import simulate_batch_warp

    seeds = range(worlds)
    template = stacking_controller(problem)
    controllers = [template.fork() for _ in seeds]
    states0 = np.stack([problem.trial_state(s) for s in seeds])
    out = simulate_batch_warp(
        problem,
        controllers,
        states0,
        duration,
        device=device,
        calibration_worlds=calibration_worlds,
    )
    rows = []
    for i, seed in enumerate(seeds):
        reason = problem.goal_failure(out.time, out.states[:, i])
        if out.errors[i]:
            reason = "controller error: " + out.errors[i]
        if out.diverged[i]:
            reason = "diverged"
        if out.overflow[i]:
            reason = f"MJWarp capacity overflow (nconmax={out.nconmax}, njmax={out.njmax})"
        check = problem.check(out.states[-1, i])
        rows.append(
            {
                "seed": seed,
                "success": reason is None,
                "failure": reason,
                "xy_err_mm": round(1000 * check.xy_err, 2),
                "dz_mm": round(1000 * check.dz, 2),
            }
        )
    wins = sum(r["success"] for r in rows)
    return {
        "worlds": worlds,
        "device": out.device,
        "successes": wins,
        "success_rate": wins / worlds,
        "success_rate_95ci": wilson(wins, worlds),
        "overflowed_worlds": int(out.overflow.sum()),
        "diverged_worlds": int(out.diverged.sum()),
        "nconmax": out.nconmax,
        "njmax": out.njmax,
        "calibration_contacts_constraints": list(out.calibration),
        "setup_s": round(out.setup_s, 2),
        "wall_s": round(out.wall_s, 2),
        "controller_host_s": round(out.controller_s, 2),
        "world_steps_per_s": round(out.world_steps_per_s, 1),
        "failures": [r for r in rows if not r["success"]],
        "per_trial": rows if worlds <= 256 else [],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arm", default="aloha", choices=["aloha", "panda"])
    parser.add_argument("--trials", type=int, default=100, help="CPU trials (0: none)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--worlds", type=int, default=0, help="MJWarp worlds (0: none)")
    parser.add_argument("--device", default=None, help="warp device: cuda, cuda:0 or cpu")
    parser.add_argument(
        "--calibration-worlds", type=int, default=16, help="CPU runs that size nconmax/njmax"
    )
    parser.add_argument("--suffix", default="", help="results/stacking_SUFFIX.json")
    args = parser.parse_args()
    problem = StackCubes(args.arm, threads=1)
    duration = PickPlaceTiming().total
    result: dict = {
        "benchmark": "stacking",
        "arm": args.arm,
        "controller": "waypoints (mink IK, phase-aware, replanned from measured cubes)",
        "duration_s": duration,
        "success_check": "xy_err <= 15 mm, 35 <= dz <= 55 mm, cubes slower than 0.02 m/s",
        "machine": os.environ.get("MPCBOX_MACHINE", "2-core sandbox CPU, shared"),
        "platform": platform.platform(),
        "command": " ".join(["python", *sys.argv]),
    }
    if args.trials:
        seeds = range(args.first_seed, args.first_seed + args.trials)
        result["cpu"] = cpu_trials(problem, seeds, duration)
        cpu = result["cpu"]
        print(f"CPU: {cpu['successes']}/{cpu['trials']} stacked, {cpu['wall_s']} s", flush=True)
    if args.worlds:
        result["warp"] = warp_trials(
            problem, args.worlds, duration, args.device, args.calibration_worlds
        )
        w = result["warp"]
        print(
            f"MJWarp ({w['device']}): {w['successes']}/{w['worlds']} stacked, "
            f"{w['overflowed_worlds']} overflowed, wall {w['wall_s']} s "
            f"(setup {w['setup_s']} s), {w['world_steps_per_s']} world-steps/s",
            flush=True,
        )
        if "cpu" in result:
            cpu_ok = {r["seed"]: r["success"] for r in result["cpu"]["per_trial"]}
            same = [
                r["success"] == cpu_ok[r["seed"]] for r in w["per_trial"] if r["seed"] in cpu_ok
            ]
            w["agree_with_cpu"] = f"{sum(same)}/{len(same)}"
    name = "stacking" + (f"_{args.suffix}" if args.suffix else "") + ".json"
    path = Path(__file__).resolve().parent / "results" / name
    summary = {k: v for k, v in result.items()}
    path.write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
