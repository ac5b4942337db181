"""Which planning model makes humanoid sampling MPC fast on the GPU, and does it still stand?

    PYTHONUNBUFFERED=1 python benchmarks/sampling_planning_model.py [--quick]

The planning model is the controller's own (hydrax style): a copy of the simulation model
that may cap the constraint solver, shorten the line search or integrate with Euler instead
of implicitfast. For each variant this prints (and writes to
``$OUT/sampling_planning_model.json``):

* the full tick and the raw MJWarp step throughput at N = 2048 candidates x 32 steps of
  0.005 s (the sweep of ``benchmarks/sampling.py``), so ``efficiency = in-loop / raw``
  (raw uses the same solver loop: caps up to 3 iterations are unrolled in the graph);
* how well the variant ranks candidates: the rank correlation of 64 candidates' costs with
  those of the full simulation model (CPU backend, float64);
* closed loop (``--closed-loop variant:controller:seed,...``): the controller with
  ``HumanoidStand.controller_configs`` plus the variant, 10 s under the published
  actuator-noise recipe.

Variant keys: ``solver_iterations`` (cap), ``conditional`` (keep the conditional while node
for a low cap), ``ls_iterations`` (the line search's limit; a compile-time constant in
MJWarp), ``integrator`` and ``solver``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from mpcbox.config import config_options

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sampling import HORIZON_STEPS, _controller, _problem, _start_state, raw_throughput, time_ticks

EULER = {"planning_integrator": "euler"}
CARTPOLE_OFF = {"planning_disable": ("constraint", "eulerdamp")}

#: name -> variant: controller options (``solver_iterations``, ``planning_integrator``,
#: ``planning_disable``, ``planning_timestep``) plus ``task``, ``steps``, ``n`` and the
#: model-level keys ``ls_iterations``, ``solver`` and ``conditional``.
VARIANTS: dict[str, dict] = {
    "full": {},
    "cap1": {"solver_iterations": 1},
    "cap2": {"solver_iterations": 2},
    "cap3": {"solver_iterations": 3},
    "cap2_conditional": {"solver_iterations": 2, "conditional": True},
    "euler": {**EULER},
    "euler_cap1": {**EULER, "solver_iterations": 1},
    "euler_cap2": {**EULER, "solver_iterations": 2},
    "euler_cap3": {**EULER, "solver_iterations": 3},
    "euler_cap2_ls8": {**EULER, "solver_iterations": 2, "ls_iterations": 8},
    "cg_cap3": {"solver": "cg", "solver_iterations": 3},
    "cg_cap5": {"solver": "cg", "solver_iterations": 5},
    "euler_cg_cap3": {**EULER, "solver": "cg", "solver_iterations": 3},
    # The cart-pole (Euler already; no contacts): N = 1024, 32 steps of 0.01 s, and its tuned
    # controllers' 50 steps of 0.02 s.
    "cartpole": {"task": "cartpole"},
    "cartpole_no_eulerdamp": {"task": "cartpole", "planning_disable": ("eulerdamp",)},
    "cartpole_no_constraint": {"task": "cartpole", "planning_disable": ("constraint",)},
    "cartpole_off": {"task": "cartpole", **CARTPOLE_OFF},
    "cartpole_tuned": {"task": "cartpole", "planning_timestep": 0.02, "steps": 50},
    "cartpole_tuned_off": {
        "task": "cartpole", "planning_timestep": 0.02, "steps": 50, **CARTPOLE_OFF
    },
}  # fmt: skip

CONTROLLER_KEYS = ("solver_iterations", "planning_integrator", "planning_disable")


def variant_problem(base, spec: dict):
    """A copy of ``base`` with the variant's model-level planning options."""
    import mujoco

    p = base.with_planning_timestep(spec.get("planning_timestep", base.dt))
    if "ls_iterations" in spec:
        p.planning_model.opt.ls_iterations = int(spec["ls_iterations"])
    if spec.get("solver") == "cg":
        p.planning_model.opt.solver = int(mujoco.mjtSolver.mjSOL_CG)
    return p


def controller_options(spec: dict) -> dict:
    return {k: v for k, v in spec.items() if k in CONTROLLER_KEYS}


def unroll(ctrl, spec: dict) -> None:
    """Force the conditional solver loop (the backend unrolls low caps by itself)."""
    if spec.get("conditional"):
        ctrl.backend.m.opt.graph_conditional = True


