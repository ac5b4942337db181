"""The cost's sensors from mpcbox's kernel against MJWarp's sensor pipeline, per tick; JSON.

    MENAGERIE_ROOT=... python benchmarks/own_sensors_ab.py --gpu "NVIDIA H200"

For each task, MPPI with the task's tuned settings (and the sample count of :data:`TASKS`
where given) is built twice on the warp backend: with the cost's sensors computed by
:mod:`mpcbox.controllers.sampling.backends.warp_sensors` (the default) and with MJWarp's own
sensor pipeline (the plan forced off). After five ticks from the task's start, one tick's
CUDA graph is replayed 100 times for each (``realtime_tick.graph_ms``), alternating, five
rounds; the JSON holds each round's mean and their median (ms). Needs a CUDA GPU; writes
``--json`` or ``$OUT/own_sensors_ab.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import numpy as np
from realtime_tick import graph_ms  # benchmarks/ is not a package

import mpcbox
import mpcbox.controllers.sampling.backends.warp_sensors as warp_sensors
from mpcbox.registry import task_class

TASKS = {"g1_getup": 512, "humanoid_getup": None, "humanoid_stand": 1024}


def compare(task: str, num_samples: int | None, rounds: int) -> dict:
    problem = task_class(task)()
    options = {} if num_samples is None else {"num_samples": num_samples}
    own_plan = warp_sensors.own_sensor_plan
    controllers = {}
    try:
        for mode in ("own", "mjwarp"):
            if mode == "mjwarp":
                warp_sensors.own_sensor_plan = lambda problem, model: None
            ctrl = mpcbox.make_controller("mppi", problem, backend="warp", **options)
            for i in range(5):
                ctrl(problem.initial_state(), 0.02 * i)
            controllers[mode] = ctrl
    finally:
        warp_sensors.own_sensor_plan = own_plan
    times: dict[str, list[float]] = {mode: [] for mode in controllers}
    for _ in range(rounds):
        for mode, ctrl in controllers.items():
            times[mode].append(graph_ms(ctrl.backend, reps=100))
    own = controllers["own"]
    return {
        "task": task,
        "opts": options,
        "own_sensors": own.backend.stats["own_sensors"],
        "steps": own.horizon_steps,
        **{mode: float(np.median(values)) for mode, values in times.items()},
        "all": times,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tasks", default=",".join(TASKS), help="comma-separated task names")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--gpu", default=None, help="GPU name to record")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = sorted(set(tasks) - set(TASKS))
    if unknown or args.rounds < 1:
        parser.error(f"--tasks must be among {sorted(TASKS)} and --rounds >= 1, got {args}")
    rows = []
    for task in tasks:
        row = compare(task, TASKS[task], args.rounds)
        rows.append(row)
        print(f"{task}: own {row['own']:.2f} ms, MJWarp's {row['mjwarp']:.2f} ms", flush=True)
    out = {
        "gpu": args.gpu,
        "platform": platform.platform(),
        "what": "median of rounds of 100 CUDA-graph replays of one tick, same inputs (ms)",
        "rows": rows,
    }
    path = args.json or (
        os.path.join(os.environ["OUT"], "own_sensors_ab.json") if "OUT" in os.environ else None
    )
    if path:
        Path(path).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
