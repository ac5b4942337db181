"""Pendulum swing-up: iLQR-MPC and the IPOPT plan (tracked with TV-LQR) on one scenario.

A thin wrapper of ``mpcbox compare pendulum_swingup``: one noise-free 6 s run from rest.
Prints a markdown table and writes ``results.md``, ``results.csv`` and PNG plots into
``results/pendulum_swingup/``. LQR is left out: it only stabilizes about upright and cannot
swing the pendulum up. The IPOPT reference needs CasADi (``pip install mpcbox[casadi]``).

    python problems/pendulum_swingup.py [--duration 6] [--out results/pendulum_swingup]
"""

from __future__ import annotations

import importlib.util
import sys

from mpcbox.cli import run_task_script


def default_controllers() -> str:
    """``"ilqr,ipopt"``, or ``"ilqr"`` when CasADi is not installed."""
    if importlib.util.find_spec("casadi") is not None:
        return "ilqr,ipopt"
    print("casadi is not installed: skipping the IPOPT reference", file=sys.stderr)
    return "ilqr"


def main(argv: list[str] | None = None, task: str = "pendulum_swingup", **defaults) -> int:
    """Run the comparison for ``task`` (``argv`` defaults to the command line)."""
    defaults = {"duration": 6.0, "seeds": 1, "noise": "0", **defaults}
    return run_task_script(task, argv, controllers=default_controllers(), **defaults)


if __name__ == "__main__":
    sys.exit(main())
