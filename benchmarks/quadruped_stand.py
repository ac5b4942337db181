"""Quadrupeds standing (Menagerie Go1, A1, ANYmal C): LQR and QP-MPC under the generic recipe.

For each robot, :class:`~mpcbox.tasks.legged.quadruped.QuadrupedStand` (its keyframe, or
``qpos0`` for the ANYmal C which has none, with the root height and holding set-points from
the actuator model) and each controller (default LQR and QP-MPC with a friction pyramid at
each foot):

* success over ``--seeds`` seeds of ``--duration`` s under the robot-independent noise
  recipe (``problem.noise()``: 5 % of each actuator's range; for these position servos,
  5 % of the force range as torque);
* the largest forward push on the root body (0.1 s at 1 s, no noise, 2 s to recover), by
  bisection to ``--push-tolerance`` N;
* QP-MPC fallbacks over all solves of the noise runs, and the median and 99th percentile
  tick time of the online solves.

The QP-MPC runs with the task's configuration (``QuadrupedStand.controller_configs``) and
OSQP's settings as they are in ``mpcbox/controllers/qp_mpc`` at the time of the run.
Needs ``MENAGERIE_ROOT`` (or the mujoco-menagerie package)::

    python benchmarks/quadruped_stand.py --json benchmarks/results/quadruped_stand.json
    python benchmarks/quadruped_stand.py --robots unitree_go1 --seeds 5 --duration 3
    python benchmarks/quadruped_stand.py --controllers qp \\
        --controller-options '{"qp": {"between_ticks": "lqr"}}'
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from json_report import SANDBOX, check_balance_args, finish  # benchmarks/ is not a package

from mpcbox.cli.checks import script_main
from mpcbox.cli.compare_parser import add_push_scan_step
from mpcbox.comparison.report import Comparison
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.tasks.legged.quadruped import QuadrupedStand

ROBOTS = ("unitree_go1", "unitree_a1", "anybotics_anymal_c")


def controller_summary(result: Comparison, name: str) -> dict:
    """One controller's runs of the first scenario and its push limits, JSON-ready."""
    runs = result.runs_of(name, 0)
    metrics = [r.metrics for r in runs]
    out: dict = {}
    if metrics:
        solves = sum(m.solve_ticks for m in metrics)
        fallbacks = sum(m.fallbacks for m in metrics)
        out = {
            "success": sum(m.success for m in metrics),
            "runs": len(metrics),
            "outcomes": sorted({m.outcome for m in metrics}),
            "failed_seeds": [r.seed for r in runs if not r.metrics.success],
            "failures": sorted({r.failure for r in runs if r.failure}),
            "solves": solves,
            "fallbacks": fallbacks,
            "fallback_fraction": round(fallbacks / solves, 5) if solves else None,
            "tick_median_ms": round(float(np.median([m.compute_p50_ms for m in metrics])), 3),
            "tick_p99_ms": round(float(np.max([m.compute_p99_ms for m in metrics])), 3),
            "period_ms": round(1000 * metrics[0].period_s, 2),
            # Runs that failed before recording (a build error) have no measures.
            "tilt_rms_deg": _mean_measure(metrics, "tilt_rms_deg", 1.0),
            "com_deviation_rms_cm": _mean_measure(metrics, "com_deviation_rms_m", 100.0),
        }
    for label, limit in result.push_limits.get(name, {}).items():
        out[f"largest_push_{label}"] = {
            "force_N": round(limit.force, 1),
            "smallest_failed_N": round(limit.smallest_failed, 1),
            "simulations": limit.simulations,
            "travel_m": round(limit.travel, 3),
        }
    return out


def add_push_options(parser: argparse.ArgumentParser, settle: float = 2.0) -> None:
    """``--push-settle`` (default ``settle``) and ``--push-rest-speed`` of the largest-push
    test."""
    parser.add_argument("--push-settle", type=float, default=settle, help="time after the push (s)")
    parser.add_argument(
        "--push-rest-speed",
        type=float,
        default=None,
        help="a survived push must also end with the root slower than this (m/s)",
    )
    add_push_scan_step(parser)


