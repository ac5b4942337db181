"""``mpcbox simulate TASK --controller NAME --viewer [FILE|live]``: watch one run as it goes.

With ``--viewer`` the one run (the first noise scale, ``--seed``) runs in this process under
a viewer (:func:`mpcbox.sim.viewer_choice.make_viewer`) instead of going through the
comparison machinery: no table and no ``--out`` records, only a summary line, and the
``--save-trajectory`` / ``--video`` files when asked.

* ``--viewer`` alone: a window where there is a display, else ``OUT/viewer.gif``;
* ``--viewer live``: a window (an error without a display);
* ``--viewer FILE.gif`` / ``FILE.mp4``: an offscreen video.

Sampling controllers get their best traces drawn (``--viewer-traces K``, 0 for none).
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mpcbox.errors import InvalidArgumentError

#: Value of ``--viewer`` given without one.
AUTO = "auto"


def add_viewer_flags(parser: argparse.ArgumentParser) -> None:
    """``--viewer [FILE|live]``, ``--viewer-traces K`` and ``--viewer-fps FPS``."""
    group = parser.add_argument_group("watching the run")
    group.add_argument(
        "--viewer",
        nargs="?",
        const=AUTO,
        default=None,
        metavar="FILE|live",
        help="show the run as it goes: a window where there is a display, else OUT/viewer.gif; "
        "'live' for a window, FILE.gif/.mp4 for an offscreen video",
    )
    group.add_argument(
        "--viewer-traces",
        type=int,
        default=8,
        metavar="K",
        help="best sampling rollouts drawn per tick (0: none)",
    )
    group.add_argument("--viewer-fps", type=float, default=30.0, help="viewer frames per second")


def viewer_from_args(args: argparse.Namespace, out: Path) -> Any:
    """The viewer that ``--viewer`` asks for (checked before anything runs)."""
    from mpcbox.sim.viewer_choice import make_viewer

    if args.viewer_traces < 0:
        raise InvalidArgumentError(f"--viewer-traces must be >= 0, got {args.viewer_traces}")
    options = {"traces": args.viewer_traces, "fps": args.viewer_fps}
    if args.viewer == AUTO:
        return make_viewer(out / "viewer.gif", mode="auto", **options)
    if args.viewer == "live":
        return make_viewer(None, mode="live", **options)
    return make_viewer(args.viewer, mode="offscreen", **options)


def run_watched(
    task: str,
    args: argparse.Namespace,
    *,
    controller_defaults: Mapping[str, Mapping[str, Any]],
    stream: Any,
) -> int:
    """Run one controller on ``task`` under the viewer of ``--viewer``; print a summary.

    Args:
        task: Task name.
        args: Parsed ``mpcbox simulate`` arguments (``args.controllers``: one name).
        controller_defaults: Option overrides of the CLI (before ``--set``).
        stream: Where the summary goes.

    Returns:
        The exit status (0).
    """
    from mpcbox.cli.checks import check_arguments, check_options, check_output_folder
    from mpcbox.cli.compare import (
        default_push_body,
        parse_sets,
        scenarios_from_args,
        task_parameters,
    )
    from mpcbox.cli.outputs import check_single_run_flags
    from mpcbox.comparison.runner import resolve_controllers
    from mpcbox.registry import make_controller, task_class

    out = check_output_folder(args.out)
    check_arguments(args)
    check_single_run_flags(args)
    chosen = list(resolve_controllers(task_class(task), args.controllers))
    if len(chosen) != 1:
        raise InvalidArgumentError(
            f"--viewer watches one controller; --controller gave {', '.join(chosen)}"
        )
    name = chosen[0]
    sets = parse_sets(args.set)
    for label, options in sets.items():
        check_options(label, options, [name])
    options = {**dict(controller_defaults.get(name, {})), **sets.get(name, {})}
    viewer = viewer_from_args(args, out)
    task_options = {k: getattr(args, k) for k in task_parameters(task)}
    problem = task_class(task)(**task_options)
    default_push_body(args, problem)
    controller = make_controller(name, problem, **options)
    scenario = scenarios_from_args(args, task)[0]
    result = scenario.run(problem, controller, args.seed, viewer=viewer)
    m = result.metrics
    print(
        f"{task}, {name}, seed {args.seed}: {m.outcome}, cost {m.cost:.4g}, "
        f"{m.solve_ticks} solves of {m.compute_mean_ms:.2f} ms mean, "
        f"{viewer.frames} viewer frames",
        file=stream,
    )
    if result.failure:
        print(f"{name}: {result.failure}", file=stream)
    for path in _files(result, problem, task, task_options, args, viewer):
        print(f"wrote {path}", file=stream)
    return 0


def _files(result, problem, task, task_options, args, viewer) -> Sequence[Path]:
    from mpcbox.cli.outputs import save_or_render
    from mpcbox.sim.trajectory import trajectory_from_result

    written: list[Path] = []
    path = getattr(viewer, "path", None)
    if path is not None and Path(path).exists():
        written.append(Path(path))
    if args.save_trajectory or args.video:
        meta = {"task": task, "task_options": dict(task_options)}
        traj = trajectory_from_result(result, problem, metadata=meta)
        written += save_or_render(traj, problem, args.save_trajectory, args.video)
    return written


__all__ = ["AUTO", "add_viewer_flags", "run_watched", "viewer_from_args"]
