"""Is the real-time world slowing the planner? An arm's replan latency at several speeds.

:func:`mpcbox.simulate_realtime` steps the world in the calling thread at the model's rate
(1000 steps per wall second for a 1 ms model) while the planner runs in another thread of
the same process; both need Python's GIL, and on a machine with few cores the world's
wake-ups also take CPU from the planner's threads. Slowing the world down (``speed < 1``:
simulated seconds per wall second) removes that load and leaves the planner's work per
replan the same. A latency that falls with the speed is the world's doing; one that stays
is the planner's own (such as line searches that fail and are retried, counted here as
stalled replans). One run per speed and repeat of the arm reach of
``benchmarks/panda_reach.py`` (seed 0), printing JSON::

    MENAGERIE_ROOT=/work/menagerie python benchmarks/realtime_world_rate.py \
        [--arm unitree_z1] [--speeds 1,0.5,0.25,0.1] [--repeats 2] [--out FILE]
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from arm_reach_control_steps import ALL_ARMS  # benchmarks/ is not a package
from panda_reach import build, default_args

import mpcbox
from mpcbox.registry import make_controller
from mpcbox.sim.trajectory import jsonable


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arm", default="unitree_z1", choices=sorted(ALL_ARMS))
    parser.add_argument("--speeds", default="1,0.5,0.25,0.1")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--duration", type=float, default=1.0, help="simulated seconds")
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args()
    options = default_args("menagerie:" + args.arm)
    options.offset, options.timestep = ALL_ARMS[args.arm]
    problem = build(0, options)
    rows = []
    started = time.perf_counter()
    for repeat in range(args.repeats):
        for speed in [float(s) for s in args.speeds.split(",")]:
            controller = make_controller("ilqr", problem)
            sim = mpcbox.simulate_realtime(problem, controller, args.duration, speed=speed)
            rt = sim.realtime
            assert rt is not None
            row = {
                "repeat": repeat,
                "speed": speed,
                "world_steps_per_wall_s": speed / problem.model.opt.timestep,
                "replan_latency_p50_ms": rt.latency_p50_ms,
                "replan_latency_p99_ms": rt.latency_p99_ms,
                "world_lag_ms": 1e3 * rt.world_lag_s,
                "replans": int(controller.stats["replans"]),
                "stalled_replans": int(controller.stats["fallbacks"]),
                "final_error_mm": 1e3 * float(problem.reach_error(sim.states[-1])),
            }
            rows.append(row)
            print(json.dumps(jsonable(row)), file=sys.stderr)
    by_speed = {}
    for speed in sorted({r["speed"] for r in rows}, reverse=True):
        lat = [r["replan_latency_p50_ms"] for r in rows if r["speed"] == speed]
        by_speed[str(speed)] = {"replan_latency_p50_ms": [round(v, 1) for v in lat]}
    out = {
        "arm": args.arm,
        "timestep_s": problem.model.opt.timestep,
        "ilqr": {
            "horizon": controller.horizon,
            "control_steps": controller.steps,
            "knot_dt_s": controller.knot_dt,
        },
        "machine": f"{os.cpu_count()}-core CPU ({platform.machine()})",
        "python": platform.python_version(),
        "command": "python benchmarks/realtime_world_rate.py " + " ".join(sys.argv[1:]),
        "wall_s": round(time.perf_counter() - started, 1),
        "summary": by_speed,
        "median_latency_by_speed_ms": {
            k: float(np.median(v["replan_latency_p50_ms"])) for k, v in by_speed.items()
        },
        "runs": rows,
    }
    text = json.dumps(jsonable(out), indent=2)
    if args.out:
        Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
