"""A 40 cm reach of a Menagerie arm (the Panda by default): iLQR-MPC, offline iLQR, LQR, MPPI.

Each seed perturbs the start posture (arm joints +- ``--posture-noise`` rad, uniform) and
the target (``--target-noise`` m per axis around a 40 cm offset from the hand). Per seed:
iLQR-MPC in closed loop (the task's tuned config): final error, time to within 1 cm, median
replan tick; offline iLQR over ``--offline-horizon`` s from the start: its stop reason and
the final error of its plan; LQR about the IK goal posture in closed loop, and the ratio of
iLQR-MPC's time to 1 cm to LQR's. Needs ``MENAGERIE_ROOT`` (an offline Menagerie copy).

    MENAGERIE_ROOT=/work/menagerie python benchmarks/panda_reach.py [--seeds 5] [--first-seed 0]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np

import mpcbox
from mpcbox.cli.compare import parse_sets
from mpcbox.config import config_options
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.core.menagerie import MissingMeshWarning, model_source
from mpcbox.core.model import load_spec
from mpcbox.registry import make_controller
from mpcbox.sim.trajectory import jsonable
from mpcbox.tasks.reach import ArmReach
from mpcbox.tasks.reach_measures import arrival

sys.path.insert(0, str(Path(__file__).resolve().parent))
from quadruped_walk import parse_set  # benchmarks/ is not a package

#: The default nominal target offset from the hand's start position (40 cm; ``--offset``).
OFFSET = np.array([0.0, 0.3, -0.2646])
TOLERANCE = 0.01


def default_args(model: str = "menagerie:franka_emika_panda") -> argparse.Namespace:
    """The command line's defaults for :func:`build`, for other scripts."""
    return argparse.Namespace(
        model=model,
        frame=None,
        offset=OFFSET,
        posture_noise=0.1,
        target_noise=0.03,
        parent_contacts="exclude",
        dry_friction="drop",
        timestep=None,
    )


def build(seed: int, args: argparse.Namespace) -> ArmReach:
    """The seed's reach: perturbed start posture and target."""
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MissingMeshWarning)
        nominal = np.asarray(args.offset, dtype=float)
        options = {"parent_contacts": args.parent_contacts, "dry_friction": args.dry_friction}
        options.update(parse_set(getattr(args, "task_set", "")))
        model = model_source(args.model)
        if args.timestep:
            model = load_spec(model)
            model.option.timestep = args.timestep
        home = ArmReach(model, frame=args.frame, target=nominal, relative=True, **options)
        start = home.start_qpos.copy()
        # The arm's joints lead qpos on Menagerie arms; a gripper's slide joints among the
        # first seven (AgileX Piper, ARX L5) are left closed as the keyframe has them.
        hinges = home.model.jnt_qposadr[home.model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE]
        arm = [i for i in range(min(7, home.nu)) if i in set(hinges.tolist())]
        start[arm] += rng.uniform(-args.posture_noise, args.posture_noise, len(arm))
        offset = nominal + rng.uniform(-args.target_noise, args.target_noise, 3)
        return ArmReach(
            model,
            frame=args.frame,
            target=offset,
            relative=True,
            start_qpos=start,
            tolerance=TOLERANCE,
            **options,
        )


def closed_loop(problem: ArmReach, name: str, duration: float, options: dict | None = None) -> dict:
    """One closed-loop run: final error, time to 1 cm, ticks (``"mppi_servo"``: MPPI of
    joint set-points through :meth:`ArmReach.servo_planner`, for torque-driven arms)."""
    if name == "mppi_servo":
        controller = problem.servo_planner("mppi", **(options or {}))
    else:
        controller = make_controller(name, problem, **(options or {}))
    t0 = time.perf_counter()
    sim = mpcbox.simulate(problem, controller, duration, seed=0)
    wall = time.perf_counter() - t0
    errors = np.array([problem.reach_error(s) for s in sim.states])
    hit = arrival(errors, sim.time, TOLERANCE)
    out = {
        "final_error_m": float(errors[-1]),
        "time_to_1cm_s": hit.time,
        "error_after_arrival_max_m": hit.overshoot,
        "within_1cm_by_2s": bool(hit.time <= 2.0),
        "final_within_1cm": bool(errors[-1] <= TOLERANCE),
        "wall_s": round(wall, 2),
    }
    stats = getattr(controller, "stats", {})
    replans = int(stats.get("replans", 0))
    if replans:  # called every step; the replans are the expensive calls
        ticks = np.sort(sim.compute_times)[-replans:]
        out["median_replan_tick_ms"] = float(1e3 * np.median(ticks))
        out["p99_replan_tick_ms"] = sim.metrics.compute_p99_ms  # online solves only
        out["fallbacks"] = int(stats.get("fallbacks", 0))
        out["replans"] = replans
    out["median_call_ms"] = float(1e3 * np.median(sim.compute_times))
    out["median_solve_ms"] = sim.metrics.compute_p50_ms  # calls that planned, not held
    return out


