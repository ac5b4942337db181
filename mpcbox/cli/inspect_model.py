"""``mpcbox inspect MODEL [options]``: a robot's model checked before controlling it.

Prints :func:`mpcbox.core.robot_check.check_robot`'s findings, one topic a line, and with
``--json FILE`` writes them as JSON. ``MODEL`` is an MJCF path or a MuJoCo Menagerie robot
(``unitree_g1``, ``menagerie:unitree_g1/g1``). Exit status: 0 when nothing is worse than a
note, 1 for a warning or an error, 2 for a bad argument or a model that cannot be loaded.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mpcbox.core.robot_check import Finding, RobotCheck


#: Longest open-loop hold ``--hold`` takes (s).
MAX_HOLD = 3600.0


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or not 0 <= value <= MAX_HOLD:
        raise argparse.ArgumentTypeError(
            f"--hold must be a number of seconds in [0, {MAX_HOLD:g}], got {text!r}"
        )
    return value


def build_inspect_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mpcbox inspect``."""
    p = argparse.ArgumentParser(
        prog="mpcbox inspect",
        description="Check a robot's model before controlling it: integrator, actuators, "
        "joint limits, contacts with static parents, dry friction, servos that ring, the "
        "equilibrium through the actuator model, and an open-loop hold.",
    )
    p.add_argument("model", help="MJCF path or Menagerie robot name (unitree_g1, menagerie:...)")
    p.add_argument("--keyframe", default=None, help="posture: keyframe name or index")
    p.add_argument("--hold", type=_seconds, default=1.0, help="open-loop hold (s); 0 skips it")
    p.add_argument("--no-servo-test", action="store_true", help="skip the servo step test")
    p.add_argument("--json", default=None, metavar="FILE", help="also write the findings")
    return p


def _legged_finding(report: RobotCheck, name: str) -> Finding | None:
    """For a floating root: the feet found on the ground, and the task that balances it."""
    from mpcbox.core.model import free_body
    from mpcbox.core.robot_check import Finding
    from mpcbox.errors import MpcboxError
    from mpcbox.tasks.legged.ground_feet import ground_feet

    model = report.model
    if free_body(model) is None or model.nu == 0:
        return None
    for count, task in ((2, "biped_stand"), (4, "quadruped_stand")):
        try:
            feet = ground_feet(model, report.posture, count)
        except MpcboxError:
            continue
        held = all(f.level in ("ok", "note") for f in report.findings if f.topic == "equilibrium")
        if not held:
            return Finding(
                "legged task",
                "warning",
                f"its {count} lowest bodies look like feet ({', '.join(feet)}), but no "
                f"equilibrium holds it (above): {task} needs one",
            )
        return Finding(
            "legged task",
            "ok",
            f"stands on {count} feet ({', '.join(feet)}): mpcbox compare {task} --model {name}",
        )
    return Finding(
        "legged task",
        "note",
        "the bodies on the ground form neither 2 nor 4 legs: name the feet "
        "(mpcbox.tasks.legged.balance.LeggedBalance(model, feet=[...]))",
    )


def run_inspect(argv: Sequence[str], stream=None) -> int:
    """Run ``mpcbox inspect`` with ``argv`` (after the command name).

    Returns:
        0 when no finding is worse than a note, 1 otherwise.
    """
    from mpcbox.core.menagerie import model_source
    from mpcbox.core.robot_check import check_robot

    stream = stream or sys.stdout
    args = build_inspect_parser().parse_args(list(argv))
    keyframe = args.keyframe
    if keyframe is not None and keyframe.isdigit():
        keyframe = int(keyframe)
    if args.json:
        from mpcbox.cli.checks import check_output_folder

        check_output_folder(Path(args.json).parent, "--json")
    report = check_robot(
        model_source(args.model),
        keyframe=keyframe,
        hold=args.hold,
        servo_test=not args.no_servo_test,
    )
    legged = _legged_finding(report, model_source(args.model))
    if legged is not None:
        report = report._replace(findings=(*report.findings, legged))
    print(f"{args.model}: {report.level}", file=stream)
    print(report.format(), file=stream)
    if args.json:
        data = {
            "model": args.model,
            "level": report.level,
            "findings": [f._asdict() for f in report.findings],
        }
        Path(args.json).write_text(json.dumps(data, indent=2) + "\n")
    return 0 if report.level in ("ok", "note") else 1
