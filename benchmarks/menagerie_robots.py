"""Legged robots nobody here tuned for (MuJoCo Menagerie), standing by name: LQR and QP-MPC.

For each robot the script builds the task a new user would (:class:`BipedStand` or
:class:`QuadrupedStand` with the feet named), records the equilibrium (root residual wrench,
tilt, actuator shortfall, warnings, build time), and simulates each controller for
``--duration`` s under the robot-independent noise recipe on ``--seeds`` seeds. A robot or
controller that cannot be built is recorded with its error. Results are stored under
``--label`` in ``--out`` (merged with the labels already there), so runs of other code (the
``before`` label: ``git archive <commit> mpcbox | tar -x -C /tmp/base`` and
``PYTHONPATH=/tmp/base``) sit beside this one::

    MENAGERIE_ROOT=... python benchmarks/menagerie_robots.py --label after --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import time
import traceback
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from quadruped_stand import add_push_options  # benchmarks/ is not a package
from quadruped_walk import parse_set  # benchmarks/ is not a package

from mpcbox.cli.checks import check_output_folder, number_flag
from mpcbox.cli.compare import parse_sets
from mpcbox.errors import InvalidArgumentError, MpcboxError
from mpcbox.registry import controller_class
from mpcbox.validation import positive_int

OUT = Path(__file__).parent / "results" / "menagerie_robots.json"

#: Robot (``"name"`` or ``"name/entry"``) -> feet. Four feet: a quadruped.
ROBOTS: dict[str, tuple[str, ...]] = {
    "unitree_h1": ("body:left_ankle_link", "body:right_ankle_link"),
    "booster_t1": ("body:left_foot_link", "body:right_foot_link"),
    "berkeley_humanoid": ("body:ll_faa", "body:lr_faa"),
    "apptronik_apollo": ("body:l_foot_link", "body:r_foot_link"),
    "fourier_n1": ("body:left_foot_pitch_link", "body:right_foot_pitch_link"),
    "pal_talos/scene_motor": ("body:leg_left_6_link", "body:leg_right_6_link"),
    "pal_talos/scene_position": ("body:leg_left_6_link", "body:leg_right_6_link"),
    "pndbotics_adam_lite": ("body:toeLeft", "body:toeRight"),
    "robotis_op3": ("body:l_ank_roll_link", "body:r_ank_roll_link"),
    "agility_cassie": ("body:left-foot", "body:right-foot"),
    "anybotics_anymal_b": ("body:LF_SHANK", "body:RF_SHANK", "body:LH_SHANK", "body:RH_SHANK"),
    "unitree_go2": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
    "boston_dynamics_spot": ("body:fl_lleg", "body:fr_lleg", "body:hl_lleg", "body:hr_lleg"),
}


#: Robots the other QP benchmarks measure besides :data:`ROBOTS`.
MORE_ROBOTS: dict[str, tuple[str, ...]] = {
    "unitree_g1": ("body:left_ankle_roll_link", "body:right_ankle_roll_link"),
    "unitree_go1": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
    "anybotics_anymal_c": ("body:LF_SHANK", "body:RF_SHANK", "body:LH_SHANK", "body:RH_SHANK"),
    # Rounded mesh foot tips (stop 44): the feet ground_feet finds.
    "google_barkour_vb": tuple(
        f"body:{b}" for b in ("lower_leg_front_left", "lower_leg_2", "lower_leg_3", "lower_leg_4")
    ),
    "google_barkour_v0": tuple(
        f"body:lower_leg_1to1_{leg}"
        for leg in ("front_right", "front_left", "hind_right", "hind_left")
    ),
}


def stand_task(robot: str, **kwargs):
    """The task a new user would build for ``robot`` (a key of :data:`ROBOTS` or
    :data:`MORE_ROBOTS`): ``BipedStand`` or ``QuadrupedStand`` with only its feet named,
    one thread, warnings silenced."""
    from mpcbox.registry import task_class

    feet = {**ROBOTS, **MORE_ROBOTS}[robot]
    task = task_class("quadruped_stand" if len(feet) == 4 else "biped_stand")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return task(f"menagerie:{robot}", feet=feet, threads=1, **kwargs)


def chosen_robots(parser: argparse.ArgumentParser, args: argparse.Namespace) -> list[str]:
    """The robots of ``--robots`` (comma-separated); a usage error without ``MENAGERIE_ROOT``."""
    if not os.environ.get("MENAGERIE_ROOT"):
        parser.error("set MENAGERIE_ROOT to an offline Menagerie copy")
    robots = [r for r in args.robots.split(",") if r]
    known = {**ROBOTS, **MORE_ROBOTS}
    unknown = [r for r in robots if r not in known]
    if unknown:
        parser.error(f"--robots: unknown {unknown}; known: {', '.join(known)}")
    return robots


def _error(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {str(exc)[:300]}"


def run_robot(
    robot: str,
    seeds: int,
    duration: float,
    controllers: tuple[str, ...],
    qp_time_limit: str = "preset",
    dry_friction: str = "keep",
    task_options: dict | None = None,
    noise_scale: float = 1.0,
    first_seed: int = 0,
    push: bool = False,
    push_settle: float = 3.0,
    push_rest_speed: float | None = None,
    controller_options: dict | None = None,
    push_scan_step: float | None = None,
) -> dict:
    import mpcbox
    from mpcbox.tasks.legged.biped import BipedStand
    from mpcbox.tasks.legged.quadruped import QuadrupedStand

    feet = {**ROBOTS, **MORE_ROBOTS}[robot]
    task = QuadrupedStand if len(feet) == 4 else BipedStand
    out: dict = {"task": task.name, "feet": list(feet)}
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            problem = task(
                f"menagerie:{robot}",
                feet=feet,
                threads=1,
                dry_friction=dry_friction,
                **(task_options or {}),
            )
        except Exception as exc:  # recorded, not raised: the point is what breaks
            out["build_error"] = _error(exc)
            return out
    out["build_s"] = round(time.perf_counter() - start, 2)
    out["warnings"] = [
        f"{w.category.__name__}: {str(w.message)[:200]}"
        for w in caught
        if "mesh" not in str(w.message)
    ]
    eq = problem.equilibrium
    out["residual_wrench"] = np.round(eq.residual_wrench, 4).tolist()
    tilt = getattr(eq, "root_tilt", None)  # absent before stop 31
    out["root_tilt_deg"] = np.round(np.degrees(np.zeros(2) if tilt is None else tilt), 4).tolist()
    out["shortfall"] = float(eq.shortfall)
    for name in controllers:
        runs = []
        for seed in range(first_seed, first_seed + seeds):
            try:
                unlimited = name == "qp" and qp_time_limit == "none"
                overrides = {"time_limit": None} if unlimited else {}
                overrides.update((controller_options or {}).get(name, {}))
                controller = mpcbox.make_controller(name, problem, **overrides)
                noise = problem.noise(noise_scale)
                res = mpcbox.simulate(problem, controller, duration, noise=noise, seed=seed)
                runs.append(
                    {
                        "seed": seed,
                        "success": bool(res.metrics.success),
                        "failure": res.failure,
                        "tilt_rms_deg": round(float(res.metrics.measures["tilt_rms_deg"]), 2),
                        "fallbacks": int(res.metrics.fallbacks),
                        **_stalled(controller),
                        **_qp_counts(controller),
                    }
                )
            except Exception as exc:
                runs.append({"seed": seed, "success": False, "error": _error(exc)})
                break
        out[name] = {"successes": sum(r["success"] for r in runs), "runs": runs}
        if push:
            options = (controller_options or {}).get(name, {})
            out[name].update(
                _largest_push(problem, name, push_settle, push_rest_speed, options, push_scan_step)
            )
    problem.close()
    return out


def _largest_push(
    problem,
    name: str,
    settle: float = 3.0,
    rest_speed: float | None = None,
    controller_options: dict | None = None,
    scan_step: float | None = None,
) -> dict:
    """The largest forward push of 0.1 s on the root that ``name`` survives (no noise, 5 N):
    standing ``settle`` s after it and, with ``rest_speed``, the root slower than that.
    Returns ``largest_push_n`` (or the error), the bisection's smallest failed force and
    how far the root's subtree travelled in the largest survived trial."""
    from mpcbox.comparison.push_limits import largest_push
    from mpcbox.comparison.scenario import PushTest

    test = PushTest(
        body=problem.root,
        tolerance=5.0,
        max_force=1500.0,
        settle=settle,
        rest_speed=rest_speed,
        scan_step=scan_step,
    )
    try:
        limit = largest_push(problem, name, test, controller_options=controller_options or None)
    except Exception as exc:
        return {"largest_push_n": _error(exc)}
    return {
        "largest_push_n": round(float(limit.force), 1),
        "smallest_failed_push_n": round(float(limit.smallest_failed), 1),
        "largest_push_travel_m": round(float(limit.travel), 3),
    }


