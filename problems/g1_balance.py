"""Unitree's G1 balancing on two feet or one: LQR, QP-MPC and iLQR-MPC under noise and pushes.

The task is :class:`~mpcbox.tasks.legged.biped.BipedStand`: the robot's keyframe (on one
foot, an inverse-kinematics stance with the center of mass over the stance foot, checked
for self-collision), the root height adjusted until the feet carry the weight, the holding
set-points through the G1's 29 position servos, the robot-independent noise recipe (5 % of
each actuator's range), QP-MPC with a friction pyramid at each of the feet's spheres, and
iLQR-MPC linearized at the standing reference (the LQR's model). Every controller runs the
same seeded scenarios (:func:`mpcbox.compare`): noise alone, and noise with a forward push
on the root body at 1 s; then the largest forward push (0.1 s, no noise) is found by
bisection, a push counting as survived when the pelvis is back at rest (under 0.05 m/s) 4 s
after it (iLQR-MPC recovers from large pushes by hopping, and a G1 still hopping at the end
of a shorter window had counted). Prints a markdown table.

Examples::

    python problems/g1_balance.py
    python problems/g1_balance.py --stance one --controllers lqr,qp
    python problems/g1_balance.py --controllers lqr --seeds 5 --duration 10
    python problems/g1_balance.py --model booster_t1  # feet found from the model
    python problems/g1_balance.py --model path/to/biped.xml --feet left_foot,right_foot
"""

from __future__ import annotations

import argparse
import sys

from mpcbox.cli.checks import check_push_flags
from mpcbox.cli.compare_parser import add_push_scan_step
from mpcbox.comparison.balance_suite import balance_suite
from mpcbox.comparison.runner import compare
from mpcbox.core.menagerie import model_source
from mpcbox.errors import MpcboxError
from mpcbox.tasks.legged.biped import BipedStand

#: ``--stance`` values and the task's ``stance``.
STANCES = {"two": "two", "one": "left", "left": "left", "right": "right"}


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    parser = argparse.ArgumentParser(
        prog="g1_balance.py",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--model", default="unitree_g1", help="Menagerie name or MJCF path")
    parser.add_argument(
        "--feet", default="", help="comma-separated left,right feet (default: known or found)"
    )
    parser.add_argument(
        "--stance", default="two", choices=sorted(STANCES), help="'one' stands on the left foot"
    )
    parser.add_argument("--controllers", default="lqr,qp,ilqr", help="comma-separated")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per scenario")
    parser.add_argument("--duration", type=float, default=5.0, help="seconds per run")
    parser.add_argument(
        "--push", type=float, default=0.0, help="forward push (N); default: 20 %% of the weight"
    )
    parser.add_argument(
        "--largest-push",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="bisect the largest forward push (0.1 s, no noise)",
    )
    add_push_scan_step(parser)
    parser.add_argument("--workers", type=int, default=1, help="worker processes")
    args = parser.parse_args(argv)
    try:
        check_push_flags(args)
        feet = [f for f in args.feet.split(",") if f] or None
        problem = BipedStand(
            model_source(args.model), stance=STANCES[args.stance], feet=feet, threads=1
        )
        suite = balance_suite(
            problem,
            duration=args.duration,
            force=args.push,
            weight_fraction=0.2,
            max_force_weights=5,
            largest_push=args.largest_push,
            scan_step=args.push_scan_step,
            settle=4.0,
            rest_speed=0.05,
        )
        result = compare(
            problem,
            args.controllers.split(","),
            suite.scenarios,
            args.seeds,
            push_tests=suite.push_tests,
            workers=args.workers,
            progress=False,
        )
    except MpcboxError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{problem!r}: stance {problem.stance}, feet {', '.join(problem.contacts)}\n")
    print(result.to_markdown())
    return 0


if __name__ == "__main__":
    sys.exit(main())
