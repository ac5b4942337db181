"""OSQP's rho on legged robots nobody here tuned for: fixed 0.3 against adaptive.

For each robot the script runs the task's QP-MPC (:class:`BipedStand` or
:class:`QuadrupedStand` with the feet named; no solve-time budget) for ``--duration`` s
under the robot-independent noise recipe (seed 1), exporting every tick's QP, and then
solves the exported QPs in order with one persistent OSQP per variant (OSQP's own warm
start from the previous solution), as the controller does. It prints and stores the
iterations and solve times per variant::

    MENAGERIE_ROOT=... OMP_NUM_THREADS=1 python benchmarks/qp_rho_robots.py
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from menagerie_robots import chosen_robots, stand_task

OUT = Path(__file__).parent / "results" / "qp_rho_robots.json"

#: The robots measured (feet from ``menagerie_robots.py``).
ROBOTS = (
    "unitree_g1",
    "unitree_h1",
    "apptronik_apollo",
    "pal_talos/scene_motor",
    "pal_talos/scene_position",
    "pndbotics_adam_lite",
    "robotis_op3",
    "agility_cassie",
    "unitree_go2",
    "unitree_go1",
    "anybotics_anymal_c",
)

#: OSQP settings over the task's, by variant name.
VARIANTS: dict[str, dict] = {
    "fixed 0.3": {},
    "adaptive, every 25": {"adaptive_rho": True, "adaptive_rho_interval": 25},
    "adaptive, every 50": {"adaptive_rho": True, "adaptive_rho_interval": 50},
}


def export(robot: str, folder: Path, duration: float) -> dict:
    import mpcbox

    problem = stand_task(robot)
    controller = mpcbox.make_controller("qp", problem, time_limit=None, export_dir=folder)
    res = mpcbox.simulate(problem, controller, duration, noise=problem.noise(), seed=1)
    settings = dict(controller.backend.settings)
    problem.close()
    return {"failure": res.failure, "settings": settings, "stats": controller.stats}


def sweep(folder: Path, settings: dict) -> dict:
    import osqp

    from mpcbox.controllers.qp_mpc.solvers import load_qp

    qps = [load_qp(f) for f in sorted(folder.glob("tick_*.npz"))]
    out = {}
    for name, extra in VARIANTS.items():
        solver = osqp.OSQP()
        first = qps[0]
        solver.setup(first.P, first.q, first.A, first.l, first.u, **{**settings, **extra})
        iters, times, failed = [], [], 0
        for qp in qps:
            solver.update(q=qp.q, l=qp.l, u=qp.u)
            start = time.perf_counter()
            res = solver.solve(raise_error=False)
            times.append(time.perf_counter() - start)
            iters.append(int(res.info.iter))
            failed += res.info.status_val not in (1, 2)  # solved, solved inaccurate
        out[name] = {
            "iterations_p50": float(np.median(iters)),
            "iterations_p90": float(np.percentile(iters, 90)),
            "iterations_max": max(iters),
            "solve_ms_p50": round(float(np.median(times)) * 1e3, 2),
            "solve_ms_p90": round(float(np.percentile(times, 90)) * 1e3, 2),
            "failed": failed,
        }
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--duration", type=float, default=0.6)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args()
    results = {}
    for robot in chosen_robots(parser, args):
        with tempfile.TemporaryDirectory() as tmp:
            run = export(robot, Path(tmp), args.duration)
            results[robot] = {"closed_loop_failure": run["failure"]}
            results[robot].update(sweep(Path(tmp), run["settings"]))
        print(robot, json.dumps(results[robot]), flush=True)
    Path(args.out).write_text(
        json.dumps(
            {
                "command": "MENAGERIE_ROOT=... OMP_NUM_THREADS=1 python "
                f"benchmarks/qp_rho_robots.py --duration {args.duration}",
                "machine": "2-core sandbox CPU, shared",
                "robots": results,
            },
            indent=1,
        )
        + "\n"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
