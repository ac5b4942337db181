"""The options of ``mpcbox compare`` and ``problems/*.py``: :data:`DEFAULTS` and
:func:`build_parser`, with each task's own keyword arguments as flags."""

from __future__ import annotations

import argparse
import inspect
from collections.abc import Sequence
from typing import Any

from mpcbox.errors import UnknownNameError

#: Defaults of ``mpcbox compare``; :func:`run_task_script` takes overrides by these names.
DEFAULTS: dict[str, Any] = {
    "controllers": "",
    "seeds": 5,
    "seed": 0,
    "duration": 10.0,
    "realtime": False,
    "speed": 1.0,
    "lookahead": None,
    "delay": None,
    "noise": None,
    "push": 0.0,
    "push_time": 2.0,
    "push_duration": 0.1,
    "push_body": None,
    "mass_scale": 1.0,
    "friction_scale": 1.0,
    "largest_push": False,
    "push_tolerance": 2.0,
    "push_rest_speed": None,
    "push_scan_step": None,
    "set": (),
    "workers": 0,
    "executor": "",
    "address": None,
    "out": "results",
    "plots": True,
    "progress": True,
}

_SIMPLE = (bool, int, float, str)


def task_parameters(task: str) -> dict[str, inspect.Parameter]:
    """Keyword arguments of a task class that have a plain (bool/int/float/str) default."""
    from mpcbox.registry import task_class

    params = {}
    for name, param in inspect.signature(task_class(task).__init__).parameters.items():
        if name == "self" or param.kind in (param.VAR_KEYWORD, param.VAR_POSITIONAL):
            continue
        if isinstance(param.default, _SIMPLE) or _names(param.default):
            params[name] = param
    return params


def _names(value: object) -> bool:
    """Whether ``value`` is a non-empty tuple of strings (a flag of comma-separated names)."""
    return isinstance(value, tuple) and bool(value) and all(isinstance(v, str) for v in value)


def _name_list(text: str) -> tuple[str, ...]:
    names = tuple(part.strip() for part in text.split(","))
    if not all(names):
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return names


def _default_noise(task: str | None) -> str:
    """``"1"`` for a task with a noise model, ``"0"`` for one without (or no task yet)."""
    if task is None:
        return "1"
    from mpcbox.comparison.scenario import has_noise_model
    from mpcbox.registry import task_class

    return "1" if has_noise_model(task_class(task)) else "0"


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def add_push_scan_step(parser: argparse.ArgumentParser, default: float | None = None) -> None:
    """Add ``--push-scan-step`` (N): the largest-push search first tries that force and its
    multiples up to the first failure, then bisects (``PushTest.scan_step``)."""
    parser.add_argument(
        "--push-scan-step",
        type=float,
        default=default,
        help="largest-push search: before bisecting, try this force and its multiples up to "
        "the first failure (N), so that a survival region that is not one interval is not "
        "skipped (default: bisection only)",
    )


