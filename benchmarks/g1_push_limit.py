"""Unitree's G1 on two feet: where the forward push limit lies and why (issue #13).

The target "QP-MPC or iLQR-MPC survives >= 1.3x LQR's largest forward push (0.1 s on the
pelvis)" is checked against the physics and against QP-MPC's options. Three parts:

* ``bounds``: capture-point estimates from the model at the reference state. With the
  linear inverted pendulum of the center of mass (height :math:`z`, :math:`\\omega =
  \\sqrt{g/z}`) and the center of pressure put on the toe line at once (distance :math:`d`
  ahead of the center of mass), a push :math:`F` of duration :math:`T` leaves the capture
  point :math:`\\xi = x + \\dot x/\\omega` at

  .. math:: \\xi(T) - d = -d\\,e^{\\omega T} + \\frac{F}{m\\omega^2}(e^{\\omega T} - 1),

  so the ankle strategy alone survives at most :math:`F_a = m\\omega^2 d\\,e^{\\omega T} /
  (e^{\\omega T} - 1)` (an upper bound: a real center of pressure needs time to move, and
  the pelvis is pushed slightly above the center of mass, whose angular momentum this
  neglects). A larger push needs the capture point pulled back by centroidal angular
  momentum (hip strategy): :math:`\\Delta\\xi = \\Delta L/(m z \\omega)`. A bang-bang upper
  body swing with torque :math:`\\tau` for :math:`t_1` then :math:`-\\tau` for :math:`t_1`
  moves it by at most :math:`\\frac{\\tau}{mg}(1 - e^{-\\omega t_1})^2` and turns the upper
  body (composite pitch inertia :math:`I_u` about the hips) by :math:`\\tau t_1^2/I_u`;
  ``bounds`` reports the swing angle that 1.3x LQR's push needs.
* ``searches``: the largest survived push (the bisection of ``g1_balance.py``: 0.1 s at 1 s
  on the pelvis, 2 s to recover, no noise, to ``--push-tolerance`` N) of LQR and of QP-MPC
  with the preset and with one option changed at a time (replanning period, horizon,
  ``dt``, terminal cost and scale, relinearization, the model's foot friction 0.6, the
  stance slack weight, the lifted-point force law). Each variant is fixed before it runs.
* ``traces``: what happens at each controller's smallest failed push and at its largest
  survived one, over the push and the second after it (heel lift as the foot's pitch, when
  the center of pressure reaches the toe, saturated actuators, time in the air, fallbacks).
* ``tick_serial``: QP-MPC's tick at the preset's 50 Hz and at 100 Hz, one ``--tick-seconds``
  run under the noise recipe (seed 0) each, in this process (one thread; other jobs on the
  machine still count): whether a faster replanning fits its period.

Needs ``MENAGERIE_ROOT``::

    python benchmarks/g1_push_limit.py --json benchmarks/results/g1_push_limit.json
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np
from json_report import finish  # benchmarks/ is not a package

from mpcbox.comparison.push_limits import largest_push
from mpcbox.comparison.scenario import PushTest
from mpcbox.registry import make_controller
from mpcbox.sim.simulation import simulate
from mpcbox.tasks.legged.biped import BipedStand

MODEL = "menagerie:unitree_g1"
#: QP-MPC variants: each changes the preset (``BipedStand.controller_configs["qp"]``) in one
#: respect (two for the finer QP step, which keeps the 0.2 s horizon).
VARIANTS: dict[str, dict] = {
    "preset": {},
    "period_0.01": {"period": 0.01},
    "dt_0.01_horizon_20_period_0.01": {"dt": 0.01, "horizon": 20, "period": 0.01},
    "horizon_25": {"horizon": 25},
    "terminal_scale_0.3": {"terminal_scale": 0.3},
    "terminal_scale_3": {"terminal_scale": 3.0},
    "terminal_stance": {"terminal": "stance"},
    "relinearize": {"relinearize": True},
    "friction_0.6": {"friction": 0.6},
    "stance_weight_1e4": {"stance_weight": 1e4},
    "lifted_force_law_cancel": {"lifted_force_law": "cancel"},
}


def _pitch(data: mujoco.MjData, body: int) -> float:
    """Forward pitch of a body's z axis from the vertical (deg)."""
    R = data.xmat[body].reshape(3, 3)
    return float(np.degrees(np.arctan2(R[0, 2], R[2, 2])))


