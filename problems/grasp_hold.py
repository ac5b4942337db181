"""A parallel-jaw gripper lifts, pushes and shakes an object: force-QP grasp against position grasp.

Runs ``--trials`` randomized trials at one friction level (``low`` 0.3-0.6, ``medium``
1.0-1.25, ``high`` 1.25-1.5 sliding friction) with both controllers on the same draws and
prints one line per trial and a table by object kind: success rate (the object stays within
1 cm of where it sat in the gripper), median and largest finger force, median slip. The
force grasp (:class:`mpcbox.controllers.grasp.ForceGrasp`) solves a QP for finger forces in
the friction cones each 2 ms and squeezes harder when it sees slip; the position grasp
closes the finger servos fully.

    python problems/grasp_hold.py [--level low] [--trials 9] [--kind hard] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys

from mpcbox.cli.checks import script_main
from mpcbox.tasks.grasp import FRICTION_LEVELS, KINDS, run_trials, success_table
from mpcbox.validation import integer, positive_int


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line); a bad argument prints
    its named error and returns 2."""
    return script_main(_run, argv)


def _run(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", default="low", choices=list(FRICTION_LEVELS))
    parser.add_argument("--trials", type=int, default=9)
    parser.add_argument("--kind", default=None, choices=list(KINDS))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    positive_int("--trials", args.trials)
    integer("--seed", args.seed, minimum=0)  # NumPy seeds

    kinds = None if args.kind is None else [args.kind]
    records = run_trials(args.level, args.trials, seed=args.seed, kinds=kinds)
    print(f"friction level {args.level!r}: sliding friction {FRICTION_LEVELS[args.level]}")
    for r in records:
        obj, res = r.draw.object, r.result
        print(
            f"trial {r.index:3d} {r.controller:8s} {obj.kind:9s} {obj.shape:9s} "
            f"m={obj.mass:.2f} kg mu={obj.friction[0]:.2f} K={obj.stiffness:.0e} N/m: "
            f"{'held' if res.success else 'LOST'} (slip {1e3 * res.slip:.1f} mm, "
            f"max finger force {res.max_finger_force:.1f} N)"
        )
    print(
        "\n| controller | objects | trials | success | median / max finger force (N) "
        "| median slip (mm) |"
    )
    print("|---|---|---|---|---|---|")
    for name, rows in success_table(records).items():
        for kind, row in rows.items():
            print(
                f"| {name} | {kind} | {row['trials']} | {100 * row['success_rate']:.0f} % | "
                f"{row['median_max_finger_force']:.1f} / {row['max_finger_force']:.1f} | "
                f"{1e3 * row['median_slip']:.1f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