def build_parser(
    task: str | None = None,
    *,
    prog: str | None = None,
    parents: Sequence[argparse.ArgumentParser] = (),
    description: str | None = None,
    **defaults: Any,
):
    """The argument parser of a comparison, with the task's options when ``task`` is given.

    Args:
        task: Task name; ``None`` adds a positional ``task`` argument instead.
        prog: Program name shown in the usage.
        parents: Parsers (``add_help=False``) whose options a script adds in front of the
            comparison's (shown in its ``--help``).
        description: The ``--help`` text's first paragraph (default: the comparison's).
        **defaults: Overrides of :data:`DEFAULTS`.
    """
    unknown = set(defaults) - set(DEFAULTS)
    if unknown:
        raise UnknownNameError("option", sorted(unknown)[0], DEFAULTS)
    d = {**DEFAULTS, **defaults}
    parser = argparse.ArgumentParser(
        prog=prog,
        parents=list(parents),
        description=description
        or (f"Compare controllers on {task!r}: " if task else "Compare controllers on a task: ")
        + "every controller runs the same seeded scenarios; prints a markdown table and "
        "writes results.md, results.csv and PNG plots to --out.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    if task is None:
        parser.add_argument("task", help="task name (see `mpcbox list`)")
    add = parser.add_argument
    add(
        "--controllers",
        default=d["controllers"],
        help="comma-separated controller names (default: every controller tuned for the task)",
    )
    add("--seeds", type=int, default=d["seeds"], help="number of seeds per scenario")
    add("--seed", type=int, default=d["seed"], help="first seed")
    add("--duration", type=float, default=d["duration"], help="simulated seconds per run")
    add(
        "--realtime",
        action="store_true",
        default=d["realtime"],
        help="asynchronous real-time loop: the world does not wait for the planner; the "
        "table reports whether each planner kept up (use --workers 1)",
    )
    add("--speed", type=float, default=d["speed"], help="real time: sim seconds per wall second")
    add(
        "--lookahead",
        default=d["lookahead"],
        help="real time: plan from the state predicted this many seconds ahead, 'auto' "
        "(the recent median tick time) or 'none'; default: the task's choice (auto for "
        "g1_getup), else from the observed state",
    )
    add(
        "--delay",
        type=float,
        default=d["delay"],
        help="real time: a simulated latency (s) instead of the wall clock: reproducible",
    )
    add(
        "--noise",
        default=d["noise"] if d["noise"] is not None else _default_noise(task),
        help="noise scale(s) on the task's noise recipe, comma-separated for a sweep "
        "(default: 1 for tasks with a noise model, 0 for the others)",
    )
    add("--push", type=float, default=d["push"], help="forward push force (N), 0 for none")
    add("--push-time", type=float, default=d["push_time"], help="push start (s)")
    add("--push-duration", type=float, default=d["push_duration"], help="push duration (s)")
    add(
        "--push-body",
        default=d["push_body"],
        help="pushed body (default: the task's root body, such as a humanoid's torso)",
    )
    add("--mass-scale", type=float, default=d["mass_scale"], help="model mismatch: body masses")
    add(
        "--friction-scale",
        type=float,
        default=d["friction_scale"],
        help="model mismatch: friction",
    )
    add(
        "--largest-push",
        action=argparse.BooleanOptionalAction,
        default=d["largest_push"],
        help="bisect the largest forward and backward push over --push-duration per controller",
    )
    add(
        "--push-tolerance",
        type=float,
        default=d["push_tolerance"],
        help="bisection tolerance of --largest-push (N)",
    )
    add(
        "--push-rest-speed",
        type=float,
        default=d["push_rest_speed"],
        help="--largest-push: a push counts only if the pushed body ends slower (m/s)",
    )
    add_push_scan_step(parser, d["push_scan_step"])
    add(
        "--set",
        action="append",
        default=list(d["set"]),
        metavar="NAME.OPTION=VALUE",
        help="controller option override, e.g. mppi.num_samples=256 (repeatable)",
    )
    add("--workers", type=int, default=d["workers"], help="worker processes (0: one per core)")
    add(
        "--executor",
        default=d["executor"],
        metavar="NAME",
        help="where runs go: serial, processes (default with --workers) or ray "
        '(pip install "mpcbox[ray]")',
    )
    add(
        "--address",
        default=d["address"],
        metavar="auto|HOST:PORT",
        help="Ray cluster to join with --executor ray (default: start a local Ray)",
    )
    add("--out", default=d["out"], help="output folder")
    add("--plots", action=argparse.BooleanOptionalAction, default=d["plots"], help="write PNGs")
    add(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=d["progress"],
        help="show a progress bar",
    )
    if task is not None:
        group = parser.add_argument_group(f"options of the task {task!r}")
        taken = {a.dest for a in parser._actions}
        for name, param in task_parameters(task).items():
            if name in taken:
                continue
            default = param.default
            if isinstance(default, bool):
                group.add_argument(
                    _flag(name), action=argparse.BooleanOptionalAction, default=default
                )
            elif _names(default):
                group.add_argument(
                    _flag(name),
                    type=_name_list,
                    default=default,
                    help="comma-separated names",
                )
            else:
                group.add_argument(_flag(name), type=type(default), default=default)
    return parser


__all__ = ["DEFAULTS", "add_push_scan_step", "build_parser", "task_parameters"]
