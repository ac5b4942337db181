"""Lock-step vs real-time closed loop for the sampling controllers; prints JSON.

Runs the cart-pole swing-up (``CartpoleSwingup``) with each controller's task defaults
twice per seed: in :func:`mpcbox.simulate` (the world waits for the planner) and in
:func:`mpcbox.sim.realtime.simulate_realtime` (it does not). Reports per controller and
loop: outcomes, success rate, tick latency (p50/p99), state age, share of ticks over the
control period and whether the planner kept up::

    python benchmarks/realtime.py                                  # CPU, ps/mppi/cem, 2 seeds
    python benchmarks/realtime.py --backend warp --seeds 5 --json OUT.json
    python benchmarks/realtime.py --task humanoid_stand --backend warp --loops realtime

Robustness beyond the tuned scenario (issue #17), with every setting fixed on the command
line before the runs: ``--noise-scale`` scales the task's noise recipe
(``problem.noise(scale)``), ``--push F,START,DURATION`` pushes the task's root body with a
force of ``F`` newtons whose direction turns by 90 degrees from seed to seed (+x, +y, -x,
-y), and ``--mass-scale`` makes the simulated plant heavier than the planning model
(:class:`~mpcbox.sim.disturbances.ModelMismatch`)::

    python benchmarks/realtime.py --task humanoid_stand --backend warp --loops realtime \
        --seeds 10 --first-seed 100 --noise-scale 1.5 --push 40,2.0,0.1 --mass-scale 1.1

``--task`` takes any registered task (default the cart-pole swing-up), ``--task-set`` its
keyword arguments; ``--period`` defaults to each controller's tuned period.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import numpy as np
from quadruped_walk import parse_set

import mpcbox
from mpcbox.cli.checks import check_output_folder, lookahead_option, number_flag, script_main
from mpcbox.comparison.records import gpu_names
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.registry import task_class
from mpcbox.sim.disturbances import ModelMismatch, Push
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.validation import integer, positive_int

LOOPS = ("lockstep", "realtime")


def check_args(args: argparse.Namespace) -> list[float] | None:
    """Every number and name before any run (a named :class:`MpcboxError`); returns the
    parsed ``--push`` (force, start, duration) or ``None``."""
    from mpcbox.registry import controller_class

    for loop in args.loops.split(","):
        if loop not in LOOPS:
            raise UnknownNameError("--loops entry", loop, LOOPS)
    for name in args.controllers.split(","):
        fields = getattr(controller_class(name).config_class, "__dataclass_fields__", {})
        if "backend" not in fields:
            raise InvalidArgumentError(
                f"--controllers: {name!r} is not a sampling controller (this benchmark runs "
                "ps, mppi and cem with --backend)"
            )
    positive_int("--seeds", args.seeds)
    integer("--first-seed", args.first_seed, minimum=0)
    number_flag("--duration", args.duration, low=0.0)
    number_flag("--speed", args.speed, low=0.0)
    number_flag("--start-perturbation", args.start_perturbation, low=0.0, strict=False)
    for flag in ("--period", "--mass-scale", "--delay", "--noise-scale"):
        value = getattr(args, flag[2:].replace("-", "_"))
        if value is not None:
            number_flag(flag, value, low=0.0, strict=flag in ("--period", "--mass-scale"))
    if args.num_samples is not None:
        positive_int("--num-samples", args.num_samples)
    if args.json:
        check_output_folder(Path(args.json).parent, "--json")
    if not args.push:
        return None
    try:
        spec = [float(v) for v in args.push.split(",")]
    except ValueError:
        spec = []
    if len(spec) != 3:
        raise InvalidArgumentError(f"--push takes FORCE,START,DURATION, got {args.push!r}")
    number_flag("--push force", spec[0], low=0.0, strict=False)
    number_flag("--push start", spec[1], low=0.0, strict=False)
    number_flag("--push duration", spec[2], low=0.0)
    return spec


def main() -> int:
    """Run the loops; a bad argument prints its named error and returns 2."""
    return script_main(_run, None)


def _run(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--task", default="cartpole_swingup")
    parser.add_argument("--loops", default="lockstep,realtime")
    parser.add_argument("--controllers", default="ps,mppi,cem")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--num-samples", type=int, default=None)
    parser.add_argument("--period", type=float, default=None)
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument(
        "--lookahead", default=None, help="real-time loop: seconds or 'auto' (default: none)"
    )
    parser.add_argument(
        "--delay",
        type=float,
        default=None,
        help="real-time loop: a simulated latency (s) instead of the wall clock",
    )
    parser.add_argument(
        "--set",
        default="",
        help="config fields for every controller, e.g. planning_timestep=0.015,horizon=0.48",
    )
    parser.add_argument(
        "--task-set",
        default="",
        help="keyword arguments of the task, e.g. com_velocity_cost=30",
    )
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--noise-scale", type=float, default=None)
    parser.add_argument("--push", default=None, help="FORCE,START,DURATION on the root body")
    parser.add_argument("--mass-scale", type=float, default=None)
    parser.add_argument(
        "--start-perturbation",
        type=float,
        default=0.05,
        help="std of the Gaussian added to qpos at the start of every seed but 0",
    )
    parser.add_argument("--gpu", default=None, help="GPU name to record (default nvidia-smi)")
    parser.add_argument("--machine", default="2-core sandbox CPU, shared")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    lookahead = lookahead_option(args.lookahead)
    push_spec = check_args(args)

    problem = task_class(args.task)(**parse_set(args.task_set))
    noise = problem.noise(args.noise_scale) if args.noise_scale is not None else None
    mismatch = ModelMismatch(mass_scale=args.mass_scale) if args.mass_scale else None
    report: dict = {
        "task": args.task,
        "machine": args.machine,
        "gpu": args.gpu or (next(iter(gpu_names()), None) if args.backend == "warp" else None),
        "set": args.set,
        "task_set": args.task_set,
        "platform": platform.platform(),
        "backend": args.backend,
        "duration_s": args.duration,
        "seeds": args.seeds,
        "period_s": args.period,
        "speed": args.speed,
        "lookahead": args.lookahead,
        "delay_s": args.delay,
        "command": "python benchmarks/realtime.py " + " ".join(sys.argv[1:]),
        "first_seed": args.first_seed,
        "noise_scale": args.noise_scale,
        "push": dict(zip(("force_n", "start_s", "duration_s"), push_spec)) if push_spec else None,
        "mass_scale": args.mass_scale,
        "start_perturbation": args.start_perturbation,
        "results": {},
    }
    for name in args.controllers.split(","):
        options: dict = {"backend": args.backend}
        if args.period is not None:
            options["period"] = args.period
        if args.num_samples is not None:
            options["num_samples"] = args.num_samples
        options.update(parse_set(args.set))
        ctrl = mpcbox.make_controller(name, problem, **options)
        entry: dict = {}
        entry["period_s"] = ctrl.period
        entry["num_samples"] = ctrl.config.num_samples
        for loop in args.loops.split(","):
            rows = []
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                disturb = dict(noise=noise, mismatch=mismatch, seed=seed, pushes=())
                if push_spec:
                    force, start, length = push_spec
                    angle = 0.5 * np.pi * (seed % 4)
                    direction = (np.cos(angle), np.sin(angle), 0.0)
                    disturb["pushes"] = [
                        Push(
                            force=force * np.round(direction, 12),
                            start=start,
                            duration=length,
                            body=problem.root,
                        )
                    ]
                init = problem.initial_state()
                if seed and args.start_perturbation:
                    rng = np.random.default_rng(seed)
                    jitter = rng.normal(0, args.start_perturbation, problem.nq)
                    init = init + np.concatenate([jitter, np.zeros(problem.nv + problem.na)])
                if loop == "lockstep":
                    res = mpcbox.simulate(
                        problem, ctrl, args.duration, initial_state=init, **disturb
                    )
                else:
                    res = simulate_realtime(
                        problem,
                        ctrl,
                        args.duration,
                        initial_state=init,
                        speed=args.speed,
                        lookahead=lookahead,
                        delay=args.delay,
                        **disturb,
                    )
                row = {
                    "seed": seed,
                    "outcome": res.metrics.outcome,
                    "time_to_fall_s": res.metrics.time_to_fall,
                    "tick_p50_ms": res.metrics.compute_p50_ms,
                    "tick_p99_ms": res.metrics.compute_p99_ms,
                }
                if loop == "realtime":
                    rt = res.realtime
                    row.update(
                        kept_up=rt.kept_up,
                        ticks=rt.ticks,
                        over_period_share=rt.over_period_share,
                        lookahead_mean_s=rt.lookahead_mean_s,
                        state_age_mean_ms=rt.state_age_mean_s * 1e3,
                        world_lag_ms=rt.world_lag_s * 1e3,
                        sim_over_wall=rt.sim_time_s / rt.wall_time_s,
                    )
                rows.append(row)
            entry[loop] = {
                "success_rate": float(np.mean([r["outcome"] == "success" for r in rows])),
                "runs": rows,
            }
            if loop == "realtime":
                entry[loop]["kept_up_rate"] = float(np.mean([r["kept_up"] for r in rows]))
        report["results"][name] = entry
        if hasattr(ctrl, "close"):
            ctrl.close()
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
