"""Unitree's Go1 standing: ``problems/go2_stand.py`` with ``--model unitree_go1`` by default.

The Go1 of MuJoCo Menagerie drives its joints with position servos (kp 100), where the Go2
has torque motors; the same options apply (``python problems/go1_stand.py --help``).

Examples::

    python problems/go1_stand.py
    python problems/go1_stand.py --model unitree_a1 --seeds 3
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from go2_stand import main as go2_main


def main(argv: list[str] | None = None) -> int:
    """Run the comparison on the Go1 (``argv`` defaults to the command line)."""
    return go2_main(
        argv,
        default_model="unitree_go1",
        prog="go1_stand.py",
        description=__doc__.split("\n\n")[0],
    )


if __name__ == "__main__":
    sys.exit(main())
