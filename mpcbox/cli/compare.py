"""``mpcbox compare``, ``mpcbox simulate``, and the shared entry point of ``problems/*.py``.

Commands::

    mpcbox list
    mpcbox compare TASK [--controllers lqr,ilqr,...] [--seeds N] [--duration S]
                        [--noise SCALE[,SCALE...]] [--push N] [--largest-push] [--out DIR]

``mpcbox compare TASK --help`` also lists the task's own options (for example ``--leg`` of
``humanoid_balance``), read from the task class's keyword arguments.

A problem script is one call, e.g. ``problems/pendulum_swingup.py``::

    import sys
    from mpcbox.cli import run_task_script

    if __name__ == "__main__":
        sys.exit(run_task_script("pendulum_swingup", duration=5.0))
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mpcbox.cli.checks import (
    check_arguments,
    check_options,
    check_output_folder,
    lookahead_option,
)
from mpcbox.cli.compare_parser import build_parser, task_parameters
from mpcbox.errors import InvalidArgumentError, MpcboxError, UnknownNameError


def default_push_body(args: argparse.Namespace, problem: Any) -> None:
    """Fill ``--push-body`` when it was not given: the task's root body (``problem.root``,
    the legged tasks' and the humanoid presets'), else the model's floating body, else
    ``"torso"``. A Unitree G1 has no body called ``torso``: its root is ``pelvis``."""
    if args.push_body is not None:
        return
    import mujoco

    from mpcbox.core.model import free_body

    root = getattr(problem, "root", None)
    if not root:
        body = free_body(problem.model)
        root = (
            None
            if body is None
            else mujoco.mj_id2name(problem.model, mujoco.mjtObj.mjOBJ_BODY, body)
        )
    args.push_body = root or "torso"


def realtime_lookahead(args: argparse.Namespace, task: str | None) -> float | str | None:
    """The lookahead of a ``--realtime`` run: ``--lookahead``, else the task's own
    ``realtime_lookahead`` (``None`` for most tasks); ``--lookahead none``: none."""
    from mpcbox.registry import task_class

    if args.lookahead == "none":
        return None
    ahead = lookahead_option(args.lookahead)
    if ahead is None and args.realtime and task is not None:
        ahead = getattr(task_class(task), "realtime_lookahead", None)
    return ahead


def scenarios_from_args(args: argparse.Namespace, task: str | None = None):
    """The scenarios that the duration, noise, push and mismatch flags describe (the
    lookahead of a real-time run from :func:`realtime_lookahead` with ``task``)."""
    from mpcbox.comparison.scenario import Scenario
    from mpcbox.sim.disturbances import ModelMismatch, Push

    try:
        scales = [float(s) for s in str(args.noise).split(",") if s.strip()]
    except ValueError:
        raise MpcboxError(
            f"--noise must be numbers separated by commas, got {args.noise!r}"
        ) from None
    pushes = ()
    if args.push:
        pushes = (
            Push(
                force=(args.push, 0.0, 0.0),
                start=args.push_time,
                duration=args.push_duration,
                body=args.push_body,
            ),
        )
    mismatch = None
    if args.mass_scale != 1.0 or args.friction_scale != 1.0:
        mismatch = ModelMismatch(mass_scale=args.mass_scale, friction_scale=args.friction_scale)
    return Scenario.noise_sweep(
        scales or [0.0],
        duration=args.duration,
        pushes=pushes,
        mismatch=mismatch,
        realtime=args.realtime,
        speed=args.speed,
        lookahead=realtime_lookahead(args, task),
        delay=args.delay,
    )


def parse_sets(items: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``["mppi.num_samples=64"]`` -> ``{"mppi": {"num_samples": 64}}`` (Python literals;
    ``true``, ``false``, ``none`` and ``null`` in any case too)."""
    import ast

    words = {"true": True, "false": False, "none": None, "null": None}

    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        name, dot, option = key.partition(".")
        if not (sep and dot and name and option):
            raise MpcboxError(f"--set takes NAME.OPTION=VALUE, got {item!r}")
        try:
            value = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            value = words.get(text.strip().lower(), text)
        out.setdefault(name.strip(), {})[option.strip()] = value
    return out


