"""The MuJoCo-to-MJWarp gates on given scenes; prints JSON and writes one file per scene.

Runs :func:`mpcbox.gates.validate_scene` (the five gates of ``mpcbox validate``) on each
``--scene`` (default: mujoco-warp's ALOHA pot scene with ``--controls keyframes``: arms and
grippers move linearly through the controls of its 11 keyframes, from the neutral pose to
its pot-lift poses, up to 36 contacts at once in 4 s on the CPU) and writes
``benchmarks/results/gates_<scene>[_<tag>].json`` with the device's name, the machine and
the command. On a GPU (the numbers)::

    python benchmarks/gates.py --worlds 256,1024,2048,4096,8192 --duration 4

and on warp's CPU device at small sizes (a check that it runs)::

    python benchmarks/gates.py --device cpu --worlds 2,4 --duration 0.5 --scaling-worlds 4 \\
        --throughput-steps 20 --block-steps 10 --tag cpu
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def aloha_scene() -> str:
    """mujoco-warp's ``test_data/aloha_pot/scene.xml``."""
    import mujoco_warp

    return os.path.join(
        os.path.dirname(mujoco_warp.__file__), "test_data", "aloha_pot", "scene.xml"
    )


def main() -> None:
    from mpcbox.gates import GatesConfig, format_report, validate_scene, write_report

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scene",
        action="append",
        default=None,
        help="MJCF path or menagerie:NAME (repeatable; default: ALOHA pot)",
    )
    parser.add_argument("--ctrl-trajectory", default=None, help="controls for every scene")
    parser.add_argument("--task", default=None, help="a task's closed loop gives the controls")
    parser.add_argument("--controls", default="keyframes", help="hold, keyframes or zero")
    parser.add_argument("--duration", type=float, default=4.0)
    parser.add_argument("--device", default=None)
    parser.add_argument("--worlds", default=None, help="e.g. 256,1024,2048,4096,8192")
    parser.add_argument("--scaling-worlds", type=int, default=2048)
    parser.add_argument("--throughput-steps", type=int, default=500)
    parser.add_argument("--block-steps", type=int, default=50)
    parser.add_argument("--headroom", type=float, default=1.5)
    parser.add_argument("--machine", default=None, help="words on the machine for the JSON")
    parser.add_argument("--tag", default="", help="file name suffix, e.g. cpu: gates_<scene>_cpu")
    parser.add_argument("--out", default=str(RESULTS))
    args = parser.parse_args()

    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    worlds = tuple(int(w) for w in args.worlds.split(",")) if args.worlds else None
    scenes = args.scene or ([None] if args.task or args.ctrl_trajectory else [aloha_scene()])
    config = GatesConfig(
        duration=args.duration,
        controls=args.controls,
        device=args.device,
        worlds=worlds,
        scaling_worlds=min(args.scaling_worlds, max(worlds)) if worlds else args.scaling_worlds,
        headroom=args.headroom,
        throughput_steps=args.throughput_steps,
        block_steps=args.block_steps,
    )
    summary = []
    for scene in scenes:
        report = validate_scene(
            scene, ctrl_trajectory=args.ctrl_trajectory, task=args.task, config=config
        )
        print(format_report(report), file=sys.stderr)
        path = write_report(report, args.out)
        if args.tag:
            path = path.rename(path.with_name(f"{path.stem}_{args.tag}.json"))
        data = json.loads(path.read_text())
        gpu = report.device and report.device["is_cuda"]
        data["machine"] = args.machine or (
            report.device["name"] if gpu else "2-core sandbox CPU, shared"
        )
        data["command"] = " ".join(["python", *sys.argv])
        path.write_text(json.dumps(data, indent=2) + "\n")
        summary.append({"scene": report.scene, "file": str(path), "passed": report.passed})
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
