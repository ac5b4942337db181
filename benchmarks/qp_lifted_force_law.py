"""QP-MPC's two treatments of a lifted point's force law, on the same pushes; prints JSON.

``QPMPCConfig.lifted_force_law``: ``"drop"`` leaves the linearized force law of a point that
is lifted at the measured state out of the QP, ``"cancel"`` keeps it and cancels the force
with the penalized slack. For each task and direction, the largest survived push of 0.1 s on
the root body (bisection, no noise, 2 s to recover) with each setting, and the failed solves
over the trial runs::

    python benchmarks/qp_lifted_force_law.py
    MENAGERIE_ROOT=... python benchmarks/qp_lifted_force_law.py --tasks quadruped_stand
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

from json_report import finish  # benchmarks/ is not a package

from mpcbox.comparison.push_limits import largest_push
from mpcbox.comparison.scenario import PushTest
from mpcbox.registry import task_class

SETTINGS = ("drop", "cancel")
DIRECTIONS = {"forward": (1.0, 0.0, 0.0), "backward": (-1.0, 0.0, 0.0)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--tasks", default="humanoid_balance,humanoid_two_feet", help="comma-separated names"
    )
    parser.add_argument("--tolerance", type=float, default=2.0, help="bisection bracket (N)")
    parser.add_argument("--max-force", type=float, default=300.0, help="search range (N)")
    parser.add_argument("--json", default="", help="also write the JSON here")
    args = parser.parse_args(argv)
    out: dict = {
        "benchmark": "qp_lifted_force_law",
        "machine": f"{platform.machine()}, {os.cpu_count()} cores (2-core sandbox CPU, shared)",
        "push": {"start_s": 1.0, "duration_s": 0.1, "settle_s": 2.0, "noise": 0},
        "largest_push_N": {},
    }
    t0 = time.perf_counter()
    for task in args.tasks.split(","):
        root = task_class(task)(threads=1)
        body = root.root if hasattr(root, "root") else "torso"
        root.close()
        for name, direction in DIRECTIONS.items():
            test = PushTest(
                body=body,
                direction=direction,
                start=1.0,
                duration=0.1,
                settle=2.0,
                tolerance=args.tolerance,
                max_force=args.max_force,
                name=name,
            )
            for law in SETTINGS:
                options = {"lifted_force_law": law}
                limit = largest_push(task, "qp", test, controller_options=options)
                out["largest_push_N"][f"{task}/{name}/{law}"] = round(limit.force, 1)
                print(task, name, law, round(limit.force, 1), file=sys.stderr, flush=True)
    return finish(out, args.json, started=t0, machine=None)


if __name__ == "__main__":
    sys.exit(main())
