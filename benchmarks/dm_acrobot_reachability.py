"""How soon can dm_control's acrobot (2 N m elbow) be upright? Offline iLQR by horizon.

Evidence for the time target of issue #13 on ``dm_acrobot_swingup``: for each horizon of
``--horizons`` seconds (0.02 s planning step) iLQR (Tassa's regularization schedule, factor
1.6, from 1; at most ``--iterations`` iterations) minimizes a terminal-only cost from the
hanging rest: terminal tip distance weight 1000 and terminal velocity weight 100 (``--rest``)
or 0 (the tip may pass through the target), running velocity 0.001 and control 0.01 only,
so no running tip cost pulls the plan into the one-link-up local minimum. Six control
guesses ``cos(w t + phi)``, ``w`` in {2.67 (the slow hanging mode), 4, 6.9 (the fast
mode)} rad/s and ``phi`` in {0, pi/2}, act as restarts; the best final tip distance over
them is recorded with each restart's. Also records the energy that a swing-up must add
(potential energy upright minus hanging) and the elbow travel it needs at the torque limit.
A local optimizer gives no proof of infeasibility: the result bounds what iLQR finds.

    nice -n 5 python benchmarks/dm_acrobot_reachability.py [--horizons 4.8,5.5,6.5]

Prints the JSON and writes it to ``benchmarks/results/dm_acrobot_reachability.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.errors import PlanningModelWarning
from mpcbox.tasks.swingup.dm_control import (
    END_SOLVER_OPTIONS,
    SWING_GUESSES,
    DmAcrobotSwingup,
    end_weights,
)

RESULTS = Path(__file__).parent / "results" / "dm_acrobot_reachability.json"


def energy_needed(problem: DmAcrobotSwingup) -> dict:
    """Potential energy upright minus hanging, and the elbow travel it takes at full torque."""
    model, data = problem.model, mujoco.MjData(problem.model)
    heights = []
    for qpos in (problem.qpos_ref, problem.initial_state()[: problem.nq]):
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        mujoco.mj_energyPos(model, data)
        heights.append(float(data.energy[0]))
    torque = float(model.actuator_gear[0, 0] * model.actuator_ctrlrange[0, 1])
    return {
        "delta_potential_J": heights[0] - heights[1],
        "elbow_torque_limit_Nm": torque,
        "elbow_travel_needed_rad": (heights[0] - heights[1]) / torque,
    }


def end_cost_solver(
    seconds: float, iterations: int, rest: bool = True, **options
) -> tuple[DmAcrobotSwingup, ILQRSolver]:
    """The acrobot under the task's :func:`~mpcbox.tasks.swingup.dm_control.end_weights`
    (``options``: e.g. ``planning_timestep``, ``plan_rk4``) and an iLQR solver over
    ``seconds`` with the task's ``END_SOLVER_OPTIONS`` (Tassa's regularization schedule)."""
    problem = DmAcrobotSwingup(threads=1, weights=end_weights(rest), **options)
    solver = ILQRSolver(
        problem,
        horizon=round(seconds / problem.dt),
        max_iterations=iterations,
        threads=1,
        **END_SOLVER_OPTIONS,
    )
    return problem, solver


def solve_horizon(seconds: float, rest: bool, iterations: int) -> dict:
    # Recorded on the implicitfast copy, before the task planned in RK4 by default.
    problem, solver = end_cost_solver(
        seconds, iterations, rest, planning_timestep=0.02, plan_rk4=False
    )
    horizon = solver.horizon
    t = problem.dt * np.arange(horizon)
    restarts = []
    for w, phi in SWING_GUESSES:
        wall = time.perf_counter()
        res = solver.solve(problem.initial_state(), np.cos(w * t + phi)[:, None])
        restarts.append(
            {
                "omega": w,
                "phase": round(phi, 4),
                "final_tip_error_m": round(float(problem.upright_errors(res.states)[-1]), 4),
                "final_speed_rad_s": round(float(np.linalg.norm(res.states[-1, 2:])), 3),
                "iterations": res.iterations,
                "status": res.status,
                "solve_s": round(time.perf_counter() - wall, 1),
            }
        )
    return {
        "horizon_s": seconds,
        "at_rest": rest,
        "best_final_tip_error_m": min(r["final_tip_error_m"] for r in restarts),
        "restarts": restarts,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--horizons", default="4.8,5.5,6.5")
    parser.add_argument("--iterations", type=int, default=300)
    args = parser.parse_args()
    warnings.simplefilter("ignore", PlanningModelWarning)
    runs = []
    for seconds in (float(s) for s in args.horizons.split(",")):
        for rest in (True, False):
            runs.append(solve_horizon(seconds, rest, args.iterations))
            print(json.dumps({k: v for k, v in runs[-1].items() if k != "restarts"}), flush=True)
    out = {
        "benchmark": "dm_acrobot_reachability",
        "machine": {
            "description": "2-core sandbox CPU, shared",
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "settings": vars(args),
        "energy": energy_needed(DmAcrobotSwingup(threads=1)),
        "runs": runs,
    }
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
