"""ALOHA's bimanual pot lift over randomized trials: both arms grasp the handles and lift.

Trial ``s`` shifts the pot by up to 2 cm and turns it by up to 10 degrees (seed ``s``,
:meth:`PotLift.trial_state`) and runs :func:`pot_lift_controller` (the phase-aware IK
waypoint controller driving both arms) under :func:`mpcbox.simulate`. Success: the pot's
centre at least 5 cm above its start and tilted less than 15 degrees at the end of a 1 s
hold. JSON to ``benchmarks/results/pot_lift.json``.

    python benchmarks/pot_lift.py [--trials 20]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import mpcbox
from mpcbox.tasks.manipulation.pot_lift import PotLift, PotLiftTiming, pot_lift_controller


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    args = parser.parse_args()
    problem = PotLift(threads=1)
    controller = pot_lift_controller(problem)
    duration = PotLiftTiming().total
    rows = []
    wall0 = time.perf_counter()
    for seed in range(args.trials):
        states0 = problem.trial_state(seed)
        sim = mpcbox.simulate(problem, controller, duration, initial_state=states0)
        rows.append(
            {
                "seed": seed,
                "success": bool(sim.metrics.success),
                "outcome": sim.metrics.outcome,
                "failure": sim.failure,
                "rise_mm": round(
                    1000 * (problem.pot_height(sim.states[-1]) - problem.pot_height(states0)), 1
                ),
                "tilt_deg": round(
                    float(problem.pot_tilt(sim.states[-1]) * 180 / 3.141592653589793), 2
                ),
            }
        )
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    wins = sum(r["success"] for r in rows)
    result = {
        "benchmark": "pot_lift",
        "controller": "waypoints (mink IK, both arms, phase-aware)",
        "duration_s": duration,
        "success_check": "pot rises >= 50 mm, tilt <= 15 deg at the end of a 1 s hold",
        "trials": len(rows),
        "successes": wins,
        "success_rate": wins / len(rows) if rows else None,
        "wall_s": round(time.perf_counter() - wall0, 1),
        "machine": os.environ.get("MPCBOX_MACHINE", "2-core sandbox CPU, shared"),
        "platform": platform.platform(),
        "command": " ".join(["python", *sys.argv]),
        "failures": [r for r in rows if not r["success"]],
        "per_trial": rows,
    }
    print(f"pot lift: {wins}/{len(rows)} lifted, {result['wall_s']} s")
    path = Path(__file__).resolve().parent / "results" / "pot_lift.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
