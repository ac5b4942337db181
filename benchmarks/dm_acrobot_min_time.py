"""Minimum time to swing dm_control's acrobot (2 N m elbow) up: direct collocation, IPOPT.

Evidence for the time target of issue #13 ("upright within 5 s") on ``dm_acrobot_swingup``.
The acrobot's equations of motion are written in CasADi from the MuJoCo model's own numbers
(masses, centres of mass, inertias about the hinge axis, link length, joint damping,
armature, gear, gravity) and checked against MuJoCo's ``qacc`` (``mj_forward``) at random
states and controls (``dynamics_check``; the largest difference is recorded). With
``q = (shoulder, elbow)``, ``s_i = sin``, ``c_i = cos``, ``q_12 = q_1 + q_2`` and link ``i``
of mass ``m_i``, centre of mass ``r_i`` along it, inertia ``I_i`` about it, length ``l_1``:

    M(q) qdd = B u - D qd + g_q(q) + h sin(q_2) (2 qd_1 qd_2 + qd_2^2, -qd_1^2)

    M_11 = I_1 + I_2 + m_1 r_1^2 + m_2 (l_1^2 + r_2^2 + 2 l_1 r_2 c_2) + a_1
    M_12 = I_2 + m_2 (r_2^2 + l_1 r_2 c_2),  M_22 = I_2 + m_2 r_2^2 + a_2,  h = m_2 l_1 r_2
    g_q = g ((m_1 r_1 + m_2 l_1) s_1 + m_2 r_2 s_12,  m_2 r_2 s_12)

Two questions, each solved by multiple shooting (one RK4 step per interval, the model's
own integrator) with ``u`` in ``[-1, 1]``, from guesses made by mpcbox's iLQR on the RK4
model (:func:`random_guess`: ``--fixed`` given ``cos(w t + phi)`` seeds first, then
``--starts`` random ones; raw random guesses leave multiple shooting at the hanging rest):

- ``reach``: the least time ``T`` for the tip to come within ``--radius`` (0.2 m, the task's
  tolerance) of the target, at any speed: a lower bound on any controller's time to upright.
- ``rest``: the least time to the upright at rest (``q`` a multiple of ``2 pi``, ``qd = 0``).

Each uses ``--knots`` intervals of ``T / knots`` and shrinks ``T`` from ``--duration`` by
continuation (:func:`min_time`), ``reach`` from the ``rest`` solution. The best ``rest``
solution is then re-solved on the simulator's own grid (0.01 s steps, ``T`` rounded up to
it, least control effort) and its controls replayed in MuJoCo's RK4 simulation from the
hanging rest, where the final tip distance and speed are recorded. IPOPT is a local
solver: the times found are upper bounds on the true minimum (for ``rest``) and the best
lower-bound estimate a local search gives (for ``reach``), not proofs. Recorded result
(one seed, 162 knots): rest 6.31 s (6.32 s on the 0.01 s grid, replayed to 0.5 mm),
reach 5.94 s; in unrecorded runs about 14 random seeds (``--starts``) did not converge.

    nice -n 5 python benchmarks/dm_acrobot_min_time.py --fixed 2.928:4.584 --starts 0

Prints the JSON and writes it to ``benchmarks/results/dm_acrobot_min_time.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca
import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import dm_acrobot_reachability as reach  # benchmarks/ is not a package

from mpcbox.errors import PlanningModelWarning
from mpcbox.tasks.swingup.dm_control import suite_path

RESULTS = Path(__file__).parent / "results" / "dm_acrobot_min_time.json"


class AcrobotParameters(NamedTuple):
    """Numbers of a planar two-hinge chain read from a MuJoCo model (SI units)."""

    mass: tuple[float, float]
    com: tuple[float, float]
    inertia: tuple[float, float]
    length: float
    damping: tuple[float, float]
    armature: tuple[float, float]
    gear: float
    gravity: float
    dt: float


def parameters(model: mujoco.MjModel) -> AcrobotParameters:
    """The acrobot's masses, centres of mass along the links, inertias about the hinge axis.

    Both hinges must share one horizontal axis and each link's centre of mass must lie on
    the line from its hinge to the next (as in dm_control's acrobot).
    """
    bodies = [int(model.jnt_bodyid[j]) for j in range(2)]
    axis = model.jnt_axis[0]
    inertia = []
    for b in bodies:
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.body_iquat[b])
        rot = rot.reshape(3, 3)
        inertia.append(float(axis @ rot @ np.diag(model.body_inertia[b]) @ rot.T @ axis))
    return AcrobotParameters(
        mass=tuple(float(model.body_mass[b]) for b in bodies),
        com=tuple(float(np.linalg.norm(model.body_ipos[b])) for b in bodies),
        inertia=tuple(inertia),
        length=float(np.linalg.norm(model.body_pos[bodies[1]])),
        damping=tuple(float(d) for d in model.dof_damping[:2]),
        armature=tuple(float(a) for a in model.dof_armature[:2]),
        gear=float(model.actuator_gear[0, 0]),
        gravity=float(-model.opt.gravity[2]),
        dt=float(model.opt.timestep),
    )


def qacc(p: AcrobotParameters, q: Any, qd: Any, u: Any) -> Any:
    """Joint accelerations ``(2,)`` from the equations of motion in the module docstring.

    Works on NumPy arrays and on CasADi symbols alike.
    """
    (m1, m2), (r1, r2), (i1, i2), l1 = p.mass, p.com, p.inertia, p.length
    c2, s2 = ca.cos(q[1]), ca.sin(q[1])
    s1, s12 = ca.sin(q[0]), ca.sin(q[0] + q[1])
    m11 = i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2 + 2 * l1 * r2 * c2) + p.armature[0]
    m12 = i2 + m2 * (r2**2 + l1 * r2 * c2)
    m22 = i2 + m2 * r2**2 + p.armature[1]
    h = m2 * l1 * r2 * s2
    f1 = p.gravity * ((m1 * r1 + m2 * l1) * s1 + m2 * r2 * s12)
    f1 += h * (2 * qd[0] * qd[1] + qd[1] ** 2) - p.damping[0] * qd[0]
    f2 = p.gravity * m2 * r2 * s12 - h * qd[0] ** 2 - p.damping[1] * qd[1] + p.gear * u
    det = m11 * m22 - m12**2
    return ca.vertcat((m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det)


def rk4_step(p: AcrobotParameters, x: Any, u: Any, dt: Any) -> Any:
    """One classical RK4 step of the state ``x = (q, qd)`` ``(4,)`` with ``u`` held."""

    def f(z: Any) -> Any:
        return ca.vertcat(z[2:4], qacc(p, z[0:2], z[2:4], u))

    k1 = f(x)
    k2 = f(x + dt / 2 * k1)
    k3 = f(x + dt / 2 * k2)
    k4 = f(x + dt * k3)
    return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def dynamics_check(model: mujoco.MjModel, samples: int = 200, seed: int = 0) -> dict:
    """Largest ``|qacc|`` and one-step RK4 state differences, CasADi against MuJoCo."""
    p = parameters(model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    worst_acc = worst_step = 0.0
    for _ in range(samples):
        q, qd, u = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-8, 8, 2), rng.uniform(-1, 1)
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, qd, u
        mujoco.mj_forward(model, data)
        mine = np.asarray(qacc(p, q, qd, u)).ravel()
        worst_acc = max(worst_acc, float(np.max(np.abs(mine - data.qacc))))
        x1 = np.asarray(rk4_step(p, ca.DM(np.r_[q, qd]), u, p.dt)).ravel()
        mujoco.mj_step(model, data)
        worst_step = max(worst_step, float(np.max(np.abs(x1 - np.r_[data.qpos, data.qvel]))))
    return {"samples": samples, "max_qacc_diff": worst_acc, "max_rk4_step_diff": worst_step}


def tip(p: AcrobotParameters, q: Any) -> Any:
    """Tip ``(x, z)`` relative to the shoulder (the second link's length is ``2 r_2``)."""
    return ca.vertcat(
        p.length * ca.sin(q[0]) + 2 * p.com[1] * ca.sin(q[0] + q[1]),
        p.length * ca.cos(q[0]) + 2 * p.com[1] * ca.cos(q[0] + q[1]),
    )


def random_guess(
    p: AcrobotParameters,
    knots: int,
    duration: float,
    rng: np.random.Generator,
    iterations: int,
    wave: tuple[float, float] | None = None,
) -> tuple:
    """A random smooth control guess, pulled towards the upright by iLQR, on ``knots``.

    The guess ``cos(w t + phi)`` (``w`` in [2.2, 3.4] rad/s about the slow hanging mode's
    2.67, ``phi`` in [0, 2 pi); ``wave = (w, phi)`` fixes them)
    seeds mpcbox's iLQR (terminal tip weight 1000 and velocity weight 100 only, on the RK4
    model itself, ``Problem(plan_rk4=True)``, at IPOPT's step ``duration / knots``,
    ``iterations`` at most), a single-shooting method that escapes the hanging rest where
    multiple shooting from a raw guess stays; its plan (no defects: the same RK4 step) is
    IPOPT's guess, and the upright angles nearest its
    end (multiples of ``2 pi``) are the goal. Returns (ctrl ``(knots,)``, states
    ``(4, knots + 1)``, the raw guess's parameters, goal angles ``(2,)``).
    """
    problem, solver = reach.end_cost_solver(
        duration, iterations, planning_timestep=duration / knots, plan_rk4=True
    )
    steps = solver.horizon
    t = problem.dt * np.arange(steps)
    waves = [(1.0, *(wave or (rng.uniform(2.2, 3.4), rng.uniform(0, 2 * np.pi))))]
    ctrl = np.clip(sum(a * np.cos(w * t + f) for a, w, f in waves), -1, 1)
    plan = solver.solve(problem.initial_state(), ctrl[:, None])
    states, ctrls = plan.states.T, plan.ctrls[:, 0]
    goal = (2 * np.pi * np.round(states[:2, -1] / (2 * np.pi))).tolist()
    raw = [[round(float(v), 3) for v in wave] for wave in waves]
    return ctrls.copy(), states.copy(), raw, goal


def end_conditions(
    opti: Any, p: AcrobotParameters, end: Any, kind: str, radius: float, goal: Any
) -> None:
    """Constrain the final state ``(4,)``: ``"reach"`` (tip within ``radius``) or ``"rest"``
    (at rest at the upright joint angles ``goal`` ``(2,)``, multiples of ``2 pi``)."""
    if kind == "reach":
        target = ca.DM([0.0, p.length + 2 * p.com[1]])
        opti.subject_to(ca.sumsqr(tip(p, end[0:2]) - target) <= radius**2)
        return
    opti.subject_to(end[0:2] == ca.DM(goal))
    opti.subject_to(end[2:4] == 0)


def solve_fixed(
    p: AcrobotParameters,
    kind: str,
    duration: float,
    knots: int,
    radius: float,
    init: tuple,
    goal: Any,
) -> tuple[bool, np.ndarray, np.ndarray, int]:
    """Multiple shooting over a fixed ``duration`` from ``init = (ctrl, states)``.

    Minimizes control effort under :func:`end_conditions` for ``kind`` (``"reach"`` or
    ``"rest"``). Returns (solved, ctrl, states, iterations).
    """
    opti = ca.Opti()
    x = opti.variable(4, knots + 1)
    u = opti.variable(1, knots)
    effort = ca.sumsqr(u) / knots
    opti.subject_to(x[:, 0] == ca.DM([np.pi, 0, 0, 0]))
    opti.subject_to(opti.bounded(-1, u, 1))
    for k in range(knots):
        opti.subject_to(x[:, k + 1] == rk4_step(p, x[:, k], u[0, k], duration / knots))
    end = x[:, knots]
    opti.minimize(effort)
    end_conditions(opti, p, end, kind, radius, goal)
    opti.set_initial(u, init[0][None, :])
    opti.set_initial(x, init[1])
    opti.solver(
        "ipopt",
        {"print_time": False},
        {"print_level": 0, "max_iter": 400, "mu_strategy": "adaptive"},
    )
    try:
        sol = opti.solve()
        ok, value = True, sol.value
    except RuntimeError:
        ok, value = False, opti.debug.value
    iters = int(opti.stats().get("iter_count", -1))
    return ok, np.asarray(value(u)).ravel(), np.asarray(value(x)), iters


def min_time(
    p: AcrobotParameters,
    kind: str,
    knots: int,
    radius: float,
    start: tuple[float, np.ndarray, np.ndarray],
    step: float,
    goal: Any,
) -> dict:
    """Least ``T`` for ``kind`` by continuation from ``start = (T_0, ctrl, states)``.

    The hard problem is solved at ``T_0`` and, warm-started from each success, at
    durations shorter by ``step`` until IPOPT fails, then bisected twice. The controls and
    states keep their knots as ``T`` shrinks (each interval is ``T / knots``).
    """
    wall = time.perf_counter()
    duration, ctrl, states = start
    ok, ctrl, states, _ = solve_fixed(p, kind, duration, knots, radius, (ctrl, states), goal)
    if not ok:
        return {"kind": kind, "solved": False, "min_time_s": None}
    best = (duration, ctrl, states)
    low, high = None, duration
    while low is None:
        trial = high - step
        ok, c, s, _ = solve_fixed(p, kind, trial, knots, radius, best[1:], goal)
        if ok:
            best, high = (trial, c, s), trial
        else:
            low = trial
    for _ in range(2):
        trial = 0.5 * (low + high)
        ok, c, s, _ = solve_fixed(p, kind, trial, knots, radius, best[1:], goal)
        if ok:
            best, high = (trial, c, s), trial
        else:
            low = trial
    return {
        "kind": kind,
        "solved": True,
        "min_time_s": round(float(best[0]), 4),
        "failed_at_s": round(float(low), 4),
        "solve_s": round(time.perf_counter() - wall, 1),
        "_best": best,
        "_goal": goal,
    }


def refine_on_sim_grid(p: AcrobotParameters, best: dict) -> dict:
    """Re-solve ``rest`` at the simulator's 0.01 s step (``T`` rounded up), least effort."""
    duration, ctrl_old, states_old = best["_best"]
    steps = math.ceil(duration / p.dt - 1e-9)
    knots = ctrl_old.size
    t_old = np.linspace(0, duration, knots + 1)
    t_new = np.arange(steps + 1) * duration / steps
    opti = ca.Opti()
    x = opti.variable(4, steps + 1)
    u = opti.variable(1, steps)
    opti.minimize(ca.sumsqr(u))
    opti.subject_to(x[:, 0] == ca.DM([np.pi, 0, 0, 0]))
    opti.subject_to(opti.bounded(-1, u, 1))
    for k in range(steps):
        opti.subject_to(x[:, k + 1] == rk4_step(p, x[:, k], u[0, k], p.dt))
    end_conditions(opti, p, x[:, steps], "rest", 0.0, best["_goal"])
    opti.set_initial(x, np.stack([np.interp(t_new, t_old, row) for row in states_old]))
    held = np.minimum(np.searchsorted(t_old, t_new[:-1], side="right") - 1, knots - 1)
    opti.set_initial(u, ctrl_old[held][None, :])
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "max_iter": 3000})
    try:
        sol = opti.solve()
        ctrl, ok = np.asarray(sol.value(u)).ravel(), True
    except RuntimeError:
        ctrl, ok = np.asarray(opti.debug.value(u)).ravel(), False
    return {"steps": steps, "duration_s": round(steps * p.dt, 2), "solved": ok, "_ctrl": ctrl}


