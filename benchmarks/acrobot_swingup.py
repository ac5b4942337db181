"""Acrobot swing-ups by iLQR: mpcbox's acrobot in closed loop, dm_control's offline.

``acrobot_swingup`` (6 N m elbow, :class:`mpcbox.tasks.swingup.AcrobotSwingup`): iLQR-MPC
with the preset's tuned config (4 s plan from the control guess ``cos(5 t)``, 400 iterations
before the first control, one per 0.02 s replan) from the hanging rest and from ``--seeds``
starts with both angles perturbed by N(0, 0.05) rad, ``--duration`` seconds through
:func:`mpcbox.simulate`; success is the task's ``goal_failure`` (upright within 0.2 rad over
the last second).

``dm_acrobot_swingup`` (dm_control's, 2 N m elbow), offline only: multiple shooting from a
time-reversed state guess. Falling from upright (angles perturbed by N(0, 0.05) rad) on an
undamped RK4 copy of the planning model with the energy-draining elbow law
``u = -clip(c v_elbow, -1, 1)`` (c drawn in [0.2, 5]; 400 draws; the ``--keep`` that come
closest to the hanging rest within 8 s are kept, each cut where it is closest) gives
trajectories whose time reverse (flip the velocities, reverse the controls) is nearly a
swing-up of the damped model. It is the
state and control guess of iLQR (``states_init``), with running tip weight 1, terminal tip
weight 1000 and terminal velocity weight 100. Records the tip's distance to the target at the
end and its largest distance over the last second.

    nice -n 5 python benchmarks/acrobot_swingup.py [--seeds 4] [--duration 6]

Prints the JSON and writes it to ``benchmarks/results/acrobot_swingup.json``.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import time
import warnings
from pathlib import Path

import mujoco
import numpy as np

import mpcbox
from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.tasks.swingup import AcrobotSwingup, SwingupWeights
from mpcbox.tasks.swingup.dm_control import DmAcrobotSwingup

RESULTS = Path(__file__).parent / "results" / "acrobot_swingup.json"


def closed_loop(seed: int, duration: float) -> dict:
    start = AcrobotSwingup(threads=1).initial_state()
    if seed:
        start[:2] += np.random.default_rng(seed).normal(0.0, 0.05, 2)
    problem = AcrobotSwingup(initial=start, threads=1)
    controller = mpcbox.make_controller("ilqr", problem)
    wall = time.perf_counter()
    result = mpcbox.simulate(problem, controller, duration)
    wall = time.perf_counter() - wall
    errors = problem.upright_errors(result.states)
    ticks = np.asarray(result.compute_times)  # online calls (the offline solve is not timed)
    return {
        "seed": seed,
        "start_qpos": np.round(start[:2], 4).tolist(),
        "success": problem.goal_failure(result.time, result.states) is None,
        "failure": problem.goal_failure(result.time, result.states),
        "time_to_upright_s": float(problem.time_to_upright(result.time, result.states)),
        "final_error_rad": float(errors[-1]),
        "median_tick_ms": 1e3 * float(np.median(ticks)),
        "wall_s": wall,
    }


def reversed_guesses(
    problem: DmAcrobotSwingup, draws: int, seconds: float, keep: int, seed: int = 0
) -> list:
    """The ``keep`` time-reversed energy-draining falls from upright that end closest to the
    hanging rest (see the module docstring), as (distance, states, controls)."""
    dt, up = problem.dt, np.zeros(4)
    fine = copy.deepcopy(problem.planning_model)
    fine.dof_damping[:] = 0.0
    fine.opt.timestep, fine.opt.integrator = 0.001, mujoco.mjtIntegrator.mjINT_RK4
    data, sub = mujoco.MjData(fine), round(dt / 0.001)
    hanging = problem.initial_state()
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(draws):
        gain = rng.uniform(0.2, 5.0)
        mujoco.mj_resetData(fine, data)
        data.qpos[:] = up[:2] + rng.normal(0.0, 0.05, 2)
        states, ctrls = [np.r_[data.qpos, data.qvel]], []
        for _ in range(round(seconds / dt)):
            data.ctrl[:] = -np.clip(gain * data.qvel[1], -1.0, 1.0)
            ctrls.append(data.ctrl.copy())
            for _ in range(sub):
                mujoco.mj_step(fine, data)
            states.append(np.r_[data.qpos, data.qvel])
        states = np.array(states)
        wrapped = (states[:, :2] - hanging[:2] + np.pi) % (2 * np.pi) - np.pi
        dist = np.sqrt((wrapped**2).sum(1) + 0.3 * (states[:, 2:] ** 2).sum(1))
        j = 100 + int(np.argmin(dist[100:]))
        reverse = states[j::-1].copy()
        reverse[:, 2:] *= -1.0
        found.append((float(dist[j]), reverse, np.array(ctrls[:j])[::-1].copy()))
    return sorted(found, key=lambda f: f[0])[:keep]


def dm_offline(draws: int, keep: int) -> list[dict]:
    weights = SwingupWeights(
        site=1.0,
        velocity=0.01,
        ctrl=0.01,
        position=0.0,
        angle=0.0,
        terminal_site=1000.0,
        terminal_velocity=100.0,
        terminal_position=0.0,
        terminal_angle=0.0,
    )
    # Planned on the implicitfast copy, as recorded (the task now defaults to plan_rk4=True).
    problem = DmAcrobotSwingup(planning_timestep=0.02, threads=1, weights=weights, plan_rk4=False)
    t0 = time.perf_counter()
    guesses = reversed_guesses(problem, draws, 8.0, keep)
    t_guess = time.perf_counter() - t0
    rows = []
    for dist, states, ctrls in guesses:
        horizon = len(ctrls)
        solver = ILQRSolver(problem, horizon=horizon, max_iterations=600, tolerance=1e-9, threads=1)
        t0 = time.perf_counter()
        res = solver.solve(problem.initial_state(), ctrls, states_init=states)
        errors = problem.upright_errors(res.states)
        rows.append(
            {
                "guess_distance_to_hanging_rest": dist,
                "guess_s": t_guess,
                "horizon": horizon,
                "plan_seconds": horizon * problem.dt,
                "iterations": res.iterations,
                "status": res.status,
                "solve_s": time.perf_counter() - t0,
                "final_tip_error_m": float(errors[-1]),
                "max_tip_error_last_second_m": float(errors[-round(1.0 / problem.dt) - 1 :].max()),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--draws", type=int, default=400)
    parser.add_argument("--keep", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    runs = [closed_loop(seed, args.duration) for seed in range(args.seeds + 1)]
    out = {
        "benchmark": "acrobot_swingup",
        "machine": {
            "description": "2-core sandbox CPU, shared",
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "settings": vars(args),
        "acrobot_swingup_ilqr_mpc": {
            "successes": f"{sum(r['success'] for r in runs)}/{len(runs)}",
            "runs": runs,
        },
        "dm_acrobot_swingup_offline_reversed_guess": dm_offline(args.draws, args.keep),
    }
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
