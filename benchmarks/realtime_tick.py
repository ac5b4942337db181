"""Where the time of one sampling-MPC tick goes, per controller and planning variant; JSON.

    PYTHONUNBUFFERED=1 python benchmarks/realtime_tick.py --task humanoid_stand \\
        --num-samples 1024 --variants "base;dt015:planning_timestep=0.015,horizon=0.48"

For each variant (the task's tuned config of each controller with the variant's fields
replaced) this runs lock-step ticks from the task's start state (velocities jittered every
tick) and reports, in ms:

* ``tick_p50``/``tick_p99``: the whole ``controller(state, t)`` call;
* ``sample``: drawing the candidates (host);
* ``submit``: clamping, upload and graph launch (host, the device starts working);
* ``prefetch``: drawing the next iteration's noise while the device works (host);
* ``collect``: waiting for the device and reading back costs (host blocked);
* ``update``: refitting the nominal (host);
* ``graph``: one replay of the captured tick alone (device, synchronized);

plus the number of planning steps and the setup time. Also writes
``$OUT/realtime_tick_<task>.json`` when ``OUT`` is set, else ``--json``.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.registry import task_class


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_variants(text: str) -> dict[str, dict]:
    """``"name:k=v,k=v;name2"`` -> ``{name: {k: v}}``."""
    out: dict[str, dict] = {}
    for item in filter(None, text.split(";")):
        name, _, rest = item.partition(":")
        fields = {}
        for pair in filter(None, rest.split(",")):
            key, _, val = pair.partition("=")
            fields[key.strip()] = _value(val.strip())
        out[name.strip()] = fields
    return out


def _timed(obj, name: str, acc: dict[str, list[float]]) -> None:
    fn = getattr(obj, name)

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[name].append(time.perf_counter() - t0)

    setattr(obj, name, wrapper)


def graph_ms(backend, reps: int = 50) -> float:
    """Mean wall time of one synchronized replay of the captured tick (ms; NaN without)."""
    graph = getattr(backend, "_graph", None)
    if graph is None:
        return float("nan")
    import warp as wp

    with wp.ScopedDevice(backend.device):
        wp.capture_launch(graph)
        wp.synchronize_device()
        t0 = time.perf_counter()
        for _ in range(reps):
            wp.capture_launch(graph)
        wp.synchronize_device()
    return (time.perf_counter() - t0) / reps * 1e3


def profile(
    problem, name: str, fields: dict, seconds: float, backend: str, no_gc: bool = False
) -> dict:
    t0 = time.perf_counter()
    ctrl = mpcbox.make_controller(name, problem, backend=backend, **fields)
    state0 = problem.initial_state()
    ctrl(state0, 0.0)
    setup = time.perf_counter() - t0
    acc: dict[str, list[float]] = defaultdict(list)
    for method in ("sample", "update", "_prefetch"):
        _timed(ctrl, method, acc)
    if hasattr(ctrl.backend, "submit"):
        _timed(ctrl.backend, "submit", acc)
        _timed(ctrl.backend, "collect", acc)
    rng = np.random.default_rng(0)
    ticks: list[float] = []
    period = ctrl.period or problem.dt
    t, start = 0.0, time.perf_counter()
    if no_gc:
        gc.collect()
        gc.disable()
    while len(ticks) < 20 or (time.perf_counter() - start < seconds and len(ticks) < 2000):
        state = state0.copy()
        state[problem.nq :] += rng.normal(0, 0.05, problem.nv + problem.na)
        t += period
        t1 = time.perf_counter()
        ctrl(state, t)
        ticks.append(time.perf_counter() - t1)
    gc.enable()
    for k in list(acc):
        acc[k] = acc[k][-len(ticks) * ctrl.iterations :]
    ms = np.asarray(ticks) * 1e3
    row = {
        "controller": name,
        "fields": fields,
        "num_samples": ctrl.num_samples,
        "planning_steps": ctrl.horizon_steps,
        "planning_timestep": ctrl.problem.dt,
        "iterations": ctrl.iterations,
        "period_ms": period * 1e3,
        "ticks": len(ticks),
        "setup_s": setup,
        "tick_p50": float(np.percentile(ms, 50)),
        "tick_p99": float(np.percentile(ms, 99)),
        "tick_max": float(ms.max()),
        **{k.strip("_"): float(np.mean(v) * 1e3) for k, v in acc.items()},
        "graph": graph_ms(ctrl.backend),
    }
    ctrl.close()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="humanoid_stand")
    parser.add_argument("--controllers", default="ps,mppi,cem")
    parser.add_argument("--num-samples", type=int, default=1024)
    parser.add_argument("--variants", default="base")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--gpu", default=None, help="GPU name to record")
    parser.add_argument("--no-gc", action="store_true", help="no garbage collection in ticks")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    problem = task_class(args.task)()
    report: dict = {
        "task": args.task,
        "gpu": args.gpu,
        "platform": platform.platform(),
        "backend": args.backend,
        "rows": [],
    }
    out = (
        Path(os.environ["OUT"]) / f"realtime_tick_{args.task}.json" if "OUT" in os.environ else None
    )
    if args.json:
        out = Path(args.json)
    for vname, fields in parse_variants(args.variants).items():
        for name in args.controllers.split(","):
            opts = {"num_samples": args.num_samples, **fields}
            try:
                row = profile(problem, name, opts, args.seconds, args.backend, args.no_gc)
            except Exception as exc:  # keep the other rows
                row = {"controller": name, "fields": opts, "error": repr(exc)}
            row["variant"] = vname
            row["no_gc"] = args.no_gc
            report["rows"].append(row)
            print(json.dumps(row), flush=True)
            if out is not None:
                out.parent.mkdir(parents=True, exist_ok=True)
                out.write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
