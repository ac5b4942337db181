"""iLQR's regularization schedules on the problems of ``benchmarks/ilqr_vs_crocoddyl.py``.

For the pendulum and cart-pole swing-ups (150 x 0.02 s) and the 7-DoF torque-controlled Panda
reach, each from the control guess (single shooting) and from zero controls with a state
guess (multiple shooting), runs mpcbox's iLQR with each schedule of
:mod:`mpcbox.controllers.ilqr.regularization`:

- ``mpcbox``: the default config (factor 4, minimum 1e-8, initial 1e-6);
- ``crocoddyl``: Crocoddyl's constants (factor 10, minimum and initial 1e-9), with and
  without its line search (step sizes 2^-k, k = 0..9, and Armijo constant 0.1);
- ``tassa``: Tassa et al. 2012's constants (factor 1.6, minimum 1e-6, initial 1).

Records iterations (derivative evaluations), rollouts, wall time, the final cost (one common
rollout) and the stop reason. Prints the JSON and writes it to
``benchmarks/results/ilqr_regularization.json``.

    nice -n 5 python benchmarks/ilqr_regularization.py [--problems pendulum cartpole arm]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import warnings
from pathlib import Path
from typing import Any

import mujoco
from ilqr_vs_crocoddyl import build, run_mpcbox

RESULTS = Path(__file__).parent / "results" / "ilqr_regularization.json"
CROCODDYL_STEPS = tuple(0.5**k for k in range(10))
SCHEDULES: dict[str, dict[str, Any]] = {
    "mpcbox": {},
    "crocoddyl": {
        "regularization_schedule": "crocoddyl",
        "regularization_factor": 10.0,
        "regularization_min": 1e-9,
        "regularization": 1e-9,
    },
    "crocoddyl_line_search": {
        "regularization_schedule": "crocoddyl",
        "regularization_factor": 10.0,
        "regularization_min": 1e-9,
        "regularization": 1e-9,
        "step_sizes": CROCODDYL_STEPS,
        "armijo": 0.1,
    },
    "tassa": {
        "regularization_schedule": "tassa",
        "regularization_factor": 1.6,
        "regularization_min": 1e-6,
        "regularization": 1.0,
    },
}
KEEP = ("cost", "iterations", "rollouts", "wall_s", "status", "converged", "upright_or_goal_error")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=["pendulum", "cartpole", "arm"])
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    out: dict[str, Any] = {
        "machine": "2-core sandbox CPU, shared",
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "schedules": {k: {n: str(v) for n, v in o.items()} for k, o in SCHEDULES.items()},
        "problems": {},
    }
    for name in args.problems:
        case = build(name)
        row: dict[str, Any] = {}
        for shooting in ("single", "multiple"):
            for schedule, options in SCHEDULES.items():
                run = run_mpcbox(case, shooting, **options)
                row[f"{shooting}/{schedule}"] = {key: run[key] for key in KEEP}
                print(name, shooting, schedule, json.dumps(row[f"{shooting}/{schedule}"]))
        out["problems"][name] = row
    RESULTS.parent.mkdir(exist_ok=True)
    if RESULTS.exists():  # keep the other problems' rows of an earlier run
        earlier = json.loads(RESULTS.read_text()).get("problems", {})
        out["problems"] = {**earlier, **out["problems"]}
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
