"""QP-MPC's QPs on Menagerie robots: OSQP (the task's settings) against PIQP's sparse
interior-point method, with its general and its multistage KKT factorization.

For each robot the task's QP-MPC (no solve-time budget) runs ``--duration`` s under the
noise recipe (seed 1), exporting every tick's QP; the exported QPs are then solved in
order by one persistent solver per variant (OSQP warm-started from its previous solution;
PIQP updated in place). Rows with ``l = u`` are PIQP's equalities, the rest its two-sided
inequalities. Prints and stores per variant the solve time, iterations, solves reported
solved and the largest relative objective gap to PIQP's general factorization. Needs
``pip install piqp`` (not a dependency of mpcbox)::

    MENAGERIE_ROOT=... OMP_NUM_THREADS=1 python benchmarks/qp_interior_point.py \\
        --robots unitree_g1,pal_talos/scene_motor,unitree_go2
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from menagerie_robots import chosen_robots
from qp_rho_robots import export

OUT = Path(__file__).parent / "results" / "qp_interior_point.json"
KKT_SOLVERS = ("sparse_ldlt", "sparse_multistage")


def _hessian(qp) -> sp.csc_matrix:
    upper = sp.triu(qp.P)
    return (upper + sp.triu(upper, 1).T).tocsc()


def solve_osqp(qps: list, settings: dict) -> list[tuple]:
    import osqp

    solver, first = osqp.OSQP(), qps[0]
    solver.setup(first.P, first.q, first.A, first.l, first.u, **settings)
    out = []
    for qp in qps:
        solver.update(q=qp.q, l=qp.l, u=qp.u, Ax=qp.A.data)
        start = time.perf_counter()
        res = solver.solve(raise_error=False)
        out.append(
            (time.perf_counter() - start, res.info.iter, res.info.status_val in (1, 2), res.x)
        )
    return out


def solve_piqp(qps: list, kkt: str, eps: float) -> list[tuple]:
    import piqp

    solver = piqp.SparseSolver()
    solver.settings.eps_abs = solver.settings.eps_rel = eps
    solver.settings.kkt_solver = piqp.KKTSolver.__members__[kkt]
    out = []
    for i, qp in enumerate(qps):
        eq = qp.u - qp.l <= 1e-12
        rows = qp.A.tocsr()
        parts = dict(A=rows[eq].tocsc(), b=qp.u[eq], G=rows[~eq].tocsc())
        parts.update(h_l=qp.l[~eq], h_u=qp.u[~eq])
        start = time.perf_counter()
        if i == 0:
            solver.setup(_hessian(qp), qp.q, **parts)
        else:
            solver.update(c=qp.q, **parts)
        status = solver.solve()
        x = solver.result.x.copy()
        out.append(
            (time.perf_counter() - start, solver.result.info.iter, status == piqp.PIQP_SOLVED, x)
        )
    return out


def summary(qps: list, out: list[tuple], reference: list[float]) -> dict:
    ms = np.array([o[0] for o in out]) * 1e3
    gaps = [
        abs(0.5 * x @ (_hessian(qp) @ x) + qp.q @ x - ref) / max(1.0, abs(ref))
        for qp, (_, _, ok, x), ref in zip(qps, out, reference)
        if ok and x is not None
    ]
    return {
        "solve_ms_p50": round(float(np.median(ms)), 2),
        "solve_ms_p90": round(float(np.percentile(ms, 90)), 2),
        "solve_ms_max": round(float(ms.max()), 2),
        "iterations_p50": float(np.median([o[1] for o in out])),
        "solved": int(sum(o[2] for o in out)),
        "max_relative_objective_gap": float(max(gaps)) if gaps else None,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="unitree_g1,pal_talos/scene_motor,unitree_go2")
    parser.add_argument("--duration", type=float, default=0.3)
    parser.add_argument("--eps", type=float, default=1e-5, help="PIQP's eps_abs and eps_rel")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args()
    results: dict = {
        "command": "MENAGERIE_ROOT=... OMP_NUM_THREADS=1 python benchmarks/qp_interior_point.py "
        f"--robots {args.robots} --duration {args.duration} --eps {args.eps}",
        "machine": f"{platform.processor() or platform.machine()}, one thread",
        "robots": {},
    }
    for robot in chosen_robots(parser, args):
        with tempfile.TemporaryDirectory() as tmp:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                info = export(robot, Path(tmp), args.duration)
            from mpcbox.controllers.qp_mpc.solvers import load_qp

            qps = [load_qp(f) for f in sorted(Path(tmp).glob("tick_*.npz"))]
        runs = {"osqp (task settings)": solve_osqp(qps, info["settings"])}
        for kkt in KKT_SOLVERS:
            runs[f"piqp {kkt}"] = solve_piqp(qps, kkt, args.eps)
        reference = [
            0.5 * x @ (_hessian(qp) @ x) + qp.q @ x
            for qp, (_, _, _, x) in zip(qps, runs["piqp sparse_ldlt"])
        ]
        row = {
            "variables": qps[0].A.shape[1],
            "rows": qps[0].A.shape[0],
            "nonzeros_A": int(qps[0].A.nnz),
            "ticks": len(qps),
            **{name: summary(qps, out, reference) for name, out in runs.items()},
        }
        results["robots"][robot] = row
        print(robot, json.dumps(row), flush=True)
        Path(args.out).write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
