"""mpcbox's iLQR (single and multiple shooting) against Crocoddyl's box-FDDP, one process.

Problems: pendulum swing-up (150 x 0.02 s), cart-pole swing-up (150 x 0.02 s) and a 7-DoF
torque-controlled Panda reach (40 x 0.01 s): ``arm`` is the Panda of the ``panda.urdf`` that
Crocoddyl's wheel ships (example-robot-data: its masses and inertias, joint damping 0.003, no
armature, the fingers fixed), with joint motors limited to the Franka torque limits, reaching
0.3 m along each axis (x, y and -z) from the ``home`` posture, control guess the torques that
hold the start posture still (gravity compensation, what a real Panda adds to a zero torque
command); ``arm_menagerie`` is the easier reach of earlier runs (Menagerie's
``panda_nohand.xml``, armature 0.1, motors instead of its servos, 0.15 / 0.1 / -0.15 m, guess
``ctrl_ref``: the torques that hold the goal posture, kept so its row compares with earlier
runs). Crocoddyl runs the same MuJoCo dynamics through a Python action model: ``calc`` is
one ``mj_step`` of mpcbox's planning model (:meth:`mpcbox.Problem.step`) plus the running
cost, ``calcDiff`` is ``mjd_transitionFD`` (:meth:`mpcbox.Problem.linearize`) plus the
Gauss-Newton cost model (:meth:`mpcbox.Problem.quadratize`); horizon, control limits and
initial guesses are the same.

Each solver runs twice per problem: from the control guess alone (single shooting; Crocoddyl
with the rollout of that guess, ``is_feasible=True``) and from zero controls with a state guess
(multiple shooting: a straight line hanging -> upright for the swing-ups, the start state held
for the arm). The final cost of every solution is scored by one common rollout of its controls
from the start state (:meth:`mpcbox.Problem.rollout_cost`). Derivative evaluations and rollouts
are counted in whole trajectories (calls per knot / ``T``).

Crocoddyl's wall time includes its Python callbacks, which call mpcbox's checked one-knot API
(``Problem.step``, ``running_cost``, ``linearize``, ``quadratize``) and dominate it; the JSON
also gives the time inside them and the wall time without them (Crocoddyl's own C++ work), the
fair reference for mpcbox's solver overhead.

Every solution also gets a finite-difference stationarity check of its rollout cost over
the controls (:func:`stationarity`), and on the arms a check of how hard it drives the joints
(:func:`joint_motion`: largest joint speed against the Franka datasheet's 2.175 / 2.61 rad/s,
closest approach to a joint limit). On ``arm``, earlier runs started single shooting from the
torques that hold the goal posture; applied at ``home`` they throw joint 2 backward, and both
solvers ended at a non-stationary point of the cost's jump where that joint meets its lower
limit at about -12 rad/s (1925.53 vs 1916.39). From the torques that hold the start posture
both shooting modes of both solvers reach the same smooth minimum (586.0285, relative gap
< 1.1e-7, a 1e-5 step down the gradient lowers the cost): the joints stay below 0.55 of their
datasheet speed and at least 1.4 rad from their limits, and no torque saturates. The
optimum ends 0.29 m short of the 0.52 m reach at 0.4 s: the cost trades the remaining
distance against joint speed and torque.

Crocoddyl is optional (``pip install crocoddyl``); without it only mpcbox's numbers are written.

    python benchmarks/ilqr_vs_crocoddyl.py [--problems pendulum cartpole arm arm_menagerie]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

import mpcbox
from mpcbox.controllers.ilqr import forward_pass, multiple_shooting
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.multiple_shooting import straight_line_states
from mpcbox.tasks.reach import ArmReach
from mpcbox.tasks.swingup import CartpoleSwingup, PendulumSwingup

RESULTS = Path(__file__).parent / "results" / "ilqr_vs_crocoddyl.json"
#: The Franka ``home`` posture (rad).
PANDA_HOME = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
#: Franka Emika Panda joint torque limits (N m).
PANDA_TORQUE = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
#: Franka Emika Panda joint velocity limits (rad/s), from its datasheet.
PANDA_SPEED = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
#: The two Panda reaches.
ARMS = ("arm", "arm_menagerie")
MAX_ITERATIONS = 300
#: Finite-difference step (control units) of the stationarity check.
FD_STEP = 1e-6


def torque_panda() -> mujoco.MjSpec:
    """Menagerie's hand-less Panda with joint motors instead of position servos."""
    path = mpcbox.core.menagerie.robot_xml("franka_emika_panda", "panda_nohand")
    spec = mujoco.MjSpec.from_file(str(path))
    for act in list(spec.actuators):
        spec.delete(act)
    for j, limit in enumerate(PANDA_TORQUE, start=1):
        spec.add_actuator(
            name=f"torque{j}",
            target=f"joint{j}",
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            ctrllimited=True,
            ctrlrange=[-limit, limit],
        )
    return spec


