"""Unitree G1 get-up (MuJoCo Menagerie): from lying on its back to standing, by sampling MPC.

A thin wrapper of ``mpcbox compare g1_getup`` (:class:`~mpcbox.tasks.humanoid.g1_getup.G1Getup`:
29 position servos, sampling noise 5 % of each servo's range, the torso's height weighted
1000): one seed of 5 s, success when the torso is up within the 5 s and held for the last
0.5 s. Needs the robot: ``pip install "mpcbox[menagerie]"`` or ``MENAGERIE_ROOT`` pointing at
an offline copy (without it the script names what is missing and returns 2). With an NVIDIA
GPU MPPI runs its tuned config on MuJoCo Warp. With ``--realtime`` it plans from the state
predicted one median tick ahead (the task's default, ``--lookahead none`` turns it off): on
an H200 up in 132 of 140 runs where the plain loop got 119 on the same seeds
(``docs/results/sampling_gpu.md``);
without one it runs with a handful of samples, which shows the loop but does not get the G1
up.

Examples::

    MENAGERIE_ROOT=... python problems/g1_getup.py --controllers mppi
    MENAGERIE_ROOT=... python problems/g1_getup.py --controllers mppi --seeds 10 --realtime
    MENAGERIE_ROOT=... python problems/g1_getup.py --controllers mppi --realtime --lookahead none
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # problems/ is not a package
from humanoid_getup import main as getup_main


def main(argv: list[str] | None = None) -> int:
    """Run the comparison (``argv`` defaults to the command line)."""
    return getup_main(argv, task="g1_getup")


if __name__ == "__main__":
    sys.exit(main())
