"""The sampler knobs on the cart-pole swing-up (lock-step, CPU backend); prints JSON.

Each variant is a controller's task defaults plus the listed options, fixed before the
runs. Seeds perturb the initial joint positions (normal, 0.05 rad/m; seed 0 unperturbed).
Reports per variant: success rate, mean final distance from upright, the time the pole
first stays within 0.3 rad of upright, and the mean tick time::

    python benchmarks/sampler_knobs.py --seeds 3 --duration 5
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.tasks.swingup import CartpoleSwingup

VARIANTS: dict[str, tuple[str, dict]] = {
    "mppi default": ("mppi", {}),
    "mppi noise_schedule=linear": ("mppi", {"noise_schedule": "linear"}),
    "mppi interpolation=cubic_c2": ("mppi", {"interpolation": "cubic_c2"}),
    "mppi temperature_mode=absolute, temperature=10": (
        "mppi",
        {"temperature_mode": "absolute", "temperature": 10.0},
    ),
    "cem default": ("cem", {}),
    "cem std_init=0.1": ("cem", {"std_init": 0.1}),
    "cem noise_schedule=linear": ("cem", {"noise_schedule": "linear"}),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--machine", default="2-core sandbox CPU, shared")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    problem = CartpoleSwingup()
    report: dict = {
        "task": "cartpole_swingup",
        "loop": "lock-step (mpcbox.simulate)",
        "machine": args.machine,
        "platform": platform.platform(),
        "duration_s": args.duration,
        "seeds": args.seeds,
        "variants": {},
    }
    for label, (name, options) in VARIANTS.items():
        ctrl = mpcbox.make_controller(name, problem, **options)
        outcomes, final, t_up, ticks = [], [], [], []
        for seed in range(args.seeds):
            init = problem.initial_state().copy()
            if seed:
                rng = np.random.default_rng(seed)
                init[: problem.nq] += rng.normal(0, 0.05, problem.nq)
            res = mpcbox.simulate(problem, ctrl, args.duration, initial_state=init)
            err = np.array([problem.upright_error(s) for s in res.states])
            down = np.flatnonzero(err >= 0.3)
            up_from = 0.0 if down.size == 0 else float(res.time[min(down[-1] + 1, len(err) - 1)])
            outcomes.append(res.metrics.outcome)
            final.append(float(err[-1]))
            t_up.append(up_from if err[-1] < 0.3 else float("nan"))
            ticks.append(res.metrics.compute_mean_ms)
        report["variants"][label] = {
            "controller": name,
            "options": options,
            "success_rate": float(np.mean([o == "success" for o in outcomes])),
            "outcomes": outcomes,
            "final_upright_error_rad_mean": float(np.mean(final)),
            "upright_from_s": t_up,
            "tick_mean_ms": float(np.mean(ticks)),
        }
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
