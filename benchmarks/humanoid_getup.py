"""Humanoid get-up (``humanoid_getup``) in the real-time loop: success and time taken; JSON.

    PYTHONUNBUFFERED=1 python benchmarks/humanoid_getup.py --backend warp --seeds 2 \\
        --variants "base;nobal:task.balance_cost=0" --final-seeds 10

Each variant (``task.<kwarg>=v`` for :class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup`,
``<field>=v`` for the controller config; ``hand.stand=C`` and optionally
``hand.transfer=false``, ``stand.<field>=v`` (its config) and ``standtask.<kwarg>=v`` (its
:class:`~mpcbox.tasks.humanoid.stand.HumanoidStand`) build the task-stage hand-over of
:meth:`~mpcbox.tasks.humanoid.getup.HumanoidGetup.handover_controller` instead, ``C`` the
standing stage's controller; ``hand.stand_on=getup`` plans that stage on the get-up task
itself, and ``stand.noise_factor=F`` gives it the get-up config's noise times ``F``) runs
every controller for ``--seeds`` seeds (from
``--first-seed``, default 0) of ``--duration`` s in
:func:`~mpcbox.sim.realtime.simulate_realtime` (``--loop lockstep``: :func:`mpcbox.simulate`,
the world waits for the planner) (seed ``s``: joint angles
of the lying start perturbed by N(0, 0.05) rad after the settle, controller seed ``s``).
Reported per run: outcome, the time it got up for good (``getup_time``), the highest torso
height, tick p50/p99 and whether the planner kept up. With ``--final-seeds`` the best
(variant, controller) of that screen (most successes, then highest mean torso height) is
run again over that many seeds (``--final-first-seed``, default 100, and on), fixed before
those runs; with ``--seeds 0``
the screen is skipped and the first variant and controller are the final ones.
``--task g1_getup`` (or any registered get-up task) runs the same on that task, e.g.
Unitree's G1 (:class:`~mpcbox.tasks.humanoid.g1_getup.G1Getup`, needs ``MENAGERIE_ROOT``).
``task.servo=KP/KV`` runs the task on a servo copy of the project's humanoid
(:func:`servo_humanoid`): the planner samples joint set-points instead of torques.
Also per run: when the torso was first up (``first_up_s``, :meth:`HumanoidGetup.is_up`), the
hand-over's switches and their times, and the torso height every 0.1 s.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import numpy as np

import mpcbox
from mpcbox.cli.checks import lookahead_option
from mpcbox.registry import task_class
from mpcbox.sim.realtime import simulate_realtime


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_variants(text: str) -> dict[str, tuple[dict, dict, dict]]:
    out = {}
    for item in filter(None, text.split(";")):
        name, _, rest = item.partition(":")
        task, ctrl, hand = {}, {}, {}
        for pair in filter(None, rest.split(",")):
            key, _, val = pair.partition("=")
            key = key.strip()
            if key.startswith("task."):
                task[key[5:]] = _value(val)
            elif key.startswith("hand."):
                hand[key[5:]] = _value(val)
            elif key.startswith("stand."):
                hand.setdefault("stand_options", {})[key[6:]] = _value(val)
            elif key.startswith("standtask."):
                hand.setdefault("stand_task", {})[key[10:]] = _value(val)
            else:
                ctrl[key] = _value(val)
        out[name.strip()] = (task, ctrl, hand)
    return out


def servo_humanoid(kp: float, kv: float) -> str:
    """The project's humanoid with each motor (gear ``g``) replaced by a position servo of
    the same torque limit: ``kp * g`` N m/rad, ``kv * g`` N m s/rad, set-points over the
    joint's range, force clamped to ``[-g, g]``. Returns the path of the written MJCF."""
    import tempfile

    import mujoco

    from mpcbox.tasks import scene_path

    spec = mujoco.MjSpec.from_file(str(scene_path("humanoid.xml")))
    for act in spec.actuators:
        gear = float(act.gear[0])
        act.set_to_position(kp=kp * gear, kv=kv * gear)
        act.gear[0] = 1.0
        act.inheritrange = 1.0
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-gear, gear]
    path = Path(tempfile.mkdtemp()) / f"humanoid_servo_kp{kp:g}_kv{kv:g}.xml"
    path.write_text(spec.to_xml())
    return str(path)


def task_options(task_kw: dict) -> dict:
    """``task_kw`` with ``servo="KP/KV"`` turned into the servo model's path."""
    opts = dict(task_kw)
    if "servo" in opts:
        kp, _, kv = str(opts.pop("servo")).partition("/")
        opts["model"] = servo_humanoid(float(kp), float(kv))
    return opts


def build(problem, name, ctrl_opts, hand, seed, backend):
    factor = hand.get("stand_options", {}).get("noise_factor")
    if factor is not None:  # stand.noise_factor=F: the get-up noise times F, once up
        hand = {**hand, "stand_options": dict(hand["stand_options"])}
        del hand["stand_options"]["noise_factor"]
        base = problem.controller_configs[hand.get("stand", name)].noise_scale
        hand["stand_options"]["noise_scale"] = np.asarray(base) * float(factor)
    if hand:
        return problem.handover_controller(name, backend=backend, seed=seed, **hand, **ctrl_opts)
    return mpcbox.make_controller(name, problem, backend=backend, seed=seed, **ctrl_opts)


def first_up(problem, time, states) -> float:
    for t, x in zip(time, states):
        if problem.is_up(x):
            return float(t)
    return float("nan")


