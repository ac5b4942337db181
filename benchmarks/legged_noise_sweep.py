"""Legged balance on held-out seeds under stronger noise: LQR against QP-MPC; JSON.

    MENAGERIE_ROOT=... python benchmarks/legged_noise_sweep.py --workers 15 \\
        --json benchmarks/results/legged_noise_sweep.json

Every case is one ``mpcbox compare`` command line (printed in the JSON, so any row can be
re-run by hand): the task by name on a Menagerie robot (``quadruped_stand`` on the Go2, Go1,
A1 and ANYmal C; ``biped_stand`` on the G1 on two feet and on its left foot), ``--seeds``
seeds from ``--seed`` (default 100-119: seeds no benchmark was tuned on), 10 s each, noise at
x1, x1.5 and x2 of each task's recipe. The controllers: the task's LQR and QP-MPC with its
defaults (``qp``: the soft stance, the first stage's forces free), QP-MPC with every stage's
forces bounded (``qp_first_bounded``, the default before this sweep) and with
``stance_model="rigid"`` (``qp_rigid``, every stage bounded); ``--variants`` picks some.
Reported per case, controller and noise level: successes, mean time to fall, the compute
time per call (mean of the runs' medians, largest p99; lock-step, so it does not change the
outcome) and the fallbacks.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from json_report import finish

from mpcbox.cli import main as mpcbox_main

#: (case, task, task options) of the sweep.
CASES: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("go2", "quadruped_stand", ("--model", "menagerie:unitree_go2")),
    ("go1", "quadruped_stand", ("--model", "menagerie:unitree_go1")),
    ("a1", "quadruped_stand", ("--model", "menagerie:unitree_a1")),
    ("anymal_c", "quadruped_stand", ("--model", "menagerie:anybotics_anymal_c")),
    ("g1_two_feet", "biped_stand", ("--model", "menagerie:unitree_g1", "--stance", "two")),
    ("g1_left_foot", "biped_stand", ("--model", "menagerie:unitree_g1", "--stance", "left")),
)

#: (label, controllers, extra options) compared in each case.
VARIANTS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("defaults", "lqr,qp", ()),
    ("qp_first_bounded", "qp", ("--set", "qp.first_stage_forces='bounded'")),
    (
        "qp_rigid",
        "qp",
        ("--set", "qp.stance_model='rigid'", "--set", "qp.first_stage_forces='bounded'"),
    ),
)


def run_case(task: str, options: list[str], folder: Path) -> tuple[int, list[dict]]:
    """Run one ``mpcbox compare`` command; its exit status and per-group rows."""
    status = mpcbox_main(["compare", task, *options, "--out", str(folder)])
    groups = folder / "groups.json"
    return status, json.loads(groups.read_text()) if groups.exists() else []


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default=",".join(c[0] for c in CASES))
    parser.add_argument("--variants", default=",".join(v[0] for v in VARIANTS))
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--noise", default="1,1.5,2")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", default="")
    parser.add_argument("--machine", default=None, help="what runs it (default: the sandbox)")
    args = parser.parse_args()
    started = time.perf_counter()
    wanted = args.cases.split(",")
    out: dict = {"benchmark": "legged_noise_sweep", "cases": {}}
    common = [
        "--seed", str(args.seed), "--seeds", str(args.seeds), "--duration", str(args.duration),
        "--noise", args.noise, "--workers", str(args.workers), "--no-plots", "--no-progress",
    ]  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for case, task, task_opts in CASES:
            if case not in wanted:
                continue
            rows: dict = {}
            commands = []
            for label, controllers, extra in VARIANTS:
                if label not in args.variants.split(","):
                    continue
                options = [*task_opts, "--controllers", controllers, *extra, *common]
                commands.append(" ".join(["mpcbox compare", task, *options]))
                status, groups = run_case(task, options, Path(tmp) / f"{case}_{label}")
                for g in groups:
                    name = g["controller"] if label == "defaults" else label
                    rows.setdefault(name, {})[g["scenario"]] = {
                        "successes": round(g["success_mean"] * g["runs"]),
                        "runs": g["runs"],
                        "outcomes": g["outcomes"],
                        "time_to_fall_mean_s": round(g["time_to_fall_mean"], 2),
                        "compute_p50_ms_mean": round(g["compute_p50_ms_mean"], 2),
                        "compute_p99_ms_max": round(g["compute_p99_ms_max"], 2),
                        "fallbacks_mean": round(g["fallbacks_mean"], 1),
                    }
                if status:
                    rows.setdefault("errors", []).append(f"{label}: exit status {status}")
            out["cases"][case] = {"task": task, "commands": commands, "controllers": rows}
            print(json.dumps({case: rows}), flush=True)
            if args.json:  # keep what finished if a later case is cut short
                Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return finish(out, args.json, started=started, machine=args.machine or "2-core sandbox CPU")


if __name__ == "__main__":
    raise SystemExit(main())
