"""What a comparison keeps on disk: per-seed rows, group spread, settings and trajectories.

:func:`write_records` writes into one folder:

* ``runs.csv`` / ``runs.json``: one row per controller, scenario and seed: ``scenario,
  controller, seed, outcome, survived, time_to_fall, failure``, then every field of
  :class:`~mpcbox.Metrics` (read from ``Metrics._fields``, so new fields appear without a
  change here; the task measures are spread into one column per summary key);
* ``groups.csv`` / ``groups.json``: per scenario and controller, the ``mean``, ``std``
  (sample standard deviation, 0 for one seed), ``min`` and ``max`` over seeds of every
  numeric column (booleans as 0/1, so ``survived_mean`` is the success rate);
* ``run.json``: the task and its options, the scenarios, the controllers' settings (config
  dataclasses as dicts), package versions, the command line, the machine and the date, and
  where the jobs ran (``placement``: jobs per host, Ray node and GPU ids);
* ``trajectories/``: the traced run (first seed) of each controller and scenario, as
  :func:`~mpcbox.sim.trajectory_files.save_trajectory` writes them.

In JSON a non-finite number is ``null``; in CSV it is ``nan``/``inf``.
"""

from __future__ import annotations

import csv
import datetime
import json
import os
import platform
import re
import shutil
import subprocess
import sys
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from mpcbox.comparison.report import Comparison, Run
from mpcbox.config import resolve_config
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.registry import CONTROLLERS, controller_class
from mpcbox.sim.trajectory import Trajectory, jsonable, make_trajectory
from mpcbox.sim.trajectory_files import save_trajectory

#: Packages whose versions ``run.json`` records (distribution names).
PACKAGES = ("mpcbox", "mujoco", "mujoco-warp", "warp-lang", "numpy", "scipy", "osqp")
#: Statistics of each numeric column per group.
STATS = ("mean", "std", "min", "max")
_KEYS = ("scenario", "controller", "seed")


def _outcome(metrics: Any) -> str:
    outcome = getattr(metrics, "outcome", None)
    if outcome:
        return str(outcome)
    return "success" if metrics.survived else "failed"


def run_row(run: Run, scenario: str) -> dict[str, Any]:
    """One run's row: keys, outcome, failure and every :class:`~mpcbox.Metrics` field.

    Args:
        run: The run.
        scenario: Its scenario's label.

    Dict-valued fields (``measures``) are spread into one entry per key.
    """
    metrics = run.metrics
    row: dict[str, Any] = {
        "scenario": scenario,
        "controller": run.controller,
        "seed": run.seed,
        "outcome": _outcome(metrics),
        "survived": bool(metrics.survived),
        "time_to_fall": float(metrics.time_to_fall),
        "failure": run.failure or "",
    }
    for name in type(metrics)._fields:
        value = getattr(metrics, name)
        if isinstance(value, Mapping):
            row.update({str(k): v for k, v in value.items()})
        elif name not in row:
            row[name] = value
    return row


def run_rows(comparison: Comparison) -> list[dict[str, Any]]:
    """:func:`run_row` of every run of ``comparison``, in its order."""
    return [run_row(run, comparison.scenarios[run.scenario].label) for run in comparison.runs]


def _numeric(value: Any) -> bool:
    return isinstance(value, bool | int | float | np.integer | np.floating)


def _float(value: Any) -> float:
    """``value`` as a float; NaN for a missing or ``None`` value (``Metrics.kept_up`` of
    a lock-step run, or of a real-time run that raised before it started)."""
    return np.nan if value is None else float(value)


