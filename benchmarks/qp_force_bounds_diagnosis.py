"""Why QP-MPC falls under stronger noise where LQR stands: a diagnosis; JSON.

    MENAGERIE_ROOT=... python benchmarks/qp_force_bounds_diagnosis.py \\
        --json benchmarks/results/qp_force_bounds_diagnosis.json

``benchmarks/legged_noise_sweep.py`` found QP-MPC standing fewer seeds than LQR at x1.5 and
x2 of the noise recipe on every Menagerie robot. This script runs QP-MPC on two of them
(the Go2 on four feet, the G1 on two) at ``--noise`` over ``--seeds`` seeds from 100, in
lock-step, with one part of its QP changed at a time:

* ``bounded``: the task's QP-MPC with every stage's force bounds
  (``first_stage_forces="bounded"``, the tasks' default until this diagnosis);
* ``first_stage_free``: ``first_stage_forces="free"`` (the legged tasks' default now): the
  first stage's forces of touching points unbounded, later stages bounded;
* ``no_force_bounds``: the friction-pyramid and normal-force rows of every stage left
  unbounded (a patch of ``QPFormulation.vectors`` in this script, not an option of the
  controller): the forces then follow the linearized soft-contact force law, as in LQR's
  model, and only the control limits remain;
* ``no_pyramid``: only the pyramid rows unbounded (normal forces stay in ``[0, f_max]``);
* ``rigid``: ``stance_model="rigid"`` (with every stage bounded);
* ``lqr``: the task's LQR, for reference.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from json_report import finish

import mpcbox
from mpcbox.registry import task_class

CASES = {
    "go2": ("quadruped_stand", {"model": "menagerie:unitree_go2"}),
    "g1_two_feet": ("biped_stand", {"model": "menagerie:unitree_g1"}),
}
VARIANTS = ("bounded", "first_stage_free", "no_force_bounds", "no_pyramid", "rigid", "lqr")


def _unbound(variant: str) -> None:
    """Patch the QP's bounds for ``variant`` (in this worker process only)."""
    from mpcbox.controllers.qp_mpc import formulation

    cls = formulation.QPFormulation
    vectors = cls.vectors

    def patched(self, lin, state):
        q, lo, hi = vectors(self, lin, state)
        L = self.layout
        hi[L.r_fr : L.r_fn] = np.inf
        if variant == "no_force_bounds":
            lo[L.r_fn : L.r_u] = -np.inf
            hi[L.r_fn : L.r_u] = np.inf
        return q, lo, hi

    cls.vectors = patched


def run(case: str, variant: str, seed: int, noise: float, duration: float) -> dict:
    task, options = CASES[case]
    if variant in ("no_force_bounds", "no_pyramid"):
        _unbound(variant)
    problem = task_class(task)(**options)
    if variant == "lqr":
        ctrl = mpcbox.make_controller("lqr", problem)
    else:
        extra = {"first_stage_forces": "free" if variant == "first_stage_free" else "bounded"}
        if variant == "rigid":
            extra["stance_model"] = "rigid"
        ctrl = mpcbox.make_controller("qp", problem, **extra)
    res = mpcbox.simulate(problem, ctrl, duration, noise=problem.noise(scale=noise), seed=seed)
    return {
        "seed": seed,
        "outcome": res.metrics.outcome,
        "time_s": round(float(res.time[-1]), 3),
        "fallbacks": int(ctrl.stats.get("fallbacks", 0)),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--noise", type=float, default=2.0)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    started = time.perf_counter()
    out: dict = {
        "benchmark": "qp_force_bounds_diagnosis",
        "noise_scale": args.noise,
        "duration_s": args.duration,
        "seeds": list(range(100, 100 + args.seeds)),
        "cases": {},
    }
    with ProcessPoolExecutor(args.workers, max_tasks_per_child=1) as pool:  # patches die
        for case in args.cases.split(","):
            out["cases"][case] = {}
            for variant in args.variants.split(","):
                jobs = [
                    pool.submit(run, case, variant, s, args.noise, args.duration)
                    for s in out["seeds"]
                ]
                rows = [j.result() for j in jobs]
                ok = sum(r["outcome"] == "success" for r in rows)
                out["cases"][case][variant] = {"successes": ok, "runs": len(rows), "rows": rows}
                print(case, variant, f"{ok}/{len(rows)}", flush=True)
    return finish(out, args.json, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
