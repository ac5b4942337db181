"""Cart-pole swing-up: iLQR-MPC and the IPOPT plan (tracked with TV-LQR) on one scenario.

Prints a markdown table and writes PNG plots into ``results/cartpole_swingup/``.

    python problems/cartpole_swingup.py [--duration 8] [--out results/cartpole_swingup]
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from pendulum_swingup import main as _main


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if "--duration" not in args:
        args += ["--duration", "8"]
    return _main(args, task="cartpole_swingup")


if __name__ == "__main__":
    sys.exit(main())
