"""Gates for moving a MuJoCo scene to MuJoCo Warp: ``mpcbox validate SCENE`` in Python.

:func:`validate_scene` runs, on any scene, over recorded or generated controls:

1. the CPU baseline (MuJoCo, divergence detection);
2. one-world MJWarp parity (state difference over time against the CPU);
3. contact and constraint capacity sizing (most contacts and rows seen, with headroom;
   overflows flagged as failures);
4. N worlds at once with no per-step copies to the host;
5. throughput against the number of worlds (CUDA graph, cold and warm, synchronized).

The MJWarp parts import ``warp`` and ``mujoco_warp`` only when they run.
"""

from __future__ import annotations

from mpcbox.gates.config import CONTROL_MODES, GatesConfig
from mpcbox.gates.report import GateReport, format_report, write_report
from mpcbox.gates.run import validate_scene

__all__ = [
    "CONTROL_MODES",
    "GateReport",
    "GatesConfig",
    "format_report",
    "validate_scene",
    "write_report",
]