def _stalled(controller: object) -> dict:
    """An iLQR-MPC's stalled replans (``stats["stalled"]``; empty for others)."""
    stats = getattr(controller, "stats", None)
    if not isinstance(stats, dict) or "stalled" not in stats:
        return {}
    return {"stalled": int(stats["stalled"]), "replans": int(stats["replans"])}


def _qp_counts(controller: object) -> dict:
    """A QP-MPC's solves, truncated solves and failures by status (empty for others)."""
    stats = getattr(controller, "stats", None)
    if not isinstance(stats, dict) or "truncated_solves" not in stats:
        return {}
    keep = ("solves", "truncated_solves", "failed_solves")
    return {k: v for k, v in stats.items() if k in keep or k.startswith("failed:")}


def _job(args: tuple) -> tuple[str, dict]:
    robot = args[0]
    try:
        return robot, run_robot(*args)
    except Exception:
        return robot, {"crash": traceback.format_exc()[-1500:]}


def _stored_results(path: Path) -> dict:
    """The labels already in ``--out`` (``{}`` for a new file), checked to be writable.

    Raises:
        InvalidArgumentError: If ``--out`` is not a JSON object or cannot be written.
    """
    check_output_folder(path.parent, "--out")
    if not path.exists():
        return {}
    try:
        stored = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InvalidArgumentError(f"--out: {str(path)!r} is not a results JSON: {exc}") from exc
    if not isinstance(stored, dict):
        raise InvalidArgumentError(f"--out: {str(path)!r} holds no labels (a JSON object)")
    return stored


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--controllers", default="lqr,qp")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--qp-time-limit",
        choices=("preset", "none"),
        default="preset",
        help="QP-MPC's OSQP time budget: the task's (BipedStand: 15 ms) or none",
    )
    parser.add_argument(
        "--dry-friction",
        choices=("drop", "keep"),
        default="keep",
        help="linearize with the joints' frictionloss (keep, the tasks' default) or without",
    )
    parser.add_argument(
        "--task-set",
        default="",
        help="task options for every robot, read as realtime.py reads them: 'joint_cost=10'",
    )
    parser.add_argument(
        "--controller-set",
        action="append",
        default=[],
        metavar="NAME.KEY=VALUE",
        help="override an option of a controller's task config, e.g. ilqr.mpc_iterations=2",
    )
    parser.add_argument("--noise-scale", type=float, default=1.0, help="x the noise recipe")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument(
        "--largest-push",
        action="store_true",
        help="also bisect each controller's largest forward push (0.1 s on the root, no noise)",
    )
    add_push_options(parser, settle=3.0)  # PushTest's default, as the tables before
    parser.add_argument("--label", default="after")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args()
    robots = chosen_robots(parser, args)
    controllers = tuple(c for c in args.controllers.split(",") if c)
    task_options = parse_set(args.task_set)
    try:
        controller_options = parse_sets(args.controller_set)
    except MpcboxError as exc:
        parser.error(f"--controller-set: {exc}")
    try:
        positive_int("--workers", args.workers)
        positive_int("--seeds", args.seeds)
        number_flag("--duration", args.duration, low=0.0)
        for name in controllers:
            controller_class(name)
        stored = _stored_results(Path(args.out))  # before the runs, which take minutes
    except MpcboxError as exc:
        parser.error(str(exc))
    jobs = [
        (
            r,
            args.seeds,
            args.duration,
            controllers,
            args.qp_time_limit,
            args.dry_friction,
            task_options,
            args.noise_scale,
            args.first_seed,
            args.largest_push,
            args.push_settle,
            args.push_rest_speed,
            controller_options,
            args.push_scan_step,
        )
        for r in robots
    ]
    path = Path(args.out)
    started = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        results = dict(pool.map(_job, jobs))
    stored[args.label] = {
        "command": "MENAGERIE_ROOT=... python benchmarks/menagerie_robots.py "
        f"--robots {args.robots} --label {args.label} --seeds {args.seeds} "
        f"--duration {args.duration} "
        f"--controllers {args.controllers} --qp-time-limit {args.qp_time_limit} "
        f"--dry-friction {args.dry_friction}"
        + (f" --task-set '{args.task_set}'" if args.task_set else "")
        + "".join(f" --controller-set {item}" for item in args.controller_set)
        + f" --noise-scale {args.noise_scale} --first-seed {args.first_seed}"
        + (" --largest-push" if args.largest_push else "")
        + (
            f" --push-settle {args.push_settle}"
            + (f" --push-rest-speed {args.push_rest_speed}" if args.push_rest_speed else "")
            + (f" --push-scan-step {args.push_scan_step}" if args.push_scan_step else "")
            if args.largest_push
            else ""
        ),
        "task_options": task_options,
        "controller_options": controller_options,
        "seeds": args.seeds,
        "duration_s": args.duration,
        "noise": "each task's robot-independent recipe (5 % of each actuator's half range)"
        f" x {args.noise_scale}",
        "first_seed": args.first_seed,
        "machine": "2-core sandbox CPU, shared",
        "wall_time_s": round(time.perf_counter() - started, 1),
        "robots": results,
    }
    path.write_text(json.dumps(stored, indent=1) + "\n")
    summary = {}
    for robot, found in results.items():
        summary[robot] = {"build": "build_error" not in found}
        summary[robot].update({c: found.get(c, {}).get("successes") for c in controllers})
        if args.largest_push:
            summary[robot].update(
                {f"{c}_push_n": found.get(c, {}).get("largest_push_n") for c in controllers}
            )
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