def replay(model: mujoco.MjModel, ctrl: np.ndarray) -> dict:
    """Final tip distance and joint speed after playing ``ctrl`` in MuJoCo from hanging."""
    data = mujoco.MjData(model)
    data.qpos[:] = [np.pi, 0.0]
    for c in ctrl:
        data.ctrl[0] = c
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    gap = data.site_xpos[model.site("target").id] - data.site_xpos[model.site("tip").id]
    return {
        "final_tip_error_m": float(np.linalg.norm(gap)),
        "final_speed_rad_s": float(np.linalg.norm(data.qvel)),
        "ctrl_at_limit_fraction": round(float(np.mean(np.abs(ctrl) > 0.99)), 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=20)
    parser.add_argument("--knots", type=int, default=162)
    parser.add_argument("--duration", type=float, default=6.5)
    parser.add_argument("--step", type=float, default=0.25)
    parser.add_argument("--ilqr-iterations", type=int, default=150)
    parser.add_argument("--radius", type=float, default=0.2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--fixed", default="", help="extra first guesses 'w:phi,w:phi' (e.g. 2.67:0)"
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore", PlanningModelWarning)
    model = mujoco.MjModel.from_xml_path(str(suite_path("acrobot")))
    p = parameters(model)
    check = dynamics_check(model)
    print(json.dumps({"dynamics_check": check}), flush=True)
    rng = np.random.default_rng(args.seed)
    runs, best = [], None
    fixed = [tuple(float(v) for v in f.split(":")) for f in args.fixed.split(",") if f]
    for start in range(len(fixed) + args.starts):
        wall = time.perf_counter()
        wave = fixed[start] if start < len(fixed) else None
        guess = random_guess(p, args.knots, args.duration, rng, args.ilqr_iterations, wave)
        ctrl, states, waves, goal = guess
        first = (args.duration, ctrl, states)
        rest = min_time(p, "rest", args.knots, args.radius, first, args.step, goal)
        reach = {"solved": False, "min_time_s": None}
        if rest["solved"]:
            reach = min_time(p, "reach", args.knots, args.radius, rest["_best"], args.step, goal)
            if best is None or rest["min_time_s"] < best["min_time_s"]:
                best = rest
        runs.append(
            {
                "start": start,
                "guess_waves_a_w_phi": waves,
                "ilqr_guess_final_state": states[:, -1].round(3).tolist(),
                "goal_angles": [round(g, 4) for g in goal],
                "rest_min_time_s": rest["min_time_s"],
                "rest_failed_at_s": rest.get("failed_at_s"),
                "reach_min_time_s": reach["min_time_s"],
                "reach_failed_at_s": reach.get("failed_at_s"),
                "wall_s": round(time.perf_counter() - wall, 1),
            }
        )
        print(json.dumps(runs[-1]), flush=True)
        RESULTS.parent.mkdir(exist_ok=True)
        RESULTS.write_text(json.dumps({"partial": True, "runs": runs}, indent=2) + "\n")
    rest_times = sorted(r["rest_min_time_s"] for r in runs if r["rest_min_time_s"])
    reach_times = sorted(r["reach_min_time_s"] for r in runs if r["reach_min_time_s"])
    out: dict[str, Any] = {
        "benchmark": "dm_acrobot_min_time",
        "machine": {
            "description": "2-core sandbox CPU, shared",
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "settings": vars(args),
        "parameters": p._asdict(),
        "dynamics_check": check,
        "rest": {
            "solved": f"{len(rest_times)}/{len(runs)}",
            "best_min_time_s": rest_times[0] if rest_times else None,
            "times_s": rest_times,
        },
        "reach": {
            "solved": f"{len(reach_times)}/{len(runs)}",
            "best_min_time_s": reach_times[0] if reach_times else None,
            "times_s": reach_times,
        },
        "runs": runs,
    }
    if best is not None:
        refined = refine_on_sim_grid(p, best)
        refined.update(replay(model, refined.pop("_ctrl")))
        out["rest"]["on_sim_grid"] = refined
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "runs"}, indent=2))


if __name__ == "__main__":
    main()
