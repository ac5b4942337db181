"""How a Unitree G1 recovers from forward pushes: feet, hops and the time to rest, by force.

For each force of a grid, a 0.1 s forward push on the pelvis at 1 s (no noise), then
``--duration`` s in all, with a controller of the ``biped_stand`` task (Menagerie's G1 on
two feet). Reported per force: outcome and time, the highest foot (ankle-roll body origin,
3.5 cm at rest), the time with a foot above 4.5 cm, how far the feet moved, the pelvis's
speed at the end, and whether the feet were still moving in the last second. Prints JSON;
needs ``MENAGERIE_ROOT`` (an offline Menagerie copy)::

    MENAGERIE_ROOT=/work/menagerie python benchmarks/g1_push_recovery.py \
        [--controller ilqr] [--forces 150,200,250,300,350,400] [--duration 6] \
        [--set cost_hessian=reference] [--task-set balance_target=support]

To see what an older version of mpcbox did on the same robot, run this file with that
checkout first on the path (``git worktree add /tmp/old COMMIT``, then
``PYTHONPATH=/tmp/old python benchmarks/g1_push_recovery.py ...``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings

import mujoco
import numpy as np
from quadruped_walk import parse_set  # benchmarks/ is not a package

import mpcbox
from mpcbox.cli.compare import parse_sets
from mpcbox.core.menagerie import MissingMeshWarning
from mpcbox.registry import make_controller, task_class

FEET = ("left_ankle_roll_link", "right_ankle_roll_link")
LIFTED = 0.045  # m: a foot origin this high is off the floor (3.5 cm at rest)


def pelvis_speed(problem, state: np.ndarray) -> float:
    """Speed (m/s) of the root body's centre of mass in ``state`` (written out here rather
    than imported, so that the script also runs against older checkouts of mpcbox)."""
    model, data = problem.model, mujoco.MjData(problem.model)
    problem.set_state(data, state)
    mujoco.mj_forward(model, data)
    velocity = np.zeros(6)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, problem.root)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
    return float(np.linalg.norm(velocity[3:]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controller", default="ilqr")
    parser.add_argument("--forces", default="150,200,250,300,350,400")
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--out", default=None, help="also write the JSON here")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="OPTION=VALUE",
        help="controller option, read as `mpcbox compare --set` reads it (repeatable)",
    )
    parser.add_argument("--task-set", default="", help="task options, e.g. balance_target=support")
    args = parser.parse_args()
    sets = [f"{args.controller}.{item}" for item in args.set]
    options = parse_sets(sets).get(args.controller, {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MissingMeshWarning)
        problem = task_class("biped_stand")("menagerie:unitree_g1", **parse_set(args.task_set))
    model, data = problem.model, mujoco.MjData(problem.model)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in FEET]
    rows = []
    started = time.perf_counter()
    for force in [float(f) for f in args.forces.split(",")]:
        controller = make_controller(args.controller, problem, **options)
        push = mpcbox.Push(force=(force, 0.0, 0.0), start=1.0, duration=0.1, body=problem.root)
        sim = mpcbox.simulate(problem, controller, args.duration, pushes=[push], seed=0)
        height, along = [], []
        for state in sim.states:
            problem.set_state(data, state)
            mujoco.mj_kinematics(model, data)
            height.append(max(data.xpos[f][2] for f in feet))
            along.append(float(np.mean([data.xpos[f][0] for f in feet])))
        t, height, along = np.asarray(sim.time), np.asarray(height), np.asarray(along)
        last = t >= t[-1] - 1.0
        row = {
            "force_N": force,
            "outcome": sim.metrics.outcome,
            "end_s": round(float(t[-1]), 3),
            "foot_height_max_m": round(float(height.max()), 4),
            "foot_lifted_s": round(float((height > LIFTED).sum() * model.opt.timestep), 3),
            "feet_moved_m": round(float(along[-1] - along[0]), 4),
            "feet_moving_last_1s_m": round(float(np.ptp(along[last])), 4),
            "pelvis_speed_end_m_s": round(pelvis_speed(problem, sim.states[-1]), 4),
            "stalled_replans": controller.stats.get("fallbacks"),
            "replans": controller.stats.get("replans"),
            "tick_median_ms": round(float(sim.metrics.compute_p50_ms), 2),
            "tick_p99_ms": round(float(sim.metrics.compute_p99_ms), 2),
        }
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    out = {
        "robot": "menagerie:unitree_g1 (biped_stand, two feet)",
        "controller": args.controller,
        "options": options,
        "task_options": parse_set(args.task_set),
        "push": "forward on the pelvis at 1 s for 0.1 s, no noise, seed 0",
        "machine": f"{os.cpu_count()}-core CPU ({platform.machine()})",
        "python": platform.python_version(),
        "command": "python benchmarks/g1_push_recovery.py " + " ".join(sys.argv[1:]),
        "wall_s": round(time.perf_counter() - started, 1),
        "runs": rows,
    }
    text = json.dumps(out, indent=2)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