def push_record(args: argparse.Namespace) -> dict:
    """The push test's settings, for the JSON: 0.1 s at 1 s, no noise."""
    return {
        "start_s": 1.0,
        "duration_s": 0.1,
        "settle_s": args.push_settle,
        "rest_speed_m_s": args.push_rest_speed,
        "scan_step_N": args.push_scan_step,
        "noise": 0,
    }


def _mean_measure(metrics: list, name: str, scale: float) -> float | None:
    """Mean of measure ``name`` times ``scale`` over the runs that recorded it."""
    values = [m.measures[name] for m in metrics if name in m.measures]
    return round(scale * float(np.mean(values)), 3) if values else None


def evaluate(robot: str, args: argparse.Namespace) -> dict:
    """One robot's results, JSON-ready."""
    model = f"menagerie:{robot}"
    probe = QuadrupedStand(model, threads=1)
    test = PushTest(
        body=probe.root,
        start=1.0,
        duration=0.1,
        settle=args.push_settle,
        rest_speed=args.push_rest_speed,
        scan_step=args.push_scan_step,
        tolerance=args.push_tolerance,
        max_force=20 * float(probe.model.body_subtreemass[probe.root_id]) * 9.81,
        name="forward",
    )
    t0 = time.perf_counter()
    result = compare(
        "quadruped_stand",
        args.controllers.split(","),
        Scenario(name="noise", duration=args.duration),
        range(args.first_seed, args.first_seed + args.seeds),
        push_tests=[test] if args.push else [],
        problem_options={"model": model, "threads": 1},
        controller_options=json.loads(args.controller_options),
        workers=args.workers or None,
        progress=False,
    )
    out = {
        "root": probe.root,
        "feet": list(probe.contacts),
        "mass_kg": round(float(probe.model.body_subtreemass[probe.root_id]), 3),
        "fall_height_m": round(probe.fall_height, 4),
        "noise_std_ctrl": [round(float(s), 5) for s in probe.noise().std],
        "noise_std_torque_Nm": [
            round(float(s * k), 4) for s, k in zip(probe.noise().std, _k(probe))
        ],
        "controllers": {},
        "wall_time_s": round(time.perf_counter() - t0, 1),
    }
    for name in args.controllers.split(","):
        out["controllers"][name] = controller_summary(result, name)
    probe.close()
    return out


def _k(problem: QuadrupedStand) -> np.ndarray:
    """Torque per unit control of each actuator at the reference posture."""
    from mpcbox.core.actuator_scales import actuator_scales

    return actuator_scales(problem.model, problem.qpos_ref).torque_per_ctrl


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--robots", default=",".join(ROBOTS), help="Menagerie names")
    parser.add_argument("--controllers", default="lqr,qp", help="comma-separated names")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run from this one")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds per run")
    parser.add_argument("--push-tolerance", type=float, default=5.0, help="bisection (N)")
    add_push_options(parser)
    parser.add_argument("--no-push", dest="push", action="store_false", help="skip pushes")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument(
        "--controller-options",
        default="{}",
        help='JSON overrides per controller name, e.g. \'{"qp": {"between_ticks": "lqr"}}\'',
    )
    parser.add_argument("--machine", default=SANDBOX, help="what runs it, for the JSON")
    parser.add_argument("--json", default="", help="also write the JSON here")
    args = parser.parse_args(argv)
    check_balance_args(args, "--first-seed")
    t0 = time.perf_counter()
    out = {
        "benchmark": "quadruped_stand",
        "task": "quadruped_stand (LeggedBalance defaults; noise recipe: 5 % of each range)",
        "seeds": args.seeds,
        "duration_s": args.duration,
        "push": push_record(args),
        "controller_options": json.loads(args.controller_options),
        "robots": {robot: evaluate(robot, args) for robot in args.robots.split(",")},
    }
    return finish(out, args.json, started=t0, machine=args.machine)


if __name__ == "__main__":
    sys.exit(script_main(main, None))