def offline(problem: ArmReach, horizon_s: float, iterations: int) -> dict:
    """Offline iLQR from the start state over ``horizon_s`` seconds."""
    options = config_options(problem.controller_configs["ilqr"])
    options.update(horizon=round(horizon_s / problem.dt), linearize_every=5, control_steps=1)
    solver = ILQR(problem, **options)
    result = solver.solve(problem.initial_state(), max_iterations=iterations)
    return {
        "stop_reason": result.stop_reason.value,
        "status": result.status,
        "converged": bool(result.converged),
        "iterations": int(result.iterations),
        "regularization": float(result.regularization),
        "final_error_m": problem.reach_error(result.states[-1]),
        "cost": float(result.cost),
        "wall_s": round(result.timing.total, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="menagerie:franka_emika_panda")
    parser.add_argument("--frame", default=None, help="default: picked from the model")
    parser.add_argument(
        "--offset", type=float, nargs=3, default=OFFSET.tolist(), help="nominal target offset (m)"
    )
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds run from this one")
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--posture-noise", type=float, default=0.1)
    parser.add_argument("--target-noise", type=float, default=0.03)
    parser.add_argument("--offline-horizon", type=float, default=1.0)
    parser.add_argument("--offline-iterations", type=int, default=30)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results/panda_reach.json"))
    parser.add_argument(
        "--parent-contacts",
        default="exclude",
        choices=["exclude", "keep"],
        help="links touching their static parent (mpcbox.core.parent_contacts)",
    )
    parser.add_argument(
        "--dry-friction",
        default="drop",
        choices=["drop", "keep"],
        help="linearize without the joints' frictionloss (drop, ArmReach's default) or with it",
    )
    parser.add_argument("--timestep", type=float, default=None, help="replace the model's")
    parser.add_argument(
        "--task-set",
        default="",
        help="ArmReach options for every seed, 'key=value,...' (e.g. velocity_weight=0.1)",
    )
    parser.add_argument(
        "--controllers",
        default="ilqr,lqr,offline",
        help="comma-separated from ilqr, lqr, offline, mppi (CPU sampling), mppi_servo (MPPI "
        "of joint set-points on a torque-driven arm, ArmReach.servo_planner)",
    )
    parser.add_argument(
        "--mppi-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an option of the task's MPPI config (VALUE as a Python literal)",
    )
    parser.add_argument(
        "--ilqr-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an option of the task's iLQR config (VALUE as a Python literal)",
    )
    args = parser.parse_args()
    chosen = args.controllers.split(",")
    known = {"ilqr", "lqr", "offline", "mppi", "mppi_servo"}
    unknown = sorted(set(chosen) - known)
    if unknown:
        parser.error(f"--controllers: unknown {unknown}; choose from {', '.join(sorted(known))}")
    sets = parse_sets([f"mppi.{s}" for s in args.mppi_set] + [f"ilqr.{s}" for s in args.ilqr_set])
    mppi_options, ilqr_options = sets.get("mppi", {}), sets.get("ilqr", {})

    rows = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        problem = build(seed, args)
        row = {
            "seed": seed,
            "start_error_m": problem.reach_error(problem.initial_state()),
            "ik_goal_error_m": float(problem.goal.position_error),
            "excluded_contacts": [f"{c.parent}/{c.child}" for c in problem.excluded_contacts],
        }
        if "ilqr" in chosen:
            row["ilqr_mpc"] = closed_loop(problem, "ilqr", args.duration, ilqr_options)
        if "lqr" in chosen:
            row["lqr_at_ik_posture"] = closed_loop(problem, "lqr", args.duration)
        if "mppi" in chosen:
            row["mppi_cpu"] = closed_loop(problem, "mppi", args.duration, mppi_options)
        if "mppi_servo" in chosen:
            row["mppi_servo"] = closed_loop(problem, "mppi_servo", args.duration, mppi_options)
        if "offline" in chosen:
            row["ilqr_offline"] = offline(problem, args.offline_horizon, args.offline_iterations)
        mpc, lqr = row.get("ilqr_mpc"), row.get("lqr_at_ik_posture")
        if mpc and lqr:
            row["time_to_1cm_ratio_mpc_over_lqr"] = mpc["time_to_1cm_s"] / lqr["time_to_1cm_s"]
            row["final_error_ratio_mpc_over_lqr"] = mpc["final_error_m"] / lqr["final_error_m"]
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)

    summary: dict = {}
    for key, label in (
        ("ilqr_mpc", "ilqr_mpc"),
        ("mppi_cpu", "mppi"),
        ("mppi_servo", "mppi_servo"),
        ("lqr_at_ik_posture", "lqr"),
    ):
        runs = [r[key] for r in rows if key in r]
        if runs:
            summary[f"{label}_within_1cm_by_2s"] = (
                f"{sum(run['within_1cm_by_2s'] for run in runs)}/{len(runs)}"
            )
            summary[f"{label}_final_within_1cm"] = (
                f"{sum(run['final_within_1cm'] for run in runs)}/{len(runs)}"
            )
            summary[f"{label}_time_to_1cm_max_s"] = float(max(run["time_to_1cm_s"] for run in runs))
            summary[f"{label}_final_error_max_m"] = max(run["final_error_m"] for run in runs)
    offline_runs = [r["ilqr_offline"] for r in rows if "ilqr_offline" in r]
    if offline_runs:
        summary["offline_stop_reasons"] = sorted({run["stop_reason"] for run in offline_runs})
    out = {
        "task": f"ArmReach {np.linalg.norm(args.offset):.2f} m, " + args.model,
        "machine": "2-core sandbox CPU, shared",
        "python": platform.python_version(),
        "command": "python benchmarks/panda_reach.py " + " ".join(sys.argv[1:]),
        "settings": vars(args) | {"tolerance_m": TOLERANCE},
        "ilqr_config": config_options(ArmReach.controller_configs["ilqr"]) | ilqr_options,
        "mppi_config": config_options(ArmReach.controller_configs["mppi"]) | mppi_options,
        "summary": summary,
        "seeds": rows,
    }
    text = json.dumps(jsonable(out), indent=2, default=float)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
