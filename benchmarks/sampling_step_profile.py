"""Where the GPU time of one humanoid planning step goes: MJWarp kernels, by name.

    PYTHONUNBUFFERED=1 python benchmarks/sampling_step_profile.py [--nworld 2048]

For each planning model (full, solver capped, Euler, CG), steps N worlds with diverse
controls for 32 steps without a graph under Warp's kernel timing, and prints JSON (also
``$OUT/sampling_step_profile.json``): kernel launches per step, summed kernel time per step,
the graph-replayed wall time per step (``benchmarks/sampling.py``'s raw throughput), and the
kernels that take most of the time. Launch-bound steps have a summed kernel time well below
the wall time; compute-bound ones come close to it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sampling import HORIZON_STEPS, raw_throughput

from mpcbox.controllers.sampling.backends.warp import UNROLL_MAX_ITERATIONS

#: name -> MjOption fields of the planning model.
MODELS: dict[str, dict] = {
    "full": {},
    "cap1": {"iterations": 1},
    "cap2": {"iterations": 2},
    "euler_cap2": {"iterations": 2, "integrator": 0},
    "cg_cap3": {"iterations": 3, "solver": 1},
    "cg_cap5": {"iterations": 5, "solver": 1},
}


def profile(base, name: str, options: dict, nworld: int) -> dict:
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    p = base.with_planning_timestep(base.dt)
    for field, value in options.items():
        setattr(p.planning_model.opt, field, value)
    model = p.planning_model
    data = mujoco.MjData(model)
    p.set_state(data, p.initial_state())
    mujoco.mj_forward(model, data)
    m = mjw.put_model(model)
    m.opt.warn_overflow = 0
    if 0 < model.opt.iterations <= UNROLL_MAX_ITERATIONS:  # as the warp backend does
        m.opt.graph_conditional = False
    d = mjw.put_data(model, data, nworld=nworld, nconmax=16, njmax=96)
    rng = np.random.default_rng(0)
    d.ctrl.assign(p.clip_ctrl(p.ctrl_ref + rng.normal(0, 0.1, (nworld, p.nu))).astype(np.float32))
    for _ in range(HORIZON_STEPS):
        mjw.step(m, d)
    wp.synchronize()
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
    for _ in range(HORIZON_STEPS):
        mjw.step(m, d)
    wp.synchronize()
    results = wp.timing_end()
    per: dict[str, list[float]] = defaultdict(lambda: [0, 0.0])
    for r in results:
        per[r.name][0] += 1
        per[r.name][1] += r.elapsed
    total = sum(v[1] for v in per.values()) / HORIZON_STEPS
    launches = sum(v[0] for v in per.values()) / HORIZON_STEPS
    raw = raw_throughput(
        p, nworld, 16, 96, model=model, diverse=0.1, graph_conditional=bool(m.opt.graph_conditional)
    )
    top = sorted(per.items(), key=lambda kv: -kv[1][1])[:20]
    return {
        "model": name,
        "options": options,
        "nworld": nworld,
        "launches_per_step": launches,
        "kernel_ms_per_step": total,
        "graph_wall_ms_per_step": nworld / raw * 1e3,
        "top_kernels_ms_per_step": {
            k: [v[0] / HORIZON_STEPS, v[1] / HORIZON_STEPS] for k, v in top
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nworld", type=int, default=2048)
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    import warp as wp

    from mpcbox.tasks.humanoid.stand import HumanoidStand

    wp.config.quiet = True
    wp.init()
    base = HumanoidStand()
    out = {"device": wp.get_device().name, "profiles": []}
    path = Path(args.out or os.environ.get("OUT", "benchmarks/results"))
    for name in args.models.split(","):
        row = profile(base, name, MODELS[name], args.nworld)
        out["profiles"].append(row)
        print(json.dumps(row), flush=True)
        (path / "sampling_step_profile.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
