"""``mpcbox inspect`` over Menagerie robots and third-party test models; prints JSON.

Runs :func:`mpcbox.core.robot_check.check_robot` (the command's checks) on each model as a
user would name it, and records every finding's level and text and the wall time::

    MENAGERIE_ROOT=... python benchmarks/inspect_robots.py [--robots unitree_g1,...]
        [--out benchmarks/results/inspect_robots.json]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from json_report import finish  # benchmarks/ is not a package
from servo_ringing import ROBOTS


def third_party() -> list[str]:
    """dm_control's suite models and mujoco-warp's test scenes, where installed."""
    paths = []
    try:
        import dm_control

        suite = Path(dm_control.__file__).parent / "suite"
        paths += [str(suite / f"{n}.xml") for n in ("cartpole", "acrobot", "quadruped")]
        paths += [str(suite / f"{n}.xml") for n in ("humanoid", "manipulator")]
    except ImportError:
        pass
    try:
        import mujoco_warp

        data = Path(mujoco_warp.__file__).parent / "test_data"
        paths += [str(data / "aloha_pot" / "scene.xml"), str(data / "humanoid" / "humanoid.xml")]
    except ImportError:
        pass
    return paths


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join([f"menagerie:{r}" for r in ROBOTS]))
    parser.add_argument("--no-third-party", action="store_true")
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    from mpcbox.core.robot_check import check_robot

    started = time.perf_counter()
    names = [r for r in args.robots.split(",") if r]
    if not args.no_third_party:
        names += third_party()
    rows = {}
    for name in names:
        tic = time.perf_counter()
        try:
            report = check_robot(name)
            rows[name] = {
                "level": report.level,
                "findings": {f.topic: [f.level, f.text] for f in report.findings},
            }
        except Exception as exc:  # recorded: a model that does not load
            rows[name] = {"error": f"{type(exc).__name__}: {exc}"}
        rows[name]["seconds"] = round(time.perf_counter() - tic, 2)
    out = {
        "benchmark": "inspect_robots: mpcbox inspect's checks (check_robot) on each model",
        "command": "MENAGERIE_ROOT=... python benchmarks/inspect_robots.py",
        "levels": {k: v.get("level", "load error") for k, v in rows.items()},
        "models": rows,
    }
    return finish(out, args.out, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
