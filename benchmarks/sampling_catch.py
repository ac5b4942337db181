"""MPPI with and without the LQR catch (``catch="lqr"``) on swing-ups, same options otherwise.

For each task, MPPI on the CPU backend with the task's MPPI config when it has one (else
:data:`OPTIONS`), once as configured without a catch and once with ``catch="lqr"`` (the
basin level estimated when the controller is built, unless the task's config sets it),
from the task's hanging start (seed 0) and from ``--seeds`` starts with every joint angle
perturbed by N(0, 0.05) rad (seeds 1..N; with ``--start random`` the unlimited hinges
uniform in [-pi, pi) at rest instead, as dm_control's swing-ups start), ``--duration``
seconds in lock-step
(:func:`mpcbox.simulate`). Success is the task's own goal (upright within its tolerance over
the last second); also the first time after which it stays upright, the closest approach,
the final error, the calls the catch answered and the median tick.

    nice -n 5 python benchmarks/sampling_catch.py [--tasks acrobot_swingup,cartpole_swingup]
        [--seeds 4] [--duration 8] [--start perturbed|random] [--out PATH]

Prints the JSON and writes it to ``benchmarks/results/sampling_catch.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.controllers.lqr import unlimited_hinges
from mpcbox.registry import task_class

RESULTS = Path(__file__).parent / "results" / "sampling_catch.json"
#: MPPI options for a task without an MPPI config: a 2 s horizon of 10 knots at a 0.02 s
#: planning step, replanning every 0.02 s.
OPTIONS: dict = {
    "horizon": 2.0,
    "num_knots": 10,
    "planning_timestep": 0.02,
    "replan_period": 0.02,
}


def start_state(name: str, seed: int, start: str = "perturbed") -> np.ndarray:
    """The task's initial state for ``seed > 0``: every joint angle perturbed by N(0, 0.05)
    rad (``"perturbed"``), or, for the hinges without a range, uniform in ``[-pi, pi)`` at
    rest as dm_control's swing-ups start (``"random"``). Seed 0: the initial state."""
    problem = task_class(name)(threads=1)
    state = problem.initial_state()
    if not seed:
        return state
    rng = np.random.default_rng(seed)
    if start == "perturbed":
        state[: problem.nq] += rng.normal(0.0, 0.05, problem.nq)
        return state
    hinges = unlimited_hinges(problem.model)
    state[problem.model.jnt_qposadr[hinges]] = rng.uniform(-np.pi, np.pi, hinges.size)
    return state


def run(name: str, seed: int, catch: bool, duration: float, start: str = "perturbed") -> dict:
    problem = task_class(name)(initial=start_state(name, seed, start), threads=1)
    options = {} if "mppi" in problem.controller_configs else dict(OPTIONS)
    options["catch"] = "lqr" if catch else None
    if not catch:
        options["catch_level"] = None
    ctrl = mpcbox.make_controller("mppi", problem, **options)
    wall = time.perf_counter()
    result = mpcbox.simulate(problem, ctrl, duration)
    wall = time.perf_counter() - wall
    errors = problem.upright_errors(result.states)
    t_up = problem.time_to_upright(result.time, result.states)
    failure = result.failure or problem.goal_failure(result.time, result.states)
    return {
        "seed": seed,
        "catch": catch,
        "level": None if ctrl.catch is None else round(float(ctrl.catch.level), 3),
        "success": failure is None,
        "time_to_upright_s": None if np.isnan(t_up) else round(float(t_up), 2),
        "closest": round(float(errors.min()), 4),
        "final_error": round(float(errors[-1]), 4),
        "error_unit": problem.goal.unit,
        "catch_calls": int(ctrl.stats["catch_calls"]),
        "median_tick_ms": round(float(np.median(result.compute_times)) * 1e3, 1),
        "wall_s": round(wall, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default="acrobot_swingup,cartpole_swingup")
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--duration", type=float, default=8.0)
    parser.add_argument(
        "--start",
        choices=("perturbed", "random"),
        default="perturbed",
        help="seeds > 0: perturbed initial state, or unlimited hinges uniform at rest",
    )
    parser.add_argument("--out", default=str(RESULTS))
    args = parser.parse_args()
    report: dict = {
        "benchmark": "sampling_catch",
        "machine": {
            "description": "2-core sandbox CPU, shared",
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "settings": vars(args),
        "options_without_a_task_config": OPTIONS,
        "tasks": {},
    }
    for name in args.tasks.split(","):
        rows = []
        for catch in (False, True):
            for seed in range(args.seeds + 1):
                rows.append(run(name, seed, catch, args.duration, args.start))
                print(json.dumps({"task": name, **rows[-1]}), flush=True)
        summary = {
            label: f"{sum(r['success'] for r in rows if r['catch'] == on)}/{args.seeds + 1}"
            for label, on in (("without", False), ("with_catch", True))
        }
        report["tasks"][name] = {"summary": summary, "runs": rows}
    text = json.dumps(report, indent=1)
    print(text)
    Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