def urdf_panda() -> mujoco.MjSpec:
    """Crocoddyl's (example-robot-data's) ``panda.urdf`` without meshes, with joint motors."""
    import re

    import example_robot_data

    urdf = Path(example_robot_data.getModelPath("panda_description/urdf/panda.urdf"))
    urdf = urdf / "panda_description" / "urdf" / "panda.urdf"
    text = urdf.read_text()
    for tag in ("visual", "collision"):
        text = re.sub(rf"<{tag}>.*?</{tag}>", "", text, flags=re.S)
    text = re.sub(r'(<joint name="panda_finger_joint\d" type=")prismatic', r"\1fixed", text)
    compiler = '<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>'
    text = re.sub(r"(<robot[^>]*>)", r"\1" + compiler, text, count=1)
    spec = mujoco.MjSpec.from_string(text)
    spec.option.timestep = 0.01
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for j, limit in enumerate(PANDA_TORQUE, start=1):
        spec.add_actuator(
            name=f"torque{j}",
            target=f"panda_joint{j}",
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            ctrllimited=True,
            ctrlrange=[-limit, limit],
        )
    return spec


def build(name: str) -> dict[str, Any]:
    """The Problem, horizon, control guess and state guess of one benchmark problem."""
    if name == "pendulum":
        p = PendulumSwingup(planning_timestep=0.02, threads=1)
        x0 = p.initial_state()
        return {
            "problem": p,
            "horizon": 150,
            "ctrls": np.full((150, 1), 0.5),
            "states": straight_line_states(p, x0, p.reference_state(), 150),
        }
    if name == "cartpole":
        p = CartpoleSwingup(planning_timestep=0.02, threads=1)
        x0 = p.initial_state()
        return {
            "problem": p,
            "horizon": 150,
            "ctrls": np.full((150, 1), 0.1),
            "states": straight_line_states(p, x0, p.reference_state(), 150, arrival=105),
        }
    if name in ARMS:
        # (model, reaching frame, target offset, start posture: None keeps the keyframe's,
        # control guess: "hold_start" the torques that hold the start posture still,
        # "ctrl_ref" those that hold the goal posture)
        spec, frame, offset, start, guess = {
            "arm": (urdf_panda, "panda_hand_tcp", [0.3, 0.3, -0.3], PANDA_HOME, "hold_start"),
            "arm_menagerie": (torque_panda, "attachment", [0.15, 0.1, -0.15], None, "ctrl_ref"),
        }[name]
        p = ArmReach(
            spec(),
            frame=frame,
            target=np.array(offset),
            relative=True,
            start_qpos=start,
            planning_timestep=0.01,
            threads=1,
        )
        x0 = p.initial_state()
        if guess == "hold_start":
            ctrl = mpcbox.find_equilibrium(p.planning_model, x0[: p.nq]).ctrl
        else:
            ctrl = p.ctrl_ref
        return {
            "problem": p,
            "horizon": 40,
            "ctrls": np.tile(np.clip(ctrl, p.ctrl_low, p.ctrl_high), (40, 1)),
            "states": np.tile(x0, (41, 1)),
        }
    raise ValueError(name)


