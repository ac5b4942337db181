"""``mpcbox inspect`` over Menagerie robots and third-party test models; prints JSON.

Runs :func:`mpcbox.core.robot_check.check_robot` (the command's checks) on each model as a
user would name it, and records every finding's level and text and the wall time::

    MENAGERIE_ROOT=... python benchmarks/inspect_robots.py [--robots unitree_g1,...]
        [--out benchmarks/results/inspect_robots.json]
    python benchmarks/inspect_robots.py --every-test-model  # 56 third-party MJCFs
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from json_report import finish  # benchmarks/ is not a package
from servo_ringing import ROBOTS


def every_test_model() -> list[str]:
    """Every MJCF of dm_control's suite and of mujoco-warp's test data, where installed."""
    paths: list[str] = []
    try:
        import dm_control

        paths += sorted(str(p) for p in (Path(dm_control.__file__).parent / "suite").glob("*.xml"))
    except ImportError:
        pass
    try:
        import mujoco_warp

        data = Path(mujoco_warp.__file__).parent / "test_data"
        paths += sorted(str(p) for p in data.rglob("*.xml"))
    except ImportError:
        pass
    return paths


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
    parser.add_argument(
        "--every-test-model",
        action="store_true",
        help="every MJCF of dm_control's suite and mujoco-warp's test data instead",
    )
    parser.add_argument("--out", default="")
    args = parser.parse_args()
    from mpcbox.core.menagerie import model_source
    from mpcbox.core.robot_check import check_robot
    from mpcbox.errors import MpcboxError

    started = time.perf_counter()
    names = [model_source(r) for r in args.robots.split(",") if r]  # a bare name: Menagerie's
    if args.every_test_model:
        names = every_test_model()
    elif not args.no_third_party:
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
        except MpcboxError as exc:  # a named refusal (a model that does not load)
            rows[name] = {"refused": f"{type(exc).__name__}: {exc}"}
        except Exception as exc:  # recorded: any other exception is a bug
            rows[name] = {"error": f"{type(exc).__name__}: {exc}"}
        rows[name]["seconds"] = round(time.perf_counter() - tic, 2)
    out = {
        "benchmark": "inspect_robots: mpcbox inspect's checks (check_robot) on each model",
        "command": "MENAGERIE_ROOT=... python benchmarks/inspect_robots.py "
        + " ".join(sys.argv[1:]),
        "levels": {
            k: v.get("level", "refused" if "refused" in v else "ERROR") for k, v in rows.items()
        },
        "raw_errors": sum("error" in v for v in rows.values()),
        "models": rows,
    }
    return finish(out, args.out, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
