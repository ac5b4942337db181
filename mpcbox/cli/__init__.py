"""The ``mpcbox`` command line.

Commands::

    mpcbox list                                   tasks and controllers
    mpcbox compare TASK [options]                 compare controllers on a task
    mpcbox simulate TASK --controller NAME [...]  one controller, one seed, its measures
    mpcbox options CONTROLLER                     a controller's options and their defaults
    mpcbox replay FILE [--video OUT.mp4|OUT.gif]  re-simulate or render a saved run
    mpcbox validate [SCENE] [options]             MuJoCo-to-MJWarp gates on a scene
    mpcbox inspect MODEL [options]                a robot's model checked before control
    mpcbox --version

``mpcbox simulate`` also takes ``--save-trajectory PATH``, ``--video FILE`` and
``--viewer [FILE|live]`` (watch the run as it goes, :mod:`mpcbox.cli.watch`).

``mpcbox compare TASK --help`` lists every option, the task's own ones included (for example
``--leg`` of ``humanoid_balance``). A user error (a bad name, value or folder) prints one line
starting with ``error:`` and exits with status 2, never a traceback.

A problem script is one call, e.g. ``problems/pendulum_swingup.py``::

    import sys
    from mpcbox.cli import run_task_script

    if __name__ == "__main__":
        sys.exit(run_task_script("pendulum_swingup", duration=5.0))
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from mpcbox.cli.compare import (
    quick_sampling_options,
    run_comparison,
    run_task_script,
)
from mpcbox.cli.compare_parser import DEFAULTS, build_parser
from mpcbox.errors import InvalidArgumentError, MpcboxError, UnknownNameError

__all__ = [
    "DEFAULTS",
    "build_parser",
    "main",
    "quick_sampling_options",
    "run_comparison",
    "run_task_script",
]

COMMANDS = ("list", "compare", "simulate", "options", "replay", "validate", "inspect")
USAGE = """usage: mpcbox {list,compare,simulate,options,replay,validate,inspect} ... | --version

  mpcbox list                                   tasks and controllers
  mpcbox compare TASK [options]                 compare controllers on a task (--help)
  mpcbox simulate TASK --controller NAME [...]  one run of one controller (--help)
  mpcbox options CONTROLLER                     a controller's options and defaults
  mpcbox replay FILE [--video OUT]              re-simulate or render a saved run (--help)
  mpcbox validate [SCENE] [options]             MuJoCo-to-MJWarp gates on a scene (--help)
  mpcbox inspect MODEL [options]                check a robot's model before control (--help)
"""


def _list(stream) -> int:
    from mpcbox.registry import CONTROLLERS, TASKS, available_controllers, task_class

    print("tasks (controllers tuned for each; others can be named explicitly):", file=stream)
    for name in TASKS:
        try:
            tuned = ", ".join(available_controllers(task_class(name))) or "-"
        except ImportError as exc:
            tuned = f"unavailable ({exc})"
        print(f"  {name}: {tuned}", file=stream)
    print("controllers: " + ", ".join(CONTROLLERS), file=stream)
    return 0


def _options(rest: Sequence[str], stream) -> int:
    from mpcbox.config import describe_config
    from mpcbox.registry import CONTROLLERS, controller_class

    if rest and rest[0] in ("-h", "--help"):
        print(
            "usage: mpcbox options CONTROLLER\n\nA controller's config options and their "
            f"defaults. Controllers: {', '.join(CONTROLLERS)}",
            file=stream,
        )
        return 0
    if not rest:
        raise InvalidArgumentError(
            f"mpcbox options needs a controller name, one of: {', '.join(CONTROLLERS)}"
        )
    if len(rest) != 1:
        raise UnknownNameError("controller", " ".join(rest), CONTROLLERS)
    cls = controller_class(rest[0])
    print(
        f"{rest[0]}: {cls.__module__}.{cls.__name__}, config {cls.config_class.__name__}",
        file=stream,
    )
    for info in describe_config(cls.config_class):
        print(f"  {info.name} = {info.default!r}", file=stream)
    return 0


def _simulate(rest: Sequence[str], command: Sequence[str]) -> int:
    import argparse

    from mpcbox.cli.outputs import add_single_run_flags
    from mpcbox.cli.watch import add_viewer_flags, run_watched
    from mpcbox.registry import TASKS

    pre = argparse.ArgumentParser(prog="mpcbox simulate", add_help=False)
    pre.add_argument("task")
    pre.add_argument("--controller")
    wants_help = any(a in ("-h", "--help") for a in rest)
    if not rest or rest[0].startswith("-"):
        print(SIMULATE_USAGE, file=sys.stdout if wants_help else sys.stderr)
        return 0 if wants_help else 2
    known, remaining = pre.parse_known_args(list(rest))
    if known.task not in TASKS:
        raise UnknownNameError("task", known.task, TASKS)
    parser = build_parser(
        known.task,
        prog=f"mpcbox simulate {known.task} --controller NAME",
        description=f"One run of one controller on {known.task!r}: prints its measures and "
        "writes them to --out (--seeds repeats it with the next seeds).",
        seeds=1,
    )
    for action in parser._actions:  # one run takes --controller, not compare's list
        if action.dest == "controllers":
            action.help = argparse.SUPPRESS
    add_single_run_flags(parser)
    add_viewer_flags(parser)
    args = parser.parse_args(remaining)  # --help prints the options and exits here
    if known.controller is None:
        raise InvalidArgumentError(
            "--controller is required: mpcbox simulate TASK --controller NAME"
        )
    if args.controllers:
        raise InvalidArgumentError(
            "--controllers belongs to mpcbox compare; simulate takes one --controller"
        )
    if "," in known.controller:
        raise InvalidArgumentError(
            f"--controller takes one name, got {known.controller!r}: to run several, use "
            f"mpcbox compare {known.task} --controllers {known.controller}"
        )
    args.controllers = known.controller
    if args.viewer is not None:
        return run_watched(
            known.task,
            args,
            controller_defaults=quick_sampling_options(known.task),
            stream=sys.stdout,
        )
    return run_comparison(
        known.task, args, controller_defaults=quick_sampling_options(known.task), command=command
    )


SIMULATE_USAGE = (
    "usage: mpcbox simulate TASK --controller NAME [options]\n\n"
    "One run of one controller on a task (see `mpcbox list`); "
    "`mpcbox simulate TASK --controller NAME --help` lists the options."
)


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A warning as one ``warning: MESSAGE`` line, without the source line that Python
    prints under it (the command's user did not write that code)."""
    return f"warning: {message}\n"


