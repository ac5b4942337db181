"""Benchmark arm moves on Menagerie's Franka Panda: quintic vs iLQR plans, and tracking; JSON.

Each seed draws a point-to-point move: a start posture (home +- ``--start-noise`` rad per arm
joint), a goal posture (start +- ``--move`` rad per joint, inside the joint ranges, at least
15 cm of hand travel), a move time in ``--durations``, and a virtual spherical obstacle of
radius ``--radius`` placed 1-3 cm off the quintic's end-effector path at mid-move.

Plans (:mod:`mpcbox.tasks.arm.moves`): the quintic in joint space and the iLQR-optimal move
of :class:`~mpcbox.tasks.arm.track.ArmTrack`'s cost (started from the quintic), each with its
cost, effort, largest joint torque over the actuators' limits (``forcerange``; the quintic's
torque from inverse dynamics, what it needs; iLQR's as its actuators apply it), clearance of
the hand from the obstacle and compute time. The same move in ``--fast`` seconds (no obstacle)
shows the quintic past the torque limits: its ratio, iLQR's, and both tracked by TV-LQR.

Tracking, in closed loop with ``mpcbox.simulate`` on a plant whose link masses are
``--mass-scale`` times the model's, with smooth actuator noise of ``--noise-torque`` N m per
joint: the quintic played open loop (feedforward), the quintic tracked by time-varying LQR
with default and with tuned weights, the iLQR plan tracked by the tuned weights, and two
regulators toward the goal posture (a step, no planned path): LQR with the tuned weights and
iLQR-MPC with ArmReach's config. Rows give the hand's tracking RMSE against the tracked plan
(m; for the regulators against the quintic), overshoot past the target along the move (%
of its length) and settling time after the plan's end (s, within 5 mm). The tuned weights
were chosen on one move outside these seeds. Needs ``MENAGERIE_ROOT``.

    MENAGERIE_ROOT=/work/menagerie python benchmarks/arm_trajectories.py [--seeds 6]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.controllers.trajectory import TrackingWeights
from mpcbox.core.actuator_scales import actuator_scales
from mpcbox.core.menagerie import MissingMeshWarning
from mpcbox.errors import EquilibriumWarning
from mpcbox.registry import make_controller
from mpcbox.sim.trajectory import jsonable
from mpcbox.tasks.arm import (
    ArmTrack,
    Sphere,
    ilqr_move,
    move_report,
    move_tracker,
    quintic_move,
    step_move,
)
from mpcbox.tasks.arm.moves import held

MODEL = "menagerie:franka_emika_panda"
#: The Panda's hand frame and the point between its fingertips (m, in the hand's frame).
FRAME, OFFSET = "hand", (0.0, 0.0, 0.1034)
ARM_JOINTS = 7
#: Tracking weights: the defaults, and those tuned on one move outside the seeds.
WEIGHTS = {
    "default": TrackingWeights(),
    "tuned": TrackingWeights(position_weight=1e6, velocity_weight=1e3, torque_weight=1e-3),
}


def draw_move(seed: int, home: ArmTrack, args: argparse.Namespace) -> dict:
    """The seed's start and goal postures and move time."""
    rng = np.random.default_rng(seed)
    low, high = home.model.jnt_range[:ARM_JOINTS].T
    for _ in range(100):
        start = home.start_qpos.copy()
        start[:ARM_JOINTS] += rng.uniform(-args.start_noise, args.start_noise, ARM_JOINTS)
        goal = start.copy()
        goal[:ARM_JOINTS] += rng.uniform(-args.move, args.move, ARM_JOINTS)
        start[:ARM_JOINTS] = np.clip(start[:ARM_JOINTS], low + 0.1, high - 0.1)
        goal[:ARM_JOINTS] = np.clip(goal[:ARM_JOINTS], low + 0.1, high - 0.1)
        path = home.frame_path(
            np.vstack([np.r_[start, np.zeros(home.nv)], np.r_[goal, np.zeros(home.nv)]])
        )
        if np.linalg.norm(path[1] - path[0]) >= 0.15:
            break
    return {
        "start": start,
        "goal": goal,
        "duration": float(rng.uniform(*args.durations)),
        "rng": rng,
    }


