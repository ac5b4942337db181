"""iLQR-MPC in the real-time loop: the world holding its returned control, or running its law.

Before stop 40 the real-time loop (:func:`mpcbox.simulate_realtime`) held iLQR-MPC's last
returned control between the planner's calls, so the feedback law paused while a replan
ran; now the world evaluates the latest plan's law (:meth:`mpcbox.ILQR.policy`) at every
step. This script runs a task's tuned iLQR-MPC both ways on the same seeds under the task's
noise recipe (the first by hiding ``policy`` from the loop) and prints JSON: outcome, tilt
and latency per run, successes per loop::

    python benchmarks/realtime_feedback_law.py [--task humanoid_balance] [--seeds 0-2,100-109]
        [--loops held,law] [--set control_steps=2 --set horizon=12] [--push -115]

``--delay D`` runs the held and law loops on a simulated latency of ``D`` seconds instead of
the wall clock (reproducible), ``--lookahead auto`` (or seconds) plans from the predicted
state. ``--loops lockstep`` adds the lock-step loop of :func:`mpcbox.simulate` (the world waits for
every replan; its "latencies" are the replan ticks). ``--set KEY=VALUE`` (repeatable, VALUE a
Python literal) overrides an option of the task's iLQR config in every loop. ``--push F`` adds
a push of ``F`` newtons along x (negative: backward) on the task's root body at 2 s for 0.1 s;
each run reports that body's speed at its end (``root_speed_end_m_s``), to tell a robot at
rest from one still moving. Legged tasks also report each stance foot's pitch every 0.2 s
(``feet_pitch_deg_every_0.2s``, degrees, negative: toes up), and the largest backward pitch
(``feet_pitch_min_deg``): a foot rocked back onto its heel, which the reference-linearized
planner models as flat on the ground.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

import mpcbox
from mpcbox.cli.checks import lookahead_option
from mpcbox.cli.compare import default_push_body, parse_sets
from mpcbox.comparison.robustness import end_speed
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.trajectory import jsonable


class HeldControl:
    """A controller seen without its ``policy``: the real-time world holds what it returns."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.period = inner.period

    def reset(self) -> None:
        self.inner.reset()

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        return self.inner(state, time)

    def __getattr__(self, name: str) -> Any:
        if name == "policy":
            raise AttributeError(name)
        return getattr(self.inner, name)


def feet_pitch(problem: Any, run: Any, every: float = 0.2) -> list[list[float]] | None:
    """Each stance foot's pitch (deg, about its body's y axis in the world; negative: toes
    up) every ``every`` s of ``run``, or ``None`` for a task without stance feet."""
    feet = getattr(problem, "feet", None)
    if not feet:
        return None
    data = mujoco.MjData(problem.model)
    out = []
    for t in np.arange(0.0, float(run.time[-1]) + 1e-9, every):
        problem.set_state(data, run.states[min(np.searchsorted(run.time, t), len(run.time) - 1)])
        mujoco.mj_kinematics(problem.model, data)
        pitch = [np.degrees(np.arcsin(np.clip(-data.xmat[f.body][6], -1, 1))) for f in feet]
        out.append([round(float(p), 1) for p in pitch])
    return out


