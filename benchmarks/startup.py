"""Start-up time of a warp-backend sampling controller: cold and warm kernel cache; JSON.

    PYTHONUNBUFFERED=1 python benchmarks/startup.py --task humanoid_stand --controller mppi

Runs a fresh Python process twice with one Warp kernel cache directory (``WARP_CACHE_PATH``,
emptied first): the first finds the cache empty (cold: every kernel compiles), the second
finds it filled (warm: the same model hashes to the same modules, nothing compiles). Each
process reports the seconds spent importing mpcbox and Warp, building the Problem, building
the controller, the first tick (calibration, allocation, module compile or load, graph
capture), a second tick and the median of 20 more; it also lists the slowest module loads
that Warp printed. ``--warp-config`` sets ``warp.config`` fields in the child (for example a
lower ``optimization_level``, which compiles faster and may run slower: compare the ticks).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.perf_counter()
import mpcbox, warp, mujoco_warp
warp.config.verbose = True  # prints each module load with its time
for key, value in json.loads(sys.argv[4]).items():
    setattr(warp.config, key, value)
from mpcbox.registry import task_class
t1 = time.perf_counter()
problem = task_class(sys.argv[1])()
t2 = time.perf_counter()
opts = json.loads(sys.argv[3])
ctrl = mpcbox.make_controller(sys.argv[2], problem, backend="warp", **opts)
t3 = time.perf_counter()
x = problem.initial_state()
ctrl(x, 0.0)
t4 = time.perf_counter()
ctrl(x, ctrl.period or problem.dt)
t5 = time.perf_counter()
ticks = []
for k in range(20):
    s0 = time.perf_counter()
    ctrl(x, (k + 2) * (ctrl.period or problem.dt))
    ticks.append(time.perf_counter() - s0)
ticks.sort()
print(json.dumps({
    "import_s": t1 - t0, "problem_s": t2 - t1, "controller_s": t3 - t2,
    "first_tick_s": t4 - t3, "second_tick_s": t5 - t4, "total_to_first_plan_s": t4 - t0,
    "precompiled_modules": ctrl.backend.stats.get("precompiled_modules"),
    "tick_median_ms": 1e3 * ticks[len(ticks) // 2],
}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="humanoid_stand")
    parser.add_argument("--controller", default="mppi")
    parser.add_argument("--options", default='{"num_samples": 1024}')
    parser.add_argument("--cache", default="/tmp/mpcbox_startup_warp_cache")
    parser.add_argument(
        "--warp-config",
        default="{}",
        help='warp.config fields set in the child before compiling, e.g. {"optimization_level": 2}',
    )
    parser.add_argument("--gpu", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    shutil.rmtree(args.cache, ignore_errors=True)
    env = dict(os.environ, WARP_CACHE_PATH=args.cache)
    report: dict = {
        "task": args.task,
        "controller": args.controller,
        "options": json.loads(args.options),
        "warp_config": json.loads(args.warp_config),
        "gpu": args.gpu,
        "cpus": os.cpu_count(),
    }
    for label in ("cold", "warm"):
        out = subprocess.run(
            [
                sys.executable,
                "-c",
                CHILD,
                args.task,
                args.controller,
                args.options,
                args.warp_config,
            ],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
        report[label] = json.loads(lines[-1]) if lines else {"error": out.stderr[-2000:]}
        # Warp prints "Module NAME HASH load on device 'cuda:0' took T ms (compiled)".
        loads = re.findall(
            r"Module (\S+) \S+ load on device \S+ took ([\d.]+) ms\s+\((\w+)", out.stdout
        )
        slowest = sorted(loads, key=lambda m: -float(m[1]))[:8]
        report[label]["slowest_module_loads_ms"] = [[m[0], float(m[1]), m[2]] for m in slowest]
        report[label]["module_loads"] = len(loads)
        print(json.dumps({label: report[label]}), flush=True)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
