"""How good is a QP-MPC plan cut off by OSQP's time budget? Residual against first control.

Runs a robot's QP-MPC (:class:`BipedStand` / :class:`QuadrupedStand` with the feet named,
the task's solve-time budget, every truncated iterate accepted: ``truncated_residual=1e9``)
for ``--duration`` s under the noise recipe, and solves every truncated QP again without a
budget. For bins of the truncated iterate's violation of its first stage's rows (those
that bind the control applied now) it reports how far its first control lies from the
converged one, as a fraction of each actuator's control range (the largest over the
actuators), and the whole QP's primal residual. This is what
``QPMPCConfig.truncated_residual`` (default 1e-3) is checked against. The budget is
wall-clock time, so the truncations depend on the machine::

    MENAGERIE_ROOT=... python benchmarks/qp_truncation_quality.py --robots pal_talos/scene_motor
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import numpy as np
from menagerie_robots import chosen_robots, stand_task

OUT = Path(__file__).parent / "results" / "qp_truncation_quality.json"
BINS = (0.0, 1e-4, 1e-3, 1e-2, 1e-1, np.inf)
ROBOTS = ("pal_talos/scene_motor", "robotis_op3", "apptronik_apollo")


def run(robot: str, duration: float, seed: int) -> dict:
    import osqp

    import mpcbox
    from mpcbox.controllers.qp_mpc.solvers import constraint_residual

    problem = stand_task(robot)
    controller = mpcbox.make_controller("qp", problem, truncated_residual=1e9)
    span = problem.ctrl_high - problem.ctrl_low
    rows: list[tuple[float, float]] = []
    solve = controller.backend.solve

    def checked(qp, changed, warm):
        sol = solve(qp, changed, warm)
        if sol.truncated:
            ref = osqp.OSQP()
            settings = {**controller.backend.settings, "time_limit": 1e10, "max_iter": 4000}
            ref.setup(qp.P, qp.q, qp.A, qp.l, qp.u, **settings)
            exact = ref.solve(raise_error=False).x
            lay, scale = controller.layout, controller.formulation.ctrl_scale
            first = slice(lay.ou, lay.ou + lay.nu)
            error = np.abs((sol.x[first] - exact[first]) * scale) / span
            stage0 = constraint_residual(qp, sol.x, lay.first_stage_rows)
            rows.append((stage0, float(np.max(error)), sol.primal_residual))
        return sol

    controller.backend.solve = checked
    res = mpcbox.simulate(problem, controller, duration, noise=problem.noise(), seed=seed)
    problem.close()
    table = []
    data = np.array(rows).reshape(-1, 3)
    for lo, hi in itertools.pairwise(BINS):
        inside = (data[:, 0] >= lo) & (data[:, 0] < hi)
        if inside.any():
            table.append(
                {
                    "first_stage_residual": [lo, None if np.isinf(hi) else hi],
                    "count": int(inside.sum()),
                    "first_control_error_median": round(float(np.median(data[inside, 1])), 4),
                    "first_control_error_max": round(float(np.max(data[inside, 1])), 4),
                    "whole_qp_residual_median": float(np.median(data[inside, 2])),
                }
            )
    return {
        "failure": res.failure,
        "solves": controller.stats["solves"],
        "truncated": len(rows),
        "bins": table,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--duration", type=float, default=1.5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args()
    results = {}
    for robot in chosen_robots(parser, args):
        results[robot] = run(robot, args.duration, args.seed)
        print(robot, json.dumps(results[robot]), flush=True)
    out = {
        "command": "MENAGERIE_ROOT=... python benchmarks/qp_truncation_quality.py "
        f"--duration {args.duration} --seed {args.seed}",
        "machine": "2-core sandbox CPU, shared (the budget is wall-clock time)",
        "robots": results,
    }
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
