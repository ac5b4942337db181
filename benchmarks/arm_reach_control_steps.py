"""iLQR-MPC on Menagerie arms with held controls (``control_steps``) against the former config.

For every arm and seed (the perturbed starts and targets of ``benchmarks/panda_reach.py``)
the 40 cm (Z1: 20 cm) reach runs twice in closed loop for 2 s: with ``ArmReach``'s iLQR
config (25 knots of four model steps, one iteration per replan) and with the config it
replaced (100 knots of one step, two iterations per replan). Reported per run: time to
within 1 cm, final error, median and p99 replan tick, stalled replans. With
``--loop realtime`` the world runs in wall-clock time while the controller plans in a thread
of its own (:func:`mpcbox.simulate_realtime`): a slow replan then costs accuracy, and the
planner's latencies are reported instead of the lock-step ticks. Needs
``MENAGERIE_ROOT`` (an offline Menagerie copy); arms missing from it are skipped and listed.

    MENAGERIE_ROOT=/work/menagerie python benchmarks/arm_reach_control_steps.py [--seeds 3]
        [--loop realtime] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from panda_reach import (  # benchmarks/ is not a package
    OFFSET,
    TOLERANCE,
    build,
    closed_loop,
    default_args,
)

import mpcbox
from mpcbox.cli.compare import parse_sets
from mpcbox.errors import MpcboxError
from mpcbox.registry import make_controller
from mpcbox.sim.trajectory import jsonable
from mpcbox.tasks.reach import ArmReach
from mpcbox.tasks.reach_measures import arrival

#: The config ``ArmReach`` used before ``control_steps`` (every other option is the task's).
FORMER = {"horizon": 100, "control_steps": 1, "mpc_iterations": 2}

#: Arm, target offset (m) and timestep override. The UR5e of the mirror used in stop 40
#: cannot reach 40 cm sideways (the IK stops 3 cm short), so it takes the Panda's offset;
#: the Z1 needs 1 ms (its wrist servo rings at 2 ms, docs/results/stops.md, "Stop 35").
ARMS = {
    "franka_emika_panda": (OFFSET, None),
    "franka_fr3": (OFFSET, None),
    "kuka_iiwa_14": (np.array([0.0, 0.4, 0.0]), None),
    "universal_robots_ur5e": (OFFSET, None),
    "rethink_robotics_sawyer": (np.array([0.0, 0.4, 0.0]), None),
    "kinova_gen3": (np.array([0.0, 0.4, 0.0]), None),
    "unitree_z1": (np.array([0.0, 0.2, 0.0]), 0.001),
}
#: Ten more Menagerie arms first tried in stop 40 (``--arms new``): the larger two at the
#: Panda's 40 cm, the others 14 cm down and sideways, the two smallest 7 cm.
SMALL, TINY = np.array([0.0, 0.1, -0.1]), np.array([0.0, 0.05, -0.05])
NEW_ARMS = {
    "ufactory_xarm7": (OFFSET, None),
    "universal_robots_ur10e": (OFFSET, None),
    "ufactory_lite6": (SMALL, None),
    "agilex_piper": (SMALL, None),
    "arx_l5": (SMALL, None),
    "trossen_vx300s": (SMALL, None),
    "trossen_wx250s": (SMALL, None),
    "i2rt_yam": (SMALL, None),
    "trs_so_arm100": (TINY, None),
    "low_cost_robot_arm": (TINY, None),
}
ALL_ARMS = ARMS | NEW_ARMS


def realtime_loop(problem: ArmReach, duration: float, options: dict) -> dict:
    """One real-time run: the world in wall-clock time, the planner in its own thread."""
    controller = make_controller("ilqr", problem, **options)
    sim = mpcbox.simulate_realtime(problem, controller, duration)
    errors = np.array([problem.reach_error(s) for s in sim.states])
    hit = arrival(errors, sim.time, TOLERANCE)
    rt = sim.realtime
    assert rt is not None
    return {
        "outcome": sim.metrics.outcome,
        "final_error_m": float(errors[-1]),
        "time_to_1cm_s": hit.time,
        "error_after_arrival_max_m": hit.overshoot,
        "within_1cm_by_2s": bool(hit.time <= 2.0),
        "final_within_1cm": bool(errors[-1] <= TOLERANCE),
        "latency_p50_ms": rt.latency_p50_ms,
        "latency_p99_ms": rt.latency_p99_ms,
        "replan_latency_median_ms": sim.metrics.compute_p50_ms,  # the online solves
        "state_age_mean_s": rt.state_age_mean_s,
        "world_lag_s": rt.world_lag_s,
        "fallbacks": int(controller.stats["fallbacks"]),
        "replans": int(controller.stats["replans"]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--arms",
        default=",".join(ARMS),
        help="comma-separated Menagerie names, or 'new' for the ten arms of NEW_ARMS",
    )
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument(
        "--configs", default="task,former", help="comma-separated from task, former"
    )
    parser.add_argument("--loop", default="lockstep", choices=["lockstep", "realtime"])
    parser.add_argument(
        "--ilqr-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an option of the task's config (VALUE a Python literal); "
        "the former config is left as it is",
    )
    parser.add_argument(
        "--out",
        default=str(Path(__file__).parent / "results/arm_reach_control_steps.json"),
    )
    args = parser.parse_args()
    arms = list(NEW_ARMS) if args.arms == "new" else args.arms.split(",")
    unknown = sorted(set(arms) - set(ALL_ARMS))
    if unknown:
        parser.error(f"--arms: unknown {unknown}; choose from {', '.join(ALL_ARMS)} or new")
    configs = args.configs.split(",")
    task_options = parse_sets([f"ilqr.{item}" for item in args.ilqr_set]).get("ilqr", {})
    if set(configs) - {"task", "former"}:
        parser.error("--configs: choose from task, former")
    rows, skipped = [], []
    started = time.perf_counter()
    for arm in arms:
        offset, timestep = ALL_ARMS[arm]
        reach = default_args(f"menagerie:{arm}")
        reach.offset, reach.timestep = offset, timestep
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            try:
                problem = build(seed, reach)
            except (MpcboxError, FileNotFoundError) as err:
                skipped.append({"arm": arm, "seed": seed, "error": str(err)})
                print(f"{arm} seed {seed}: skipped ({err})", file=sys.stderr)
                continue
            row = {"arm": arm, "seed": seed}
            for name in configs:
                options = FORMER if name == "former" else task_options
                if args.loop == "realtime":
                    row[name] = realtime_loop(problem, args.duration, dict(options))
                else:
                    row[name] = closed_loop(problem, "ilqr", args.duration, options)
            rows.append(row)
            brief = {name: _brief(row[name]) for name in configs}
            print(f"{arm} seed {seed}: {brief}", file=sys.stderr)
    summary = {}
    for arm in arms:
        for name in configs:
            runs = [r[name] for r in rows if r["arm"] == arm]
            if not runs:
                continue
            summary[f"{arm}/{name}"] = {
                "within_1cm_by_2s": f"{sum(r['within_1cm_by_2s'] for r in runs)}/{len(runs)}",
                "final_within_1cm": f"{sum(r['final_within_1cm'] for r in runs)}/{len(runs)}",
                "final_error_mm": [round(1e3 * r["final_error_m"], 2) for r in runs],
                "stalled_replans": [r["fallbacks"] for r in runs],
            } | {key: [val[key] for val in map(_brief, runs)] for key in _brief(runs[0])}
    out = {
        "machine": "2-core sandbox CPU",
        "loop": args.loop,
        "python": platform.python_version(),
        "command": "python benchmarks/arm_reach_control_steps.py " + " ".join(sys.argv[1:]),
        "former_config": FORMER,
        "task_config_changes": task_options,
        "wall_s": round(time.perf_counter() - started, 1),
        "summary": summary,
        "skipped": skipped,
        "runs": rows,
    }
    text = json.dumps(jsonable(out), indent=2, default=float)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text + "\n")
    print(json.dumps(jsonable(summary), indent=1))


def _brief(run: dict) -> dict:
    """Arrival and timing of one run, rounded."""
    out = {"time_to_1cm_s": round(run["time_to_1cm_s"], 3)}
    if "latency_p99_ms" in run:
        out["replan_latency_median_ms"] = round(run["replan_latency_median_ms"], 1)
        out["latency_p99_ms"] = round(run["latency_p99_ms"], 1)
    else:
        out["median_tick_ms"] = round(run["median_replan_tick_ms"], 1)
        out["p99_tick_ms"] = round(run["p99_replan_tick_ms"], 1)
    return out


if __name__ == "__main__":
    main()
