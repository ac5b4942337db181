"""Results of a comparison: the runs, the table rows, and the markdown and CSV tables.

The columns are the generic metrics of every run (:class:`~mpcbox.Metrics`), the task's own
measures (:meth:`~mpcbox.Problem.measures`, one column per measure and summary; e.g. COM
deviation and tilt for the humanoid tasks, none for the swing-ups) and the largest pushes.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from mpcbox.comparison.push_limits import PushLimit
from mpcbox.comparison.scenario import Scenario
from mpcbox.sim.measures import Measure
from mpcbox.sim.simulation import Metrics


class Trace(NamedTuple):
    """Time series of one run (``T`` simulation steps), kept for plotting.

    Attributes:
        time: Times ``(T,)`` (s).
        series: Samples ``(T,)`` of each task measure, by measure name, in its unit.
        ctrls: Applied controls ``(T, nu)``.
        ctrl_ref: The problem's reference control ``(nu,)``.
        states: States ``(T, nstate)`` (for saving the trajectory), or ``None``.
    """

    time: np.ndarray
    series: dict[str, np.ndarray]
    ctrls: np.ndarray
    ctrl_ref: np.ndarray
    states: np.ndarray | None = None


class Run(NamedTuple):
    """One closed-loop run of a comparison.

    Attributes:
        controller: Controller label.
        scenario: Index into :attr:`Comparison.scenarios`.
        seed: Noise seed.
        metrics: The run's :class:`~mpcbox.Metrics`.
        failure: Why it stopped early, or ``None``.
        compute_times: Controller time per call ``(calls,)`` (s).
        trace: Time series (kept for the first seed only), or ``None``.
    """

    controller: str
    scenario: int
    seed: int
    metrics: Metrics
    failure: str | None
    compute_times: np.ndarray
    trace: Trace | None


class Row(NamedTuple):
    """One line of the comparison table: a controller on a scenario, over all seeds.

    Attributes:
        scenario: Scenario label.
        controller: Controller label.
        runs: Number of seeds.
        success_rate: Fraction of runs that did not fail.
        mean_time_to_fall: Mean of the failure times, counting survived runs at the full
            duration (s).
        measures: Mean over runs of each task measure's summary, in its display unit, by
            :meth:`~mpcbox.sim.measures.Measure.display_key` (e.g. ``"com_deviation_rms_cm"``,
            ``"tilt_rms_deg"`` for the humanoid tasks).
        control_effort: Mean over runs of the RMS control.
        largest_push: Largest survived force per :class:`~mpcbox.comparison.scenario.PushTest`
            label (N); empty when no push test ran.
        compute_mean_ms: Mean controller time per call over all runs (ms).
        compute_p99_ms: 99th percentile of the controller time per call (ms).
        realtime_factor: Total simulated time over total wall time.
        fallbacks: Controller fallbacks summed over runs.
    """

    scenario: str
    controller: str
    runs: int
    success_rate: float
    mean_time_to_fall: float
    measures: dict[str, float]
    control_effort: float
    largest_push: dict[str, float]
    compute_mean_ms: float
    compute_p99_ms: float
    realtime_factor: float
    fallbacks: int


@dataclass
class Comparison:
    """Everything :func:`~mpcbox.compare` measured.

    :func:`~mpcbox.comparison.plots.plot_comparison` draws its figures.

    Attributes:
        problem: Problem name.
        controllers: Controller labels, in the order given.
        scenarios: The scenarios.
        seeds: The seeds.
        runs: One :class:`Run` per controller, scenario and seed, in that order.
        push_limits: ``{controller: {push test label: PushLimit}}``.
        measures: The task's measures (:meth:`~mpcbox.Problem.measures`).
        wall_time: Seconds the whole comparison took.
    """

    problem: str
    controllers: tuple[str, ...]
    scenarios: tuple[Scenario, ...]
    seeds: tuple[int, ...]
    runs: tuple[Run, ...]
    push_limits: dict[str, dict[str, PushLimit]] = field(default_factory=dict)
    measures: tuple[Measure, ...] = ()
    wall_time: float = 0.0

    def runs_of(self, controller: str, scenario: int) -> list[Run]:
        """The runs of one controller on one scenario (by index), in seed order."""
        return [r for r in self.runs if r.controller == controller and r.scenario == scenario]

    def _measure_columns(self) -> list[tuple[Measure, str]]:
        return [(m, s) for m in self.measures for s in m.summaries]

    def rows(self) -> list[Row]:
        """The table rows: scenarios in order, controllers in order within each."""
        rows = []
        for s, scenario in enumerate(self.scenarios):
            for name in self.controllers:
                runs = self.runs_of(name, s)
                if not runs:
                    continue
                metrics = [r.metrics for r in runs]
                ticks = np.concatenate([r.compute_times for r in runs])
                sim_time = sum(m.time_to_fall for m in metrics)
                wall = sum(
                    m.time_to_fall / m.realtime_factor
                    for m in metrics
                    if m.realtime_factor > 0 and math.isfinite(m.realtime_factor)
                )
                measures = {
                    measure.display_key(summary): measure.display_scale
                    * float(np.mean([m.measures[measure.key(summary)] for m in metrics]))
                    for measure, summary in self._measure_columns()
                }
                pushes = self.push_limits.get(name, {})
                rows.append(
                    Row(
                        scenario=scenario.label,
                        controller=name,
                        runs=len(runs),
                        success_rate=float(np.mean([m.survived for m in metrics])),
                        mean_time_to_fall=float(np.mean([m.time_to_fall for m in metrics])),
                        measures=measures,
                        control_effort=float(np.mean([m.control_effort for m in metrics])),
                        largest_push={k: v.force for k, v in pushes.items()},
                        compute_mean_ms=float(ticks.mean() * 1e3) if ticks.size else 0.0,
                        compute_p99_ms=float(np.percentile(ticks, 99) * 1e3) if ticks.size else 0.0,
                        realtime_factor=sim_time / wall if wall > 0 else float("inf"),
                        fallbacks=int(sum(m.fallbacks for m in metrics)),
                    )
                )
        return rows

    def _push_labels(self) -> list[str]:
        labels: list[str] = []
        for limits in self.push_limits.values():
            labels += [k for k in limits if k not in labels]
        return labels

    def _table(self) -> tuple[list[str], list[list[str]]]:
        labels = self._push_labels()
        columns = self._measure_columns()
        header = [
            "scenario",
            "controller",
            "seeds",
            "success",
            "mean time to fall (s)",
            *[measure.header(summary) for measure, summary in columns],
            "effort",
            *[f"largest push {k} (N)" for k in labels],
            "compute mean (ms)",
            "compute p99 (ms)",
            "real-time factor",
            "fallbacks",
        ]
        body = []
        for row in self.rows():
            pushes = []
            for k in labels:
                force = row.largest_push.get(k)
                pushes.append("-" if force is None else f"{force:.0f}")
            body.append(
                [
                    row.scenario,
                    row.controller,
                    str(row.runs),
                    f"{100 * row.success_rate:.0f}%",
                    f"{row.mean_time_to_fall:.2f}",
                    *[f"{row.measures[m.display_key(s)]:.2f}" for m, s in columns],
                    f"{row.control_effort:.3f}",
                    *pushes,
                    f"{row.compute_mean_ms:.2f}",
                    f"{row.compute_p99_ms:.2f}",
                    f"{row.realtime_factor:.1f}",
                    str(row.fallbacks),
                ]
            )
        return header, body

    def to_markdown(self) -> str:
        """The table as GitHub-flavoured markdown (one row per scenario and controller)."""
        header, body = self._table()
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(cells) + " |" for cells in body]
        return "\n".join(lines)

    def to_csv(self, path: str | Path | None = None) -> str:
        """The rows as CSV with full precision; also written to ``path`` when given.

        Columns: ``scenario, controller, runs, success_rate, mean_time_to_fall``, one column
        per task measure and summary (e.g. ``com_deviation_rms_cm, tilt_rms_deg``),
        ``control_effort, largest_push_<label>..., compute_mean_ms, compute_p99_ms,
        realtime_factor, fallbacks``.
        """
        measures = [m.display_key(s) for m, s in self._measure_columns()]
        labels = self._push_labels()
        pushes = [f"largest_push_{k}" for k in labels]
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        header: list[str] = []
        for name in Row._fields:
            header += {"measures": measures, "largest_push": pushes}.get(name, [name])
        writer.writerow(header)
        for row in self.rows():
            values: list[object] = []
            for name in Row._fields:
                if name == "measures":
                    values += [row.measures[k] for k in measures]
                elif name == "largest_push":
                    values += [row.largest_push.get(k, "") for k in labels]
                else:
                    values.append(getattr(row, name))
            writer.writerow(values)
        text = buffer.getvalue()
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        return text

    def __str__(self) -> str:
        return self.to_markdown()
