"""Humanoid get-up: from lying on its back on the floor to standing, by sampling MPC.

A thin wrapper of ``mpcbox compare humanoid_getup``: one seed of 5 s, success when the
torso is up within the 5 s and held for the last 0.5 s. With an NVIDIA GPU the sampling
controllers run their tuned configs on MuJoCo Warp (MPPI, in the real-time loop on an H100
or H200: 54 of 60 held-out runs, see ``docs/results/sampling_gpu.md``). Without one they run
with a handful of samples (see :func:`mpcbox.cli.quick_sampling_options`), which shows the
loop but does not get the humanoid up; ``--set mppi.num_samples=512`` gives it more.
``problems/g1_getup.py`` runs the same on Unitree's G1.

Examples::

    python problems/humanoid_getup.py
    python problems/humanoid_getup.py --controllers mppi --seeds 5 --realtime
    python problems/humanoid_getup.py --help
"""

from __future__ import annotations

import sys

from mpcbox.cli import quick_sampling_options, run_task_script


def main(argv: list[str] | None = None, task: str = "humanoid_getup") -> int:
    """Run the comparison of get-up ``task`` (``argv`` defaults to the command line)."""
    return run_task_script(
        task,
        argv,
        controller_options=quick_sampling_options(task),
        duration=5.0,
        seeds=1,
        push=0.0,
    )


if __name__ == "__main__":
    sys.exit(main())
