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

from mpcbox.comparison.robustness import PushLimit
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
        success_rate: Fraction of runs whose outcome is ``"success"`` (see
            :data:`~mpcbox.sim.simulation.OUTCOMES`): no fall, no divergence, no controller
            error, the task's goal met, and at most half of the controller's solves fell back.
        outcomes: Number of runs per outcome other than ``"success"`` (e.g.
            ``{"goal missed": 2}``).
        mean_time_to_fall: Mean of the failure times, counting survived runs at the full
            duration (s).
        measures: Mean over runs of each task measure's summary, in its display unit, by
            :meth:`~mpcbox.sim.measures.Measure.display_key` (e.g. ``"com_deviation_rms_cm"``,
            ``"tilt_rms_deg"`` for the humanoid tasks).
        control_effort: Mean over runs of the RMS control.
        largest_push: Largest survived force per :class:`~mpcbox.comparison.scenario.PushTest`
            label (N); empty when no push test ran.
        compute_mean_ms: Mean time of the controller's online solves over all runs (ms);
            calls that held the plan and offline solves are left out.
        compute_p99_ms: 99th percentile of the online solve times (ms).
        period_ms: Control period: seconds between controller calls, in ms.
        p99_fits: Whether ``compute_p99_ms <= period_ms`` (the controller keeps up in real
            time on this machine).
        offline_ms: Mean time of the offline solves per run (ms), e.g. IPOPT's one solve.
        realtime_factor: Total simulated time over total wall time.
        fallbacks: Controller fallbacks summed over runs.
        fallback_rate: ``fallbacks`` over all controller calls of all runs.
        kept_up: Real-time scenarios (``Scenario.realtime``): the share of runs whose
            planner kept up (p99 tick within the period, :attr:`~mpcbox.Metrics.kept_up`);
            ``None`` for lock-step runs.
        stalls: Solves that kept their warm start (:attr:`~mpcbox.Metrics.stalls`), summed
            over runs.
        stall_rate: ``stalls`` over the online solves of all runs.
    """

    scenario: str
    controller: str
    runs: int
    success_rate: float
    outcomes: dict[str, int]
    mean_time_to_fall: float
    measures: dict[str, float]
    control_effort: float
    largest_push: dict[str, float]
    compute_mean_ms: float
    compute_p99_ms: float
    period_ms: float
    p99_fits: bool
    offline_ms: float
    realtime_factor: float
    fallbacks: int
    fallback_rate: float
    kept_up: float | None = None
    stalls: int = 0
    stall_rate: float = 0.0


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
        placement: Jobs run per host (and GPU ids, where workers had GPUs).
    """

    problem: str
    controllers: tuple[str, ...]
    scenarios: tuple[Scenario, ...]
    seeds: tuple[int, ...]
    runs: tuple[Run, ...]
    push_limits: dict[str, dict[str, PushLimit]] = field(default_factory=dict)
    measures: tuple[Measure, ...] = ()
    wall_time: float = 0.0
    placement: dict[str, int] = field(default_factory=dict)

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
                    measure.display_key(summary): measure.scale_of(summary)
                    * _mean([m.measures.get(measure.key(summary), math.nan) for m in metrics])
                    for measure, summary in self._measure_columns()
                }
                outcomes: dict[str, int] = {}
                for m in metrics:
                    if m.outcome != "success":
                        outcomes[m.outcome] = outcomes.get(m.outcome, 0) + 1
                calls = sum(m.solve_ticks + m.held_ticks for m in metrics)
                p99 = float(np.percentile(ticks, 99) * 1e3) if ticks.size else 0.0
                period_ms = 1e3 * float(np.mean([m.period_s for m in metrics]))
                pushes = self.push_limits.get(name, {})
                rows.append(
                    Row(
                        scenario=scenario.label,
                        controller=name,
                        runs=len(runs),
                        success_rate=float(np.mean([m.success for m in metrics])),
                        outcomes=outcomes,
                        mean_time_to_fall=float(np.mean([m.time_to_fall for m in metrics])),
                        measures=measures,
                        control_effort=float(np.mean([m.control_effort for m in metrics])),
                        largest_push={k: v.force for k, v in pushes.items()},
                        compute_mean_ms=float(ticks.mean() * 1e3) if ticks.size else 0.0,
                        compute_p99_ms=p99,
                        period_ms=period_ms,
                        p99_fits=p99 <= period_ms,
                        offline_ms=float(np.mean([m.offline_ms for m in metrics])),
                        realtime_factor=sim_time / wall if wall > 0 else float("inf"),
                        fallbacks=int(sum(m.fallbacks for m in metrics)),
                        fallback_rate=sum(m.fallbacks for m in metrics) / max(calls, 1),
                        kept_up=_kept_up(metrics),
                        stalls=int(sum(m.stalls for m in metrics)),
                        stall_rate=sum(m.stalls for m in metrics)
                        / max(sum(m.solve_ticks for m in metrics), 1),
                    )
                )
        return rows

    def _push_labels(self) -> list[str]:
        labels: list[str] = []
        for limits in self.push_limits.values():
            labels += [k for k in limits if k not in labels]
        return labels

    def _stalled(self) -> bool:
        """Whether any run's controller stalled (then the tables get a "stalled" column)."""
        return any(r.metrics.stalls for r in self.runs)

    def _realtime(self) -> bool:
        """Whether any run was real-time (then the tables get a "kept up" column)."""
        return any(r.metrics.kept_up is not None for r in self.runs)

    def _table(self) -> tuple[list[str], list[list[str]]]:
        realtime = self._realtime()
        rows = self.rows()
        # Only when some controller stalled (iLQR-MPC replans that kept their warm start).
        stalled = self._stalled()
        labels = self._push_labels()
        columns = self._measure_columns()
        header = [
            "scenario",
            "controller",
            "seeds",
            "success",
            "not successful",
            "mean time to fall (s)",
            *[measure.header(summary) for measure, summary in columns],
            "effort",
            *[f"largest push {k} (N)" for k in labels],
            "compute mean (ms)",
            "compute p99 (ms)",
            "period (ms)",
            *(["kept up"] if realtime else []),
            "real-time factor",
            "fallbacks",
            *(["stalled"] if stalled else []),
        ]
        body = []
        for row in rows:
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
                    ", ".join(f"{n} {k}" for k, n in row.outcomes.items()) or "-",
                    f"{row.mean_time_to_fall:.2f}",
                    # NaN: no run gave a value (a settle time that never came).
                    *[_cell(row.measures[m.display_key(s)]) for m, s in columns],
                    f"{row.control_effort:.3f}",
                    *pushes,
                    f"{row.compute_mean_ms:.2f}",
                    f"{row.compute_p99_ms:.2f}" + ("" if row.p99_fits else " (over)"),
                    f"{row.period_ms:.1f}",
                    *([_share(row.kept_up)] if realtime else []),
                    f"{row.realtime_factor:.1f}",
                    f"{row.fallbacks} ({100 * row.fallback_rate:.0f}%)",
                    *([f"{row.stalls} ({100 * row.stall_rate:.0f}%)"] if stalled else []),
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

        Columns: the fields of :class:`Row` (``kept_up`` only with real-time runs, the
        stall counts only when a controller stalled), with ``measures`` spread to one
        column per task measure and summary (e.g. ``com_deviation_rms_cm, tilt_rms_deg``),
        ``largest_push`` to one ``largest_push_<label>`` column per push test, and
        ``outcomes`` written as ``"<count> <outcome>; ..."``.
        """
        measures = [m.display_key(s) for m, s in self._measure_columns()]
        labels = self._push_labels()
        pushes = [f"largest_push_{k}" for k in labels]
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        realtime, stalled = self._realtime(), self._stalled()
        fields = [
            f
            for f in Row._fields
            if (f != "kept_up" or realtime) and (f not in ("stalls", "stall_rate") or stalled)
        ]
        header: list[str] = []
        for name in fields:
            header += {"measures": measures, "largest_push": pushes}.get(name, [name])
        writer.writerow(header)
        for row in self.rows():
            values: list[object] = []
            for name in fields:
                if name == "measures":
                    values += [row.measures[k] for k in measures]
                elif name == "largest_push":
                    values += [row.largest_push.get(k, "") for k in labels]
                elif name == "outcomes":
                    values.append("; ".join(f"{n} {k}" for k, n in row.outcomes.items()))
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


def _cell(value: float) -> str:
    """A measure in the markdown table: two decimals, ``-`` where no run gave one."""
    return "-" if math.isnan(value) else f"{value:.2f}"


def _kept_up(metrics: list[Metrics]) -> float | None:
    """Share of the real-time runs that kept up, or ``None`` when none was real-time."""
    flags = [m.kept_up for m in metrics if m.kept_up is not None]
    return float(np.mean(flags)) if flags else None


def _share(value: float | None) -> str:
    """``"100%"``, or ``"-"`` for rows without real-time runs."""
    return "-" if value is None else f"{100 * value:.0f}%"


def _mean(values: list[float]) -> float:
    """Mean of the finite values (NaN when none is finite, e.g. a settle time never reached)."""
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else float("nan")