def bounds(problem: BipedStand, lqr_push: float, ratio: float, duration: float) -> dict:
    """Capture-point estimates at the reference state (see the module docstring)."""
    m, d = problem.model, mujoco.MjData(problem.model)
    problem.set_state(d, problem.reference_state())
    mujoco.mj_forward(m, d)
    root = problem.root_id
    mass = float(m.body_subtreemass[root])
    g = float(-m.opt.gravity[2])
    com = d.subtree_com[root].copy()
    spheres = [
        i
        for i in range(m.ngeom)
        if m.geom_type[i] == mujoco.mjtGeom.mjGEOM_SPHERE
        and d.geom_xpos[i][2] - m.geom_size[i][0] < 1e-3
    ]
    xs = np.array([d.geom_xpos[i][0] for i in spheres])
    toe, heel = float(xs.max()), float(xs.min())
    z, dist = float(com[2]), toe - float(com[0])
    omega = np.sqrt(g / z)
    e = np.exp(omega * duration)
    ankle = mass * omega**2 * dist * e / (e - 1)

    def shortfall(force: float) -> float:  # xi(T) - toe (m)
        return float(-dist * e + force / (mass * omega**2) * (e - 1))

    # Upper body: the bodies above the hips (pelvis and waist subtree), pitch inertia about
    # the hip pitch axis (composite, y axis through the hips' mean position).
    hips = [m.body(n).id for n in ("left_hip_pitch_link", "right_hip_pitch_link")]
    pivot = np.mean([d.xanchor[m.body_jntadr[b]] for b in hips], axis=0)
    legs = set()
    for b in range(m.nbody):
        a = b
        while a not in (0, root):
            if a in hips:
                legs.add(b)
            a = m.body_parentid[a]
    upper = [b for b in range(1, m.nbody) if b not in legs]
    inertia = 0.0
    for b in upper:
        r = d.xipos[b] - pivot
        R = d.ximat[b].reshape(3, 3)
        Iw = R @ np.diag(m.body_inertia[b]) @ R.T
        inertia += Iw[1, 1] + m.body_mass[b] * (r[0] ** 2 + r[2] ** 2)
    jnt = {m.joint(j).name: j for j in range(m.njnt)}
    ankle_x = float(d.xanchor[jnt["left_ankle_pitch_joint"]][0])
    hip_tau = 2 * float(m.jnt_actfrcrange[jnt["left_hip_pitch_joint"]][1])
    friction = float(m.geom_friction[spheres[0]][0])
    # The hip torque reaches the ground as a horizontal force about z: friction caps it.
    tau = min(hip_tau, friction * mass * g * z)
    target = ratio * lqr_push
    need = shortfall(target)
    out: dict = {
        "mass_kg": round(mass, 3),
        "com_height_m": round(z, 4),
        "com_to_toe_m": round(dist, 4),
        "com_to_heel_m": round(float(com[0]) - heel, 4),
        "pelvis_above_com_m": round(float(d.xipos[root][2]) - z, 4),
        "omega_1_s": round(float(omega), 3),
        "foot_friction": friction,
        "ankle_pitch_force_range_Nm": float(m.jnt_actfrcrange[jnt["left_ankle_pitch_joint"]][1]),
        "ankle_torque_for_toe_cop_Nm_per_foot": round(mass * g * (toe - ankle_x) / 2, 1),
        "ankle_strategy_bound_N": round(float(ankle), 1),
        "lqr_push_N": lqr_push,
        "lqr_fraction_of_ankle_bound": round(lqr_push / float(ankle), 3),
        "target_N": round(target, 1),
        "target_capture_point_beyond_toe_m": round(need, 4),
        "target_angular_momentum_Nms": round(need * mass * z * float(omega), 2),
        "upper_body_mass_kg": round(float(sum(m.body_mass[b] for b in upper)), 2),
        "upper_body_pitch_inertia_about_hips_kgm2": round(float(inertia), 3),
        "hip_strategy_torque_Nm": round(tau, 1),
        "hip_strategy_torque_caps": {
            "hip_pitch_2x": hip_tau,
            "friction": round(friction * mass * g * z, 1),
        },
    }
    if need > 0:
        reach = tau / (mass * g)
        if need < reach:
            t1 = -np.log(1 - np.sqrt(need / reach)) / omega
            out["target_swing_half_time_s"] = round(float(t1), 4)
            out["target_upper_body_swing_rad"] = round(float(tau * t1**2 / inertia), 3)
        else:
            out["target_upper_body_swing_rad"] = None  # out of reach at any angle
        out["waist_pitch_range_rad"] = [
            round(float(v), 3) for v in m.jnt_range[jnt["waist_pitch_joint"]]
        ]
    return out


