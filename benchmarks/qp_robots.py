"""QP-MPC across robots: tick time, failed solves and fallbacks under torque noise; prints JSON.

Robots: the project's humanoid tasks (``humanoid_two_feet``, ``humanoid_balance``, with their
tuned QP config) and Menagerie quadrupeds standing on four feet named as bodies
(``unitree_go1``, ``unitree_a1``, ``anybotics_anymal_c``;
:class:`quadruped_problem.QuadrupedStand`, needs ``MENAGERIE_ROOT``). Every run adds 1 N m
of smooth torque noise per actuator (``std = 1 N m / gain``, so ``1 / kp`` rad on a position
servo and ``1 / gear`` on a motor) and lasts ``--duration`` seconds, for each of ``--seeds``.

Variants, each in its own process on one thread (``OMP_NUM_THREADS=1``, ``threads=1``), one
after the other so that their timings share the machine's load:

* ``before``: the code of ``--baseline`` (a checkout of an earlier commit, e.g. made with
  ``git worktree add /tmp/base 1794910``), its default settings; skipped without it;
* ``new``: this tree's defaults;
* ``new_adaptive_rho``: this tree with OSQP's adaptive rho (``max_iter`` 400 kept).

Per robot and variant: QP size, runs survived, the fraction of solves that failed and of
ticks that fell back, mean and largest OSQP iterations, median and p99 of the controller's
time per call (the fallback included), and the ratio of each to ``before``::

    MENAGERIE_ROOT=/work/menagerie nice -n 5 python benchmarks/qp_robots.py \\
        --baseline /tmp/base --json benchmarks/results/qp_robots.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

HERE = Path(__file__).resolve().parent
ROBOTS = (
    "humanoid_two_feet",
    "humanoid_balance",
    "unitree_go1",
    "unitree_a1",
    "anybotics_anymal_c",
)
VARIANTS: dict[str, dict] = {
    "before": {},
    "new": {},
    "new_adaptive_rho": {"osqp_settings": {"adaptive_rho": True}},
}


def worker(robot: str, variant: str, seeds: int, duration: float) -> dict:
    """Runs of one robot and variant in this process (imports the ``mpcbox`` on the path)."""
    import warnings

    import numpy as np

    sys.path.insert(0, str(HERE))
    warnings.filterwarnings("ignore")
    from quadruped_problem import QuadrupedStand, torque_noise

    from mpcbox.controllers.qp_mpc.controller import QPMPC
    from mpcbox.registry import task_class
    from mpcbox.sim.simulation import simulate

    if robot.startswith("humanoid"):
        problem = task_class(robot)(threads=1)
        config = problem.controller_configs["qp"]
    else:
        problem = QuadrupedStand(robot, threads=1)
        config = None
    noise = torque_noise(problem.model, 1.0)
    controller = QPMPC(problem, config, **VARIANTS[variant])
    times: list[float] = []
    solves = failed = fallbacks = survived = 0
    iters: list[float] = []
    iters_max: float | None = None  # the code before this branch does not report it
    for seed in range(seeds):
        res = simulate(problem, controller, duration, noise=noise, seed=seed)
        stats = res.controller_stats
        times.extend(res.compute_times[1:])  # the first call sets the solver up
        solves += int(stats["solves"])
        # The code before this branch had no failed_solves key: sum its failed:<status>.
        failed += int(sum(v for k, v in stats.items() if k.startswith("failed:")))
        fallbacks += int(stats["fallbacks"])
        survived += bool(res.survived)
        iters.append(stats["iterations"])
        if "solver_iterations_max" in stats:
            iters_max = max(iters_max or 0.0, stats["solver_iterations_max"])
    t = np.asarray(times) * 1e3
    return dict(
        nv=problem.nv,
        nu=problem.nu,
        contact_points=controller.points.count,
        variables=controller.nvar,
        constraints=controller.ncon,
        runs=seeds,
        survived=survived,
        solves=solves,
        failed_solves=failed,
        failed_fraction=failed / max(1, solves),
        fallbacks=fallbacks,
        fallback_fraction=fallbacks / max(1, solves),
        iterations_mean=float(np.mean(iters)),
        iterations_max=iters_max,
        tick_ms_median=float(np.median(t)),
        tick_ms_p99=float(np.percentile(t, 99)),
    )


def run_variant(robot: str, variant: str, args: argparse.Namespace) -> dict | None:
    """``worker`` in a fresh process whose ``mpcbox`` is this tree or the baseline."""
    tree = Path(args.baseline) if variant == "before" else HERE.parent
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1")
    cmd = [
        sys.executable,
        __file__,
        "--worker",
        f"{robot}:{variant}",
        "--seeds",
        str(args.seeds),
        "--duration",
        str(args.duration),
    ]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        print(f"{robot} {variant} failed:\n{out.stderr[-2000:]}", file=sys.stderr)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def _commit(tree: str | None) -> str | None:
    """The git commit checked out at ``tree`` (``None`` when unknown)."""
    if tree is None:
        return None
    out = subprocess.run(
        ["git", "-C", tree, "rev-parse", "HEAD"], capture_output=True, text=True, check=False
    )
    return out.stdout.strip() or None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--baseline", help="checkout of the earlier code (variant 'before')")
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--json", help="also write the JSON here")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        robot, variant = args.worker.split(":")
        print(json.dumps(worker(robot, variant, args.seeds, args.duration)))
        return

    variants = [v for v in args.variants.split(",") if v != "before" or args.baseline]
    t0 = time.perf_counter()
    robots: dict[str, dict] = {}
    for robot in args.robots.split(","):
        rows = {v: run_variant(robot, v, args) for v in variants}
        rows = {v: r for v, r in rows.items() if r is not None}
        base = rows.get("before")
        if base is not None:
            for v, r in rows.items():
                if v != "before":
                    r["tick_ms_median_ratio"] = r["tick_ms_median"] / base["tick_ms_median"]
                    r["tick_ms_p99_ratio"] = r["tick_ms_p99"] / base["tick_ms_p99"]
        robots[robot] = rows
        print(robot, json.dumps(rows), file=sys.stderr, flush=True)
    out = dict(
        benchmark="qp_robots",
        machine=f"2-core sandbox CPU, shared ({platform.processor() or platform.machine()}); "
        "one thread per run, variants run one after the other",
        noise="1 N m torque std per actuator through its gain (ActuatorNoise, width 0.8 s)",
        seeds=args.seeds,
        duration_s=args.duration,
        baseline=args.baseline,
        baseline_commit=_commit(args.baseline),
        commit=_commit(str(HERE.parent)),
        wall_s=time.perf_counter() - t0,
        robots=robots,
    )
    text = json.dumps(out, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
