"""Arm point-to-point move: quintic vs iLQR plan, then time-varying LQR tracking; CSV of the run.

Builds :class:`~mpcbox.tasks.arm.track.ArmTrack` from the start keyframe to a goal posture
(the start plus ``--offsets`` per arm joint, in rad), optionally with a virtual spherical
obstacle of radius ``--obstacle`` m placed just off the quintic's end-effector path at
mid-move. Prints the two plans (cost, largest torque over the actuators' limits, clearance,
compute time) and tracks each with time-varying LQR in closed loop on a plant with
``--mass-scale`` times the model's masses: tracking RMSE, overshoot and settling time. With
``--save`` the quintic's tracking run is written as ``NAME.csv`` + ``NAME.json`` (columns
time, qpos, qvel, ctrl, measures, site ``ee`` x/y/z), which ``mpcbox replay NAME.csv``
replays.

The default model is Menagerie's Franka Panda (needs ``MENAGERIE_ROOT`` or the
``mujoco_menagerie`` package); ``--model arm3`` uses the three-joint arm shipped with mpcbox.
Any other arm works by name or path: the end effector defaults to the one
:func:`~mpcbox.core.end_effector.end_effector` picks, and the goal to the start with each
servo- or motor-driven hinge turned by :data:`DEFAULT_OFFSET` rad towards the middle of its
range (:func:`default_offsets`).

    python problems/arm_trajectory.py [--model franka_emika_panda] [--duration 0.8]
        [--offsets 0.4 0.3 0.2 -0.3 0.1 0.2 -0.4] [--obstacle 0.05] [--save run]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import mujoco
import numpy as np

import mpcbox
from mpcbox.cli.checks import check_save_name, number_flag, script_main
from mpcbox.core import menagerie
from mpcbox.core.end_effector import end_effector
from mpcbox.core.menagerie import MissingMeshWarning
from mpcbox.core.model import compile_spec, load_spec
from mpcbox.errors import EquilibriumWarning, InvalidArgumentError
from mpcbox.sim.trajectory import trajectory_from_result
from mpcbox.sim.trajectory_files import save_trajectory
from mpcbox.tasks import scene_path
from mpcbox.tasks.arm import (
    ArmTrack,
    Sphere,
    ilqr_move,
    move_report,
    move_tracker,
    quintic_move,
)
from mpcbox.validation import positive_int

#: Per-model defaults: end-effector frame, site offset in it (m), joint offsets (rad).
PRESETS = {
    "franka_emika_panda": ("hand", [0.0, 0.0, 0.1034], [0.4, 0.3, 0.2, -0.3, 0.1, 0.2, -0.4]),
    "arm3": ("ee", [0.0, 0.0, 0.0], [1.2, 0.4, -0.3]),
}


#: Turn of each driven hinge (rad) when ``--offsets`` is not given for an arm without a preset.
DEFAULT_OFFSET = 0.3


def default_offsets(model: mujoco.MjModel, start: np.ndarray) -> np.ndarray:
    """Offsets ``(nq,)`` from ``start``: each hinge driven by an actuator (through a joint
    transmission) turns by :data:`DEFAULT_OFFSET` towards the middle of its range (up to
    its middle when that is nearer; positive for an unlimited hinge); other joints stay."""
    out = np.zeros(model.nq)
    for a in range(model.nu):
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            continue
        j = int(model.actuator_trnid[a, 0])
        if int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_HINGE):
            continue
        i = int(model.jnt_qposadr[j])
        if model.jnt_limited[j]:
            toward = 0.5 * float(model.jnt_range[j].sum()) - float(start[i])
            out[i] = np.sign(toward) * min(DEFAULT_OFFSET, abs(toward))
        else:
            out[i] = DEFAULT_OFFSET
    return out


def model_source(name: str) -> str:
    """An MJCF path as given, ``arm3`` as mpcbox's scene, else ``"menagerie:NAME"``."""
    if name == "arm3":
        return str(scene_path("arm3.xml"))
    return menagerie.model_source(name)


def main(argv: list[str] | None = None) -> int:
    """Plan, track and print (``argv`` defaults to the command line); a bad argument
    prints its named error and returns 2."""
    return script_main(_run, argv)


