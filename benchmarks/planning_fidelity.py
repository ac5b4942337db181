"""Ranking fidelity of coarser planning models against the full model; prints JSON.

    python benchmarks/planning_fidelity.py [--json benchmarks/results/planning_fidelity.json]

A sampling controller only needs its planning model to *rank* candidates as the real world
would. For each task and planning variant (planning timestep, integrator, solver cap, servo
armature: ``SamplingConfig.servo_armature``; and for the G1 get-up, the planning model's
collision geoms, fitted capsules, against the world's meshes) this
scores the same candidate knots (the task's knot count and noise scale around the reference
control, over the task's horizon) from a few perturbed start states with the variant and with
the full model (the simulation model: its own timestep, integrator and converged solver),
both on the CPU in float64 (``mujoco.rollout``), and reports per variant, averaged over the
start states:

* ``spearman``: rank correlation of the two cost vectors;
* ``top10_overlap``: share of the full model's best 10 % that the variant also puts in its
  best 10 %;
* ``regret``: full-model cost of the variant's best candidate above the full model's best,
  as a share of the full model's spread (median minus best); 0 is a perfect pick.

With ``--backend warp`` the variants run on MJWarp (float32) with their solver caps;
with ``--backend cpu`` (default) the caps are dropped, since MuJoCo's solver stopped after one
or two iterations does not behave as MJWarp's.
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import mujoco
import numpy as np

from mpcbox.controllers.sampling.planning import servo_armature
from mpcbox.controllers.sampling.splines import Spline
from mpcbox.registry import task_class

#: task -> (horizon s, knots, noise, velocity perturbations of the start states, variants[,
#: task options of the reference problem, task options of the variants' problem]). A
#: variant is (planning timestep, integrator or None for the model's, solver cap or None[,
#: servo armature factor or None]); the noise is a fraction of each control range when
#: negative (the G1 get-up's 10 %).
SETUPS: dict[str, tuple] = {
    "humanoid_stand": (
        0.5,
        6,
        0.2,
        (0.0, 0.3, 0.6, 1.0),
        [
            (0.01, "euler", 1),
            (0.01, "euler", 2),
            (0.015, "euler", 1),
            (0.015, "euler", 2),
            (0.02, "euler", 1),
            (0.02, "euler", 2),
            (0.02, None, 2),
            (0.005, "euler", 1),
            (0.025, "euler", 2),
        ],
    ),
    "cartpole_swingup": (
        1.0,
        5,
        0.4,
        (0.0, 1.0, 2.0, 3.0),
        [(0.02, None, None), (0.03, None, None), (0.04, None, None), (0.05, None, None)],
    ),
    # Menagerie's G1 (MENAGERIE_ROOT): the world's meshes against capsule planning models
    # (``G1Getup(planning_geoms="capsules")``, the default); its task config plans at 0.02 s,
    # implicitfast, with servo_armature=0.5 (0.01 s without armature before).
    "g1_getup": (
        0.6,
        6,
        -0.1,
        (0.0, 0.3, 0.6),
        [
            (0.002, None, None, None),
            (0.01, None, None, None),
            (0.01, None, None, 1.0),
            (0.015, None, None, 1.0),
            (0.02, None, None, None),
            (0.02, None, None, 0.5),
            (0.02, None, None, 1.0),
            (0.02, None, None, 2.0),
            (0.025, None, None, 1.0),
            (0.03, None, None, 1.0),
        ],
        {"planning_geoms": "all"},
        {"planning_geoms": "capsules"},
    ),
}

INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER}


_WARP: dict = {}


def warp_costs(problem, dt, integrator, cap, armature, state, knots, horizon) -> np.ndarray:
    """Costs ``(N,)`` of knots ``(N, K, nu)`` on one planning variant (MJWarp, float32)."""
    import mpcbox

    key = (id(problem), dt, integrator, cap, armature, knots.shape)
    if key not in _WARP:
        _WARP[key] = mpcbox.make_controller(
            "ps",
            problem,
            backend="warp",
            num_samples=knots.shape[0],
            num_knots=knots.shape[1],
            horizon=horizon,
            planning_timestep=dt,
            planning_integrator=integrator,
            solver_iterations=cap,
            servo_armature=armature,
        )
    ctrl = _WARP[key]
    out = ctrl.backend.evaluate(state, ctrl.problem.clip_ctrl(knots))
    bad = out.overflow[:, 0] | out.nonfinite[:, 0] | ~np.isfinite(out.costs[:, 0])
    return np.where(bad, np.inf, out.costs[:, 0])


def costs(problem, dt, integrator, cap, armature, state, knots, horizon) -> np.ndarray:
    """Costs ``(N,)`` of knots ``(N, K, nu)`` on one planning variant (CPU, float64)."""
    p = problem.with_planning_timestep(dt)
    opt = p.planning_model.opt
    if integrator is not None:
        opt.integrator = INTEGRATORS[integrator]
    if cap is not None:
        opt.iterations = cap
    if armature is not None:
        servo_armature(p.planning_model, armature)
    steps = round(horizon / dt)
    spline = Spline(knots.shape[1], steps * dt, "cubic")
    weights = spline.weights(np.arange(steps) * dt)
    ctrls = p.clip_ctrl(np.einsum("tk,nkj->ntj", weights, knots))
    with np.errstate(all="ignore"):
        out = p.rollout_cost(p.rollout(state, ctrls))
    return np.where(np.isfinite(out), out, np.inf)


def rank(x: np.ndarray) -> np.ndarray:
    return np.argsort(np.argsort(x, kind="stable"), kind="stable").astype(float)


def compare(ref: np.ndarray, var: np.ndarray) -> dict[str, float]:
    n = len(ref)
    top = max(1, n // 10)
    best_ref = set(np.argsort(ref)[:top])
    best_var = set(np.argsort(var)[:top])
    pick = int(np.argmin(var))
    spread = float(np.median(ref) - ref.min()) or 1.0
    return {
        "spearman": float(np.corrcoef(rank(ref), rank(var))[0, 1]),
        "top10_overlap": len(best_ref & best_var) / top,
        "regret": float((ref[pick] - ref.min()) / spread),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=128)
    parser.add_argument("--tasks", default=",".join(SETUPS))
    parser.add_argument("--machine", default="2-core sandbox CPU, shared")
    parser.add_argument("--backend", default="cpu", help="cpu: MuJoCo; warp: MJWarp (caps)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    report: dict = {
        "machine": args.machine,
        "platform": platform.platform(),
        "backend": args.backend,
        "tasks": {},
    }
    variant_costs = warp_costs if args.backend == "warp" else costs
    for task in args.tasks.split(","):
        horizon, nknots, noise, perturb, variants, *options = SETUPS[task]
        variants = [(*v, None)[:4] for v in variants]
        if args.backend == "cpu":  # MuJoCo's capped solver is not MJWarp's: no caps here
            variants = list({(dt, integ, None, arm): 0 for dt, integ, _, arm in variants})
        problem = task_class(task)(**(options[0] if options else {}))
        planner = task_class(task)(**options[1]) if options else problem
        rng = np.random.default_rng(0)
        ref_u = problem.clip_ctrl(problem.ctrl_ref)
        if noise < 0:  # a fraction of each control range
            noise = -noise * np.diff(problem.model.actuator_ctrlrange, axis=1)[:, 0]
        rows: dict[str, list[dict]] = {}
        for scale in perturb:
            state = problem.initial_state().copy()
            state[problem.nq : problem.nq + problem.nv] += rng.normal(0, scale, problem.nv)
            knots = ref_u + noise * rng.standard_normal((args.samples, nknots, problem.nu))
            knots[0] = ref_u
            knots = problem.clip_ctrl(knots)
            ref = costs(problem, problem.dt, None, None, None, state, knots, horizon)
            for dt, integ, cap, arm in variants:
                name = f"dt{dt}_{integ or 'model'}_cap{cap or 'none'}"
                name += f"_armature{arm:g}" if arm is not None else ""
                var = variant_costs(planner, dt, integ, cap, arm, state, knots, horizon)
                rows.setdefault(name, []).append(compare(ref, var))
        report["tasks"][task] = {
            "task_options": {"reference": options[0], "variants": options[1]} if options else {},
            "full_model": {
                "timestep": problem.dt,
                "integrator": int(problem.model.opt.integrator),
                "iterations": int(problem.model.opt.iterations),
            },
            "horizon_s": horizon,
            "variants": {
                name: {
                    "steps": round(horizon / float(name.split("_")[0][2:])),
                    **{k: float(np.mean([r[k] for r in rs])) for k in rs[0]},
                    "min_spearman": float(min(r["spearman"] for r in rs)),
                }
                for name, rs in rows.items()
            },
        }
        print(json.dumps({task: report["tasks"][task]}, indent=1), flush=True)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