def trace(problem: BipedStand, controller, force: float, test: PushTest) -> dict:
    """What one pushed run does (module docstring, ``traces``)."""
    run = simulate(problem, controller, test.total_time, pushes=[test.push(force)], seed=0)
    m, d = problem.model, mujoco.MjData(problem.model)
    foot = m.body("left_ankle_roll_link").id
    toes = [
        i
        for i in range(m.ngeom)
        if m.geom_bodyid[i] == foot and m.geom_type[i] == mujoco.mjtGeom.mjGEOM_SPHERE
    ]
    root = problem.root_id
    limit = m.jnt_actfrcrange[m.actuator_trnid[:, 0]][:, 1]
    toe_time = None
    foot_pitch = air = 0.0
    saturated: set[str] = set()
    com_ahead = -np.inf
    step = float(m.opt.timestep)
    for k, t in enumerate(run.time[:-1]):
        if t < test.start:
            continue
        if t > test.start + test.duration + 1.0:  # the recovery, not the fall after it
            break
        problem.set_state(d, run.states[k])
        d.ctrl[:] = run.ctrls[k]
        mujoco.mj_forward(m, d)
        fz = cop = 0.0
        for i in range(d.ncon):
            f6 = np.zeros(6)
            mujoco.mj_contactForce(m, d, i, f6)
            fz, cop = fz + f6[0], cop + f6[0] * d.contact[i].pos[0]
        toe = max(d.geom_xpos[i][0] for i in toes)
        if fz < 1.0:
            air += step
        elif toe_time is None and cop / fz > toe - 0.005:
            toe_time = t - test.start
        foot_pitch = max(foot_pitch, _pitch(d, foot))
        com_ahead = max(com_ahead, d.subtree_com[root][0] - toe)
        tau = d.actuator_force
        for i in np.flatnonzero(np.abs(tau) > 0.99 * limit):
            saturated.add(m.actuator(i).name)
    return {
        "force_N": force,
        "survived": bool(run.metrics.success),
        "failure": run.failure,
        "cop_at_toe_after_s": None if toe_time is None else round(toe_time, 3),
        "max_foot_pitch_deg": round(foot_pitch, 1),
        "max_com_ahead_of_toe_m": round(float(com_ahead), 3),
        "airborne_s": round(air, 3),
        "saturated_actuators": sorted(saturated),
        "fallbacks": run.metrics.fallbacks,
        "tick_median_ms": round(run.metrics.compute_p50_ms, 2),
        "tick_p99_ms": round(run.metrics.compute_p99_ms, 2),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--push-tolerance", type=float, default=5.0, help="bisection (N)")
    parser.add_argument("--variants", default=",".join(VARIANTS), help="QP-MPC variants")
    parser.add_argument("--ratio", type=float, default=1.3, help="target push ratio to LQR")
    parser.add_argument("--tick-seconds", type=float, default=5.0, help="QP tick runs (s)")
    parser.add_argument("--json", default="", help="also write the JSON here")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    problem = BipedStand(MODEL, threads=1)
    weight = float(problem.model.body_subtreemass[problem.root_id]) * 9.81
    test = PushTest(
        body=problem.root, settle=2.0, tolerance=args.push_tolerance, max_force=5 * weight
    )
    out: dict = {
        "benchmark": "g1_push_limit",
        "model": MODEL,
        "push": {"start_s": test.start, "duration_s": test.duration, "settle_s": test.settle},
        "searches": {},
    }
    lqr = make_controller("lqr", problem)
    limit = largest_push(problem, lqr, test)
    out["searches"]["lqr"] = {
        "force_N": round(limit.force, 1),
        "smallest_failed_N": round(limit.smallest_failed, 1),
    }
    out["bounds"] = bounds(problem, round(limit.force, 1), args.ratio, test.duration)
    out["traces"] = {
        "lqr": [trace(problem, lqr, f, test) for f in (limit.force, limit.smallest_failed)]
    }
    for name in [v for v in args.variants.split(",") if v]:
        t1 = time.perf_counter()
        qp = make_controller("qp", problem, **VARIANTS[name])
        found = largest_push(problem, qp, test)
        out["searches"][f"qp:{name}"] = {
            "options": VARIANTS[name],
            "force_N": round(found.force, 1),
            "smallest_failed_N": round(found.smallest_failed, 1),
            "ratio_to_lqr": round(found.force / limit.force, 3),
            "wall_s": round(time.perf_counter() - t1, 1),
        }
        if name == "preset":
            out["traces"]["qp:preset"] = [
                trace(problem, qp, f, test) for f in (found.force, found.smallest_failed)
            ]
        print(name, out["searches"][f"qp:{name}"], file=sys.stderr, flush=True)
    if args.tick_seconds > 0:
        out["tick_serial"] = {}
        for period in (0.02, 0.01):
            qp = make_controller("qp", problem, period=period)
            run = simulate(problem, qp, args.tick_seconds, noise=problem.noise(), seed=0)
            out["tick_serial"][f"period_{period}"] = {
                "success": bool(run.metrics.success),
                "solves": run.metrics.solve_ticks,
                "fallbacks": run.metrics.fallbacks,
                "tick_median_ms": round(run.metrics.compute_p50_ms, 2),
                "tick_p99_ms": round(run.metrics.compute_p99_ms, 2),
            }
    problem.close()
    return finish(out, args.json, started=t0)


if __name__ == "__main__":
    sys.exit(main())
