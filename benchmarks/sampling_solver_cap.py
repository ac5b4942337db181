"""Sampling MPC on the GPU with the planning model's constraint solver capped: speed and
whether the humanoid still stands. Prints JSON and writes ``$OUT/sampling_solver_cap.json``.

    PYTHONUNBUFFERED=1 python benchmarks/sampling_solver_cap.py

For each cap (``solver_iterations`` of the planning model; MJWarp iterates until the slowest
world converges, so the cap bounds the tick time): humanoid ticks/s and efficiency at
N = 2048 x 32 steps (the sweep of ``benchmarks/sampling.py``), and MPPI keeping the humanoid
standing for 10 s under the published actuator-noise recipe (two seeds).
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sampling import sweep


def main() -> None:
    import warp as wp

    import mpcbox
    from mpcbox.tasks.humanoid_stand import HumanoidStand

    wp.config.quiet = True
    wp.init()
    out_path = Path(os.environ.get("OUT", "benchmarks/results")) / "sampling_solver_cap.json"
    out: dict = {"device": wp.get_device().name, "sweep": {}, "closed_loop": []}
    stand = HumanoidStand()
    for cap in (None, 3, 2, 1):
        key = f"humanoid_cap_{cap}"
        opts = {} if cap is None else {"solver_iterations": cap}
        sweep("humanoid", [2048], out, key, **opts)
        for seed in (0, 1):
            options = dict(stand.controller_options["mppi"], backend="warp", **opts)
            ctrl = mpcbox.make_controller("mppi", stand, **options)
            t0 = time.perf_counter()
            res = mpcbox.simulate(stand, ctrl, 10.0, noise=stand.noise(), seed=seed)
            row = {
                "cap": cap,
                "seed": seed,
                "survived": bool(res.metrics.survived),
                "time_to_fall_s": float(res.metrics.time_to_fall),
                "tilt_rms_deg": float(res.metrics.tilt_rms_deg),
                "compute_mean_ms": float(res.metrics.compute_mean_ms),
                "wall_s": time.perf_counter() - t0,
            }
            ctrl.close()
            out["closed_loop"].append(row)
            print(json.dumps(row), flush=True)
        out_path.write_text(json.dumps(out, indent=1, default=float))
    print(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
