"""Solver settings on hard QP-MPC ticks: the QPs after a large push, solved offline; prints JSON.

For each robot a closed-loop run (1 N m torque noise, seed 2, a 0.1 s push at 0.5 s on the
root body, 2 s) with the controller's defaults exports every tick's QP
(``QPMPC(export_dir=...)``). The ``--ticks`` QPs from the push on are then solved in order by
each variant: OSQP variants on one persistent solver, each warm-started from its own previous
solution (not shifted, unlike the controller), and Clarabel from scratch. Reported: failed
solves, median iterations, median and p90 solve time (one thread). The same closed loop is
then run again with ``rescue="clarabel"`` (Clarabel re-solves what OSQP fails): survival,
failed, rescued and fallen-back solves, median and p99 time per call.

Pushes: the humanoid on two feet 110 N forward (past its 100 N limit), Menagerie's A1 60 N
and ANYmal C 200 N (quadrupeds from ``quadruped_problem.py``, need ``MENAGERIE_ROOT``)::

    MENAGERIE_ROOT=/work/menagerie nice -n 5 python benchmarks/qp_settings_sweep.py \\
        --json benchmarks/results/qp_settings_sweep.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

#: Robot -> (push force along x in N, pushed body or None for the quadruped's root).
PUSHES: dict[str, tuple[float, str | None]] = {
    "humanoid_two_feet": (110.0, "torso"),
    "unitree_a1": (60.0, None),
    "anybotics_anymal_c": (200.0, None),
}


def variants() -> dict[str, dict]:
    """OSQP settings of each variant (``OSQP_DEFAULTS`` plus overrides)."""
    from mpcbox.controllers.qp_mpc.solvers import OSQP_DEFAULTS as O

    return {
        "default (rho 3, 400 iterations)": dict(O),
        "adaptive rho": {**O, "adaptive_rho": True},
        "rho 10": {**O, "rho": 10.0},
        "rho 1": {**O, "rho": 1.0},
        "eps 1e-3": {**O, "eps_abs": 1e-3, "eps_rel": 1e-3},
        "polishing": {**O, "polishing": True},
        "2000 iterations": {**O, "max_iter": 2000},
        "adaptive rho, 2000 iterations": {**O, "adaptive_rho": True, "max_iter": 2000},
    }


def collect(robot: str, folder: Path | None, **options) -> dict:
    """Run the pushed closed loop, exporting its QPs to ``folder`` (unless ``None``)."""
    from quadruped_problem import QuadrupedStand, torque_noise

    from mpcbox.controllers.qp_mpc.controller import QPMPC
    from mpcbox.registry import task_class
    from mpcbox.sim.disturbances import Push
    from mpcbox.sim.simulation import simulate

    force, body = PUSHES[robot]
    if robot.startswith("humanoid"):
        problem = task_class(robot)(threads=1)
        config = problem.controller_configs["qp"]
    else:
        problem = QuadrupedStand(robot, threads=1)
        config, body = None, problem.root
    ctl = QPMPC(problem, config, export_dir=folder, **options)
    push = Push(force=(force, 0.0, 0.0), start=0.5, duration=0.1, body=body)
    res = simulate(problem, ctl, 2.0, noise=torque_noise(problem.model), pushes=[push], seed=2)
    t = res.compute_times[1:] * 1e3
    stats = ctl.stats
    return dict(
        push_n=force,
        survived=bool(res.survived),
        solves=int(stats["solves"]),
        failed_solves=int(stats["failed_solves"]),
        rescued_solves=int(stats["rescued_solves"]),
        fallbacks=int(stats["fallbacks"]),
        tick_ms_median=float(np.median(t)),
        tick_ms_p99=float(np.percentile(t, 99)),
        first_tick=round(0.5 / ctl.period),
    )


def sweep(qps: list, settings: dict) -> dict:
    """Solve ``qps`` in order on one OSQP solver with ``settings``."""
    import osqp

    solver, prev = None, None
    fails, iters, times = 0, [], []
    for qp in qps:
        if solver is None:
            solver = osqp.OSQP()
            solver.setup(qp.P, qp.q, qp.A, qp.l, qp.u, **settings)
        else:
            solver.update(q=qp.q, l=qp.l, u=qp.u, Ax=qp.A.data)
        if prev is not None:
            solver.warm_start(x=prev[0], y=prev[1])
        t0 = time.perf_counter()
        res = solver.solve(raise_error=False)
        times.append(time.perf_counter() - t0)
        ok = res.info.status_val in (
            osqp.SolverStatus.OSQP_SOLVED,
            osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
        )
        if ok:
            prev = (res.x, res.y)
            iters.append(res.info.iter)
        else:
            fails += 1
    return _summary(fails, len(qps), iters, times)


def clarabel(qps: list) -> dict:
    """Solve ``qps`` with Clarabel through ``qpsolvers``, each from scratch."""
    import qpsolvers

    from mpcbox.controllers.qp_mpc.solvers import to_qpsolvers

    fails, times = 0, []
    for qp in qps:
        problem = to_qpsolvers(qp)
        t0 = time.perf_counter()
        sol = qpsolvers.solve_problem(problem, solver="clarabel")
        times.append(time.perf_counter() - t0)
        fails += not sol.found
    return _summary(fails, len(qps), [], times)


def _summary(fails: int, n: int, iters: list, times: list) -> dict:
    t = np.asarray(times) * 1e3
    return dict(
        failed=fails,
        qps=n,
        iterations_median=float(np.median(iters)) if iters else None,
        solve_ms_median=float(np.median(t)),
        solve_ms_p90=float(np.percentile(t, 90)),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", default=",".join(PUSHES))
    parser.add_argument("--ticks", type=int, default=40, help="QPs from the push on")
    parser.add_argument("--json", help="also write the JSON here")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    from mpcbox.controllers.qp_mpc.solvers import load_qp

    t0 = time.perf_counter()
    robots = {}
    for robot in args.robots.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            info = collect(robot, Path(tmp))
            files = sorted(Path(tmp).glob("tick_*.npz"))
            first = info["first_tick"]
            qps = [load_qp(f) for f in files[first : first + args.ticks]]
        rows = {name: sweep(qps, s) for name, s in variants().items()}
        rows["clarabel (qpsolvers, cold)"] = clarabel(qps)
        rescued = collect(robot, None, rescue="clarabel")
        robots[robot] = dict(
            closed_loop={"default": info, "rescue='clarabel'": rescued},
            variables=int(qps[0].P.shape[0]),
            variants=rows,
        )
        print(robot, json.dumps(robots[robot]), file=sys.stderr, flush=True)
    out = dict(
        benchmark="qp_settings_sweep",
        machine=f"2-core sandbox CPU, shared ({platform.processor() or platform.machine()}); "
        "one thread",
        wall_s=time.perf_counter() - t0,
        robots=robots,
    )
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
