"""PNG plots of closed-loop runs and comparisons (matplotlib with the headless Agg backend).

* :func:`plot_measures`: the task's measures (e.g. COM deviation and tilt of the humanoid
  tasks) over time for a few :class:`~mpcbox.SimulationResult`.
* :func:`plot_comparison`: every figure of a :class:`~mpcbox.comparison.report.Comparison`:
  :func:`plot_time_series` per scenario, :func:`plot_survival` against the noise scale and
  :func:`plot_compute_times`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mpcbox.comparison.report import Comparison, Trace
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.disturbances import Push
from mpcbox.sim.measures import Measure
from mpcbox.sim.simulation import SimulationResult

#: Shading of the intervals in which a push acts.
PUSH_SHADE = {"color": "tab:red", "alpha": 0.15, "lw": 0}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.]+", "_", text).strip("_") or "scenario"


def _control_series(ctrls: np.ndarray, ctrl_ref: np.ndarray) -> tuple[np.ndarray, str]:
    """Per-step RMS over actuators of ``ctrls - ctrl_ref``, or the control itself if nu == 1."""
    if ctrls.shape[1] == 1:
        return ctrls[:, 0], "control (actuator units)"
    rms = np.sqrt(np.mean((ctrls - ctrl_ref) ** 2, axis=1))
    return rms, "RMS control - reference\n(actuator units)"


def mark_pushes(axes: Sequence, pushes: Sequence[Push]) -> None:
    """Shade each push's interval and mark its start on every axis; the first axis gets a
    legend entry per push.

    Args:
        axes: Matplotlib axes sharing the time axis (s).
        pushes: The pushes of the run(s).
    """
    for push in pushes:
        force = float(np.linalg.norm(np.asarray(push.force, dtype=float)))
        for j, ax in enumerate(axes):
            label = f"push {force:g} N on {push.body}" if j == 0 else None
            ax.axvspan(push.start, push.start + push.duration, label=label, **PUSH_SHADE)
            ax.axvline(push.start, color="tab:red", lw=0.8)  # visible however short the push


def _axis_label(measure: Measure) -> str:
    unit = measure.shown_unit
    return f"{measure.title} ({unit})" if unit else measure.title


def plot_measures(results: Sequence[SimulationResult], path: str | Path, title: str = "") -> Path:
    """The task's measures over time, one panel per measure, one line per run.

    The panels follow the first run's :attr:`~mpcbox.SimulationResult.measures` (e.g. COM
    deviation from the support and torso tilt for the humanoid tasks), in their display
    units; the first run's pushes are shaded.

    Args:
        results: Runs to plot (typically one per controller on the same scenario).
        path: Output PNG path (folders are created).
        title: Figure title.

    Returns:
        The written path.

    Raises:
        InvalidArgumentError: When there is no run or the task declares no measures.
    """
    if not results or not results[0].measures:
        raise InvalidArgumentError(
            "plot_measures needs at least one run of a task that declares measures "
            "(Problem.measures)"
        )
    measures = results[0].measures
    plt = _pyplot()
    fig, axes = plt.subplots(len(measures), 1, figsize=(9, 3 * len(measures)), sharex=True)
    axes = np.atleast_1d(axes)
    for res in results:
        label = res.controller + (
            "" if res.metrics.success else f" ({res.metrics.outcome} at {res.time[-1]:.2f} s)"
        )
        for ax, measure in zip(axes, measures):
            ax.plot(res.time, res.series[measure.name] * measure.display_scale, label=label)
    mark_pushes(axes, results[0].pushes)
    for ax, measure in zip(axes, measures):
        ax.set_ylabel(_axis_label(measure))
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    axes[0].legend(loc="upper right")
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def plot_time_series(
    traces: dict[str, Trace],
    path: str | Path,
    title: str = "",
    failures: dict[str, str | None] | None = None,
    measures: Sequence[Measure] = (),
    pushes: Sequence[Push] = (),
) -> Path:
    """The task's measures and the control activity over time, one line per controller.

    Args:
        traces: ``{controller label: Trace}`` of runs on the same scenario and seed.
        path: Output PNG path.
        title: Figure title.
        failures: ``{controller label: failure reason or None}`` for the legend.
        measures: The task's measures, one panel each above the control panel.
        pushes: Pushes of the runs, shaded over their intervals.

    Returns:
        The written path.
    """
    plt = _pyplot()
    rows = len(measures) + 1
    fig, axes = plt.subplots(rows, 1, figsize=(9, 2 + 2 * rows), sharex=True)
    axes = np.atleast_1d(axes)
    ylabel = "control"
    for name, tr in traces.items():
        fell = (failures or {}).get(name)
        label = name + (f" (fell at {tr.time[-1]:.2f} s)" if fell else "")
        for ax, measure in zip(axes, measures):
            ax.plot(tr.time, tr.series[measure.name] * measure.display_scale, label=label)
        series, ylabel = _control_series(tr.ctrls, tr.ctrl_ref)
        # The last row of a run holds no applied control.
        axes[-1].plot(tr.time[:-1], series[:-1], label=label)
    mark_pushes(axes, pushes)
    for ax, measure in zip(axes, measures):
        ax.set_ylabel(_axis_label(measure))
    axes[-1].set_ylabel(ylabel)
    axes[-1].set_xlabel("time (s)")
    axes[0].legend(loc="upper right")
    for ax in axes:
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return _save(fig, path)


def plot_survival(comparison: Comparison, path: str | Path) -> Path:
    """Success rate against the scenarios' noise scale, one line per controller.

    Only scenarios without pushes and model mismatch are used when there are any (all
    scenarios otherwise); rates are averaged when several of them share a noise scale.

    Returns:
        The written path.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    plain = [s for s in comparison.scenarios if not s.pushes and s.mismatch is None]
    used = plain or list(comparison.scenarios)
    scales = sorted({s.noise_scale for s in used})
    for name in comparison.controllers:
        rates = []
        for scale in scales:
            runs = [
                r
                for i, s in enumerate(comparison.scenarios)
                if s.noise_scale == scale and any(s is u for u in used)
                for r in comparison.runs_of(name, i)
            ]
            rates.append(100.0 * np.mean([r.metrics.success for r in runs]) if runs else np.nan)
        ax.plot(scales, rates, marker="o", label=name)
    ax.set_xlabel("noise scale (x the task's noise standard deviation)")
    ax.set_ylabel(f"success rate over {len(comparison.seeds)} seeds (%)")
    ax.set_ylim(-5, 105)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(f"{comparison.problem}: survival against noise")
    return _save(fig, path)