class Counter:
    """Counts closed-loop and gapped rollouts of mpcbox's iLQR (patched in for the run)."""

    def __init__(self) -> None:
        self.rollouts = 0
        self._call = forward_pass.ClosedLoopRollout.__call__
        self._gapped = multiple_shooting.GappedRollout.gapped

    def __enter__(self) -> Counter:
        counter, call, gapped = self, self._call, self._gapped

        def counted_call(obj, *args, **kwargs):
            counter.rollouts += 1
            return call(obj, *args, **kwargs)

        def counted_gapped(obj, x0, states, ctrls, gaps, k, K, alpha):
            if alpha < 1.0:  # a full step goes through __call__, counted there
                counter.rollouts += 1
            return gapped(obj, x0, states, ctrls, gaps, k, K, alpha)

        forward_pass.ClosedLoopRollout.__call__ = counted_call
        multiple_shooting.GappedRollout.gapped = counted_gapped
        return self

    def __exit__(self, *exc: object) -> None:
        forward_pass.ClosedLoopRollout.__call__ = self._call
        multiple_shooting.GappedRollout.gapped = self._gapped


def common_cost(problem: mpcbox.Problem, x0: np.ndarray, ctrls: np.ndarray) -> float:
    return float(problem.rollout_cost(problem.rollout(x0, ctrls))[0])


def stationarity(problem: mpcbox.Problem, x0: np.ndarray, ctrls: np.ndarray) -> dict[str, float]:
    """Is a solution a smooth local minimum of the rollout cost over the controls?

    ``projected_gradient_max``: largest entry of the central finite-difference gradient
    (step ``FD_STEP``) of the rollout cost, zero where a control at its bound is pushed
    outward; about 0 at a smooth minimum. ``cost_change_down_gradient``: cost change after a
    step of length ``10 * FD_STEP`` along the negative projected gradient: about 0 at a smooth
    minimum, negative on a smooth slope, positive where a kink or jump of the dynamics (e.g.
    a joint limit switching on at another knot) lies that close.
    """
    lo, hi = problem.ctrl_low, problem.ctrl_high
    n = ctrls.size
    eye = FD_STEP * np.eye(n).reshape(n, *ctrls.shape)
    batch = np.concatenate([ctrls + eye, ctrls - eye])
    costs = problem.rollout_cost(problem.rollout(x0, np.clip(batch, lo, hi)))
    grad = ((costs[:n] - costs[n:]) / (2.0 * FD_STEP)).reshape(ctrls.shape)
    outward = ((ctrls <= lo + FD_STEP) & (grad > 0)) | ((ctrls >= hi - FD_STEP) & (grad < 0))
    grad = np.where(outward, 0.0, grad)
    step = -10.0 * FD_STEP * grad / max(np.linalg.norm(grad), 1e-300)
    moved = common_cost(problem, x0, np.clip(ctrls + step, lo, hi))
    return {
        "projected_gradient_max": float(np.max(np.abs(grad))),
        "cost_change_down_gradient": moved - common_cost(problem, x0, ctrls),
    }


def joint_motion(problem: mpcbox.Problem, x0: np.ndarray, ctrls: np.ndarray) -> dict[str, Any]:
    """How hard a Panda solution drives its joints (rollout of ``ctrls`` from ``x0``).

    ``max_joint_speed`` (rad/s) per joint, ``max_speed_over_datasheet``: the largest ratio of
    a joint's speed to its Franka datasheet limit (:data:`PANDA_SPEED`; <= 1 within it),
    ``min_joint_limit_distance`` (rad): the closest any joint comes to its range's ends over
    the trajectory (negative: past the limit, the limit constraint active).
    """
    model = problem.planning_model
    states = problem.rollout(x0, ctrls).states[0]
    q, v = states[:, : model.nq], states[:, model.nq :]
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    speed = np.abs(v).max(axis=0)
    return {
        "max_joint_speed": [round(float(s), 4) for s in speed],
        "max_speed_over_datasheet": float(np.max(speed / PANDA_SPEED)),
        "min_joint_limit_distance": float(np.min(np.minimum(q - lo, hi - q))),
    }


