"""Two-feet push recovery: LQR against QP-MPC variants on a grid of forces; prints JSON.

Each trial is the push scenario of ``docs/results/humanoid.md`` on
:class:`~mpcbox.tasks.HumanoidTwoFeet`: a 0.1 s push on the torso at t = 1 s, the robot must
stay up 3 s after it (no noise, seed 0). Every (controller, direction, force) runs once, in
parallel worker processes; each grid is then summarized by
:func:`mpcbox.comparison.push_limits.summarize_push_grid` (largest force below the first
failure, and whether survival is monotone in the force) and the QP-MPC fallbacks are counted.

The QP-MPC variants: the task's tuning (soft stance, 10 x 0.02 s, solved at 50 Hz), a 0.6 s
horizon (15 x 0.04 s), relinearization every tick, the rigid stance with OSQP and with
Clarabel, the task's QP (and a 0.4 s horizon) re-solved at LQR's 200 Hz instead of 50 Hz,
and the task's QP with the legged presets' OSQP settings
(:data:`~mpcbox.tasks.legged.balance.QP_OSQP_SETTINGS`), with those and rho 1 (also with a
15 ms solve budget, ``time_limit``), and with OSQP_DEFAULTS' rho 3. LQR is the peer;
iLQR-MPC with the one-leg tuning is the nonlinear reference::

    python benchmarks/qp_two_feet.py --workers 16 --json benchmarks/results/qp_two_feet.json
    python benchmarks/qp_two_feet.py --variants lqr,qp --directions fwd
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from mpcbox.comparison.scenario import PushTest
from mpcbox.config import config_options
from mpcbox.tasks.humanoid.balance import HumanoidBalance
from mpcbox.tasks.legged.balance import QP_OSQP_SETTINGS

#: Controller name and keyword overrides on top of the task's ``controller_configs``. The
#: nonlinear reference, iLQR-MPC, takes the one-leg task's tuning (0.35 s horizon, 50 Hz).
VARIANTS: dict[str, tuple[str, dict]] = {
    "lqr": ("lqr", {}),
    "ilqr": ("ilqr", config_options(HumanoidBalance.controller_configs["ilqr"])),
    "qp": ("qp", {}),
    "qp_long": ("qp", {"horizon": 15, "dt": 0.04}),
    "qp_relinearize": ("qp", {"relinearize": True}),
    "qp_rigid": ("qp", {"stance_model": "rigid"}),
    "qp_rigid_clarabel": ("qp", {"stance_model": "rigid", "solver": "clarabel"}),
    "qp_200hz": ("qp", {"period": 0.005}),
    "qp_h20_200hz": ("qp", {"horizon": 20, "period": 0.005}),
    "qp_legged_osqp": ("qp", {"osqp_settings": dict(QP_OSQP_SETTINGS)}),
    "qp_legged_rho1": ("qp", {"osqp_settings": {**QP_OSQP_SETTINGS, "rho": 1.0}}),
    "qp_rho3": ("qp", {"osqp_settings": {"rho": 3.0}}),
    "qp_legged_rho1_budget": (
        "qp",
        {"osqp_settings": {**QP_OSQP_SETTINGS, "rho": 1.0}, "time_limit": 0.015},
    ),
}
DIRECTIONS = {"fwd": (1.0, 0.0, 0.0), "bwd": (-1.0, 0.0, 0.0), "lat": (0.0, 1.0, 0.0)}
FORCES = {
    "fwd": [20, 40, 60, 80, 100, 105, 110, 115, 120, 125, 130, 140],
    "bwd": [20, 40, 60, 80, 85, 90, 95, 100, 110],
    "lat": [40, 70, 90, 105, 110, 115, 120, 125, 130, 140],
}
START, DURATION, SETTLE = 1.0, 0.1, 3.0
#: The push of each direction (its force magnitude comes from ``FORCES``).
TESTS = {
    name: PushTest(direction=d, duration=DURATION, start=START, settle=SETTLE)
    for name, d in DIRECTIONS.items()
}


def trial(variant: str, direction: str, force: float) -> dict:
    """One push trial; the controller is built fresh in the worker."""
    import warnings

    from mpcbox import make_controller, simulate
    from mpcbox.tasks.humanoid.two_feet import HumanoidTwoFeet

    warnings.filterwarnings("ignore")  # Clarabel's per-solve warnings; failures are counted
    problem = HumanoidTwoFeet(threads=1)
    name, options = VARIANTS[variant]
    controller = make_controller(name, problem, **options)
    test = TESTS[direction]
    t0 = time.perf_counter()
    res = simulate(problem, controller, test.total_time, pushes=[test.push(force)], seed=0)
    return dict(
        variant=variant,
        direction=direction,
        force=float(force),
        survived=bool(res.survived),
        time_to_fall=float(res.metrics.time_to_fall),
        fallbacks=int(res.metrics.fallbacks),
        ticks=len(res.compute_times),
        wall_s=time.perf_counter() - t0,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated")
    parser.add_argument("--directions", default=",".join(DIRECTIONS), help="comma-separated")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--json", default=None, help="also write the JSON here")
    args = parser.parse_args()
    variants = args.variants.split(",")
    directions = args.directions.split(",")
    for name, chosen, valid in (
        ("variants", variants, VARIANTS),
        ("directions", directions, DIRECTIONS),
    ):
        unknown = [v for v in chosen if v not in valid]
        if unknown:
            parser.error(f"--{name}: unknown {unknown}; valid: {', '.join(valid)}")

    from concurrent.futures import ProcessPoolExecutor, as_completed

    from tqdm import tqdm

    from mpcbox.comparison.push_limits import summarize_push_grid

    jobs = [(v, d, f) for v in variants for d in directions for f in FORCES[d]]
    t0 = time.perf_counter()
    trials = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(trial, *job) for job in jobs]
        for future in tqdm(as_completed(futures), total=len(jobs), file=sys.stderr):
            trials.append(future.result())
    grids: dict[str, dict] = {}
    for v in variants:
        for d in directions:
            rows = sorted(
                (t for t in trials if t["variant"] == v and t["direction"] == d),
                key=lambda t: t["force"],
            )
            grid = summarize_push_grid(
                np.array([t["force"] for t in rows]),
                np.array([t["survived"] for t in rows]),
                np.array([t["time_to_fall"] for t in rows]),
            )
            grids.setdefault(v, {})[d] = dict(
                forces=grid.forces.tolist(),
                survived=grid.survived.astype(int).tolist(),
                limit=grid.limit,
                largest_survived=grid.largest_survived,
                monotone=grid.monotone,
                fallbacks=[t["fallbacks"] for t in rows],
            )
    out = dict(
        benchmark="qp_two_feet",
        scenario=dict(start=START, duration=DURATION, settle=SETTLE, body="torso", seed=0),
        variants={v: dict(controller=VARIANTS[v][0], **VARIANTS[v][1]) for v in variants},
        grids=grids,
        trials=sorted(trials, key=lambda t: (t["variant"], t["direction"], t["force"])),
        host=dict(machine=platform.machine(), cpus=os.cpu_count(), workers=args.workers),
        wall_s=time.perf_counter() - t0,
    )
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