def _run(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="franka_emika_panda")
    parser.add_argument("--frame", default=None, help="end-effector site or body")
    parser.add_argument("--site-offset", type=float, nargs=3, default=None)
    parser.add_argument("--offsets", type=float, nargs="+", default=None)
    parser.add_argument("--duration", type=float, default=0.8)
    parser.add_argument("--obstacle", type=float, default=0.05, help="radius (m); 0: none")
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--mass-scale", type=float, default=1.3)
    parser.add_argument("--save", default=None, help="NAME of the CSV/JSON of the quintic run")
    args = parser.parse_args(argv)
    number_flag("--duration", args.duration, low=0.0)
    number_flag("--obstacle", args.obstacle, low=0.0, strict=False)
    number_flag("--mass-scale", args.mass_scale, low=0.0)
    positive_int("--iterations", args.iterations)
    check_save_name("--save", args.save)

    key = Path(args.model.removeprefix("menagerie:")).stem
    frame, offset, offsets = PRESETS.get(key, (None, [0.0, 0.0, 0.0], None))
    offset = args.site_offset or offset
    offsets = args.offsets or offsets
    source = model_source(args.model)
    warnings.simplefilter("ignore", MissingMeshWarning)
    warnings.simplefilter("ignore", EquilibriumWarning)
    model = compile_spec(load_spec(source))
    frame = args.frame or frame or end_effector(model)  # its error asks for --frame's value
    start = model.key_qpos[0].copy() if model.nkey else model.qpos0.copy()
    goal = start.copy()
    if offsets is None:
        goal += default_offsets(model, start)
    elif len(offsets) > model.nq:
        raise InvalidArgumentError(
            f"--offsets: {len(offsets)} given, the model has {model.nq} qpos"
        )
    else:
        goal[: len(offsets)] += np.asarray(offsets)
    options = {"frame": frame, "site_offset": offset, "goal_qpos": goal, "duration": args.duration}
    problem = ArmTrack(source, **options)
    obstacle = None
    if args.obstacle > 0:
        path = problem.frame_path(quintic_move(problem).states)
        side = np.cross(path[-1] - path[0], [0.0, 0.0, 1.0])
        side = 0.02 * side / max(np.linalg.norm(side), 1e-9)
        obstacle = Sphere(path[len(path) // 2] + side, args.obstacle)
        problem = ArmTrack(source, **options, obstacle=obstacle)
    print(
        f"{problem}: {frame!r} moves {100 * problem.reach_error(problem.initial_state()):.1f} cm "
        f"in {problem.knots * problem.dt:.2f} s"
        + (f", obstacle r={args.obstacle} m at {np.round(obstacle.center, 3)}" if obstacle else "")
    )
    plans = {"quintic": quintic_move(problem)}
    plans["iLQR"] = ilqr_move(problem, max_iterations=args.iterations)
    print("\n| plan | cost | max torque / limit | clearance (cm) | final (mm) | compute (ms) |")
    print("|---|---|---|---|---|---|")
    for name, plan in plans.items():
        r = move_report(problem, plan)
        print(
            f"| {name} | {r.cost:.4g} | {r.torque_ratio:.2f} | {100 * r.clearance:.1f} | "
            f"{1e3 * r.final_error:.2f} | {r.compute_ms:.3g} |"
        )
    mismatch = mpcbox.ModelMismatch(mass_scale=args.mass_scale)
    print(f"\nTracking, plant masses x{args.mass_scale}:")
    print("| controller | RMSE (mm) | overshoot (%) | settling (s) | final (mm) |")
    print("|---|---|---|---|---|")
    for name, plan in plans.items():
        tracker = move_tracker(problem, plan)
        sim = mpcbox.simulate(problem, tracker, problem.duration + problem.hold, mismatch=mismatch)
        m = sim.metrics.measures
        print(
            f"| {name} + TV-LQR | {1e3 * m['tracking_error_rms_m']:.2f} | "
            f"{m['overshoot_max_pct']:.2f} | {m['target_error_settling_s']:.3f} | "
            f"{1e3 * m['target_error_final_m']:.2f} |"
        )
        if args.save and name == "quintic":
            meta = {"task": "arm_track", "task_options": problem.task_options()}
            traj = trajectory_from_result(sim, problem, metadata=meta)
            csv_path, _ = save_trajectory(traj, args.save)
            print(f"(saved {csv_path}; replay: mpcbox replay {csv_path})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
