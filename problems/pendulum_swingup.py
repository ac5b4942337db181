"""Pendulum swing-up: iLQR-MPC and the IPOPT plan (tracked with TV-LQR) on one scenario.

Prints a markdown table and writes PNG plots into ``results/pendulum_swingup/``. LQR is left
out: it only stabilizes about upright and cannot swing the pendulum up.

    python problems/pendulum_swingup.py [--duration 6] [--out results/pendulum_swingup]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys

from mpcbox.compare import Scenario, compare


def main(argv: list[str] | None = None, task: str = "pendulum_swingup") -> int:
    """Run the comparison for ``task`` (``argv`` defaults to the command line)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--out", default=f"results/{task}")
    args = parser.parse_args(argv)
    controllers = ["ilqr"]
    if importlib.util.find_spec("casadi") is not None:
        controllers.append("ipopt")
    else:
        print("casadi is not installed: skipping the IPOPT reference", file=sys.stderr)
    scenario = Scenario(name="swing-up from rest", duration=args.duration, noise_scale=0.0)
    result = compare(task, controllers, scenario, seeds=1, workers=1, progress=False)
    print(result.to_markdown())
    for path in result.plot(args.out):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
