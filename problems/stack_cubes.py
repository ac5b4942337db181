"""Stack a red cube on a blue cube with an arm, in closed loop; report the success check.

Builds :class:`~mpcbox.tasks.manipulation.stacking.StackCubes` (a table, two 44 mm cubes and
the arm attached with ``MjSpec``; default: one ALOHA arm from mujoco-warp's test data) and
runs the phase-aware waypoint controller (approach, descend, close, lift, move, place,
release, retreat; mink IK, replanned from the measured cubes) on ``--trials`` random cube
layouts. Each line gives the outcome, the centre-to-centre errors and the reason of a miss.

    python problems/stack_cubes.py [--arm aloha|panda] [--trials 5] [--first-seed 0]
        [--save runs/stack]

``--save PATH`` writes the first trial as ``PATH.csv``/``PATH.json``
(:func:`mpcbox.sim.trajectory_files.save_trajectory`: time, states, controls, the tool centre
point's x, y, z), e.g. for ``mpcbox validate`` to replay its controls on the scene.
"""

from __future__ import annotations

import argparse
import sys

import mpcbox
from mpcbox.cli.checks import check_save_name, script_main
from mpcbox.sim.trajectory import trajectory_from_result
from mpcbox.sim.trajectory_files import save_trajectory
from mpcbox.tasks.manipulation.pick_place import PickPlaceTiming, stacking_controller
from mpcbox.tasks.manipulation.stacking import StackCubes
from mpcbox.validation import integer, positive_int


def main(argv: list[str] | None = None) -> int:
    """Run the trials (``argv`` defaults to the command line); a bad argument prints its
    named error and returns 2."""
    return script_main(_run, argv)


def _run(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arm", default="aloha", choices=["aloha", "panda"])
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--save", default=None, help="save the first trial as PATH.csv/.json")
    args = parser.parse_args(argv)
    positive_int("--trials", args.trials)
    integer("--first-seed", args.first_seed, minimum=0)  # NumPy seeds
    check_save_name("--save", args.save)
    problem = StackCubes(args.arm, threads=1)
    controller = stacking_controller(problem)
    duration = PickPlaceTiming().total
    wins = 0
    for seed in range(args.first_seed, args.first_seed + args.trials):
        sim = mpcbox.simulate(
            problem, controller, duration, initial_state=problem.trial_state(seed)
        )
        check = problem.check(sim.states[-1])
        wins += sim.metrics.success
        if args.save and seed == args.first_seed:
            traj = trajectory_from_result(sim, problem, sites=["arm/tcp"])
            print("saved", *save_trajectory(traj, args.save))
        print(
            f"seed {seed}: {sim.metrics.outcome:12s} xy_err {1000 * check.xy_err:5.1f} mm, "
            f"dz {1000 * check.dz:5.1f} mm" + (f"  ({sim.failure})" if sim.failure else "")
        )
    print(f"{wins}/{args.trials} stacked")
    return 0


if __name__ == "__main__":
    sys.exit(main())