def run_mpcbox(case: dict[str, Any], shooting: str, **options: Any) -> dict[str, Any]:
    """One mpcbox solve; ``options`` are further ILQRConfig fields."""
    p, horizon = case["problem"], case["horizon"]
    x0 = p.initial_state()
    solver = ILQR(p, horizon=horizon, max_iterations=MAX_ITERATIONS, threads=1, **options)
    with Counter() as counter:
        t0 = time.perf_counter()
        if shooting == "single":
            res = solver.solve(x0, case["ctrls"])
        else:
            zeros = np.clip(np.zeros((horizon, p.nu)), solver.ctrl_low, solver.ctrl_high)
            res = solver.solve(x0, zeros, states_init=case["states"])
        wall = time.perf_counter() - t0
    return {
        "cost": common_cost(p, x0, res.ctrls),
        "iterations": res.iterations,
        "derivative_evaluations": res.iterations,
        "rollouts": counter.rollouts + 1,  # + the initial rollout (or defect evaluation)
        "wall_s": wall,
        "ms_per_iteration": {
            "derivatives": 1e3 * res.timing.derivatives / max(res.iterations, 1),
            "backward": 1e3 * res.timing.backward / max(res.iterations, 1),
            "rollouts": 1e3 * res.timing.rollouts / max(res.iterations, 1),
        },
        "status": res.status,
        "converged": bool(res.converged),
        "defect": float(res.defect),
        "upright_or_goal_error": _goal_error(p, res.states[-1]),
        **stationarity(p, x0, res.ctrls),
        **(joint_motion(p, x0, res.ctrls) if case["name"] in ARMS else {}),
    }


def _goal_error(p: mpcbox.Problem, state: np.ndarray) -> float:
    if hasattr(p, "upright_error"):
        return float(p.upright_error(state))
    data = mujoco.MjData(p.planning_model)
    p.set_state(data, state)
    mujoco.mj_forward(p.planning_model, data)
    return float(
        np.linalg.norm(mpcbox.core.model.frame_position(p.planning_model, data, p.frame) - p.target)
    )