def run_comparison(
    task: str,
    args: argparse.Namespace,
    *,
    controller_defaults: dict[str, dict[str, Any]] | None = None,
    stream=None,
    command: Sequence[str] | None = None,
) -> int:
    """Run :func:`mpcbox.compare` from parsed arguments, print the table and write files.

    Args:
        task: Task name.
        args: Arguments from :func:`build_parser`.
        controller_defaults: Controller option overrides applied to the chosen controllers
            that have an entry (before ``--set``, which must name chosen controllers).
        stream (typing.TextIO | None): Where the table is printed (default: stdout).
        command: The command line recorded in ``run.json`` (default: ``sys.argv``).

    Returns:
        The exit status (0).
    """
    from mpcbox.cli.outputs import (
        check_single_run_flags,
        cpu_reductions,
        mark_reduced,
        write_outputs,
    )
    from mpcbox.comparison.plots import plot_comparison
    from mpcbox.comparison.runner import check_sized_values, compare, resolve_controllers
    from mpcbox.comparison.scenario import PushTest
    from mpcbox.comparison.stream import RunStream
    from mpcbox.config import resolve_config
    from mpcbox.core.model import object_id
    from mpcbox.registry import controller_class, task_class

    stream = stream or sys.stdout
    check_arguments(args)
    check_single_run_flags(args)
    listed = [c.strip() for c in (args.controllers or "").split(",") if c.strip()]
    twice = sorted({c for c in listed if listed.count(c) > 1})
    if twice:
        raise InvalidArgumentError(f"--controllers lists {', '.join(map(repr, twice))} twice")
    chosen = list(resolve_controllers(task_class(task), args.controllers or None))
    defaults = {k: dict(v) for k, v in (controller_defaults or {}).items() if k in chosen}
    overrides = {k: dict(v) for k, v in defaults.items()}
    sets = parse_sets(args.set)
    for name, options in sets.items():
        check_options(name, options, chosen)
        overrides.setdefault(name, {}).update(options)
    reductions = cpu_reductions(task_class(task), defaults, sets)
    task_options = {name: getattr(args, name) for name in task_parameters(task)}
    # Built here (write_outputs needs it anyway) so that a bad task option or --set value
    # stops the command before any run, instead of failing every run.
    problem = task_class(task)(**task_options)
    step = float(problem.model.opt.timestep)
    if args.duration < step:
        raise InvalidArgumentError(
            f"--duration must be at least one simulation step ({step:g} s), got {args.duration:g}"
        )
    push_body_given = args.push_body is not None
    default_push_body(args, problem)
    changed = []
    for name, options in overrides.items():
        cls = controller_class(name).config_class
        config = resolve_config(cls, problem.controller_configs.get(name), options, f"--set {name}")
        if options:
            changed.append(config)
    # Values that need the Problem's sizes (--set lqr.R=0), before --out is made.
    check_sized_values(changed, problem, type(problem), task_options)
    if args.push or args.largest_push or push_body_given:
        object_id(problem.model, "body", args.push_body, "--push-body")
    push_tests = ()
    if args.largest_push:
        common = dict(
            duration=args.push_duration,
            body=args.push_body,
            tolerance=args.push_tolerance,
            start=1.0,
            settle=3.0,
            rest_speed=args.push_rest_speed,
            scan_step=args.push_scan_step,
        )
        push_tests = (
            PushTest(direction=(1.0, 0.0, 0.0), name="forward", **common),
            PushTest(direction=(-1.0, 0.0, 0.0), name="backward", **common),
        )
    seeds = range(args.seed, args.seed + args.seeds)
    scenarios = scenarios_from_args(args, task)
    out = check_output_folder(args.out)  # made only once every argument has passed
    t0 = time.perf_counter()
    result = compare(
        task,
        chosen,
        scenarios,
        seeds,
        push_tests=push_tests,
        problem_options=task_options,
        controller_options=overrides,
        workers=args.workers or None,
        executor=_executor(args),
        checkpoint=out / "runs",
        on_done=RunStream(out, scenarios),
        progress=args.progress,
    )
    elapsed = time.perf_counter() - t0
    params = task_parameters(task)
    changed = {k: v for k, v in task_options.items() if v != params[k].default}
    options = "".join(f", {k}={v}" for k, v in changed.items())
    print(
        f"\n{result.problem}{options}: {len(result.seeds)} seed(s) from {args.seed}, "
        f"{args.duration:g} s per run, {elapsed:.1f} s wall\n",
        file=stream,
    )
    table = mark_reduced(result.to_markdown(), reductions)
    print(table, file=stream)
    (out / "results.md").write_text(table + "\n")
    result.to_csv(out / "results.csv")
    written = [out / "results.md", out / "results.csv"]
    if args.plots:
        written += plot_comparison(result, out)
    written += write_outputs(
        result,
        args,
        task=task,
        task_options=task_options,
        overrides=overrides,
        reductions=reductions,
        command=command,
        problem=problem,
    )
    folder = out / "trajectories"
    direct = [p for p in written if p.parent == out]
    traced = [p for p in written if p.parent == folder and p.suffix == ".csv"]
    print("\nwrote " + ", ".join(str(p) for p in direct), file=stream)
    if traced:
        print(f"saved {len(traced)} trajectories in {folder} (mpcbox replay FILE)", file=stream)
    for path in written:
        if path.parent not in (out, folder):
            print(f"wrote {path}", file=stream)
    places = ", ".join(f"{n} on {where}" for where, n in result.placement.items())
    print(f"jobs: {places}", file=stream)
    failed = {r.controller: r.failure for r in result.runs if r.failure}
    for name, reason in failed.items():
        print(f"{name}: first failure: {reason}", file=stream)
    return 0


