"""What the live viewer costs: trace recording per tick, trace geoms and offscreen frames; JSON.

    MUJOCO_GL=egl nice -n 5 python benchmarks/viewer_traces.py

On the cart-pole swing-up with the task's tuned predictive sampling (128 samples, 50
planning steps), from states along a swing-up:

* ``tick_ms_off`` / ``tick_ms_on``: median ``controller(state, t)`` call without and with
  ``record_traces(k)``; ``record_ms``: median time of the recording alone;
* ``geoms_ms``: median time to add the ``k`` traces' capsules to a scene;
* ``frame_ms``: median offscreen frame (``mj_forward`` of the copy, ``update_scene``, the
  traces, ``render``, caption) at 320 x 240 without traces and with them drawn as lines or
  capsules, or ``null`` without an OpenGL context.

Writes ``benchmarks/results/viewer_traces.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import mujoco
import numpy as np

import mpcbox
from mpcbox.sim.trace_geoms import add_trace_geoms
from mpcbox.tasks.swingup import CartpoleSwingup

OUT = Path(__file__).resolve().parent / "results" / "viewer_traces.json"


def _median_ms(samples: list[float]) -> float:
    return float(np.median(samples) * 1e3)


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--traces", type=int, default=8, help="traced candidates k")
    parser.add_argument("--ticks", type=int, default=40, help="ticks per measurement")
    args = parser.parse_args()
    problem = CartpoleSwingup()
    states = mpcbox.simulate(problem, mpcbox.make_controller("ps", problem), 1.0).states
    states = states[:: max(1, len(states) // args.ticks)][: args.ticks]
    off = mpcbox.make_controller("ps", problem)
    on = mpcbox.make_controller("ps", problem)
    on.record_traces(args.traces)
    recorder = on.trace_recorder
    record_s: list[float] = []
    inner = recorder.record

    def timed(*a, **k):
        t0 = time.perf_counter()
        out = inner(*a, **k)
        record_s.append(time.perf_counter() - t0)
        return out

    recorder.record = timed
    tick = {"off": [], "on": []}
    for i, x in enumerate(states):
        for name, ctrl in (("off", off), ("on", on)):
            t0 = time.perf_counter()
            ctrl(x, 0.01 * i)
            tick[name].append(time.perf_counter() - t0)
    scene = mujoco.MjvScene(problem.model, 10000)
    geoms_s = []
    for _ in range(args.ticks):
        scene.ngeom = 0
        t0 = time.perf_counter()
        add_trace_geoms(scene, on.traces)
        geoms_s.append(time.perf_counter() - t0)
    frame_ms: dict[str, float] | None = {}
    try:
        for style, traces in (("none", 0), ("line", args.traces), ("capsule", args.traces)):
            viewer = mpcbox.OffscreenViewer(
                "/tmp/viewer_traces_bench.gif",
                width=320,
                height=240,
                traces=traces,
                style="line" if style == "none" else style,
            )
            viewer.start(problem, on, problem.model, mujoco.MjData(problem.model))
            frames = []
            data = mujoco.MjData(problem.model)
            for i, x in enumerate(states):
                problem.set_state(data, x)
                data.time = 1.0 + i
                t0 = time.perf_counter()
                viewer.step(data)
                frames.append(time.perf_counter() - t0)
            viewer.finish()
            frame_ms[style] = _median_ms(frames)
    except mpcbox.BackendUnavailableError as exc:
        print("no offscreen frames:", exc)
        frame_ms = None
    result = {
        "machine": "2-core sandbox CPU, shared",
        "platform": platform.platform(),
        "task": "cartpole_swingup",
        "controller": "ps (tuned: 128 samples, 50 planning steps of 0.02 s)",
        "traces": args.traces,
        "ticks": len(states),
        "tick_ms_off": _median_ms(tick["off"]),
        "tick_ms_on": _median_ms(tick["on"]),
        "record_ms": _median_ms(record_s),
        "geoms": int(scene.ngeom),
        "geoms_ms": _median_ms(geoms_s),
        "frame_ms": frame_ms,
        "frame_size": [320, 240],
        "same_plans": bool(np.array_equal(on.knots, off.knots)),
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
