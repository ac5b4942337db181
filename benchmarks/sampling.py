"""Sampling MPC on MuJoCo Warp: throughput, efficiency, CPU comparison and GPU closed loops.

Run on the GPU machine (see ../shared/device/README.md)::

    PYTHONUNBUFFERED=1 python benchmarks/sampling.py            # everything, JSON to $OUT
    python benchmarks/sampling.py --quick                       # small sweep (CPU smoke test)

Prints one JSON document and writes it to ``$OUT/sampling_gpu.json`` (or ``--out``). Each
section is written as soon as it finishes, and a failing section records its error instead of
stopping the run. Measured:

* ``first_tick``: cold (empty kernel cache) and warm (fresh process, cached kernels) time from
  building a warp-backend controller to its first tick;
* ``sweep``: for the humanoid and the cart-pole, ticks/s and world-steps/s of the full tick
  (noise sampling, upload, graph replay, read-back, update) and of the backend alone, against
  ``N``, with ``T = 32`` planning steps. ``humanoid`` plans on the planning model of the
  humanoid's tuned MPPI/CEM (``HumanoidStand.controller_configs``: Euler, one solver
  iteration), ``humanoid_full`` on the full simulation model; ``cartpole_coarse`` covers the
  cart-pole's horizon on a 0.02 s planning model;
* ``raw``: MJWarp step throughput on the controller's planning model for the same ``N`` (a
  CUDA graph of ``T`` steps from a reset state), with identical worlds
  (``efficiency = in-loop world-steps/s / raw world-steps/s``) and with a different control
  per world (``efficiency_vs_diverse_raw``);
* ``cpu_rollout``: :func:`mujoco.rollout` on all host cores (the CPU backend, full model)
  for the same candidates and horizon, and the speed-ups of the warp tick on the task's
  planning model and on the full model;
* ``closed_loop``: the tasks' tuned sampling controllers (``controller_configs``) on the
  humanoid standing (MPPI and CEM three seeds, predictive sampling two) and on one leg under
  the published actuator-noise recipe, 10 s each.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from mpcbox.config import config_options

_T0 = time.perf_counter()
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

HORIZON_STEPS = 32
#: Planning-model options of the humanoid's tuned sampling controllers (MPPI and CEM).
HUMANOID_PLANNING_KEYS = ("planning_integrator", "solver_iterations")


def humanoid_planning() -> dict[str, Any]:
    """The planning model of ``HumanoidStand.controller_configs["mppi"]``."""
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    opts = config_options(HumanoidStand.controller_configs["mppi"])
    return {k: opts[k] for k in HUMANOID_PLANNING_KEYS if k in opts}


def _problem(task: str):
    if task == "humanoid":
        from mpcbox.tasks.humanoid.stand import HumanoidStand

        return HumanoidStand()
    from mpcbox.tasks.swingup import CartpoleSwingup

    return CartpoleSwingup()


def _start_state(problem, task: str) -> np.ndarray:
    x = problem.initial_state().copy()
    if task == "cartpole":
        x[1] = np.pi - 0.3
    return x


def _controller(problem, n: int, backend: str = "warp", steps: int = HORIZON_STEPS, **kw):
    from mpcbox.controllers.sampling import PredictiveSampling

    dt = kw.get("planning_timestep") or problem.dt
    return PredictiveSampling(
        problem,
        num_samples=n,
        horizon=steps * dt,
        num_knots=4,
        noise_scale=0.1,
        backend=backend,
        **kw,
    )


def first_tick(task: str) -> dict[str, float]:
    """Seconds to build a warp controller and run its first tick (compiles if cold)."""
    t0 = time.perf_counter()
    problem = _problem(task)
    t1 = time.perf_counter()
    ctrl = _controller(problem, 256, **(humanoid_planning() if task == "humanoid" else {}))
    ctrl.plan(_start_state(problem, task), 0.0)
    t2 = time.perf_counter()
    return {"problem_s": t1 - t0, "controller_and_first_tick_s": t2 - t1, "total_s": t2 - t0}


def time_ticks(ctrl, state: np.ndarray, seconds: float = 1.5, max_ticks: int = 200):
    """Mean seconds per full tick and per backend evaluation."""
    ctrl.plan(state, 0.0)
    ctrl.plan(state, 0.0)
    ticks, t0 = 0, time.perf_counter()
    while ticks < max_ticks and (ticks < 5 or time.perf_counter() - t0 < seconds):
        ctrl.plan(state, 0.0)
        ticks += 1
    tick = (time.perf_counter() - t0) / ticks
    cand = ctrl.problem.clip_ctrl(ctrl.sample())
    evals, t0 = 0, time.perf_counter()
    while evals < max_ticks and (evals < 5 or time.perf_counter() - t0 < seconds):
        ev = ctrl.backend.evaluate(state, cand)
        evals += 1
    backend = (time.perf_counter() - t0) / evals
    return tick, backend, ev


def raw_throughput(
    problem,
    n: int,
    nconmax: int,
    njmax: int,
    reps: int = 20,
    model=None,
    diverse: float = 0.0,
    steps: int = HORIZON_STEPS,
    graph_conditional: bool = True,
) -> float:
    """World-steps/s of ``mjw.step`` alone: a graph of T steps from a reset state.

    Every world holds the reference control (identical worlds), or with ``diverse > 0`` its
    own constant control drawn around it with that standard deviation (as different
    candidates make the worlds' constraint solvers take different iteration counts).
    """
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    model = problem.planning_model if model is None else model
    data = mujoco.MjData(model)
    problem.set_state(data, problem.initial_state())
    data.ctrl[:] = problem.clip_ctrl(problem.ctrl_ref)
    mujoco.mj_forward(model, data)
    m = mjw.put_model(model)
    m.opt.warn_overflow = 0
    m.opt.graph_conditional = graph_conditional
    d = mjw.put_data(model, data, nworld=n, nconmax=nconmax, njmax=njmax)
    if diverse > 0:
        rng = np.random.default_rng(0)
        ctrl = problem.ctrl_ref + rng.normal(0.0, diverse, (n, problem.nu))
        d.ctrl.assign(problem.clip_ctrl(ctrl).astype(np.float32))
    qpos0, qvel0 = wp.clone(d.qpos), wp.clone(d.qvel)

    def run():
        wp.copy(d.qpos, qpos0)
        wp.copy(d.qvel, qvel0)
        for _ in range(steps):
            mjw.step(m, d)

    run()
    wp.synchronize()
    graph = None
    if wp.get_device().is_cuda:
        with wp.ScopedCapture() as cap:
            run()
        graph = cap.graph
    wp.synchronize()
    t0 = time.perf_counter()
    for _ in range(reps):
        if graph is not None:
            wp.capture_launch(graph)
        else:
            run()
    wp.synchronize()
    return n * steps * reps / (time.perf_counter() - t0)


def sweep(
    task: str,
    sizes: list[int],
    out: dict,
    key: str | None = None,
    steps: int = HORIZON_STEPS,
    **options,
) -> None:
    """Tick and backend timings against ``N``; ``options`` go to the controller."""
    problem = _problem(task)
    state = _start_state(problem, task)
    rows = []
    out.setdefault("sweep", {})[key or task] = rows
    for n in sizes:
        ctrl = _controller(problem, n, steps=steps, **options)
        tick, backend, ev = time_ticks(ctrl, state)
        be = ctrl.backend
        # Raw MJWarp on the controller's own planning model (same timestep, solver options).
        model = be.models[0]
        # The same solver loop as the controller's graph (unrolled when capped low).
        cond = bool(be.m.opt.graph_conditional)
        raw = raw_throughput(
            problem, n, be.nconmax, be.njmax, model=model, steps=steps, graph_conditional=cond
        )
        raw_div = raw_throughput(
            problem,
            n,
            be.nconmax,
            be.njmax,
            model=model,
            diverse=0.1,
            steps=steps,
            graph_conditional=cond,
        )
        world_steps = n * steps
        row = {
            "N": n,
            "T": steps,
            "planning_timestep": float(model.opt.timestep),
            "options": options,
            "tick_ms": tick * 1e3,
            "ticks_per_s": 1.0 / tick,
            "backend_ms": backend * 1e3,
            "world_steps_per_s": world_steps / tick,
            "backend_world_steps_per_s": world_steps / backend,
            "raw_world_steps_per_s": raw,
            "raw_diverse_world_steps_per_s": raw_div,
            "efficiency": (world_steps / tick) / raw,
            "backend_efficiency": (world_steps / backend) / raw,
            "efficiency_vs_diverse_raw": (world_steps / tick) / raw_div,
            "nconmax": be.nconmax,
            "njmax": be.njmax,
            "excluded": int((ev.overflow | ev.nonfinite).sum()),
            "stats": ctrl.stats,
        }
        rows.append(row)
        print(json.dumps({key or task: {k: v for k, v in row.items() if k != "stats"}}), flush=True)
        ctrl.close()


def cpu_rollout(
    task: str,
    sizes: list[int],
    warp_rows: list[dict],
    out: dict,
    warp_full_rows: list[dict] | None = None,
) -> None:
    """The CPU backend (mujoco.rollout on all cores, the full model) for the same candidates
    and horizon; speed-ups of the warp tick on the task's planning model (``warp_rows``) and
    on the same full model (``warp_full_rows``)."""
    problem = _problem(task)
    state = _start_state(problem, task)
    rows = []
    out.setdefault("cpu_rollout", {})[task] = rows
    for n in sizes:
        ctrl = _controller(problem, n, backend="cpu")
        cand = problem.clip_ctrl(_cands(ctrl))
        ctrl.backend.evaluate(state, cand)
        reps, t0 = 0, time.perf_counter()
        while reps < 3 or time.perf_counter() - t0 < 2.0:
            ctrl.backend.evaluate(state, cand)
            reps += 1
        sec = (time.perf_counter() - t0) / reps
        ctrls = ctrl.backend.controls(cand)
        t0 = time.perf_counter()
        problem.rollout(state, ctrls)
        roll = time.perf_counter() - t0
        warp = next((r for r in warp_rows if r["N"] == n), None)
        full = next((r for r in warp_full_rows or [] if r["N"] == n), None)
        row = {
            "N": n,
            "threads": problem.threads,
            "tick_ms": sec * 1e3,
            "rollout_only_ms": roll * 1e3,
            "world_steps_per_s": n * HORIZON_STEPS / sec,
            "warp_speedup": None if warp is None else sec / (warp["tick_ms"] / 1e3),
            "warp_full_model_speedup": None if full is None else sec / (full["tick_ms"] / 1e3),
        }
        rows.append(row)
        print(json.dumps({f"cpu_{task}": row}), flush=True)


def _cands(ctrl) -> np.ndarray:
    ctrl.knots = ctrl.nominal_knots()
    return ctrl.sample()


def agreement(out: dict) -> None:
    """Warp (CUDA) vs CPU rollout costs for the same candidates and start state."""
    res = {}
    for task in ("humanoid", "cartpole"):
        problem = _problem(task)
        state = _start_state(problem, task)
        rng = np.random.default_rng(0)
        state[problem.nq :] += rng.normal(0, 0.1, problem.nv + problem.na)
        warp = _controller(problem, 64)
        cpu = _controller(problem, 64, backend="cpu")
        cand = problem.clip_ctrl(
            problem.ctrl_ref + rng.normal(0, 0.2, (64, warp.spline.num_knots, problem.nu))
        )
        a = cpu.backend.evaluate(state, cand).costs[:, 0]
        b = warp.backend.evaluate(state, cand).costs[:, 0]
        rel = np.abs(a - b) / np.maximum(np.abs(a), 1e-9)
        res[task] = {"max_rel_diff": float(rel.max()), "median_rel_diff": float(np.median(rel))}
        if task == "humanoid":
            # The task's planning model (sweep "humanoid") against the full model on the CPU.
            fast = _controller(problem, 64, **humanoid_planning())
            c = fast.backend.evaluate(state, cand).costs[:, 0]
            rel = np.abs(a - c) / np.maximum(np.abs(a), 1e-9)
            res["humanoid_task_model_vs_full"] = {
                "options": humanoid_planning(),
                "max_rel_diff": float(rel.max()),
                "median_rel_diff": float(np.median(rel)),
                "rank_correlation": float(
                    np.corrcoef(np.argsort(np.argsort(a)), np.argsort(np.argsort(c)))[0, 1]
                ),
            }
    out["agreement"] = res


def closed_loop(out: dict, duration: float) -> None:
    """The tasks' tuned sampling controllers (``controller_configs``) under the recipe."""
    import mpcbox
    from mpcbox.tasks.humanoid.balance import HumanoidBalance
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    runs = out.setdefault("closed_loop", [])
    stand = HumanoidStand()
    balance = HumanoidBalance()
    cases = [
        ("humanoid_stand", stand, name, {}, seed)
        for name, seeds in (("mppi", (0, 1, 2)), ("cem", (0, 1, 2)), ("ps", (0, 1)))
        for seed in seeds
    ]
    cases += [
        ("humanoid_balance", balance, "mppi", {}, 0),
        ("humanoid_balance", balance, "cem", {}, 0),
        ("humanoid_balance", balance, "ps", {}, 0),
    ]
    for task, problem, name, extra, seed in cases:
        opts = dict(
            config_options(problem.controller_configs[name])
            if name in problem.controller_configs
            else {}
        )
        opts.update(backend="warp", **extra)
        try:
            ctrl = mpcbox.make_controller(name, problem, **opts)
            t0 = time.perf_counter()
            res = mpcbox.simulate(problem, ctrl, duration, noise=problem.noise(), seed=seed)
            row = {
                "task": task,
                "controller": name,
                "options": {k: v for k, v in opts.items() if k != "randomization"},
                "noise": "tasks.humanoid.noise.balance_noise (published recipe)",
                "seed": seed,
                "duration_s": duration,
                "survived": bool(res.metrics.survived),
                "time_to_fall_s": float(res.metrics.time_to_fall),
                "failure": res.failure,
                "tilt_rms_deg": float(res.metrics.measures["tilt_rms_deg"]),
                "tilt_max_deg": float(np.max(res.series["tilt"])),
                "com_deviation_rms_m": float(res.metrics.measures["com_deviation_rms_m"]),
                "compute_mean_ms": float(res.metrics.compute_mean_ms),
                "compute_p99_ms": float(res.metrics.compute_p99_ms),
                "wall_s": time.perf_counter() - t0,
                "stats": ctrl.stats,
            }
            ctrl.close()
        except Exception as exc:
            row = {"task": task, "controller": name, "error": repr(exc)}
        runs.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "stats"}), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    parser.add_argument("--first-tick", choices=["humanoid", "cartpole"], help=argparse.SUPPRESS)
    parser.add_argument("--out", default=None, help="JSON path (default $OUT/sampling_gpu.json)")
    parser.add_argument("--skip", nargs="*", default=[], help="sections to skip")
    parser.add_argument("--duration", type=float, default=10.0, help="closed-loop seconds")
    args = parser.parse_args()
    if args.first_tick:
        t0 = time.perf_counter()
        r = first_tick(args.first_tick)
        r["since_script_start_s"] = time.perf_counter() - _T0
        del t0
        print("FIRST_TICK " + json.dumps(r), flush=True)
        return

    import warp as wp

    wp.config.quiet = True
    wp.init()
    out_dir = Path(os.environ.get("OUT", ROOT / "benchmarks" / "results"))
    out_path = Path(args.out) if args.out else out_dir / "sampling_gpu.json"
    out_path.parent.mkdir(parents=True, exist_ok=True)
    dev = wp.get_device()
    out: dict[str, Any] = {
        "device": dev.name if dev.is_cuda else "cpu",
        "warp_device": str(dev),
        "host": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "horizon_steps": HORIZON_STEPS,
        "errors": {},
    }
    try:
        import mujoco
        import mujoco_warp

        out["versions"] = {
            "mujoco": mujoco.__version__,
            "mujoco_warp": mujoco_warp.__version__,
            "warp": wp.config.version,
        }
    except Exception:
        pass
    sizes = [64, 128] if args.quick else [256, 512, 1024, 2048, 4096, 8192]
    cpu_sizes = [128] if args.quick else [1024, 4096]

    def save() -> None:
        out_path.write_text(json.dumps(out, indent=1, default=float))

    def section(name: str, fn, *a, **kw) -> None:
        if name in args.skip:
            return
        t0 = time.perf_counter()
        try:
            fn(*a, **kw)
        except Exception:
            out["errors"][name] = traceback.format_exc()[-3000:]
            print(f"SECTION {name} FAILED\n{out['errors'][name]}", flush=True)
        out.setdefault("section_seconds", {})[name] = time.perf_counter() - t0
        save()

    def cold() -> None:
        res = {}
        for task in ("humanoid", "cartpole"):
            res[task] = first_tick(task)
        out["first_tick_cold"] = res

    def warm() -> None:
        res = {}
        for task in ("humanoid", "cartpole"):
            proc = subprocess.run(
                [sys.executable, __file__, "--first-tick", task],
                capture_output=True,
                text=True,
                timeout=300,
            )
            line = [x for x in proc.stdout.splitlines() if x.startswith("FIRST_TICK ")]
            res[task] = json.loads(line[-1][11:]) if line else {"error": proc.stderr[-2000:]}
        out["first_tick_warm"] = res

    section("first_tick_cold", cold)
    section("first_tick_warm", warm)
    section("agreement", agreement, out)
    # The humanoid on its sampling controllers' planning model (Euler, solver capped), and
    # on the full simulation model for reference.
    section("sweep_humanoid", sweep, "humanoid", sizes, out, None, HORIZON_STEPS,
            **humanoid_planning())  # fmt: skip
    section("sweep_humanoid_full", sweep, "humanoid", sizes[2:5] if not args.quick else sizes,
            out, "humanoid_full")  # fmt: skip
    section("sweep_cartpole", sweep, "cartpole", sizes, out)
    # The cart-pole over the same 0.32 s horizon on a 0.02 s planning model (16 steps), as
    # its tuned sampling controllers plan.
    section(
        "sweep_cartpole_coarse",
        sweep,
        "cartpole",
        [256, 1024, 4096] if not args.quick else sizes,
        out,
        "cartpole_coarse",
        HORIZON_STEPS // 2,
        planning_timestep=0.02,
    )
    section(
        "cpu_rollout_humanoid",
        cpu_rollout,
        "humanoid",
        cpu_sizes,
        out.get("sweep", {}).get("humanoid", []),
        out,
        out.get("sweep", {}).get("humanoid_full", []),
    )
    section("closed_loop", closed_loop, out, args.duration)
    out["summary"] = summarize(out)
    save()
    print(json.dumps(out["summary"], indent=1, default=float), flush=True)


