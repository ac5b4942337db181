"""Is a legged robot's outcome monotone in the push force? A scan over forces; JSON.

    MENAGERIE_ROOT=... python benchmarks/qp_push_window.py --workers 2 \\
        --json benchmarks/results/qp_push_window_go2.json

The push-limit bisections (``mpcbox compare --largest-push``) assume that a robot which
stands a push also stands every smaller one. On Menagerie's Go2 the QP-MPC does not: forward
pushes of 60-100 N fell it where 150-300 N did not. This script runs the task
(``quadruped_stand`` by default, no noise, ``--seed``) with one forward push of 0.1 s at 1 s
on the root body, for every force of ``--forces`` and every controller variant, and reports
each run's outcome, the time of a fall, the fallbacks and the **window**: the forces that
fell while a larger one stood.

Variants are ``label=controller`` or ``label=controller:option=value,...`` (values read as
Python literals, as ``mpcbox compare --set`` does); the defaults compare LQR, the QP-MPC as
the task configures it (the first stage's forces free), every stage bounded, a cheaper
stance slack (``stance_weight=100``) and a 3 mm contact margin.
"""

from __future__ import annotations

import argparse
import ast
import time
from concurrent.futures import ProcessPoolExecutor

from json_report import finish

DEFAULT_VARIANTS = (
    "lqr=lqr",
    "qp=qp",
    "qp_bounded=qp:first_stage_forces='bounded'",
    "qp_slack100=qp:stance_weight=100.0",
    "qp_margin3mm=qp:contact_margin=0.003",
)


def parse_variant(text: str) -> tuple[str, str, dict]:
    """``label=controller[:option=value,...]`` -> (label, controller, options)."""
    label, _, rest = text.partition("=")
    controller, _, opts = rest.partition(":")
    options = {}
    for item in filter(None, opts.split(",")):
        key, _, value = item.partition("=")
        options[key.strip()] = ast.literal_eval(value.strip())
    return label.strip(), controller.strip(), options


def run_one(job: tuple) -> dict:
    """One closed-loop run of ``job`` = (model, task, variant, force, seed, duration)."""
    import warnings

    from mpcbox.core.menagerie import model_source
    from mpcbox.registry import make_controller, task_class
    from mpcbox.sim.disturbances import Push
    from mpcbox.sim.simulation import simulate

    model, task, variant, force, seed, duration = job
    label, controller, options = parse_variant(variant)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        problem = task_class(task)(model_source(model))
    ctrl = make_controller(controller, problem, **options)
    push = Push(force=(force, 0.0, 0.0), start=1.0, duration=0.1, body=problem.root)
    res = simulate(problem, ctrl, duration, pushes=[push], seed=seed)
    stats = res.controller_stats
    return {
        "variant": label,
        "force_N": force,
        "stood": res.failure is None,
        "failure": res.failure,
        "time_s": round(float(res.time[-1]), 3),
        "fallbacks": stats.get("fallbacks"),
        "solves": stats.get("solves"),
    }


def window(rows: list[dict]) -> list[float]:
    """Forces that fell while a larger force stood."""
    stood = [r["force_N"] for r in rows if r["stood"]]
    top = max(stood, default=0.0)
    return [r["force_N"] for r in rows if not r["stood"] and r["force_N"] < top]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default="unitree_go2", help="Menagerie name or MJCF path")
    parser.add_argument("--task", default="quadruped_stand")
    parser.add_argument("--forces", default="40,60,80,100,150,200,250,300")
    parser.add_argument("--variants", default=";".join(DEFAULT_VARIANTS), help="';'-separated")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    started = time.perf_counter()
    forces = [float(f) for f in args.forces.split(",")]
    variants = [v for v in args.variants.split(";") if v]
    jobs = [
        (args.model, args.task, v, f, args.seed, args.duration) for v in variants for f in forces
    ]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        rows = list(pool.map(run_one, jobs))
    summary = {}
    for variant in variants:
        label = parse_variant(variant)[0]
        mine = [r for r in rows if r["variant"] == label]
        summary[label] = {
            "stood_N": [r["force_N"] for r in mine if r["stood"]],
            "fell_N": [r["force_N"] for r in mine if not r["stood"]],
            "window_N": window(mine),
        }
    out = {
        "command": "python benchmarks/qp_push_window.py "
        + f"--model {args.model} --task {args.task} --forces {args.forces} "
        + f"--seed {args.seed} --duration {args.duration:g}",
        "variants": variants,
        "push": "forward, 0.1 s at 1 s on the root body, no noise",
        "summary": summary,
        "runs": rows,
    }
    return finish(out, args.json, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
