"""iLQR-MPC's replan tick, phase by phase, on a Menagerie arm and a humanoid; prints JSON.

Per robot and seed, one closed loop (lock-step, the task's tuned iLQR config) records each
replan's :class:`~mpcbox.controllers.ilqr.result.Timing` (derivatives, backward passes,
rollouts, total) and reports the medians over the replans after the first (which runs the
warm-up iterations), the 99th percentile of the total, and the run's outcome:

* ``panda``: :class:`~mpcbox.tasks.reach.ArmReach` on the Franka Panda, the 40 cm reach of
  ``benchmarks/panda_reach.py`` (its seeds perturb the start and the target), 2 s;
* ``g1``: :class:`~mpcbox.tasks.legged.biped.BipedStand` on the Unitree G1 under the noise
  recipe (the seed's noise), 3 s;
* ``go2``, ``anymal_c``: :class:`~mpcbox.tasks.legged.quadruped.QuadrupedStand` on Unitree's
  Go2 and ANYbotics' ANYmal C, the same way (code before stop 45 gives these the generic
  iLQR config).

To compare with other code, put its ``mpcbox`` first on the path
(``git archive <commit> mpcbox | tar -x -C /tmp/base``, then ``PYTHONPATH=/tmp/base``); the
JSON records which ``mpcbox`` ran. Needs ``MENAGERIE_ROOT``::

    MENAGERIE_ROOT=... python benchmarks/ilqr_tick.py [--robots panda,g1] [--seeds 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mpcbox
from mpcbox.cli.compare import parse_sets
from mpcbox.controllers.ilqr import solver as ilqr_solver
from mpcbox.errors import MpcboxError
from mpcbox.registry import make_controller


def _reach(seed: int):
    import panda_reach  # benchmarks/ is not a package

    return panda_reach.build(seed, panda_reach.default_args()), 2.0, None


def _stand(seed: int):
    from mpcbox.tasks.legged.biped import BipedStand

    problem = BipedStand("menagerie:unitree_g1")
    return problem, 3.0, problem.noise()


def _quadruped(name: str):
    def build(seed: int):
        from mpcbox.tasks.legged.quadruped import QuadrupedStand

        problem = QuadrupedStand(f"menagerie:{name}")
        return problem, 3.0, problem.noise()

    return build


ROBOTS = {
    "panda": _reach,
    "g1": _stand,
    "go2": _quadruped("unitree_go2"),
    "anymal_c": _quadruped("anybotics_anymal_c"),
}


def run(robot: str, seed: int, options: dict | None = None) -> dict:
    """One closed loop with every replan's timing recorded (``options``: iLQR overrides)."""
    timings: list = []
    original = ilqr_solver.ILQRSolver._optimize

    def recorded(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        timings.append(result.timing)
        return result

    ilqr_solver.ILQRSolver._optimize = recorded
    try:
        problem, duration, noise = ROBOTS[robot](seed)
        controller = make_controller("ilqr", problem, **(options or {}))
        sim = mpcbox.simulate(problem, controller, duration, noise=noise, seed=seed)
    finally:
        ilqr_solver.ILQRSolver._optimize = original
    phases = 1e3 * np.array([tuple(t) for t in timings[1:]])
    out = {
        "seed": seed,
        "replans": len(timings),
        "survived": bool(sim.metrics.success),
        **{
            f"{name}_ms_median": round(float(np.median(phases[:, i])), 1)
            for i, name in enumerate(("derivatives", "backward", "rollouts", "total"))
        },
        "total_ms_p99": round(float(np.percentile(phases[:, 3], 99)), 1),
    }
    if robot == "panda":
        out["final_error_mm"] = round(1e3 * problem.reach_error(sim.states[-1]), 3)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--robots", default="panda,g1")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--machine", default="2-core sandbox CPU, shared")
    parser.add_argument("--out", default="", help="also write the JSON here")
    parser.add_argument(
        "--ilqr-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an option of the task's iLQR config (repeatable)",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    robots = [r for r in args.robots.split(",") if r]
    unknown = sorted(set(robots) - set(ROBOTS))
    if unknown:
        parser.error(f"--robots: unknown {unknown}; choose from {sorted(ROBOTS)}")
    try:
        options = parse_sets([f"ilqr.{s}" for s in args.ilqr_set]).get("ilqr", {})
    except MpcboxError as exc:
        parser.error(f"--ilqr-set: {exc}")
    t0 = time.perf_counter()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    out = {
        "benchmark": "ilqr_tick",
        "mpcbox": str(Path(mpcbox.__file__).resolve().parent),
        "machine": args.machine,
        "command": "python benchmarks/ilqr_tick.py " + " ".join(sys.argv[1:]),
        "ilqr_options": options,
        "robots": {robot: [run(robot, seed, options) for seed in seeds] for robot in robots},
    }
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(out, indent=2)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
