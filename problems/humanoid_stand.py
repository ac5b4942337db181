"""Humanoid standing on both feet: every controller tuned for it on the same seeded scenario.

A thin wrapper of ``mpcbox compare humanoid_stand`` with a short default scenario: one seed,
5 s, the task's actuator noise and a 30 N forward push on the torso at 2 s. On a machine
without an NVIDIA GPU the sampling controllers run with a handful of samples (see
:func:`mpcbox.cli.quick_sampling_options`); ``--set mppi.num_samples=256`` overrides that.

Examples::

    python problems/humanoid_stand.py
    python problems/humanoid_stand.py --controllers mppi --seeds 5 --noise 2
    python problems/humanoid_stand.py --help
"""

from __future__ import annotations

import sys

from mpcbox.cli import quick_sampling_options, run_task_script


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    return run_task_script(
        "humanoid_stand",
        argv,
        controller_options=quick_sampling_options(),
        duration=5.0,
        seed=1,
        seeds=1,
        push=30.0,
        push_time=2.0,
    )


if __name__ == "__main__":
    sys.exit(main())
