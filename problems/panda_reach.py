"""Arm reach on a Menagerie arm (default Franka Panda): offline iLQR, iLQR-MPC, MPPI and LQR.

Builds :class:`~mpcbox.tasks.reach.ArmReach` (goal posture from mink IK with collision
avoidance, the control that holds it from the actuator model), then compares in one table:

* offline iLQR over ``--offline-horizon`` seconds from the start state, with its stop reason
  (the final error is that of its plan, rolled out on the planning model);
* iLQR as MPC, MPPI sampling MPC on the CPU, and LQR about the IK goal posture, each in
  closed loop for ``--duration`` seconds. On an arm driven by torque motors MPPI plans
  joint set-points through servos (:meth:`~mpcbox.tasks.reach.ArmReach.servo_planner`).
* iLQR-MPC once more in the real-time loop (:func:`mpcbox.simulate_realtime`): the world
  advances in wall-clock time and holds the last control while the planner thinks, so a
  replan slower than the 20 ms period costs accuracy (its tick column is the median replan
  latency).

Needs an offline Menagerie copy (``MENAGERIE_ROOT``) or the ``mujoco_menagerie`` package for
a Menagerie name; ``--model`` also takes an MJCF path. Without ``--target`` the Panda reaches
:data:`PANDA_OFFSET` (40 cm) from its start, and another arm :data:`ARM_FRACTION` of its
length (:func:`arm_length`) in the same direction, halved up to :data:`RETRIES` times while
mink's IK finds no collision-free posture there.

    python problems/panda_reach.py [--model franka_emika_panda] [--frame FRAME]
        [--target 0 0.3 -0.2646] [--absolute] [--duration 2] [--skip mppi realtime]
"""

from __future__ import annotations

import argparse
import itertools
import sys
import warnings

import mujoco
import numpy as np

import mpcbox
from mpcbox.cli.checks import script_main
from mpcbox.config import config_options
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.servo_actions import motors
from mpcbox.core.end_effector import end_effector
from mpcbox.core.menagerie import MissingMeshWarning, model_source
from mpcbox.core.model import compile_spec, frame_object, frame_position, load_spec
from mpcbox.errors import InvalidArgumentError, SolverError
from mpcbox.registry import make_controller
from mpcbox.tasks.reach import ArmReach
from mpcbox.tasks.reach_measures import arrival
from mpcbox.validation import finite_array, positive, positive_int

#: The Panda's default target offset from its start (m): 40 cm sideways and down.
PANDA_OFFSET = np.array([0.0, 0.3, -0.2646])
#: Another arm's default offset, as a fraction of its length (:func:`arm_length`).
ARM_FRACTION = 0.3
#: Halvings of the default offset tried while the IK finds no posture there.
RETRIES = 2


def arm_length(model: mujoco.MjModel, frame: str, qpos: np.ndarray) -> float:
    """Length (m) of the chain from the end effector ``frame`` down to the root at posture
    ``qpos`` ``(nq,)``: the sum of the distances between successive hinge and slide anchors,
    from the frame to its nearest joint and on to the base (the Panda's is 0.986 m, a UR10e's
    1.73 m, the low-cost robot arm's 0.304 m). An upper bound on its reach."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    kind, i = frame_object(model, frame, "frame")
    points = [frame_position(model, data, frame)]
    body = int(model.site_bodyid[i]) if kind == "site" else i
    moving = (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))
    while body > 0:
        start = int(model.body_jntadr[body])
        for j in range(start, start + int(model.body_jntnum[body])):
            if int(model.jnt_type[j]) in moving:
                points.append(data.xanchor[j].copy())
        body = int(model.body_parentid[body])
    return float(sum(np.linalg.norm(a - b) for a, b in itertools.pairwise(points)))


def default_offset(source, frame: str | None) -> np.ndarray:
    """The default target offset ``(3,)`` for the arm ``source`` (see the module docstring)."""
    model = compile_spec(load_spec(source))
    if model.nkey == 0:
        qpos = model.qpos0
    else:
        qpos = model.key_qpos[0]
    length = arm_length(model, frame or end_effector(model), qpos)
    return PANDA_OFFSET / np.linalg.norm(PANDA_OFFSET) * ARM_FRACTION * length


def offline_row(problem: ArmReach, horizon_s: float, iterations: int) -> dict[str, str]:
    """Offline iLQR from the start state: final error of the plan and why it stopped."""
    options = config_options(problem.controller_configs["ilqr"])
    options.update(
        horizon=max(1, round(horizon_s / problem.dt)), linearize_every=5, control_steps=1
    )
    result = ILQR(problem, **options).solve(problem.initial_state(), max_iterations=iterations)
    return {
        "controller": "iLQR offline",
        "final (cm)": f"{100 * problem.reach_error(result.states[-1]):.2f}",
        "to 1 cm (s)": "-",
        "median tick (ms)": f"{1e3 * result.timing.total:.0f} (whole solve)",
        "outcome": f"{result.status}; {result.iterations} iterations",
    }


def closed_loop_row(
    problem: ArmReach, name: str, duration: float, realtime: bool = False
) -> dict[str, str]:
    """One closed-loop run of controller ``name`` (in the real-time loop with ``realtime``).
    On an arm with torque motors, MPPI plans joint set-points through servos
    (:meth:`ArmReach.servo_planner`)."""
    label = {"ilqr": "iLQR-MPC", "mppi": "MPPI (CPU)", "lqr": "LQR at IK posture"}[name]
    if name == "mppi" and motors(problem.model).size:
        controller = problem.servo_planner("mppi")
        label = "MPPI (CPU, set-points via servos)"
    else:
        controller = make_controller(name, problem)
    if realtime:
        sim = mpcbox.simulate_realtime(problem, controller, duration, seed=0)
        label += " in real time"
    else:
        sim = mpcbox.simulate(problem, controller, duration, seed=0)
    errors = np.array([problem.reach_error(s) for s in sim.states])
    hit = arrival(errors, sim.time, problem.tolerance)
    missed = problem.goal_failure(sim.time, sim.states)
    return {
        "controller": label,
        "final (cm)": f"{100 * errors[-1]:.2f}",
        "to 1 cm (s)": "never" if np.isnan(hit.time) else f"{hit.time:.2f}",
        # Calls that planned; the feedback or spline between replans is not a tick.
        "median tick (ms)": f"{sim.metrics.compute_p50_ms:.3g}",
        "outcome": missed or "reached",
    }


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line); a bad argument prints its named
    error and returns 2."""
    return script_main(_run, argv)