def _executor(args: argparse.Namespace) -> Any:
    """The executor of ``--executor`` and ``--address`` (``None``: from ``--workers``)."""
    from mpcbox.comparison.executors import EXECUTORS, RayExecutor

    name = args.executor or None
    if args.address is not None and name != "ray":
        raise InvalidArgumentError("--address needs --executor ray")
    if name is not None and name not in EXECUTORS:
        raise UnknownNameError("--executor", name, EXECUTORS)
    if name == "ray":
        return RayExecutor(address=args.address, workers=args.workers or None)
    return name


#: Sampling configs with at most this many samples are sized for the CPU already (the
#: swing-ups, the quadruped walk): a quick CPU run keeps them as tuned.
CPU_SIZED_SAMPLES = 256


def quick_sampling_options(task: str | None = None) -> dict[str, dict]:
    """Sampling-controller options for a quick run: the GPU backend when there is an NVIDIA
    device, otherwise a handful of samples over a short horizon so that the CPU finishes in
    about a minute, except for the controllers that ``task`` tunes with at most
    :data:`CPU_SIZED_SAMPLES` samples, which keep their config (a cart-pole's 1 s plan cut
    to 0.15 s never swings it up).

    ``--set NAME.OPTION=VALUE`` overrides them, e.g. ``--set mppi.num_samples=256``.
    """
    if Path("/dev/nvidia0").exists():  # cheap check; importing warp takes seconds
        return {name: {"backend": "warp"} for name in ("ps", "mppi", "cem")}
    small = {"num_samples": 16, "horizon": 0.15}
    options = {"ps": small, "mppi": small, "cem": {**small, "num_elites": 4}}
    if task is not None:
        from mpcbox.registry import task_class

        configs = task_class(task).controller_configs
        for name in list(options):
            samples = getattr(configs.get(name), "num_samples", None)
            if samples is not None and samples <= CPU_SIZED_SAMPLES:
                del options[name]
    return options


def run_task_script(
    task: str,
    argv: Sequence[str] | None = None,
    *,
    controller_options: dict[str, dict[str, Any]] | None = None,
    prog: str | None = None,
    parents: Sequence[argparse.ArgumentParser] = (),
    **defaults: Any,
) -> int:
    """Entry point of a ``problems/<task>.py`` script: ``mpcbox compare <task>`` with defaults.

    Args:
        task: Task name (a key of :data:`mpcbox.registry.TASKS`).
        argv: Arguments (default: ``sys.argv[1:]``).
        controller_options: Option overrides for controllers, used when they are chosen
            (e.g. smaller sample counts for a quick CPU run); ``--set`` overrides them.
        prog: Program name in the usage (default ``<task>.py``).
        parents: The script's own option parsers (``add_help=False``), listed in
            ``--help``; the script reads them itself (their values are ignored here).
        **defaults: Overrides of :data:`~mpcbox.cli.compare_parser.DEFAULTS` (e.g.
            ``duration=5.0, seeds=1``); ``out`` defaults to ``results/<task>``.

    Returns:
        The exit status.
    """
    from mpcbox.registry import TASKS

    if task not in TASKS:
        raise UnknownNameError("task", task, TASKS)
    defaults.setdefault("out", f"results/{task}")
    parser = build_parser(task, prog=prog or f"{task}.py", parents=parents, **defaults)
    args = parser.parse_args(None if argv is None else list(argv))
    for own in parents:  # the script's options are not the comparison's
        for action in own._actions:
            if hasattr(args, action.dest):
                delattr(args, action.dest)
    try:
        return run_comparison(task, args, controller_defaults=controller_options)
    except (MpcboxError, ImportError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