def run_crocoddyl(case: dict[str, Any], shooting: str) -> dict[str, Any]:
    import crocoddyl

    p, horizon = case["problem"], case["horizon"]
    x0 = p.initial_state()
    lo, hi = p.ctrl_low, p.ctrl_high
    counts = {"calc": 0, "calcDiff": 0, "callback_s": 0.0}

    class MujocoAction(crocoddyl.ActionModelAbstract):
        def __init__(self, terminal: bool) -> None:
            crocoddyl.ActionModelAbstract.__init__(self, crocoddyl.StateVector(p.nx), p.nu, 0)
            self.terminal = terminal
            self.u_lb, self.u_ub = lo.copy(), hi.copy()

        def calc(self, data, x, u=None):
            t0 = time.perf_counter()
            self._calc(data, x, u)
            counts["callback_s"] += time.perf_counter() - t0

        def calcDiff(self, data, x, u=None):
            t0 = time.perf_counter()
            self._calc_diff(data, x, u)
            counts["callback_s"] += time.perf_counter() - t0

        def _calc(self, data, x, u):
            if self.terminal or u is None:
                data.xnext = x
                data.cost = p.terminal_cost(x) if self.terminal else 0.0
                return
            counts["calc"] += 1
            u = np.clip(u, lo, hi)
            data.xnext = p.step(x, u)
            data.cost = p.running_cost(x, u)

        def _calc_diff(self, data, x, u):
            if self.terminal or u is None:
                if self.terminal:
                    q = p.quadratize(x, p.ctrl_ref, terminal=True)
                    data.Lx, data.Lxx = q.lx, q.lxx
                return
            counts["calcDiff"] += 1
            u = np.clip(u, lo, hi)
            A, B = p.linearize(x, u)
            q = p.quadratize(x, u)
            data.Fx, data.Fu = A, B
            data.Lx, data.Lu, data.Lxx, data.Luu, data.Lxu = q.lx, q.lu, q.lxx, q.luu, q.lux.T

    running = MujocoAction(False)
    problem = crocoddyl.ShootingProblem(x0, [running] * horizon, MujocoAction(True))
    solver = crocoddyl.SolverBoxFDDP(problem)
    if shooting == "single":
        us = [u.copy() for u in case["ctrls"]]
        xs = list(p.rollout(x0, case["ctrls"]).states[0])
        feasible = True
    else:
        us = [np.clip(np.zeros(p.nu), lo, hi) for _ in range(horizon)]
        xs = list(case["states"].copy())
        xs[0] = x0
        feasible = False
    t0 = time.perf_counter()
    solver.solve(xs, us, MAX_ITERATIONS, feasible, 1e-9)
    wall = time.perf_counter() - t0
    ctrls = np.clip(np.array(solver.us), lo, hi)
    return {
        "cost": common_cost(p, x0, ctrls),
        "crocoddyl_cost": float(solver.cost),
        "iterations": int(solver.iter),
        "derivative_evaluations": counts["calcDiff"] / horizon,
        "rollouts": counts["calc"] / horizon,
        "wall_s": wall,
        "python_callbacks_s": counts["callback_s"],
        "wall_without_callbacks_s": wall - counts["callback_s"],
        "stop": float(solver.stop),
        "upright_or_goal_error": _goal_error(p, p.rollout(x0, ctrls).states[0, -1]),
        **stationarity(p, x0, ctrls),
        **(joint_motion(p, x0, ctrls) if case["name"] in ARMS else {}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=["pendulum", "cartpole", "arm"])
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    try:
        import crocoddyl

        croc_version: str | None = crocoddyl.__version__
    except ImportError:
        croc_version = None
    out: dict[str, Any] = {
        "machine": "2-core sandbox CPU, shared",
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "crocoddyl": croc_version or "blocked: crocoddyl not installed",
        "max_iterations": MAX_ITERATIONS,
        "stationarity_check": (
            "projected_gradient_max: largest entry of the central finite-difference "
            f"gradient (step {FD_STEP:g}) of the rollout cost over the controls, bound-projected; "
            "cost_change_down_gradient: cost change after a step of length "
            f"{10 * FD_STEP:g} down that gradient (large and positive: a jump of the dynamics "
            "lies that close)"
        ),
        "problems": {},
    }
    for name in args.problems:
        case = {"name": name, **build(name)}
        row: dict[str, Any] = {"horizon": case["horizon"], "dt": case["problem"].dt}
        for shooting in ("single", "multiple"):
            row[f"mpcbox_{shooting}"] = run_mpcbox(case, shooting)
            if croc_version is not None:
                croc = run_crocoddyl(case, shooting)
                row[f"crocoddyl_{shooting}"] = croc
                mine = row[f"mpcbox_{shooting}"]
                row[f"{shooting}_wall_ratio_mpcbox_over_crocoddyl"] = (
                    mine["wall_s"] / croc["wall_s"]
                )
                row[f"{shooting}_cost_gap_relative"] = (mine["cost"] - croc["cost"]) / abs(
                    croc["cost"]
                )
        out["problems"][name] = row
        print(name, json.dumps(row, indent=1), flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    if RESULTS.exists():  # keep the other problems' rows of an earlier run
        earlier = json.loads(RESULTS.read_text()).get("problems", {})
        out["problems"] = {**earlier, **out["problems"]}
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
