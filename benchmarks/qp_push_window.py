"""Is a legged robot's outcome monotone in the push force? A scan over forces; JSON.

    MENAGERIE_ROOT=... python benchmarks/qp_push_window.py --workers 2 \\
        --json benchmarks/results/qp_push_window_go2.json

The push-limit bisections (``mpcbox compare --largest-push``) assume that a robot which
stands a push also stands every smaller one. On Menagerie's Go2 the QP-MPC does not: forward
pushes of 60-100 N fell it where 150-300 N did not. This script runs
:func:`mpcbox.comparison.push_limits.push_grid` on the task (``quadruped_stand`` by default,
no noise, ``--seed``) with one forward push of 0.1 s at 1 s on the root body, at every force
of ``--forces``, for every controller variant, and reports what stood, what fell and when,
the honest limit (the largest force below which nothing fell) and the **window**: the forces
that fell while a larger one stood.

Variants are ``label=controller`` or ``label=controller:option=value,...`` (values read
as ``mpcbox compare --set`` reads them); the defaults compare LQR, the QP-MPC as
the task configures it (the first stage's forces free), every stage bounded, a cheaper
stance slack (``stance_weight=100``) and a 3 mm contact margin.
"""

from __future__ import annotations

import argparse
import time
import warnings

from json_report import finish

from mpcbox.cli.compare import parse_sets
from mpcbox.comparison.executors import ProcessExecutor
from mpcbox.comparison.push_limits import push_grid
from mpcbox.comparison.scenario import PushTest
from mpcbox.core.menagerie import model_source
from mpcbox.registry import task_class

DEFAULT_VARIANTS = (
    "lqr=lqr",
    "qp=qp",
    "qp_bounded=qp:first_stage_forces='bounded'",
    "qp_slack100=qp:stance_weight=100.0",
    "qp_margin3mm=qp:contact_margin=0.003",
)


def parse_variant(text: str) -> tuple[str, str, dict]:
    """``label=controller[:option=value,...]`` -> (label, controller, options); the values
    are read as ``mpcbox compare --set`` reads them (:func:`mpcbox.cli.compare.parse_sets`)."""
    label, _, rest = text.partition("=")
    controller, _, opts = (part.strip() for part in rest.partition(":"))
    sets = parse_sets([f"{controller}.{item}" for item in opts.split(",") if item])
    return label.strip(), controller, sets.get(controller, {})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", default="unitree_go2", help="Menagerie name or MJCF path")
    parser.add_argument("--task", default="quadruped_stand")
    parser.add_argument("--forces", default="40,60,80,100,150,200,250,300")
    parser.add_argument("--variants", default=";".join(DEFAULT_VARIANTS), help="';'-separated")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--settle", type=float, default=2.0, help="seconds after the push")
    parser.add_argument("--workers", type=int, default=1, help="1: in this process")
    parser.add_argument("--json", default="")
    args = parser.parse_args()
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a Menagerie copy without its visual meshes
        root = task_class(args.task)(model_source(args.model)).root
    test = PushTest(body=root, settle=args.settle)
    forces = [float(f) for f in args.forces.split(",")]
    out: dict = {
        "command": f"python benchmarks/qp_push_window.py --model {args.model} --task "
        f"{args.task} --forces {args.forces} --seed {args.seed} --settle {args.settle:g}",
        "push": f"forward, {test.duration:g} s at {test.start:g} s on {root!r}, no noise",
        "variants": {},
    }
    for variant in filter(None, args.variants.split(";")):
        label, controller, options = parse_variant(variant)
        grid = push_grid(
            args.task,
            controller,
            forces,
            test,
            seed=args.seed,
            problem_options={"model": model_source(args.model)},
            controller_options=options or None,
            executor=ProcessExecutor(workers=args.workers) if args.workers > 1 else None,
        )
        fell = [float(f) for f, ok in zip(grid.forces, grid.survived, strict=True) if not ok]
        out["variants"][label] = {
            "controller": controller,
            "options": options,
            "stood_N": [float(f) for f in grid.forces[grid.survived]],
            "fell_N": fell,
            "window_N": [f for f in fell if f < grid.largest_survived],
            "limit_N": grid.limit,
            "largest_survived_N": grid.largest_survived,
            "monotone": grid.monotone,
            "time_to_fall_s": [round(float(t), 3) for t in grid.time_to_fall],
        }
    return finish(out, args.json, started=started)


if __name__ == "__main__":
    raise SystemExit(main())
