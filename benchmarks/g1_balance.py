"""Unitree's G1 (MuJoCo Menagerie) balancing: the targets of issue #13, measured.

The task is :class:`~mpcbox.tasks.legged.biped.BipedStand` with its defaults: the G1's
keyframe ``stand`` (one foot: the inverse-kinematics stance on the left foot, checked for
self-collision), the root height and holding set-points from the actuator model
(:func:`~mpcbox.find_equilibrium`), cost weights in fractions of each actuator's range, and
the robot-independent noise recipe (``problem.noise()``: 5 % of each actuator's range; for
the G1's position servos, 5 % of the force range as torque). Nothing here is tuned to the
G1 beyond the preset's controller configurations (``BipedStand.controller_configs``), fixed
before the seeded runs.

Measured:

* two feet, LQR: success over ``--seeds`` seeds of ``--duration`` s under the recipe;
* the largest forward push on the pelvis (0.1 s at 1 s, no noise, ``--push-settle`` s to
  recover, 2 by default; with ``--push-rest-speed`` the pelvis must also end slower than
  that, so that a robot still hopping does not count) by bisection to ``--push-tolerance``
  N, for LQR and each MPC (``--mpc``); with ``--push-scan-step`` the bisection starts
  below the first failure of a scan in steps of that many newtons (iLQR-MPC's survival
  is not monotone in the force: ``PushTest.scan_step``);
* each MPC under the recipe over ``--mpc-seeds`` seeds: success, QP fallbacks over all
  solves, and the median and 99th percentile tick time (one thread, one process per run,
  on a shared 2-core machine: other jobs inflate the percentiles);
* one foot, LQR: success over ``--seeds`` seeds of ``--duration`` s under the recipe;
* QP-MPC's tick alone: one ``--tick-seconds`` run under the recipe in this process, after
  the worker processes have finished (one thread; other jobs on the machine still count).

Needs ``MENAGERIE_ROOT`` (or the mujoco-menagerie package)::

    python benchmarks/g1_balance.py --json benchmarks/results/g1_balance.json
    python benchmarks/g1_balance.py --seeds 3 --mpc-seeds 1 --duration 3 [--first-seed 100]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from json_report import finish  # benchmarks/ is not a package
from quadruped_stand import (  # benchmarks/ is not a package
    add_push_options,
    controller_summary,
    push_record,
)

from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.core.actuator_scales import actuator_scales
from mpcbox.registry import make_controller
from mpcbox.sim.simulation import simulate
from mpcbox.tasks.legged.biped import BipedStand

MODEL = "menagerie:unitree_g1"


def reference(problem: BipedStand) -> dict:
    """The equilibrium the controllers regulate to."""
    eq = problem.equilibrium
    scales = actuator_scales(problem.model, problem.qpos_ref)
    torque = problem.noise().std * scales.torque_per_ctrl
    lo, hi = problem.model.actuator_ctrlrange.T
    out = {
        "mass_kg": round(float(problem.model.body_subtreemass[problem.root_id]), 3),
        "contacts": list(problem.contacts),
        "fall_height_m": round(problem.fall_height, 4),
        "ctrl_within_range": bool(np.all((eq.ctrl >= lo) & (eq.ctrl <= hi))),
        "setpoint_minus_q_max_rad": round(float(np.max(np.abs(eq.ctrl - eq.qpos[7:]))), 5),
        "shortfall_actuated": float(eq.shortfall),
        "root_residual_wrench": [round(float(v), 4) for v in eq.residual_wrench],
        "noise_std_torque_Nm_range": [round(float(f(torque)), 3) for f in (np.min, np.max)],
    }
    if problem.posture is not None:
        out["posture"] = {
            "com_error_m": round(problem.posture.com_error, 5),
            "swing_height_m": round(problem.posture.swing_height, 4),
            "self_collisions": list(problem.posture.collisions),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=20, help="LQR seeds (two feet, one foot)")
    parser.add_argument("--mpc", default="qp,ilqr", help="MPC controllers to compare")
    parser.add_argument("--mpc-seeds", type=int, default=5, help="seeds of each MPC")
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run from this one")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds per run")
    parser.add_argument("--push-tolerance", type=float, default=5.0, help="bisection (N)")
    add_push_options(parser)
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument("--tick-seconds", type=float, default=5.0, help="QP tick run (s)")
    parser.add_argument("--json", default="", help="also write the JSON here")
    parser.add_argument(
        "--dry-friction",
        default="keep",
        choices=["drop", "keep"],
        help="linearize with the joints' frictionloss (keep, the task's default) or without",
    )
    parser.add_argument("--machine", default=None, help="what runs it (default: the sandbox)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    mpcs = [m for m in args.mpc.split(",") if m]
    noise = Scenario(name="noise", duration=args.duration)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    mpc_seeds = range(args.first_seed, args.first_seed + args.mpc_seeds)
    out: dict = {
        "benchmark": "g1_balance",
        "model": MODEL,
        "task": "biped_stand (LeggedBalance defaults; noise recipe: 5 % of each range)",
        "seeds": args.seeds,
        "mpc_seeds": args.mpc_seeds,
        "first_seed": args.first_seed,
        "duration_s": args.duration,
        "dry_friction": args.dry_friction,
        "push": push_record(args),
    }
    for stance in ("two", "left"):
        options = {"model": MODEL, "stance": stance, "threads": 1}
        options["dry_friction"] = args.dry_friction
        probe = BipedStand(**options)
        weight = float(probe.model.body_subtreemass[probe.root_id]) * 9.81
        test = PushTest(
            body=probe.root,
            settle=args.push_settle,
            rest_speed=args.push_rest_speed,
            scan_step=args.push_scan_step,
            tolerance=args.push_tolerance,
            max_force=5 * weight,
            name="forward",
        )
        entry: dict = {"reference": reference(probe), "controllers": {}}
        common = dict(problem_options=options, workers=args.workers or None, progress=False)
        t1 = time.perf_counter()
        lqr = compare("biped_stand", ["lqr"], noise, seeds, push_tests=[test], **common)
        entry["controllers"]["lqr"] = controller_summary(lqr, "lqr")
        if stance == "two" and mpcs:
            mpc = compare("biped_stand", mpcs, noise, mpc_seeds, push_tests=[test], **common)
            base = entry["controllers"]["lqr"]["largest_push_forward"]["force_N"]
            for name in mpcs:
                entry["controllers"][name] = controller_summary(mpc, name)
                force = entry["controllers"][name]["largest_push_forward"]["force_N"]
                entry["controllers"][name]["push_ratio_to_lqr"] = round(force / base, 3)
        entry["wall_time_s"] = round(time.perf_counter() - t1, 1)
        out["two_feet" if stance == "two" else "one_foot_left"] = entry
        probe.close()
    if "qp" in mpcs and args.tick_seconds > 0:
        problem = BipedStand(MODEL, threads=1, dry_friction=args.dry_friction)
        qp = make_controller("qp", problem)
        run = simulate(problem, qp, args.tick_seconds, noise=problem.noise(), seed=0)
        out["qp_tick_serial"] = {
            "duration_s": args.tick_seconds,
            "success": bool(run.metrics.success),
            "solves": run.metrics.solve_ticks,
            "fallbacks": run.metrics.fallbacks,
            "tick_median_ms": round(run.metrics.compute_p50_ms, 3),
            "tick_p99_ms": round(run.metrics.compute_p99_ms, 3),
        }
        problem.close()
    two = out["two_feet"]["controllers"]
    best = max((two[m]["push_ratio_to_lqr"] for m in mpcs), default=None)
    out["targets"] = {
        "two_feet_lqr_success": f"{two['lqr']['success']}/{two['lqr']['runs']}",
        "two_feet_lqr_push_N": two["lqr"]["largest_push_forward"]["force_N"],
        "best_mpc_push_ratio": best,
        "mpc_fallback_fraction": {m: two[m]["fallback_fraction"] for m in mpcs},
        "one_foot_lqr_success": "{success}/{runs}".format(
            **out["one_foot_left"]["controllers"]["lqr"]
        ),
        "qp_tick_ms_median_p99_serial": (
            [out["qp_tick_serial"][k] for k in ("tick_median_ms", "tick_p99_ms")]
            if "qp_tick_serial" in out
            else None
        ),
    }
    if args.machine:
        return finish(out, args.json, started=t0, machine=args.machine)
    return finish(out, args.json, started=t0)


if __name__ == "__main__":
    sys.exit(main())
