"""Can a feedback standing stage (LQR, QP-MPC) take over from the get-up planner? JSON.

    nice -n 5 python benchmarks/humanoid_getup_stage_basin.py --seeds 1,2,3 \\
        --stages lqr:3,qp:9 --cache /tmp/getup_runs \\
        --json benchmarks/results/humanoid_getup_stage_basin.json

Two measurements, on the CPU in lock-step (:func:`mpcbox.simulate`):

1. The standing stage's basin about the keyframe: from the standing reference at rest with
   the joint angles offset by a random direction of norm ``r`` (rad; ``--draws`` draws per
   ``r``, seed 0), and from the reference with the whole body translating forward at ``v``
   m/s, does the stage (built as in
   :meth:`~mpcbox.tasks.humanoid.getup.HumanoidGetup.handover_controller`: the get-up
   period, its control held) keep the torso at ``stand_height`` for 2 s?
2. The get-up planner's standing states: plain predictive sampling (the task's tuned
   config, ``backend="cpu"``) runs 5 s from the benchmark's lying start of each seed (as in
   ``benchmarks/humanoid_getup.py``); from every ``k``-th state of a 0.02 s tick at which
   :meth:`~mpcbox.tasks.humanoid.getup.HumanoidGetup.is_up` holds (``lqr:3``: every third),
   the stage runs alone for 2 s. Reported per state: the joints' distance from the keyframe
   (:meth:`~mpcbox.tasks.humanoid.getup.HumanoidGetup.posture_distance`), the centre of
   mass's speed and offset from the feet, and whether the stage held the torso up.

``--cache DIR`` keeps each planner run in ``DIR/ps_seed<s>.npz`` (time, states) and reuses
it (a run takes 7-11 min on the 2-core sandbox).
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.tasks.humanoid.getup import HumanoidGetup


def holds(task: HumanoidGetup, ctrl, state: np.ndarray, seconds: float = 2.0) -> float:
    """Lowest torso height (m) over ``seconds`` of ``ctrl`` from ``state``."""
    ctrl.reset()
    res = mpcbox.simulate(task, ctrl, seconds, initial_state=state, stop_on_failure=False)
    return float(task.torso_heights(res.states).min())


def keyframe_basin(task: HumanoidGetup, ctrl, draws: int) -> dict:
    ref = task.stand_problem().reference_state()
    rng = np.random.default_rng(0)
    out: dict = {"joint_offset": {}, "forward_speed": {}}
    for r in (0.05, 0.1, 0.25, 0.5):
        stood = 0
        for _ in range(draws):
            x = ref.copy()
            e = rng.normal(size=task.nq - 7)
            x[7 : task.nq] += r * e / np.linalg.norm(e)
            stood += holds(task, ctrl, x) >= task.stand_height
        out["joint_offset"][str(r)] = f"{stood}/{draws}"
    for v in (0.2, 0.4, 0.6):
        x = ref.copy()
        x[task.nq] = v
        out["forward_speed"][str(v)] = bool(holds(task, ctrl, x) >= task.stand_height)
    return out


def planner_run(task: HumanoidGetup, seed: int, cache: Path | None) -> tuple[np.ndarray, ...]:
    path = None if cache is None else cache / f"ps_seed{seed}.npz"
    if path is not None and path.exists():
        data = np.load(path)
        return data["time"], data["states"]
    ctrl = mpcbox.make_controller("ps", task, backend="cpu", seed=seed)
    init = task.initial_state()
    if seed:
        init[7 : task.nq] += np.random.default_rng(seed).normal(0, 0.05, task.nq - 7)
    res = mpcbox.simulate(task, ctrl, 5.0, initial_state=init, stop_on_failure=False)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, time=res.time, states=res.states)
    return res.time, res.states


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--stages", default="lqr:3,qp:9")
    parser.add_argument("--draws", type=int, default=3)
    parser.add_argument("--cache", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    task = HumanoidGetup()
    seeds = [int(s) for s in args.seeds.split(",")]
    cache = None if args.cache is None else Path(args.cache)
    report: dict = {
        "machine": "2-core sandbox CPU, shared",
        "platform": platform.platform(),
        "loop": "lockstep",
        "stand_height_m": task.stand_height,
        "stages": {},
        "planner_runs": {},
    }
    runs = {seed: planner_run(task, seed, cache) for seed in seeds}
    for seed, (time, states) in runs.items():
        up = [k for k in range(0, len(time), 4) if task.is_up(states[k])]
        heights = task.torso_heights(states)
        report["planner_runs"][str(seed)] = {
            "goal_failure": task.goal_failure(time, states),
            "first_up_s": float(time[up[0]]) if up else None,
            "up_ticks": len(up),
            "posture_min_rad": min((task.posture_distance(states[k]) for k in up), default=None),
            "final_torso_m": float(heights[-1]),
        }
    for item in args.stages.split(","):
        name, _, every = item.partition(":")
        ctrl = task.handover_controller("ps", stand=name, backend="cpu", num_samples=4)
        stage = ctrl.controllers[1]
        rows = []
        for seed, (time, states) in runs.items():
            up = [k for k in range(0, len(time), 4) if task.is_up(states[k])]
            for k in up[:: int(every or 1)]:
                speed, offset = task.balance_state(states[k])
                low = holds(task, stage, states[k])
                rows.append(
                    {
                        "seed": seed,
                        "t_s": round(float(time[k]), 3),
                        "posture_rad": round(task.posture_distance(states[k]), 3),
                        "com_speed_mps": round(speed, 3),
                        "com_offset_m": round(offset, 3),
                        "held": bool(low >= task.stand_height),
                        "min_torso_m": round(low, 3),
                    }
                )
        report["stages"][name] = {
            "period_s": stage.period,
            "keyframe_basin": keyframe_basin(task, stage, args.draws),
            "from_planner_states": f"{sum(r['held'] for r in rows)}/{len(rows)}",
            "states": rows,
        }
        brief = {k: v for k, v in report["stages"][name].items() if k != "states"}
        print(json.dumps({name: brief}), flush=True)
    print(json.dumps(report["planner_runs"], indent=1))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