def group_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per scenario and controller (first-seen order), ``runs`` and :data:`STATS` of every
    numeric column of ``rows`` (except ``seed``), as ``<column>_<stat>``."""
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault((row["scenario"], row["controller"]), []).append(row)
    out = []
    for (scenario, controller), members in groups.items():
        group: dict[str, Any] = {"scenario": scenario, "controller": controller}
        group["runs"] = len(members)
        outcomes = [m["outcome"] for m in members]
        group["outcomes"] = "; ".join(f"{o} {outcomes.count(o)}" for o in dict.fromkeys(outcomes))
        columns = [k for k, v in members[0].items() if k not in _KEYS and _numeric(v)]
        for column in columns:
            values = np.array([_float(m.get(column)) for m in members])
            group[f"{column}_mean"] = float(np.mean(values))
            group[f"{column}_std"] = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
            group[f"{column}_min"] = float(np.min(values))
            group[f"{column}_max"] = float(np.max(values))
        out.append(group)
    return out


def _write_table(rows: Sequence[Mapping[str, Any]], stem: Path) -> list[Path]:
    header: list[str] = []
    for row in rows:
        header += [k for k in row if k not in header]
    csv_path, json_path = stem.with_suffix(".csv"), stem.with_suffix(".json")
    with csv_path.open("w", newline="") as f:
        writer = csv.DictWriter(f, header, restval="", lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    json_path.write_text(json.dumps(jsonable([dict(r) for r in rows]), indent=1) + "\n")
    return [csv_path, json_path]


def controller_settings(
    problem: Problem | type[Problem],
    controllers: Sequence[str],
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, dict[str, Any]]:
    """The settings each controller name runs with: the task's tuned config with overrides.

    Args:
        problem: The Problem or its class (its ``controller_configs``).
        controllers: Controller labels; labels that are not registered names are recorded
            by name only.
        overrides: Options applied on top, per name (the CLI's ``--set`` and CPU sizes).

    Returns:
        ``{name: {"class": ..., "config_class": ..., "config": {field: value}}}``.
    """
    out: dict[str, dict[str, Any]] = {}
    for name in controllers:
        if name not in CONTROLLERS:
            out[name] = {"class": None, "config": None}
            continue
        cls = controller_class(name)
        config = resolve_config(
            cls.config_class,
            problem.controller_configs.get(name),
            dict((overrides or {}).get(name, {})),
            name,
        )
        out[name] = {
            "class": f"{cls.__module__}.{cls.__name__}",
            "config_class": type(config).__name__,
            "config": jsonable(config),
        }
    return out


def cpu_name() -> str:
    """The CPU model from ``/proc/cpuinfo`` (else what :mod:`platform` says)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def gpu_names() -> list[str]:
    """``"name, memory"`` of each GPU that ``nvidia-smi`` lists (empty without it)."""
    if shutil.which("nvidia-smi") is None:
        return []
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=name,memory.total", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return []
    return [line.strip() for line in out.stdout.splitlines() if line.strip()]


def environment() -> dict[str, Any]:
    """Package versions (``None`` when not installed), Python, machine and UTC date."""
    versions: dict[str, str | None] = {}
    for package in PACKAGES:
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return {
        "versions": versions,
        "python": platform.python_version(),
        "machine": {
            "platform": platform.platform(),
            "cpu": cpu_name(),
            "cpu_count": os.cpu_count(),
            "gpus": gpu_names(),
        },
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def _scenario(scenario: Any) -> dict[str, Any]:
    return {"label": scenario.label, **jsonable(scenario)}


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.]+", "_", text).strip("_") or "run"


def run_trajectory(
    comparison: Comparison,
    run: Run,
    problem: Problem,
    metadata: Mapping[str, Any] | None = None,
) -> Trajectory:
    """The :class:`~mpcbox.sim.trajectory.Trajectory` of a run that kept its trace, with its
    scenario's pushes, mismatch and noise (so that it replays).

    Args:
        comparison: The comparison the run belongs to.
        run: A run whose ``trace`` holds states.
        problem: The Problem it ran on.
        metadata: Extra JSON entries; the scenario's label is added.
    """
    trace = run.trace
    if trace is None or trace.states is None:
        raise InvalidArgumentError(f"run {run.controller!r} seed {run.seed} kept no trajectory")
    scenario = comparison.scenarios[run.scenario]
    return make_trajectory(
        problem,
        controller=run.controller,
        time=trace.time,
        states=trace.states,
        ctrls=trace.ctrls,
        series=trace.series,
        failure=run.failure,
        pushes=scenario.pushes,
        mismatch=scenario.mismatch,
        noise=scenario.resolve_noise(problem),
        seed=run.seed,
        metadata={**dict(metadata or {}), "scenario": scenario.label},
    )


def write_trajectories(
    comparison: Comparison,
    problem: Problem,
    folder: str | Path,
    metadata: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Save each traced run (the first seed of every controller and scenario).

    Files: ``<folder>/<scenario>__<controller>__seed<k>.csv`` and ``.json``.

    Args:
        comparison: The comparison.
        problem: The Problem it ran on (for site positions and sizes).
        folder: Output folder.
        metadata: Extra entries for every JSON sidecar (e.g. the task name and options).

    Returns:
        The CSV paths.
    """
    folder = Path(folder)
    paths = []
    for run in comparison.runs:
        trace = run.trace
        if trace is None or trace.states is None:
            continue
        scenario = comparison.scenarios[run.scenario]
        traj = run_trajectory(comparison, run, problem, metadata)
        name = f"{_slug(scenario.label)}__{_slug(run.controller)}__seed{run.seed}"
        paths.append(save_trajectory(traj, folder / name)[0])
    return paths


def write_records(
    comparison: Comparison,
    folder: str | Path,
    *,
    problem: Problem | None = None,
    task: str | None = None,
    task_options: Mapping[str, Any] | None = None,
    controllers: Mapping[str, Any] | None = None,
    command: Sequence[str] | str | None = None,
    extra: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write the per-seed rows, the group spread, ``run.json`` and the traced trajectories.

    Args:
        comparison: The comparison.
        folder: Output folder (created).
        problem: The Problem the comparison ran on; needed for the trajectories (none saved
            without it) and for the controller settings.
        task: Task name (:data:`mpcbox.registry.TASKS`), when the comparison ran one.
        task_options: The task's keyword arguments.
        controllers: Controller settings for ``run.json`` (default:
            :func:`controller_settings` of ``problem`` without overrides).
        command: The command line (default: ``sys.argv``).
        extra: More entries for ``run.json``.

    Returns:
        The written paths (trajectory CSVs included).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rows = run_rows(comparison)
    written = _write_table(rows, folder / "runs")
    written += _write_table(group_rows(rows), folder / "groups")
    if controllers is None and problem is not None:
        controllers = controller_settings(problem, comparison.controllers)
    if command is None:
        command = sys.argv
    if not isinstance(command, str):
        import shlex

        command = " ".join(shlex.quote(str(a)) for a in command)
    record = {
        "problem": comparison.problem,
        "task": task,
        "task_options": dict(task_options or {}),
        "scenarios": [_scenario(s) for s in comparison.scenarios],
        "seeds": list(comparison.seeds),
        "controllers": dict(controllers or {}),
        "push_limits": {
            name: {label: limit.force for label, limit in limits.items()}
            for name, limits in comparison.push_limits.items()
        },
        "push_travel_m": {
            name: {label: limit.travel for label, limit in limits.items()}
            for name, limits in comparison.push_limits.items()
        },
        "command": command,
        "wall_time_s": comparison.wall_time,
        "placement": dict(comparison.placement),
        **environment(),
        **dict(extra or {}),
    }
    run_json = folder / "run.json"
    run_json.write_text(json.dumps(jsonable(record), indent=2, default=repr) + "\n")
    written.append(run_json)
    if problem is not None:
        meta = {"task": task, "task_options": dict(task_options or {})}
        written += write_trajectories(comparison, problem, folder / "trajectories", meta)
    return written