def summarize(out: dict) -> dict[str, Any]:
    """The targets of issue #5 against the measurements."""
    s: dict[str, Any] = {}
    sweeps = out.get("sweep", {})
    hum = {r["N"]: r for r in sweeps.get("humanoid", [])}
    full = {r["N"]: r for r in sweeps.get("humanoid_full", [])}
    cart = {r["N"]: r for r in sweeps.get("cartpole", [])}
    if 2048 in hum:
        s["humanoid_planning_model"] = hum[2048]["options"]
        s["humanoid_N2048_T32_ticks_per_s"] = hum[2048]["ticks_per_s"]
        s["target_50_ticks_per_s_met"] = hum[2048]["ticks_per_s"] >= 50
        s["humanoid_N2048_efficiency"] = hum[2048]["efficiency"]
        s["target_efficiency_70pct_met"] = hum[2048]["efficiency"] >= 0.7
        s["humanoid_N2048_efficiency_vs_diverse_raw"] = hum[2048]["efficiency_vs_diverse_raw"]
    if 2048 in full:
        s["humanoid_full_model_N2048_T32_ticks_per_s"] = full[2048]["ticks_per_s"]
        s["humanoid_full_model_N2048_efficiency"] = full[2048]["efficiency"]
    cpu = {r["N"]: r for r in out.get("cpu_rollout", {}).get("humanoid", [])}
    if 4096 in cpu:
        s["humanoid_N4096_speedup_vs_mujoco_rollout"] = cpu[4096]["warp_speedup"]
        s["humanoid_N4096_full_model_speedup_vs_mujoco_rollout"] = cpu[4096][
            "warp_full_model_speedup"
        ]
        both = (cpu[4096]["warp_speedup"], cpu[4096]["warp_full_model_speedup"])
        s["target_6x_met"] = all(x is not None and x >= 6 for x in both)
    if 1024 in cart:
        s["cartpole_N1024_tick_ms"] = cart[1024]["tick_ms"]
        s["target_5ms_met"] = cart[1024]["tick_ms"] <= 5
        raw = cart[1024]["raw_world_steps_per_s"]
        s["cartpole_N1024_raw_ms"] = 1024 * HORIZON_STEPS / raw * 1e3
    coarse = {r["N"]: r for r in sweeps.get("cartpole_coarse", [])}
    if 1024 in coarse:
        s["cartpole_coarse_N1024_T16_tick_ms"] = coarse[1024]["tick_ms"]
    warm = out.get("first_tick_warm", {})
    if "humanoid" in warm and "total_s" in warm["humanoid"]:
        s["warm_first_tick_s"] = warm["humanoid"]["total_s"]
        s["target_5s_met"] = warm["humanoid"]["total_s"] <= 5
    cold = out.get("first_tick_cold", {})
    if "humanoid" in cold:
        s["cold_first_tick_s"] = {k: v["total_s"] for k, v in cold.items()}
    keys = ("task", "controller", "seed", "survived", "time_to_fall_s", "tilt_rms_deg", "error")
    s["closed_loop"] = [{k: r.get(k) for k in keys} for r in out.get("closed_loop", [])]
    return s


if __name__ == "__main__":
    main()
