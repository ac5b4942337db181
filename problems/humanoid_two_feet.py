"""Two-feet humanoid balance: LQR against the contact-force QP-MPC on one pushed scenario.

A thin wrapper of ``mpcbox compare humanoid_two_feet``: one seed, 6 s, the recipe's actuator
noise and an 80 N forward push on the torso at 1 s. Prints a markdown table and writes
``results.md``, ``results.csv`` and PNG plots into ``results/humanoid_two_feet/``. The push
limits over force grids are in ``benchmarks/qp_two_feet.py``.

Examples::

    python problems/humanoid_two_feet.py
    python problems/humanoid_two_feet.py --push 100 --seeds 5
"""

from __future__ import annotations

import sys

from mpcbox.cli import run_task_script


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    return run_task_script(
        "humanoid_two_feet", argv, duration=6.0, seed=0, seeds=1, push=80.0, push_time=1.0
    )


if __name__ == "__main__":
    sys.exit(main())