def _run(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="franka_emika_panda")
    parser.add_argument(
        "--frame", default=None, help="end-effector site or body (default: picked from the model)"
    )
    parser.add_argument(
        "--target",
        type=float,
        nargs=3,
        default=None,
        help="offset from the start (m; default: see the module docstring)",
    )
    parser.add_argument("--absolute", action="store_true", help="target in world coordinates")
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--offline-horizon", type=float, default=1.0)
    parser.add_argument("--offline-iterations", type=int, default=30)
    parser.add_argument(
        "--skip", nargs="*", default=[], choices=["offline", "ilqr", "mppi", "lqr", "realtime"]
    )
    args = parser.parse_args(argv)
    positive("--duration", args.duration)  # before any solve: a named error, exit 2
    positive("--offline-horizon", args.offline_horizon)
    positive_int("--offline-iterations", args.offline_iterations)
    if {"offline", "ilqr", "mppi", "lqr"} <= set(args.skip):
        raise InvalidArgumentError(
            "--skip leaves nothing to run: keep at least one of offline, ilqr, mppi, lqr"
        )
    if args.target is not None:
        finite_array("--target", args.target, (3,))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MissingMeshWarning)
        source = model_source(args.model)
        if args.target is not None:
            targets = [np.array(args.target)]
        elif args.model.removeprefix("menagerie:") == "franka_emika_panda":
            targets = [PANDA_OFFSET]
        else:
            offset = default_offset(source, args.frame)
            targets = [offset / 2**k for k in range(RETRIES + 1)]
        for k, target in enumerate(targets):
            try:
                problem = ArmReach(
                    source, frame=args.frame, target=target, relative=not args.absolute
                )
                break
            except SolverError as exc:
                if k + 1 == len(targets):
                    print(f"{exc}\nChoose a target with --target DX DY DZ.", file=sys.stderr)
                    return 2
                print(f"{exc}\n(trying half that offset)", file=sys.stderr)
    start = problem.reach_error(problem.initial_state())
    print(
        f"{problem}: {problem.frame!r} {100 * start:.1f} cm from the target, IK goal "
        f"{1e3 * problem.goal.position_error:.2f} mm from it"
        + (f"; welded free objects {list(problem.welded)}" if problem.welded else "")
    )
    rows = []
    if "offline" not in args.skip:
        rows.append(offline_row(problem, args.offline_horizon, args.offline_iterations))
    for name in ("ilqr", "mppi", "lqr"):
        if name not in args.skip:
            rows.append(closed_loop_row(problem, name, args.duration))
    if "realtime" not in args.skip and "ilqr" not in args.skip:
        rows.append(closed_loop_row(problem, "ilqr", args.duration, realtime=True))
    headers = list(rows[0]) if rows else []
    print("| " + " | ".join(headers) + " |")
    print("|" + "---|" * len(headers))
    for row in rows:
        print("| " + " | ".join(row[h] for h in headers) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
