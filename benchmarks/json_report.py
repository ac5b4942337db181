"""How the legged-balance benchmarks end: stamp the run, print its JSON, write it if asked."""

from __future__ import annotations

import json
import platform
import sys
import time
from pathlib import Path

#: The machine these benchmarks' JSON names by default.
SANDBOX = "2-core sandbox CPU, shared"


def finish(out: dict, path: str, *, started: float, machine: str | None = SANDBOX) -> int:
    """Add ``wall_time_s`` (since ``started``, a :func:`time.perf_counter` reading) and, unless
    ``machine`` is None, ``machine`` and ``platform`` to ``out``; print it as JSON and write
    it to ``path`` when that is not empty. Returns 0, the script's exit status."""
    out["wall_time_s"] = round(time.perf_counter() - started, 1)
    if machine is not None:
        out["machine"] = machine
        out["platform"] = f"{platform.machine()}, Python {sys.version.split()[0]}"
    text = json.dumps(out, indent=2)
    print(text)
    if path:
        Path(path).write_text(text + "\n")
    return 0