def build(move: dict, obstacle: Sphere | None, hold: float) -> ArmTrack:
    return ArmTrack(
        MODEL,
        frame=FRAME,
        site_offset=OFFSET,
        start_qpos=move["start"],
        goal_qpos=move["goal"],
        duration=move["duration"],
        hold=hold,
        obstacle=obstacle,
    )


def plan_row(problem: ArmTrack, plan) -> dict:
    report = move_report(problem, plan)
    return {
        "cost": report.cost,
        "effort_N2m2s": report.effort,
        "max_torque_ratio": report.torque_ratio,
        "clearance_m": report.clearance,
        "final_error_m": report.final_error,
        "compute_ms": report.compute_ms,
        "status": plan.status,
    }


def tracking_row(problem: ArmTrack, controller, args: argparse.Namespace, seed: int) -> dict:
    scales = actuator_scales(problem.model, problem.start_qpos).torque_per_ctrl
    std = np.where(np.arange(problem.nu) < ARM_JOINTS, args.noise_torque / scales, 0.0)
    sim = mpcbox.simulate(
        problem,
        controller,
        problem.duration + problem.hold,
        noise=mpcbox.ActuatorNoise(std=std, width=0.1),
        mismatch=mpcbox.ModelMismatch(mass_scale=args.mass_scale),
        seed=seed,
    )
    m = sim.metrics.measures
    return {
        "outcome": sim.metrics.outcome,
        "rmse_m": m["tracking_error_rms_m"],
        "max_tracking_error_m": m["tracking_error_max_m"],
        "overshoot_pct": m["overshoot_max_pct"],
        "settling_s": m["target_error_settling_s"],
        "final_error_m": m["target_error_final_m"],
    }


