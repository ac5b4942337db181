"""Linearization and Riccati throughput on the humanoid; prints JSON.

    python benchmarks/linearize.py [--knots 100] [--repeat 3]

Measures finite-difference (A, B) pairs per second on one thread (forward and centered
differences), the same for a 100-knot trajectory on 1..all cores (thread scaling), and the
time of the discrete Riccati solve for the one-leg balance LQR.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

from mpcbox.controllers.lqr import dlqr
from mpcbox.tasks.humanoid.balance import HumanoidBalance


def best_of(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--knots", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    cores = os.cpu_count() or 1
    problem = HumanoidBalance(threads=cores)
    rng = np.random.default_rng(0)
    x0 = problem.reference_state()
    states = np.array(
        [problem.state_add(x0, 0.02 * rng.standard_normal(problem.nx)) for _ in range(args.knots)]
    )
    ctrls = problem.ctrl_ref + 0.05 * rng.standard_normal((args.knots, problem.nu))
    out: dict = {
        "host": platform.node(),
        "cores": cores,
        "model": "mpcbox/tasks/scenes/humanoid.xml (nv=27, nu=21), one leg",
        "knots": args.knots,
    }
    for centered in (False, True):
        key = "centered" if centered else "forward"
        t1 = best_of(
            lambda c=centered: problem.linearize_trajectory(states, ctrls, centered=c, threads=1),
            args.repeat,
        )
        out[f"{key}_pairs_per_s_1_thread"] = args.knots / t1
        scaling = {}
        for threads in sorted({1, *range(2, cores + 1)}):
            t = best_of(
                lambda c=centered, n=threads: problem.linearize_trajectory(
                    states, ctrls, centered=c, threads=n
                ),
                args.repeat,
            )
            scaling[threads] = {"pairs_per_s": args.knots / t, "speedup": t1 / t}
        out[f"{key}_thread_scaling"] = scaling
    lin = problem.linearize(x0, problem.ctrl_ref)
    quad = problem.quadratize(x0, problem.ctrl_ref)
    t_dare = best_of(lambda: dlqr(lin.A, lin.B, quad.lxx, quad.luu), args.repeat)
    out["dare_ms"] = t_dare * 1e3
    out["target_forward_pairs_per_s_1_thread"] = 1000
    out["meets_target"] = out["forward_pairs_per_s_1_thread"] >= 1000
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
