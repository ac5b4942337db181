"""``mpcbox replay FILE [--video OUT] [--viewer live|OUT]``: re-simulate a saved run, or
render it.

Without ``--video`` the saved controls are applied open loop on the task's simulation model
(:func:`mpcbox.sim.trajectory.replay`) and the largest difference between the replayed and
the saved final state is printed; the exit status is 1 when it exceeds ``--tolerance``.
With ``--video`` the saved states are rendered to an MP4 or GIF. With ``--viewer live`` the
re-simulation is shown in a MuJoCo window held to wall-clock time (the run replayed in real
time); ``--viewer FILE`` writes it through the offscreen viewer instead.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mpcbox.errors import InvalidArgumentError


def build_replay_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mpcbox replay``."""
    parser = argparse.ArgumentParser(
        prog="mpcbox replay",
        description="Re-simulate a saved run (NAME.csv + NAME.json) and print its final-state "
        "error against the saved one, or render it with --video.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("file", help="NAME.csv, NAME.json or NAME of a saved trajectory")
    parser.add_argument("--video", default=None, metavar="FILE", help="render to FILE (.mp4/.gif)")
    parser.add_argument(
        "--viewer",
        default=None,
        metavar="live|FILE",
        help="show the re-simulation as it runs: 'live' (a window, in real time) or a "
        ".gif/.mp4 file",
    )
    parser.add_argument("--fps", type=float, default=30.0, help="video frames per second")
    parser.add_argument("--width", type=int, default=640, help="video width (pixels)")
    parser.add_argument("--height", type=int, default=480, help="video height (pixels)")
    parser.add_argument("--camera", default=None, help="a camera of the model, by name")
    parser.add_argument(
        "--tolerance",
        type=float,
        default=1e-9,
        help="largest final-state difference that counts as the same run",
    )
    return parser


def _problem(traj):
    from mpcbox.registry import TASKS, task_class

    task = traj.metadata.get("task")
    if not task:
        raise InvalidArgumentError(
            "the trajectory names no task (it was saved from Python): replay it with "
            "mpcbox.sim.trajectory.replay(traj, problem)"
        )
    if task not in TASKS:
        from mpcbox.errors import UnknownNameError

        raise UnknownNameError("task (in the trajectory)", task, TASKS)
    return task_class(task)(**dict(traj.metadata.get("task_options") or {}))


def run_replay(argv: Sequence[str], stream=None) -> int:
    """Run ``mpcbox replay`` with ``argv`` (after the command name).

    Returns:
        0 when the replay matches (or the video was written), 1 when the final states
        differ by more than ``--tolerance``.
    """
    from mpcbox.sim.trajectory import replay
    from mpcbox.sim.trajectory_files import load_trajectory

    stream = stream or sys.stdout
    args = build_replay_parser().parse_args(list(argv))
    if not args.tolerance >= 0:
        raise InvalidArgumentError(f"--tolerance must be >= 0, got {args.tolerance!r}")
    if args.video and args.viewer is not None:
        raise InvalidArgumentError(
            "--video renders the saved states and --viewer watches a re-simulation: give one"
        )
    if args.video:
        from mpcbox.sim.video import check_video_path

        check_video_path(args.video)
    traj = load_trajectory(args.file)
    problem = _problem(traj)
    outcome = f"failed: {traj.failure}" if traj.failure else "ran to the end"
    print(
        f"{traj.problem}, {traj.controller}, seed {traj.seed}: {len(traj.time)} steps, "
        f"{traj.time[-1]:.3f} s, {outcome}",
        file=stream,
    )
    if args.video:
        from mpcbox.sim.video import render_video

        path = render_video(
            traj,
            problem,
            args.video,
            fps=args.fps,
            width=args.width,
            height=args.height,
            camera=args.camera,
        )
        print(f"wrote {path}", file=stream)
        return 0
    result = replay(traj, problem, viewer=args.viewer)
    same = result.final_error <= args.tolerance
    print(
        f"replayed open loop: final-state error {result.final_error:.3g} (max abs over "
        f"{problem.nstate} state entries) -> {'same' if same else 'DIFFERENT'} "
        f"(tolerance {args.tolerance:g})",
        file=stream,
    )
    return 0 if same else 1
