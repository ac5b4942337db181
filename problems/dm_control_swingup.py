"""dm_control suite swing-ups: iLQR-MPC and MPPI (CPU backend) on the cart-pole or acrobot.

A thin wrapper of ``mpcbox compare dm_cartpole_swingup`` (or ``dm_acrobot_swingup``): one
noise-free run from hanging at rest. Prints a markdown table (success as the task defines
it: upright within tolerance over the final second) and writes ``results.md``,
``results.csv`` and PNG plots into ``results/dm_<model>_swingup/``. Needs ``dm_control``.

    python problems/dm_control_swingup.py --model cartpole [--duration 6] [--out DIR]
    python problems/dm_control_swingup.py --model acrobot

Perturbed starts over several seeds are in ``benchmarks/swingup_dm_control.py``.
"""

from __future__ import annotations

import argparse
import sys

from mpcbox.cli import run_task_script

MODELS = ("cartpole", "acrobot")


def main(argv: list[str] | None = None) -> int:
    """Parse ``--model`` and pass the other arguments to the comparison."""
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument(
        "--model", choices=MODELS, default="cartpole", help="dm_control suite model to swing up"
    )
    args, _ = parser.parse_known_args(argv)
    return run_task_script(
        f"dm_{args.model}_swingup",
        argv,
        prog="dm_control_swingup.py",
        parents=[parser],
        controllers="ilqr,mppi",
        duration=6.0,
        seeds=1,
        noise="0",
    )


if __name__ == "__main__":
    sys.exit(main())
