"""One-leg humanoid balance: every available controller on the same seeded scenario.

A thin wrapper of ``mpcbox compare humanoid_balance`` with a short default scenario: one
seed, 12 s, the recipe's actuator noise and a 30 N forward push on the torso at 2 s.
Prints a markdown table and writes ``results.md``, ``results.csv`` and PNG plots (COM
deviation, torso tilt and controls over time; survival; compute time per tick).

Examples::

    python problems/humanoid_balance.py
    python problems/humanoid_balance.py --leg right --controllers lqr --seeds 10 --noise 2
    python problems/humanoid_balance.py --help
"""

from __future__ import annotations

import sys

from mpcbox.cli import quick_sampling_options, run_task_script


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    return run_task_script(
        "humanoid_balance",
        argv,
        controller_options=quick_sampling_options(),
        duration=12.0,
        seed=1,
        seeds=1,
        push=30.0,
        push_time=2.0,
    )


if __name__ == "__main__":
    sys.exit(main())