def run_seed(seed: int, home: ArmTrack, args: argparse.Namespace) -> dict:
    move = draw_move(seed, home, args)
    plain = build(move, None, args.hold)
    quintic_plan = quintic_move(plain)
    path = plain.frame_path(quintic_plan.states)
    rng = move["rng"]
    side = np.cross(path[-1] - path[0], rng.normal(size=3))
    side *= rng.uniform(0.01, 0.03) / np.linalg.norm(side)
    obstacle = Sphere(path[len(path) // 2] + side, args.radius)
    problem = build(move, obstacle, args.hold)
    quintic_plan = quintic_move(problem)
    ilqr_plan = ilqr_move(problem, max_iterations=args.iterations)
    out = {
        "seed": seed,
        "duration_s": move["duration"],
        "move_m": float(np.linalg.norm(problem.target - problem.start_position)),
        "plans": {"quintic": plan_row(problem, quintic_plan), "ilqr": plan_row(problem, ilqr_plan)},
        "tracking": {},
    }
    runs = [
        ("quintic + feedforward (open loop)", quintic_plan, None),
        ("quintic + TV-LQR (default weights)", quintic_plan, "default"),
        ("quintic + TV-LQR (tuned weights)", quintic_plan, "tuned"),
        ("iLQR plan + TV-LQR (tuned weights)", ilqr_plan, "tuned"),
    ]
    for name, plan, weights in runs:
        t0 = time.perf_counter()
        tracker = move_tracker(
            problem,
            plan,
            None if weights is None else WEIGHTS[weights],
            feedback=weights is not None,
        )
        row = tracking_row(problem, tracker, args, seed)
        row["reference_ms"] = 1e3 * (time.perf_counter() - t0)
        out["tracking"][name] = row
    # The same move in --fast seconds, without the obstacle: past the actuators' limits.
    if args.fast > 0:
        fast = build({**move, "duration": args.fast}, None, args.hold)
        out["fast"] = {"duration_s": args.fast}
        for plan in (quintic_move(fast), ilqr_move(fast, max_iterations=args.iterations)):
            row = plan_row(fast, plan)
            track = tracking_row(fast, move_tracker(fast, plan, WEIGHTS["tuned"]), args, seed)
            row.update({f"tracked_{k}": v for k, v in track.items()})
            out["fast"][plan.method] = row
    # Regulators toward the goal posture, measured against the quintic.
    t0 = time.perf_counter()
    step = move_tracker(problem, step_move(problem), WEIGHTS["tuned"])
    problem.set_reference(held(problem, quintic_plan)[0])
    row = tracking_row(problem, step, args, seed)
    row["reference_ms"] = 1e3 * (time.perf_counter() - t0)
    out["tracking"]["LQR about the goal (step, tuned weights)"] = row
    if not args.skip_mpc:
        row = tracking_row(problem, make_controller("ilqr", problem), args, seed)
        out["tracking"]["iLQR-MPC to the goal (ArmReach config on this cost)"] = row
    return out


def summary(values: list[float]) -> dict:
    arr = np.array(values, dtype=float)
    ok = arr[np.isfinite(arr)]
    return {
        "mean": float(np.mean(ok)) if ok.size else float("nan"),
        "max": float(np.max(ok)) if ok.size else float("nan"),
        "missing": int(arr.size - ok.size),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--start-noise", type=float, default=0.3)
    parser.add_argument("--move", type=float, default=0.7)
    parser.add_argument("--durations", type=float, nargs=2, default=[0.3, 1.0])
    parser.add_argument("--hold", type=float, default=0.5)
    parser.add_argument("--radius", type=float, default=0.05)
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--fast", type=float, default=0.2, help="fast-move time (s); 0: none")
    parser.add_argument("--skip-mpc", action="store_true", help="leave out iLQR-MPC")
    parser.add_argument("--mass-scale", type=float, default=1.3)
    parser.add_argument("--noise-torque", type=float, default=2.0)
    parser.add_argument(
        "--out", default=str(Path(__file__).parent / "results/arm_trajectories.json")
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore", MissingMeshWarning)
    warnings.simplefilter("ignore", EquilibriumWarning)  # the open gripper at its ctrl limit
    home = ArmTrack(
        MODEL,
        frame=FRAME,
        site_offset=OFFSET,
        goal_qpos=np.r_[0.3, 0.3, 0, -1.8, 0, 1.8, -0.8, 0.04, 0.04],
    )
    rows = []
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        rows.append(run_seed(seed, home, args))
        print(f"seed {seed}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    plans = {
        method: {
            key: summary([r["plans"][method][key] for r in rows])
            for key in (
                "cost",
                "effort_N2m2s",
                "max_torque_ratio",
                "clearance_m",
                "final_error_m",
                "compute_ms",
            )
        }
        for method in ("quintic", "ilqr")
    }
    for method in plans:
        ratios = [r["plans"][method]["max_torque_ratio"] for r in rows]
        clear = [r["plans"][method]["clearance_m"] for r in rows]
        plans[method]["seeds_over_torque_limit"] = int(sum(x > 1.0 + 1e-3 for x in ratios))
        plans[method]["seeds_inside_obstacle"] = int(sum(x < 0.0 for x in clear))
    fast = {}
    if args.fast > 0:
        for method in ("quintic", "ilqr"):
            runs = [r["fast"][method] for r in rows]
            keys = ("max_torque_ratio", "final_error_m", "tracked_rmse_m", "tracked_final_error_m")
            fast[method] = {key: summary([run[key] for run in runs]) for key in keys}
            fast[method]["seeds_over_torque_limit"] = int(
                sum(run["max_torque_ratio"] > 1.0 + 1e-3 for run in runs)
            )
            fast[method]["tracked_successes"] = sum(
                run["tracked_outcome"] == "success" for run in runs
            )
    tracking = {}
    for name in rows[0]["tracking"]:
        runs = [r["tracking"][name] for r in rows]
        tracking[name] = {
            key: summary([run[key] for run in runs])
            for key in ("rmse_m", "overshoot_pct", "settling_s", "final_error_m")
        }
        tracking[name]["successes"] = sum(run["outcome"] == "success" for run in runs)
        tracking[name]["seeds"] = len(runs)
    out = {
        "task": f"ArmTrack point-to-point moves, {MODEL}",
        "machine": "2-core sandbox CPU, shared",
        "python": platform.python_version(),
        "mujoco": __import__("mujoco").__version__,
        "command": "python benchmarks/arm_trajectories.py " + " ".join(sys.argv[1:]),
        "settings": {
            **vars(args),
            "tuned_weights": vars(WEIGHTS["tuned"])
            if hasattr(WEIGHTS["tuned"], "__dict__")
            else str(WEIGHTS["tuned"]),
        },
        "plans": plans,
        "tracking": tracking,
        "fast_moves": fast,
        "runs": rows,
    }
    text = json.dumps(jsonable(out), indent=2, default=float)
    print(text)
    Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
