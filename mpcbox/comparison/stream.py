"""Per-seed rows written as their runs finish, so that a long sweep shows (and keeps) its
results before it ends.

:class:`RunStream` is a ``compare(on_done=...)`` hook: every finished closed-loop run
appends one row (:func:`~mpcbox.comparison.records.run_row`, plus ``where`` it ran) to
``runs.jsonl`` (one JSON object per line) and ``runs.csv`` in its folder, flushed at once.
Rows come in finishing order; :func:`~mpcbox.comparison.records.write_records` rewrites
``runs.csv`` and ``runs.json`` in the comparison's order at the end. ``mpcbox compare``
streams to ``--out``; with the checkpoint in ``--out/runs``, a re-run streams the finished
jobs first (loaded, not run) and then the rest.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mpcbox.comparison.jobs import Done
from mpcbox.comparison.records import run_row
from mpcbox.comparison.report import Run
from mpcbox.comparison.scenario import Scenario
from mpcbox.sim.trajectory import jsonable


class RunStream:
    """Appends each finished run's row to ``folder/runs.jsonl`` and ``folder/runs.csv``.

    Args:
        folder: Output folder (created); both files start empty.
        scenarios: The comparison's scenarios (for the ``scenario`` column).
    """

    def __init__(self, folder: str | Path, scenarios: Sequence[Scenario]) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.labels = [s.label for s in scenarios]
        self.jsonl = self.folder / "runs.jsonl"
        self.csv = self.folder / "runs.csv"
        self.rows: list[dict[str, Any]] = []
        self.header: list[str] = []
        self.jsonl.write_text("")
        self.csv.write_text("")

    def __call__(self, done: Done) -> None:
        """Append the row of ``done`` (push searches have no row)."""
        if not isinstance(done.result, Run):
            return
        row = run_row(done.result, self.labels[done.job.scenario])
        row["where"] = done.where
        self.rows.append(row)
        with self.jsonl.open("a") as f:
            f.write(json.dumps(jsonable(row)) + "\n")
        new = [k for k in row if k not in self.header]
        if new:  # a column first seen now (a task measure): rewrite with the wider header
            self.header += new
            self._write(self.rows, "w", header=True)
        else:
            self._write([row], "a", header=False)

    def _write(self, rows: list[dict[str, Any]], mode: str, *, header: bool) -> None:
        with self.csv.open(mode, newline="") as f:
            writer = csv.DictWriter(f, self.header, restval="", lineterminator="\n")
            if header:
                writer.writeheader()
            writer.writerows(rows)


__all__ = ["RunStream"]
