"""Grasp success over randomized trials: force-QP grasp against position grasp; JSON.

For each friction level (low 0.3-0.6, medium 1.0-1.25, high 1.25-1.5 sliding friction;
torsional 0.1-0.3 m and rolling 0.05-0.15 m everywhere) runs ``--trials`` randomized trials
(:func:`mpcbox.tasks.grasp.run_trials`: a third hard, soft and irregular objects, mass
0.1-1 kg, contact stiffness 1e3-1e6 N/m), each with both controllers on the same draw, and
a second position grasp with weaker finger servos (``--weak-kp``, a squeeze near the force
grasp's median). A trial closes on the object, lifts it 5 cm, pushes it with half its weight
in a random direction and shakes it (5 mm at 4 Hz). Success: the object stays within 1 cm
of where it sat in the gripper when the lift began. Prints the per-level tables (success
rate by object kind, largest and median finger force, slip, how often the force grasp raised
its safety factor) as JSON and writes ``benchmarks/results/grasp.json``.

    python benchmarks/grasp.py [--trials 100] [--seed 0] [--levels low medium high]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from mpcbox.controllers.grasp.config import ForceGraspConfig
from mpcbox.tasks.grasp import (
    FRICTION_LEVELS,
    GripperConfig,
    TrialConfig,
    run_trials,
    success_table,
)
from mpcbox.tasks.grasp.objects import MASS_RANGE, ROLLING_RANGE, STIFFNESS_RANGES, TORSIONAL_RANGE

RESULTS = Path(__file__).resolve().parent / "results" / "grasp.json"


def _failures(records: list) -> list[dict]:
    """The failed trials, briefly, for reading the table."""
    out = []
    for r in records:
        if r.result.success:
            continue
        obj = r.draw.object
        out.append(
            {
                "trial": r.index,
                "controller": r.controller,
                "kind": obj.kind,
                "shape": obj.shape,
                "mass": round(obj.mass, 3),
                "friction": round(float(obj.friction[0]), 3),
                "stiffness": float(f"{obj.stiffness:.3g}"),
                "slip_m": round(r.result.slip, 4),
                "max_finger_force_N": round(r.result.max_finger_force, 1),
            }
        )
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (``argv`` defaults to the command line)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--levels", nargs="*", default=list(FRICTION_LEVELS))
    parser.add_argument(
        "--weak-kp",
        type=float,
        default=150.0,
        help="finger servo gain (N/m) of a second, weaker position grasp",
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)

    gripper, trial, grasp = GripperConfig(), TrialConfig(), ForceGraspConfig()
    levels = {}
    start = time.perf_counter()
    for level in args.levels:
        t0 = time.perf_counter()
        records = run_trials(level, args.trials, seed=args.seed, gripper=gripper, trial=trial)
        weak = run_trials(
            level,
            args.trials,
            seed=args.seed,
            controllers=("position",),
            gripper=GripperConfig(finger_kp=args.weak_kp),
            trial=trial,
        )
        records += [r._replace(controller=f"position kp={args.weak_kp:g}") for r in weak]
        wall = time.perf_counter() - t0
        table = success_table(records)
        levels[level] = {
            "sliding_friction": FRICTION_LEVELS[level],
            "table": table,
            "success_rate": {name: rows["all"]["success_rate"] for name, rows in table.items()},
            "failures": _failures(records),
            "wall_s": round(wall, 1),
        }
    report = {
        "benchmark": "grasp",
        "command": "python benchmarks/grasp.py " + " ".join(argv or sys.argv[1:]),
        "machine": "2-core sandbox CPU, shared",
        "trials_per_level": args.trials,
        "seed": args.seed,
        "ranges": {
            "mass_kg": MASS_RANGE,
            "torsional_m": TORSIONAL_RANGE,
            "rolling_m": ROLLING_RANGE,
            "stiffness_N_per_m": STIFFNESS_RANGES,
            "mass_estimate_error": 0.2,
        },
        "gripper": vars(gripper),
        "trial": vars(trial),
        "force_grasp": {**vars(grasp), "friction": "middle of the level's range"},
        "position_grasp": (
            "both fingers commanded fully closed (set-point = opening), finger servo gain "
            f"{gripper.finger_kp:g} N/m ('position') and {args.weak_kp:g} N/m "
            f"('position kp={args.weak_kp:g}'), on the same draws"
        ),
        "levels": levels,
        "wall_s": round(time.perf_counter() - start, 1),
    }
    text = json.dumps(report, indent=2, default=lambda v: np.asarray(v).tolist())
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