def seed_list(text: str) -> list[int]:
    """``"0-2,100-109"`` -> ``[0, 1, 2, 100, ..., 109]``."""
    out: list[int] = []
    for part in text.split(","):
        low, _, high = part.partition("-")
        out.extend(range(int(low), int(high or low) + 1))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="humanoid_balance")
    parser.add_argument("--seeds", default="0-2,100-109")
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument(
        "--loops", default="held,law", help="comma-separated from held, law, lockstep"
    )
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--push", type=float, default=0.0, help="x force (N) at 2 s for 0.1 s")
    parser.add_argument(
        "--delay", type=float, default=None, help="held/law: a simulated latency (s)"
    )
    parser.add_argument("--lookahead", default=None, help="held/law: seconds or 'auto'")
    parser.add_argument(
        "--out", default=str(Path(__file__).parent / "results/realtime_feedback_law.json")
    )
    args = parser.parse_args()
    lookahead = lookahead_option(args.lookahead)
    names = {"held": "held control", "law": "feedback law", "lockstep": "lock-step"}
    if set(args.loops.split(",")) - set(names):
        parser.error("--loops: choose from held, law, lockstep")
    loops = [names[name] for name in args.loops.split(",")]
    options = parse_sets([f"ilqr.{item}" for item in args.set]).get("ilqr", {})
    problem = task_class(args.task)()
    where = argparse.Namespace(push_body=None)
    default_push_body(where, problem)  # the root body, as `mpcbox compare --push` pushes
    push_body = where.push_body
    pushes = (
        [mpcbox.Push(force=(args.push, 0.0, 0.0), start=2.0, duration=0.1, body=push_body)]
        if args.push
        else []
    )
    rows = []
    started = time.perf_counter()
    for seed in seed_list(args.seeds):
        for loop in loops:
            controller = make_controller("ilqr", problem, **options)
            common = dict(noise=problem.noise(), pushes=pushes, seed=seed)
            if loop == "lock-step":  # the world waits for every replan
                run = mpcbox.simulate(problem, controller, args.duration, **common)
            else:
                inner = HeldControl(controller) if loop == "held control" else controller
                run = mpcbox.simulate_realtime(
                    problem,
                    inner,
                    args.duration,
                    delay=args.delay,
                    lookahead=lookahead,
                    **common,
                )
            rt = run.realtime if loop != "lock-step" else None
            row = {
                "seed": seed,
                "loop": loop,
                "outcome": run.metrics.outcome,
                "time_to_fall_s": run.metrics.time_to_fall,
                "tilt_rms_deg": run.metrics.measures.get("tilt_rms_deg"),
                "latency_p50_ms": rt.latency_p50_ms if rt else run.metrics.compute_p50_ms,
                "latency_p99_ms": rt.latency_p99_ms if rt else run.metrics.compute_p99_ms,
                "planner_period_s": rt.period_s if rt else controller.replan_period,
                "kept_up": rt.kept_up if rt else None,
                "ticks": rt.ticks if rt else int(controller.stats["replans"]),
                "replans": int(controller.stats["replans"]),
                "stalled": int(controller.stats["stalled"]),
                "root_speed_end_m_s": end_speed(problem, run, push_body),
            }
            pitch = feet_pitch(problem, run)
            if pitch is not None:
                row["feet_pitch_min_deg"] = min(min(p) for p in pitch)
                row["feet_pitch_deg_every_0.2s"] = pitch
            rows.append(row)
            print(json.dumps(jsonable(row)), file=sys.stderr)
    summary = {}
    for loop in loops:
        runs = [r for r in rows if r["loop"] == loop]
        summary[loop] = {
            "successes": f"{sum(r['outcome'] == 'success' for r in runs)}/{len(runs)}",
            "tilt_rms_deg": [round(r["tilt_rms_deg"], 2) for r in runs],
            "latency_p50_ms": [round(r["latency_p50_ms"], 1) for r in runs],
            "latency_p99_ms": [round(r["latency_p99_ms"], 1) for r in runs],
            "kept_up": f"{sum(bool(r['kept_up']) for r in runs)}/{len(runs)}"
            if loop != "lock-step"
            else None,
        }
    out = {
        "task": args.task,
        "machine": "2-core sandbox CPU",
        "python": platform.python_version(),
        "command": "python benchmarks/realtime_feedback_law.py " + " ".join(sys.argv[1:]),
        "ilqr_options": options,
        "wall_s": round(time.perf_counter() - started, 1),
        "summary": summary,
        "runs": rows,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(jsonable(out), indent=2) + "\n")
    print(json.dumps(jsonable(summary), indent=1))


if __name__ == "__main__":
    main()