def _prepare_gl(argv: Sequence[str]) -> None:
    """Default ``MUJOCO_GL=egl`` for a video (``--video``, or ``--viewer`` that then writes
    one) on a Linux machine without a display.

    MuJoCo reads ``MUJOCO_GL`` once, on import; this runs before that import.
    """
    flags = ("--video", "--viewer")
    if (
        any(a in flags or a.startswith(tuple(f + "=" for f in flags)) for a in argv)
        and sys.platform.startswith("linux")
        and "MUJOCO_GL" not in os.environ
        and not os.environ.get("DISPLAY")
        and "mujoco" not in sys.modules
    ):
        os.environ["MUJOCO_GL"] = "egl"


def _import_mujoco() -> None:
    """Import MuJoCo, turning a failure (a bad ``MUJOCO_GL``) into a named error."""
    try:
        import mujoco  # noqa: F401
    except Exception as exc:  # a broken GL backend raises AttributeError, RuntimeError, ...
        from mpcbox.errors import BackendUnavailableError

        gl = os.environ.get("MUJOCO_GL")
        raise BackendUnavailableError(
            f"cannot import mujoco (MUJOCO_GL={gl!r}): {type(exc).__name__}: {exc}; unset "
            "MUJOCO_GL or set it to egl or osmesa with that library installed"
        ) from exc


def main(argv: Sequence[str] | None = None) -> int:
    """The ``mpcbox`` console command (see :func:`_main`); warnings print as one line
    while it runs."""
    import warnings

    shown = warnings.formatwarning
    warnings.formatwarning = _one_line_warning
    try:
        return _main(argv)
    finally:
        warnings.formatwarning = shown


def _main(argv: Sequence[str] | None = None) -> int:
    """The ``mpcbox`` console command.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit status: 0 on success, 2 for bad arguments, names, values or folders.
    """
    from mpcbox.registry import TASKS

    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE)
        return 0 if argv else 2
    if argv[0] == "--version":
        from mpcbox import __version__

        print(f"mpcbox {__version__}")
        return 0
    command, rest = argv[0], argv[1:]
    line = ["mpcbox", *argv]
    _prepare_gl(rest)
    try:
        _import_mujoco()
        if command == "list":
            if rest in (["-h"], ["--help"]):
                print(
                    "usage: mpcbox list\n\nThe tasks, each with its tuned controllers, and "
                    "every controller name."
                )
                return 0
            if rest:
                raise InvalidArgumentError(f"mpcbox list takes no arguments, got {rest}")
            return _list(sys.stdout)
        if command == "options":
            return _options(rest, sys.stdout)
        if command == "simulate":
            return _simulate(rest, line)
        if command == "replay":
            from mpcbox.cli.replay import run_replay

            return run_replay(rest)
        if command == "validate":
            from mpcbox.cli.validate import run_validate

            return run_validate(rest)
        if command == "inspect":
            from mpcbox.cli.inspect_model import run_inspect

            return run_inspect(rest)
        if command != "compare":
            raise UnknownNameError("command", command, COMMANDS)
        if not rest or rest[0].startswith("-"):
            build_parser(None, prog="mpcbox compare").parse_args(rest)  # help or the error
            return 2
        task = rest[0]
        if task not in TASKS:
            raise UnknownNameError("task", task, TASKS)
        args = build_parser(task, prog=f"mpcbox compare {task}").parse_args(rest[1:])
        return run_comparison(
            task, args, controller_defaults=quick_sampling_options(task), command=line
        )
    except (MpcboxError, ImportError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