def run(
    problem, name, ctrl_opts, hand, seed, duration, backend, loop="realtime", lookahead=None
) -> dict:
    ctrl = build(problem, name, ctrl_opts, hand, seed, backend)
    init = problem.initial_state()
    if seed:
        rng = np.random.default_rng(seed)
        init[7 : problem.nq] += rng.normal(0, 0.05, problem.nq - 7)
    if loop == "lockstep":
        res = mpcbox.simulate(problem, ctrl, duration, initial_state=init, stop_on_failure=False)
    else:
        res = simulate_realtime(
            problem,
            ctrl,
            duration,
            initial_state=init,
            stop_on_failure=False,
            lookahead=lookahead,
        )
    heights = problem.torso_heights(res.states)
    dt = float(np.median(np.diff(res.time))) if len(res.time) > 1 else 0.1
    rt = getattr(res, "realtime", None)
    ticks_ms = 1e3 * np.asarray(res.compute_times[1:])  # the first (compiling) tick left out
    stats = ctrl.stats
    if hasattr(ctrl, "close"):
        ctrl.close()
    return {
        "seed": seed,
        "outcome": res.metrics.outcome,
        "getup_time_s": problem.getup_time(res.time, res.states),
        "max_torso_m": float(heights.max()),
        "final_torso_m": float(heights[-1]),
        "loop": loop,
        "tick_p50_ms": rt.latency_p50_ms if rt else float(np.percentile(ticks_ms, 50)),
        "tick_p99_ms": rt.latency_p99_ms if rt else float(np.percentile(ticks_ms, 99)),
        "kept_up": rt.kept_up if rt else None,
        "over_period_share": rt.over_period_share if rt else None,
        "first_up_s": first_up(problem, res.time, res.states),
        "switches": stats.get("switches"),
        "switch_times_s": getattr(ctrl, "switch_times", None),
        "torso_every_0.1s": [round(float(z), 3) for z in heights[:: max(1, round(0.1 / dt))]],
        "prime_ms": rt.prime_ms if rt else None,
        "lookahead_mean_s": rt.lookahead_mean_s if rt else None,
    }


def summary(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["outcome"] == "success"]
    return {
        "successes": len(ok),
        "runs": len(rows),
        "mean_getup_time_s": float(np.mean([r["getup_time_s"] for r in ok])) if ok else None,
        "mean_max_torso_m": float(np.mean([r["max_torso_m"] for r in rows])),
        "kept_up_rate": float(np.mean([bool(r["kept_up"]) for r in rows])),
        "tick_p99_ms_max": float(max(r["tick_p99_ms"] for r in rows)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="humanoid_getup")
    parser.add_argument("--controllers", default="ps,mppi,cem")
    parser.add_argument("--variants", default="base")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--final-seeds", type=int, default=0)
    parser.add_argument("--final-first-seed", type=int, default=100)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--loop", choices=("realtime", "lockstep"), default="realtime")
    parser.add_argument(
        "--lookahead",
        default=None,
        help="real-time loop: plan from the state predicted this far ahead (s) or 'auto'",
    )
    parser.add_argument("--gpu", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    loop_options = {
        "duration": args.duration,
        "backend": args.backend,
        "loop": args.loop,
        "lookahead": lookahead_option(args.lookahead),
    }
    report: dict = {
        "command": "python benchmarks/humanoid_getup.py " + " ".join(sys.argv[1:]),
        "task": args.task,
        "gpu": args.gpu,
        "platform": platform.platform(),
        "backend": args.backend,
        "loop": args.loop,
        "lookahead": args.lookahead,
        "duration_s": args.duration,
        "screen": {},
    }

    def save() -> None:
        if args.json:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(json.dumps(report, indent=1) + "\n")

    best, best_key = None, None
    variants = parse_variants(args.variants)
    if args.seeds == 0:
        best = (next(iter(variants)), args.controllers.split(",")[0])
    for vname, (task_kw, ctrl_kw, hand) in variants.items():
        if args.seeds == 0:
            break
        problem = task_class(args.task)(**task_options(task_kw))
        for name in args.controllers.split(","):
            rows = []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                try:
                    rows.append(run(problem, name, ctrl_kw, hand, seed, **loop_options))
                except Exception as exc:
                    failed = {"seed": seed, "error": repr(exc), "outcome": "error"}
                    failed.update(max_torso_m=0.0, kept_up=False, tick_p99_ms=np.nan)
                    rows.append(failed)
                print(json.dumps({vname: {name: rows[-1]}}), flush=True)
            entry = {"task_options": task_kw, "controller_options": ctrl_kw, "handover": hand}
            entry["runs"] = rows
            entry["summary"] = summary(rows)
            report["screen"][f"{vname}/{name}"] = entry
            key = (entry["summary"]["successes"], entry["summary"]["mean_max_torso_m"])
            if best_key is None or key > best_key:
                best, best_key = (vname, name), key
            save()
    if args.final_seeds and best is not None:
        vname, name = best
        task_kw, ctrl_kw, hand = variants[vname]
        problem = task_class(args.task)(**task_options(task_kw))
        rows = []
        first = args.final_first_seed
        for seed in range(first, first + args.final_seeds):
            rows.append(run(problem, name, ctrl_kw, hand, seed, **loop_options))
            print(json.dumps({"final": rows[-1]}), flush=True)
            report["final"] = {"variant": vname, "controller": name, "runs": rows}
            report["final"].update(task_options=task_kw, controller_options=ctrl_kw)
            report["final"]["handover"] = hand
            save()
        report["final"]["summary"] = summary(rows)
        save()
    print(json.dumps({k: v["summary"] for k, v in report["screen"].items()}, indent=1))
    if "final" in report:
        print(json.dumps(report["final"]["summary"]))


if __name__ == "__main__":
    main()
