"""Acceptance evaluation of humanoid one-leg balance; prints JSON.

For each controller (default: LQR only):

* survival over ``--seeds`` seeds of ``--duration`` s at ``--noise`` times the recipe's
  actuator noise (``HumanoidBalance().noise()``), and the mean time to fall (survived runs
  counted at the full duration; the mean over failed runs alone is reported too);
* the largest sagittal push on the torso over 0.1 s, forward and backward, by bisection on
  the force (no noise, the robot must stay up 3 s after the push).

Seeds run in parallel worker processes with a progress bar::

    python benchmarks/balance_eval.py                      # LQR, 100 seeds x 60 s
    python benchmarks/balance_eval.py --controllers lqr,ilqr --seeds 20 --duration 20
    python benchmarks/balance_eval.py --json benchmarks/results/balance_eval_lqr.json
    python benchmarks/balance_eval.py --controllers qp --seeds 20 \
        --controller-options '{"qp": {"osqp_settings": {"rho": 0.3}}}'
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
from json_report import check_balance_args, json_option  # benchmarks/ is not a package

from mpcbox.cli.checks import number_flag, script_main
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import PushTest, Scenario


def problem_options(args: argparse.Namespace) -> dict:
    """HumanoidBalance keyword arguments from the flags (model and cost weights)."""
    options: dict = {"leg": args.leg, **json.loads(args.weights)}
    if args.model == "classic":
        from mpcbox.tasks.humanoid.balance import classic_humanoid_path

        path = classic_humanoid_path()
        if path is None:
            raise SystemExit(
                "--model classic needs mujoco-warp's test data (pip install mujoco-warp)"
            )
        options["model"] = str(path)
    elif args.model:
        options["model"] = args.model
    return options


def evaluate(args: argparse.Namespace) -> dict:
    """Run the evaluation and return the JSON-ready summary."""
    tests = [
        PushTest(
            direction=(sign, 0.0, 0.0),
            duration=0.1,
            start=1.0,
            settle=3.0,
            tolerance=args.push_tolerance,
            name=name,
        )
        for sign, name in ((1.0, "forward"), (-1.0, "backward"))
    ]
    t0 = time.perf_counter()
    result = compare(
        "humanoid_balance",
        args.controllers,
        Scenario(duration=args.duration, noise_scale=args.noise),
        range(args.seed, args.seed + args.seeds),
        push_tests=tests if args.push else (),
        problem_options=problem_options(args),
        controller_options=json.loads(args.controller_options),
        workers=args.workers or None,
        progress=not args.quiet,
    )
    out = {
        "task": "humanoid_balance",
        "leg": args.leg,
        "model": args.model or "mpcbox/tasks/scenes/humanoid.xml",
        "cost_weights": json.loads(args.weights),
        "controller_options": json.loads(args.controller_options),
        "seeds": args.seeds,
        "first_seed": args.seed,
        "duration_s": args.duration,
        "noise_scale": args.noise,
        "push": {"duration_s": 0.1, "start_s": 1.0, "settle_s": 3.0, "body": "torso"},
        "controllers": {},
        "wall_time_s": round(time.perf_counter() - t0, 1),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }
    for row in result.rows():
        runs = result.runs_of(row.controller, 0)
        failed = [r for r in runs if not r.metrics.survived]
        entry = {
            "survival_rate": row.success_rate,
            "survived": len(runs) - len(failed),
            "runs": len(runs),
            "mean_time_to_fall_s": round(row.mean_time_to_fall, 3),
            "mean_time_to_fall_of_failed_s": (
                round(float(np.mean([r.metrics.time_to_fall for r in failed])), 3)
                if failed
                else None
            ),
            "failed_seeds": [r.seed for r in failed],
            # A run that failed before recording (a build error) has no measures: its
            # failure is listed instead.
            "failures": sorted({r.failure for r in runs if r.failure}),
            "com_deviation_rms_cm": _rounded(row.measures.get("com_deviation_rms_cm"), 3),
            "tilt_rms_deg": _rounded(row.measures.get("tilt_rms_deg"), 3),
            "compute_mean_ms": round(row.compute_mean_ms, 3),
            "compute_p99_ms": round(row.compute_p99_ms, 3),
            "realtime_factor": round(row.realtime_factor, 2),
            "fallbacks": row.fallbacks,
        }
        for name, limit in result.push_limits.get(row.controller, {}).items():
            entry[f"largest_push_{name}"] = {
                "force_N": round(limit.force, 2),
                "impulse_Ns": round(limit.impulse, 3),
                "smallest_failed_N": round(limit.smallest_failed, 2),
                "simulations": limit.simulations,
            }
        out["controllers"][row.controller] = entry
    return out


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--controllers", default="lqr", help="comma-separated names")
    parser.add_argument(
        "--controller-options",
        default="{}",
        help='JSON overrides per controller name, e.g. \'{"qp": {"time_limit": 0.015}}\'',
    )
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0, help="first seed")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per run")
    parser.add_argument("--noise", type=float, default=1.0, help="noise scale (1 = recipe)")
    parser.add_argument("--leg", choices=["left", "right"], default="left")
    parser.add_argument(
        "--model", default="", help="MJCF path, or 'classic' for mujoco-warp's classic humanoid"
    )
    parser.add_argument(
        "--weights",
        default="{}",
        help="HumanoidBalance cost weights as JSON, e.g. '{\"ctrl_cost\": 0.3}'",
    )
    parser.add_argument("--push-tolerance", type=float, default=1.0, help="bisection (N)")
    parser.add_argument("--no-push", dest="push", action="store_false", help="skip pushes")
    parser.add_argument("--workers", type=int, default=0, help="processes (0: one per core)")
    parser.add_argument("--json", default="", help="also write the JSON to this path")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    check_balance_args(args, "--seed")
    number_flag("--noise", args.noise, low=0.0, strict=False)
    json_option("--weights", args.weights)
    summary = evaluate(args)
    text = json.dumps(summary, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(script_main(main, None))