def plot_compute_times(comparison: Comparison, path: str | Path) -> Path:
    """Distribution of the controller time per call (log scale), one box per controller,
    with each controller's control period (ms) as a dashed red line.

    Returns:
        The written path.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    data, names = [], []
    for name in comparison.controllers:
        ticks = [r.compute_times for r in comparison.runs if r.controller == name]
        ticks = np.concatenate(ticks) * 1e3 if ticks else np.zeros(0)
        if ticks.size:
            data.append(np.maximum(ticks, 1e-4))
            names.append(name)
    if data:
        ax.boxplot(data, whis=(1, 99), showfliers=False)
        ax.set_xticks(range(1, len(names) + 1), names)
        ax.set_yscale("log")
        for i, name in enumerate(names, start=1):
            periods = [getattr(r.metrics, "period_s", 0.0) for r in comparison.runs]
            periods = [p for p, r in zip(periods, comparison.runs) if r.controller == name and p]
            if periods:  # the budget of one call: p99 above this line does not fit
                label = "control period" if i == 1 else None
                ms = 1e3 * max(periods)
                ax.hlines(ms, i - 0.4, i + 0.4, colors="tab:red", linestyles="--", label=label)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best")
    ax.set_ylabel("compute time per call (ms)")
    ax.grid(alpha=0.3, axis="y")
    ax.set_title(f"{comparison.problem}: compute per tick (whiskers: 1st-99th percentile)")
    return _save(fig, path)


def plot_comparison(comparison: Comparison, folder: str | Path) -> list[Path]:
    """Write every figure of a comparison into ``folder``.

    Files: ``timeseries_<scenario>.png`` (first seed of each scenario),
    ``survival_vs_noise.png`` and ``compute_time.png``.

    Returns:
        The written paths.
    """
    folder = Path(folder)
    paths = []
    slugs = [_slug(s.label) for s in comparison.scenarios]
    for i, scenario in enumerate(comparison.scenarios):
        slug = slugs[i] if slugs.count(slugs[i]) == 1 else f"{i}_{slugs[i]}"
        traces, failures = {}, {}
        for name in comparison.controllers:
            for run in comparison.runs_of(name, i):
                if run.trace is not None:
                    traces[name], failures[name] = run.trace, run.failure
                    break
        if traces:
            title = f"{comparison.problem}, {scenario.label}, seed {comparison.seeds[0]}"
            paths.append(
                plot_time_series(
                    traces,
                    folder / f"timeseries_{slug}.png",
                    title,
                    failures,
                    comparison.measures,
                    scenario.pushes,
                )
            )
    paths.append(plot_survival(comparison, folder / "survival_vs_noise.png"))
    paths.append(plot_compute_times(comparison, folder / "compute_time.png"))
    return paths
