"""Per-tick cost of the contact-force QP-MPC on the one-leg humanoid; prints JSON.

Measures, for ``N = 10`` steps of 0.02 s with relinearization every tick: the time of
linearize + update + solve (median and p99), the QP size, OSQP iterations with and without
warm start, and each installed ``qpsolvers`` backend's time on the same exported QP.

Run single-threaded for honest numbers::

    OMP_NUM_THREADS=1 python benchmarks/qp_mpc.py [--ticks 200]
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from mpcbox.controllers.qp_mpc.controller import QPMPC
from mpcbox.controllers.qp_mpc.solvers import to_qpsolvers
from mpcbox.sim.disturbances import Push
from mpcbox.sim.simulation import simulate
from mpcbox.tasks.humanoid.balance import HumanoidBalance


def _run(problem, ticks: int, **options) -> tuple[QPMPC, list, list, list]:
    ctl = QPMPC(problem, horizon=10, dt=0.02, **options)
    timings, iters, qps = [], [], []
    solve = ctl.solve

    def record(state):
        plan = solve(state)
        timings.append(sum(ctl.timing))
        iters.append(plan.iterations if plan is not None else -1)
        qps.append(ctl.qp)
        return plan

    ctl.solve = record
    push = [Push(force=(20.0, 0.0, 0.0), start=0.5, duration=0.1)]
    simulate(problem, ctl, ticks * ctl.period, pushes=push)
    return ctl, timings, iters, qps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ticks", type=int, default=150)
    parser.add_argument("--backend-qps", type=int, default=5)
    args = parser.parse_args()

    problem = HumanoidBalance(threads=1)
    out: dict = {"task": problem.name, "horizon": 10, "dt": 0.02}
    for relin in (True, False):
        ctl, times, iters, qps = _run(problem, args.ticks, relinearize=relin)
        t = np.asarray(times[1:]) * 1e3  # the first tick sets the solver up
        key = "relinearize" if relin else "fixed_linearization"
        out[key] = {
            "tick_ms_median": float(np.median(t)),
            "tick_ms_p99": float(np.percentile(t, 99)),
            "p99_over_median": float(np.percentile(t, 99) / np.median(t)),
            "osqp_iterations_mean": float(np.mean([i for i in iters if i >= 0])),
            "fallbacks": ctl.stats["fallbacks"],
        }
    out["qp_size"] = {
        "variables": ctl.nvar,
        "constraints": ctl.ncon,
        "nnz_A": int(ctl.formulation.A.nnz),
        "nnz_P": int(ctl.formulation.P.nnz),
    }
    # Iteration counts without the controller's iteration cap, so cold solves are not cut off.
    uncapped = {"max_iter": 4000}
    cold_iters = _run(
        problem, args.ticks, relinearize=True, warm_start=False, osqp_settings=uncapped
    )[2]
    warm_iters = _run(problem, args.ticks, relinearize=True, osqp_settings=uncapped)[2]
    out["osqp_iterations"] = {
        "warm_start_mean": float(np.mean([i for i in warm_iters if i >= 0])),
        "cold_start_mean": float(np.mean([i for i in cold_iters if i >= 0])),
        "failed_warm": sum(i < 0 for i in warm_iters),
        "failed_cold": sum(i < 0 for i in cold_iters),
    }

    import qpsolvers

    backends = {}
    picks = qps[len(qps) // 2 :: max(1, len(qps) // (2 * args.backend_qps))][: args.backend_qps]
    for name in qpsolvers.available_solvers:
        ms, found = [], 0
        for qp in picks:
            prob = to_qpsolvers(qp)
            t0 = time.perf_counter()
            sol = qpsolvers.solve_problem(prob, solver=name)
            ms.append((time.perf_counter() - t0) * 1e3)
            found += bool(sol.found)
        backends[name] = {"median_ms": float(np.median(ms)), "solved": found, "qps": len(picks)}
    out["qpsolvers_cold_solve"] = backends
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
