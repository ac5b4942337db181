"""Benchmark iLQR on the one-leg humanoid balance task; prints JSON.

Measures offline iterations per second with the time split by phase, and the MPC tick
(replan) time and real-time factor at 50 Hz replanning in closed loop.

    python benchmarks/ilqr.py [--duration 2.0] [--linearize-every 2] [--control-steps 1]

``--control-steps s`` holds each knot's control for ``s`` planning steps
(``ILQRConfig.control_steps``), with ``horizon-seconds / (s * planning-timestep)`` knots.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

import mpcbox
from mpcbox.config import config_options
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.tasks.humanoid.balance import HumanoidBalance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--horizon-seconds", type=float, default=0.35)
    parser.add_argument("--planning-timestep", type=float, default=0.015)
    parser.add_argument("--linearize-every", type=int, default=None)
    parser.add_argument("--control-steps", type=int, default=None)
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--duration", type=float, default=2.0)
    args = parser.parse_args()

    problem = HumanoidBalance()
    options = config_options(HumanoidBalance.controller_configs["ilqr"])
    options["planning_timestep"] = args.planning_timestep
    if args.control_steps is not None:
        options["control_steps"] = args.control_steps
    knot = args.planning_timestep * options.get("control_steps", 1)
    options["horizon"] = round(args.horizon_seconds / knot)
    if args.linearize_every is not None:
        options["linearize_every"] = args.linearize_every
    ilqr = ILQR(problem, **options)
    x0 = problem.initial_state()

    ilqr.solve(x0, max_iterations=1)  # warm up thread pools and per-thread data
    t0 = time.perf_counter()
    res = ilqr.solve(x0, max_iterations=args.iterations)
    wall = time.perf_counter() - t0
    timing = res.timing

    controller = ILQR(problem, **options)
    sim = mpcbox.simulate(problem, controller, args.duration)
    replans = int(controller.stats["replans"])
    # The controller is called every simulation step; the replans are the expensive calls.
    ticks = np.sort(sim.compute_times)[-replans:] if replans else np.zeros(1)
    out = {
        "task": "humanoid_balance",
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "options": {
            k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in options.items()
        },
        "nx": problem.nx,
        "nu": problem.nu,
        "offline": {
            "iterations": res.iterations,
            "iterations_per_s": res.iterations / wall,
            "ms_per_iteration": {
                "derivatives": 1e3 * timing.derivatives / res.iterations,
                "backward": 1e3 * timing.backward / res.iterations,
                "rollouts": 1e3 * timing.rollouts / res.iterations,
                "total": 1e3 * timing.total / res.iterations,
            },
            "cost_first_last": [float(res.costs[0]), float(res.cost)],
        },
        "mpc": {
            "duration_s": args.duration,
            "survived": sim.metrics.survived,
            "replan_hz": 1.0 / controller.replan_period,
            "replans": replans,
            "tick_ms_mean": 1e3 * float(ticks.mean()),
            "tick_ms_p50": 1e3 * float(np.median(ticks)),
            "tick_ms_p99": 1e3 * float(np.percentile(ticks, 99)),
            "call_ms_mean_all_steps": sim.metrics.compute_mean_ms,
            "realtime_factor": sim.metrics.realtime_factor,
            "fallbacks": sim.metrics.fallbacks,
            "stats": controller.stats,
        },
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
