"""What ``mpcbox compare`` and ``mpcbox simulate`` write and say besides the table.

* :func:`cpu_reductions` and :func:`mark_reduced`: controllers whose tuned settings the CLI
  shrank for a CPU run are marked next to their table row, with a note of what changed.
* :func:`write_outputs`: per-seed rows, group spread, ``run.json`` and trajectories in
  ``--out`` (:func:`mpcbox.comparison.records.write_records`), and for ``mpcbox simulate``
  the ``--save-trajectory`` and ``--video`` files.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mpcbox.errors import InvalidArgumentError

#: Marker appended to the controller cell of a row that ran with reduced settings.
REDUCED_MARK = " (CPU-reduced*)"
#: Names of the records that ``--out`` holds (``.csv``/``.json``).
RECORDS = ("run", "runs", "groups", "results")


def cpu_reductions(
    problem: Any,
    defaults: Mapping[str, Mapping[str, Any]],
    sets: Mapping[str, Mapping[str, Any]],
) -> dict[str, dict[str, tuple[Any, Any]]]:
    """Settings that the CLI's CPU defaults made smaller than the task's tuned ones.

    Args:
        problem: The task class (its ``controller_configs``).
        defaults: Option overrides the CLI applied by itself (``quick_sampling_options``).
        sets: The user's ``--set`` options, which are not reductions.

    Returns:
        ``{controller: {option: (tuned value, value used)}}`` for numeric options whose
        value went down.
    """
    from mpcbox.registry import controller_class

    out: dict[str, dict[str, tuple[Any, Any]]] = {}
    for name, options in defaults.items():
        config = problem.controller_configs.get(name)
        if config is None:
            config = controller_class(name).config_class()
        for option, used in options.items():
            if option in sets.get(name, {}) or not hasattr(config, option):
                continue
            tuned = getattr(config, option)
            numeric = (int, float)
            if (
                isinstance(used, numeric)
                and isinstance(tuned, numeric)
                and not isinstance(tuned, bool)
                and used < tuned
            ):
                out.setdefault(name, {})[option] = (tuned, used)
    return out


def mark_reduced(table: str, reductions: Mapping[str, Mapping[str, tuple[Any, Any]]]) -> str:
    """``table`` (markdown) with :data:`REDUCED_MARK` after the controller of reduced rows,
    and a footnote per such controller: ``* mppi: num_samples 2048 -> 16, ...``."""
    if not reductions:
        return table
    lines = []
    for line in table.splitlines():
        cells = line.split("|")
        if len(cells) > 3 and cells[2].strip() in reductions:
            cells[2] = f" {cells[2].strip()}{REDUCED_MARK} "
            line = "|".join(cells)
        lines.append(line)
    lines.append("")
    for name, changes in reductions.items():
        shown = ", ".join(f"{k} {tuned!r} -> {used!r}" for k, (tuned, used) in changes.items())
        restore = " ".join(f"--set {name}.{k}={tuned!r}" for k, (tuned, _) in changes.items())
        lines.append(
            f"* {name}: settings reduced for a CPU run (no NVIDIA GPU): {shown}; "
            f"`{restore}` restores them"
        )
    return "\n".join(lines)


def add_single_run_flags(parser: argparse.ArgumentParser) -> None:
    """``--save-trajectory PATH`` and ``--video PATH`` of ``mpcbox simulate``."""
    group = parser.add_argument_group("saving the run")
    group.add_argument(
        "--save-trajectory",
        default=None,
        metavar="PATH",
        help="save the run as PATH.csv + PATH.json (replay with `mpcbox replay PATH`)",
    )
    group.add_argument(
        "--video",
        default=None,
        metavar="FILE",
        help="render the run to FILE (.mp4 needs imageio-ffmpeg, .gif needs nothing more)",
    )


def check_single_run_flags(args: argparse.Namespace) -> None:
    """Check ``--save-trajectory`` and ``--video`` before anything runs.

    Raises:
        InvalidArgumentError: For a video suffix other than .mp4/.gif or an unwritable folder.
        BackendUnavailableError: For an MP4 without imageio-ffmpeg.
    """
    from mpcbox.cli.checks import check_output_folder

    video = getattr(args, "video", None)
    if video:
        from mpcbox.sim.video import check_video_path

        check_video_path(video)
        check_output_folder(Path(video).parent or ".")
    saved = getattr(args, "save_trajectory", None)
    if saved:
        from mpcbox.sim.trajectory_files import trajectory_paths

        check_output_folder(Path(saved).parent or ".")
        out = Path(args.out).resolve()
        taken = {out / f"{name}.{ext}" for name in RECORDS for ext in ("csv", "json")}
        if any(p.resolve() in taken for p in trajectory_paths(saved)):
            raise InvalidArgumentError(
                f"--save-trajectory {saved!r} would overwrite a record of --out "
                f"({', '.join(RECORDS)}); choose another name"
            )


def write_outputs(
    result: Any,
    args: argparse.Namespace,
    *,
    task: str,
    task_options: Mapping[str, Any],
    overrides: Mapping[str, Mapping[str, Any]],
    reductions: Mapping[str, Any],
    command: Sequence[str] | str | None,
    problem: Any = None,
) -> list[Path]:
    """Write the records of a comparison into ``args.out``, and the single-run files.

    ``problem`` is the task built with ``task_options`` (built here when ``None``).

    Returns:
        The written paths.
    """
    from mpcbox.comparison.records import controller_settings, write_records
    from mpcbox.registry import task_class

    if problem is None:
        problem = task_class(task)(**task_options)
    settings = controller_settings(problem, result.controllers, overrides)
    for name, changes in reductions.items():
        settings[name]["reduced_for_cpu"] = {k: list(v) for k, v in changes.items()}
    options = {k: v for k, v in task_options.items()}
    written = write_records(
        result,
        args.out,
        problem=problem,
        task=task,
        task_options=options,
        controllers=settings,
        command=command,
        extra={"arguments": {k: v for k, v in vars(args).items() if _plain(v)}},
    )
    saved, video = getattr(args, "save_trajectory", None), getattr(args, "video", None)
    if saved or video:
        written += _single_run(result, problem, task, options, saved, video)
    return written


def _plain(value: Any) -> bool:
    return value is None or isinstance(value, bool | int | float | str | list | tuple)


def _single_run(result, problem, task, options, saved, video) -> list[Path]:
    from mpcbox.comparison.records import run_trajectory

    run = next((r for r in result.runs if r.trace is not None), None)
    if run is None or run.trace.states is None:
        raise InvalidArgumentError("the run kept no trajectory to save or render")
    traj = run_trajectory(result, run, problem, {"task": task, "task_options": dict(options)})
    return save_or_render(traj, problem, saved, video)


def save_or_render(traj, problem, saved: str | None, video: str | None) -> list[Path]:
    """Save ``traj`` as ``saved`` (CSV + JSON) and/or render it to ``video``; the files."""
    from mpcbox.sim.trajectory_files import save_trajectory

    written: list[Path] = []
    if saved:
        written += list(save_trajectory(traj, saved))
    if video:
        from mpcbox.sim.video import render_video

        written.append(render_video(traj, problem, video))
    return written
