"""``mpcbox validate [SCENE] [options]``: the MuJoCo-to-MJWarp gates on a scene.

Prints the report (:func:`mpcbox.gates.format_report`) and, with ``--out DIR``, writes
``DIR/gates_<scene>.json``. Exit status: 0 when every gate passed, 1 when one failed or did
not run, 2 for a bad argument.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from mpcbox.errors import InvalidArgumentError
from mpcbox.gates.config import CONTROL_MODES, GatesConfig


def _worlds(text: str) -> tuple[int, ...]:
    try:
        worlds = tuple(int(w) for w in text.split(",") if w.strip())
    except ValueError:
        worlds = ()
    if not worlds or any(w < 1 for w in worlds):
        raise argparse.ArgumentTypeError(
            f"--worlds must be positive integers separated by commas (256,1024), got {text!r}"
        )
    return worlds


def _keyframe(text: str) -> int | str:
    return int(text) if text.isdigit() else text


def build_validate_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mpcbox validate``."""
    defaults = GatesConfig()
    p = argparse.ArgumentParser(
        prog="mpcbox validate",
        description="Run the MuJoCo-to-MJWarp gates on a scene: CPU baseline, one-world "
        "MJWarp parity, contact/constraint capacity, N worlds, throughput.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument(
        "scene",
        nargs="?",
        default=None,
        help="MJCF path, menagerie:NAME or task:NAME (optional with --task, or with a "
        "trajectory that names its task)",
    )
    src = p.add_argument_group("controls (default: the scene's keyframe control held)")
    src.add_argument(
        "--ctrl-trajectory",
        metavar="CSV",
        default=None,
        help="replay the controls of a saved trajectory (NAME.csv/.json)",
    )
    src.add_argument("--task", default=None, help="run this task in closed loop for controls")
    src.add_argument("--controller", default=None, help="the task's controller")
    src.add_argument(
        "--controls",
        choices=CONTROL_MODES,
        default=defaults.controls,
        help="controls from the scene alone",
    )
    src.add_argument(
        "--keyframe",
        type=_keyframe,
        default=None,
        help="start keyframe, index or name (default: the first, if any)",
    )
    src.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated seconds (default: the trajectory's, else 2)",
    )
    g = p.add_argument_group("gates")
    g.add_argument("--device", default=None, help="cpu, cuda or cuda:N (default: cuda if any)")
    g.add_argument(
        "--worlds",
        type=_worlds,
        default=None,
        help="world counts of the throughput gate (default: 256..8192 on cuda, 2,4 on cpu)",
    )
    for flag, kind, default, text in (
        (
            "--scaling-worlds",
            int,
            None,
            "worlds of the N-world gate (default: the largest of --worlds)",
        ),
        (
            "--parity-tolerance",
            float,
            defaults.parity_tolerance,
            "parity tolerance on max |qpos difference| (rad or m)",
        ),
        (
            "--parity-window",
            float,
            defaults.parity_window,
            "seconds from the start that must stay within the tolerance",
        ),
        ("--headroom", float, defaults.headroom, "suggested capacity = ceil(headroom x most seen)"),
        ("--nconmax", int, None, "contacts per world for the N-world runs (default: suggested)"),
        (
            "--njmax",
            int,
            None,
            "constraint rows per world for the N-world runs (default: suggested)",
        ),
        (
            "--perturbation",
            float,
            defaults.perturbation,
            "noise on the start states of worlds 1..N-1",
        ),
        ("--seed", int, defaults.seed, "seed of that noise"),
        ("--throughput-steps", int, defaults.throughput_steps, "steps timed per world count"),
        ("--block-steps", int, defaults.block_steps, "steps per launch block (per CUDA graph)"),
    ):
        g.add_argument(flag, type=kind, default=default, help=text)
    p.add_argument("--out", default=None, metavar="DIR", help="write DIR/gates_<scene>.json")
    return p


def _check_out(out: str) -> Path:
    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidArgumentError(
            f"--out {out!r} is not a folder that can be written: {exc}"
        ) from exc
    if not path.is_dir():
        raise InvalidArgumentError(f"--out {out!r} is not a folder")
    return path


def run_validate(argv: Sequence[str], stream=None) -> int:
    """Run ``mpcbox validate`` with ``argv`` (after the command name).

    Returns:
        0 when every gate passed, 1 otherwise.
    """
    from mpcbox.gates import format_report, validate_scene, write_report

    stream = stream or sys.stdout
    args = build_validate_parser().parse_args(list(argv))
    try:  # no start-up banner or per-module load lines from Warp in the report
        import warp as wp

        wp.config.quiet = True
        wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    except ImportError:
        pass
    out = _check_out(args.out) if args.out else None
    if args.scene and ":" not in args.scene:  # a bare name: a Menagerie robot, as inspect reads it
        from mpcbox.core.menagerie import model_source

        args.scene = model_source(args.scene)
    config = GatesConfig(
        duration=args.duration,
        controls=args.controls,
        keyframe=args.keyframe,
        device=args.device,
        worlds=args.worlds,
        scaling_worlds=args.scaling_worlds,
        parity_tolerance=args.parity_tolerance,
        parity_window=args.parity_window,
        headroom=args.headroom,
        nconmax=args.nconmax,
        njmax=args.njmax,
        perturbation=args.perturbation,
        seed=args.seed,
        throughput_steps=args.throughput_steps,
        block_steps=args.block_steps,
    )
    report = validate_scene(
        args.scene,
        ctrl_trajectory=args.ctrl_trajectory,
        task=args.task,
        controller=args.controller,
        config=config,
    )
    print(format_report(report), file=stream)
    if out is not None:
        print(f"wrote {write_report(report, out)}", file=stream)
    return 0 if report.passed else 1


__all__ = ["build_validate_parser", "run_validate"]