def rank_corr(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    return float(np.corrcoef(ra, rb)[0, 1])


def measure(name: str, spec: dict, quick: bool, out: dict) -> None:
    task = spec.get("task", "humanoid")
    base = _problem(task)
    p = variant_problem(base, spec)
    steps = spec.get("steps", HORIZON_STEPS)
    n = 16 if quick else spec.get("n", 1024 if task == "cartpole" else 2048)
    state = _start_state(base, task)
    ctrl = _controller(p, n, steps=steps, **controller_options(spec))
    unroll(ctrl, spec)
    tick, backend, ev = time_ticks(ctrl, state)
    be = ctrl.backend
    model = be.models[0]
    conditional = bool(be.m.opt.graph_conditional)
    kw = dict(model=model, steps=steps, graph_conditional=conditional)
    raw = raw_throughput(p, n, be.nconmax, be.njmax, **kw)
    raw_div = raw_throughput(p, n, be.nconmax, be.njmax, diverse=0.1, **kw)
    # Ranking quality against the full simulation model (CPU backend, float64).
    rng = np.random.default_rng(0)
    x0 = state.copy()
    x0[base.nq :] += rng.normal(0, 0.1, base.nv + base.na)
    small = _controller(p, 64, steps=steps, **controller_options(spec))
    unroll(small, spec)
    ref = _controller(base, 64, backend="cpu", steps=round(steps * p.dt / base.dt))
    cand = base.clip_ctrl(base.ctrl_ref + rng.normal(0, 0.2, (64, 4, base.nu)))
    a = ref.backend.evaluate(x0, cand).costs[:, 0]
    b = small.backend.evaluate(x0, cand).costs[:, 0]
    small.close()
    ws = n * steps
    row = {
        "variant": name,
        "spec": spec,
        "N": n,
        "T": steps,
        "planning_timestep": float(model.opt.timestep),
        "tick_ms": tick * 1e3,
        "ticks_per_s": 1.0 / tick,
        "backend_ms": backend * 1e3,
        "raw_world_steps_per_s": raw,
        "raw_diverse_world_steps_per_s": raw_div,
        "raw_ms": ws / raw * 1e3,
        "efficiency": ws / tick / raw,
        "efficiency_vs_diverse_raw": ws / tick / raw_div,
        "rank_corr_vs_full": rank_corr(a, b),
        "median_rel_cost_diff_vs_full": float(
            np.median(np.abs(a - b) / np.maximum(np.abs(a), 1e-9))
        ),
        "excluded": int((ev.overflow | ev.nonfinite).sum()),
        "nconmax": be.nconmax,
        "njmax": be.njmax,
        "graph_conditional": conditional,
    }
    ctrl.close()
    out["variants"].append(row)
    print(json.dumps(row), flush=True)


def closed_loop(name: str, spec: dict, seed: int, quick: bool, out: dict, controller: str):
    """Humanoid: 10 s under the recipe noise. Cart-pole: 8 s swing-up with N = 1024."""
    import mpcbox

    task = spec.get("task", "humanoid")
    base = _problem(task)
    p = variant_problem(base, spec)
    opts = dict(config_options(base.controller_configs[controller]), backend="warp", seed=seed)
    opts.update(controller_options(spec))
    if task == "cartpole":
        opts["num_samples"] = 16 if quick else 1024
    ctrl = mpcbox.make_controller(controller, p, **opts)
    unroll(ctrl, spec)
    t0 = time.perf_counter()
    if task == "cartpole":
        res = mpcbox.simulate(base, ctrl, 0.2 if quick else 8.0)
        err = np.array([base.upright_error(s) for s in res.states])
        extra = {
            "upright_by_3s_and_held": bool(np.all(err[res.time >= 3.0] < 0.3)),
            "max_upright_error_after_3s": float(err[res.time >= 3.0].max(initial=0.0)),
        }
    else:
        res = mpcbox.simulate(base, ctrl, 0.2 if quick else 10.0, noise=base.noise(), seed=seed)
        extra = {
            "survived": bool(res.metrics.survived),
            "time_to_fall_s": float(res.metrics.time_to_fall),
            "tilt_rms_deg": float(res.metrics.measures["tilt_rms_deg"]),
            "com_deviation_rms_m": float(res.metrics.measures["com_deviation_rms_m"]),
        }
    row = {
        "variant": name,
        "controller": controller,
        "seed": seed,
        **extra,
        "compute_mean_ms": float(res.metrics.compute_mean_ms),
        "wall_s": time.perf_counter() - t0,
        "stats": ctrl.stats,
    }
    ctrl.close()
    out["closed_loop"].append(row)
    print(json.dumps(row), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (CPU smoke test)")
    ap.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated names")
    ap.add_argument(
        "--closed-loop", default="", help="variant:controller:seed,... to run in closed loop"
    )
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    import warp as wp

    wp.config.quiet = True
    wp.init()
    out_dir = Path(args.out or os.environ.get("OUT", "benchmarks/results"))
    out_path = out_dir / "sampling_planning_model.json"
    out: dict = {"device": wp.get_device().name, "variants": [], "closed_loop": [], "errors": {}}
    for name in [v for v in args.variants.split(",") if v]:
        try:
            measure(name, VARIANTS[name], args.quick, out)
        except Exception:
            out["errors"][name] = traceback.format_exc()
            print(out["errors"][name], flush=True)
        out_path.write_text(json.dumps(out, indent=1, default=float))
    for case in [v for v in args.closed_loop.split(",") if v]:
        name, controller, seed = case.split(":")
        try:
            closed_loop(name, VARIANTS[name], int(seed), args.quick, out, controller)
        except Exception:
            out["errors"][f"closed_loop_{case}"] = traceback.format_exc()
            print(out["errors"][f"closed_loop_{case}"], flush=True)
        out_path.write_text(json.dumps(out, indent=1, default=float))
    print(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
