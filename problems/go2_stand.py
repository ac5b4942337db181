"""Unitree's Go2 standing: LQR against QP-MPC with four friction-cone feet, under noise and pushes.

The robot is MuJoCo Menagerie's Go2 (12 torque motors, keyframe ``home``, foot geoms FR, FL,
RR, RL) unless ``--model`` names another Menagerie robot or an MJCF path. Its four feet are
those :class:`~mpcbox.tasks.legged.quadruped.QuadrupedStand` knows (Go1, Go2, A1, ANYmal C),
else the lowest body of each leg in the keyframe
(:func:`~mpcbox.tasks.legged.ground_feet.ground_feet`), else ``--feet`` names them.
``problems/go1_stand.py`` is this script on the Go1.

The task is :class:`~mpcbox.tasks.legged.quadruped.QuadrupedStand`: the robot's own
keyframe with the root height adjusted until the feet carry the weight, the holding control
through its actuators (torques for the Go2's motors, set-points for the Go1's position
servos), the robot-independent noise recipe (5 % of each actuator's range; on the Go2 1.2 N m
at the hips and thighs, 2.3 N m at the knees), and QP-MPC with a friction pyramid at each
foot. Every controller runs the same
seeded scenarios (:func:`mpcbox.compare`): noise alone, and noise with a forward push on the
root body at 1 s; then the largest forward push (0.1 s, no noise) is found by bisection.
Prints a markdown table.

Examples::

    python problems/go2_stand.py
    python problems/go2_stand.py --model unitree_go1 --seeds 3
    python problems/go2_stand.py --model anybotics_anymal_c --push 120
    python problems/go2_stand.py --model anybotics_anymal_b  # feet found from the model
    python problems/go2_stand.py --model path/to/robot.xml --feet FR,FL,RR,RL
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
from mpcbox.tasks.legged.quadruped import QuadrupedStand


def main(
    argv: list[str] | None = None,
    *,
    default_model: str = "unitree_go2",
    prog: str = "go2_stand.py",
    description: str | None = None,
) -> int:
    """Run the comparison (``argv`` defaults to the command line; ``description``: the
    ``--help`` text's first paragraph, by default this module's)."""
    parser = argparse.ArgumentParser(
        prog=prog,
        description=description or __doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--model", default=default_model, help="Menagerie name or MJCF path")
    parser.add_argument("--feet", default="", help="comma-separated feet (default: known or found)")
    parser.add_argument("--controllers", default="lqr,qp", help="comma-separated controllers")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per scenario")
    parser.add_argument("--duration", type=float, default=5.0, help="seconds per run")
    parser.add_argument(
        "--push", type=float, default=0.0, help="forward push (N); default: 30 %% of the weight"
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
        problem = QuadrupedStand(model_source(args.model), feet=feet)
        suite = balance_suite(
            problem,
            duration=args.duration,
            force=args.push,
            weight_fraction=0.3,
            max_force_weights=20,
            largest_push=args.largest_push,
            scan_step=args.push_scan_step,
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
    print(f"{problem!r}: feet {', '.join(problem.contacts)}, root {problem.root!r}\n")
    print(result.to_markdown())
    return 0


if __name__ == "__main__":
    sys.exit(main())
