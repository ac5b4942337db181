"""The iLQR backward pass before and after the LAPACK rewrite, per pass, on real derivatives.

For the problems of ``benchmarks/ilqr_vs_crocoddyl.py`` (pendulum and cart-pole swing-ups,
150 knots, one control; the 7-DoF Panda reach, 40 knots, seven controls), takes the
derivatives along the trajectory after 3 iLQR iterations (``arm_menagerie``: the easier
reach, where no control is clamped) from the benchmark's control guess
and times :func:`mpcbox.controllers.ilqr.backward_pass.backward_pass` against the per-knot
pass it replaced (``previous_backward_pass`` below: ``numpy.linalg`` solves and the box QP at
every knot, the closed-form box step for one control), interleaved, best of ``--repeats``
rounds of ``--passes`` passes. Also records the largest relative difference of ``k``, ``K``
and the predicted decrease between the two.

    nice -n 5 python benchmarks/ilqr_backward_pass.py [--repeats 5] [--passes 20]

Prints the JSON and writes it to ``benchmarks/results/ilqr_backward_pass.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np
from ilqr_vs_crocoddyl import build

from mpcbox.controllers.ilqr.backward_pass import BackwardPass, backward_pass
from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.core.problem import Linearization, Quadratization
from mpcbox.errors import SolverError

RESULTS = Path(__file__).parent / "results" / "ilqr_backward_pass.json"


def _scalar_box_step(
    quu_reg: np.ndarray,
    qu: np.ndarray,
    qux: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    t: int,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """The single-control box step of the pass before (bit-equal to the box QP)."""
    h = quu_reg[0, 0]
    if not (np.isfinite(h) and h > 0.0):
        raise SolverError(f"Q_uu is not positive definite at knot {t}")
    k = -np.linalg.solve(quu_reg, qu)
    if low[0] <= k[0] <= high[0]:
        return k, -np.linalg.solve(quu_reg, qux), True
    return np.clip(k, low, high), np.zeros_like(qux), False


def previous_backward_pass(
    lin: Linearization,
    quad: Quadratization,
    ctrls: np.ndarray,
    ctrl_low: np.ndarray,
    ctrl_high: np.ndarray,
    regularization: float,
    k_init: np.ndarray | None = None,
    gaps: np.ndarray | None = None,
) -> BackwardPass:
    """The per-knot pass before the LAPACK one (same arguments and result)."""
    A, B = lin
    horizon, nx, nu = B.shape
    limited = bool(np.any(np.isfinite(ctrl_low)) or np.any(np.isfinite(ctrl_high)))
    k = np.zeros((horizon, nu))
    K = np.zeros((horizon, nu, nx))
    free = np.ones((horizon, nu), dtype=bool)
    vx = quad.lx[horizon].copy()
    vxx = quad.lxx[horizon].copy()
    dv1 = dv2 = 0.0
    eye = regularization * np.eye(nu)
    for t in range(horizon - 1, -1, -1):
        At, Bt = A[t], B[t]
        if gaps is not None:
            vx = vx + vxx @ gaps[t]
        vxx_b = vxx @ Bt
        qx = quad.lx[t] + At.T @ vx
        qu = quad.lu[t] + Bt.T @ vx
        qxx = quad.lxx[t] + At.T @ vxx @ At
        quu = quad.luu[t] + Bt.T @ vxx_b
        qux = quad.lux[t] + vxx_b.T @ At
        quu = 0.5 * (quu + quu.T)
        quu_reg = quu + eye
        if limited and nu == 1:
            kt, Kt, free[t] = _scalar_box_step(
                quu_reg, qu, qux, ctrl_low - ctrls[t], ctrl_high - ctrls[t], t
            )
        elif limited:
            res = solve_box_qp(
                quu_reg,
                qu,
                ctrl_low - ctrls[t],
                ctrl_high - ctrls[t],
                None if k_init is None else k_init[t],
                check=False,
            )
            if not res.ok:
                raise SolverError(f"Q_uu is not positive definite at knot {t}")
            kt = res.x
            Kt = np.zeros((nu, nx))
            if res.factor is not None:
                f = res.free
                Kt[f] = -np.linalg.solve(quu_reg[np.ix_(f, f)], qux[f])
            free[t] = res.free
        else:
            try:
                np.linalg.cholesky(quu_reg)  # positive-definiteness check
            except np.linalg.LinAlgError:
                raise SolverError(f"Q_uu is not positive definite at knot {t}") from None
            sol = -np.linalg.solve(quu_reg, np.column_stack([qu, qux]))
            kt, Kt = sol[:, 0], sol[:, 1:]
        k[t], K[t] = kt, Kt
        dv1 += float(kt @ qu)
        dv2 += 0.5 * float(kt @ quu @ kt)
        Kquu = Kt.T @ quu
        vx = qx + Kquu @ kt + Kt.T @ qu + qux.T @ kt
        vxx = qxx + Kquu @ Kt + Kt.T @ qux + qux.T @ Kt
        vxx = 0.5 * (vxx + vxx.T)
        if not (np.all(np.isfinite(vxx)) and np.all(np.isfinite(vx))):
            raise SolverError(f"non-finite value function at knot {t}")
    return BackwardPass(k, K, (dv1, dv2), free)


def best_ms(fn, args, repeats: int, passes: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(passes):
            fn(*args)
        times.append((time.perf_counter() - t0) / passes)
    return 1e3 * min(times)


def relative(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--problems", nargs="+", default=["pendulum", "cartpole", "arm", "arm_menagerie"]
    )
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--passes", type=int, default=20)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    out = {
        "machine": "2-core sandbox CPU, shared",
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "problems": {},
    }
    for name in args.problems:
        case = build(name)
        p = case["problem"]
        solver = ILQR(p, horizon=case["horizon"], threads=1)
        res = solver.solve(p.initial_state(), case["ctrls"], max_iterations=3)
        lin, quad = solver._derivatives(res.states, res.ctrls)
        call = (lin, quad, res.ctrls, solver.ctrl_low, solver.ctrl_high, 1e-6, res.k)
        new, old = backward_pass(*call), previous_backward_pass(*call)
        before, after = [], []
        for _ in range(args.repeats):  # interleaved, so that both see the same load
            before.append(best_ms(previous_backward_pass, call, 1, args.passes))
            after.append(best_ms(backward_pass, call, 1, args.passes))
        out["problems"][name] = {
            "knots": case["horizon"],
            "nx": p.nx,
            "nu": p.nu,
            "clamped_controls": int(np.count_nonzero(~new.free)),
            "before_ms_per_pass": min(before),
            "after_ms_per_pass": min(after),
            "speedup": min(before) / min(after),
            "after_us_per_knot": 1e3 * min(after) / case["horizon"],
            "relative_difference": {
                "k": relative(new.k, old.k),
                "K": relative(new.K, old.K),
                "expected": relative(np.array(new.expected), np.array(old.expected)),
                "same_free_set": bool(np.array_equal(new.free, old.free)),
            },
        }
        print(name, json.dumps(out["problems"][name]), flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
