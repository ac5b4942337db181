"""Cart-pole swing-up: iLQR-MPC and the IPOPT plan (tracked with TV-LQR) on one scenario.

A thin wrapper of ``mpcbox compare cartpole_swingup``: one noise-free 8 s run from rest.
Prints a markdown table and writes ``results.md``, ``results.csv`` and PNG plots into
``results/cartpole_swingup/``.

    python problems/cartpole_swingup.py [--duration 8] [--out results/cartpole_swingup]
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from pendulum_swingup import main as _main


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    return _main(argv, task="cartpole_swingup", duration=8.0)


if __name__ == "__main__":
    sys.exit(main())
