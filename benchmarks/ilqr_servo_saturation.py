"""Why iLQR-MPC's line searches fail on a servo arm: jumps of MuJoCo's implicit step; prints JSON.

On the Panda reach (``benchmarks/panda_reach.py``'s seed), about half of the replans' line
searches fail at every step size although the backward pass predicts a decrease. This script
runs the task's iLQR-MPC, keeps the first ``--cases`` failed line searches, one per
iteration (start state, trajectory, ``k``, ``K``, cost, predicted ``(dV1, dV2)``), and for
each rolls the search direction out again on a fine grid of step sizes ``alpha``:

* ``slope_*``: the cost's finite-difference slope in ``alpha`` at ``alpha`` = 1e-6 and 1e-4,
  against the predicted ``dV1``;
* ``jumps``: grid intervals (``--grid`` points on [0, ``--alpha-max``]) over which the cost
  changes by more than ``--jump-factor`` times what the largest slope between the
  neighbouring intervals explains: discontinuities of the cost in ``alpha``;
* ``jumps_without_force_limits``: the same on a copy of the planning model whose actuators
  have no force limit (``actuator_forcelimited = 0``), everything else equal.

MuJoCo's implicit and implicitfast integrators treat an actuator's velocity dependence (a
position servo's ``kv``) implicitly only while its force is inside ``forcerange``; once
clamped the derivative is zero. The velocity after one step then jumps where a servo
saturates, by about ``h F (1/I - 1/(I + h kv))``. If the jumps vanish without the force
limits, that is their cause. Needs ``MENAGERIE_ROOT``::

    MENAGERIE_ROOT=... python benchmarks/ilqr_servo_saturation.py [--model menagerie:...]
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from json_report import finish  # benchmarks/ is not a package

import mpcbox
from mpcbox.controllers.ilqr import solver as ilqr_solver
from mpcbox.controllers.ilqr.forward_pass import ClosedLoopRollout
from mpcbox.registry import make_controller


def failed_searches(problem, duration: float, cases: int) -> tuple[list[dict], dict]:
    """Run the task's iLQR-MPC; copies of the first ``cases`` failed line searches."""
    kept: list[dict] = []
    counts = {"line_searches": 0, "failed": 0}
    original = ilqr_solver.line_search

    def recorded(forward, step_sizes, cost, expected, armijo, executor=None):
        result = original(forward, step_sizes, cost, expected, armijo, executor)
        counts["line_searches"] += 1
        if result.candidate is None:
            counts["failed"] += 1
            # One case per iteration: its retries search nearly the same direction.
            if len(kept) < cases and not (kept and kept[-1]["cost"] == float(cost)):
                caller = sys._getframe(1).f_locals  # ILQRSolver._optimize's arrays
                kept.append(
                    {
                        name: np.array(caller[name], copy=True)
                        for name in ("x0", "states", "ctrls", "k", "K")
                    }
                    | {"cost": float(cost), "expected": tuple(map(float, expected))}
                )
        return result

    ilqr_solver.line_search = recorded
    try:
        controller = make_controller("ilqr", problem)
        sim = mpcbox.simulate(problem, controller, duration, seed=0)
    finally:
        ilqr_solver.line_search = original
    counts["final_error_m"] = float(problem.reach_error(sim.states[-1]))
    return kept, counts


def costs_along(rollout: ClosedLoopRollout, case: dict, alphas: np.ndarray) -> np.ndarray:
    """Cost of the closed-loop rollout at each step size."""
    args = (case["x0"], case["states"], case["ctrls"], case["k"], case["K"])
    return np.array([rollout(*args, float(a))[2] for a in alphas])


def jumps(alphas: np.ndarray, costs: np.ndarray, factor: float) -> int:
    """Grid intervals whose cost change exceeds ``factor`` times what the neighbours' slopes
    explain."""
    d = np.diff(costs)
    h = np.diff(alphas)
    slope = np.abs(d / h)
    # What a smooth function would change by: the larger neighbouring slope times the step.
    neighbour = np.maximum(np.r_[slope[1:], slope[-1]], np.r_[slope[0], slope[:-1]])
    smooth = np.maximum(np.minimum(neighbour, np.median(slope) * 10), 1e-12) * h
    return int(np.sum(np.abs(d) > factor * smooth))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="menagerie:franka_emika_panda")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=0.6)
    parser.add_argument("--cases", type=int, default=4)
    parser.add_argument("--grid", type=int, default=201)
    parser.add_argument("--alpha-max", type=float, default=0.01)
    parser.add_argument("--jump-factor", type=float, default=20.0)
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args()
    started = time.perf_counter()

    import panda_reach  # benchmarks/ is not a package

    problem = panda_reach.build(args.seed, panda_reach.default_args(args.model))
    cases, counts = failed_searches(problem, args.duration, args.cases)
    planner = make_controller("ilqr", problem).problem  # the planned copy (terminal value)
    low, high = problem.ctrl_low, problem.ctrl_high
    with_limits = ClosedLoopRollout(planner, low, high)
    free = ClosedLoopRollout(planner, low, high)
    free._model = copy.deepcopy(planner.planning_model)  # same sizes: the scratch data fits
    free._model.actuator_forcelimited[:] = 0
    alphas = np.linspace(0.0, args.alpha_max, args.grid)
    rows = []
    for case in cases:
        base = costs_along(with_limits, case, alphas)
        plain = costs_along(free, case, alphas)
        probe = costs_along(with_limits, case, np.array([0.0, 1e-6, 1e-4, 1e-2, 0.1]))
        rows.append(
            {
                "cost": case["cost"],
                "predicted_dV1": case["expected"][0],
                "predicted_dV2": case["expected"][1],
                "slope_at_1e-6": float((probe[1] - probe[0]) / 1e-6),
                "slope_at_1e-4": float((probe[2] - probe[0]) / 1e-4),
                "change_at_alpha_0.01": float(probe[3] - probe[0]),
                "change_at_alpha_0.1": float(probe[4] - probe[0]),
                "predicted_change_at_alpha_0.1": float(
                    0.1 * case["expected"][0] + 0.01 * case["expected"][1]
                ),
                "jumps": jumps(alphas, base, args.jump_factor),
                "jumps_without_force_limits": jumps(alphas, plain, args.jump_factor),
                "largest_step_of_the_cost": float(np.abs(np.diff(base)).max()),
                "largest_step_without_force_limits": float(np.abs(np.diff(plain)).max()),
            }
        )
    out = {
        "benchmark": "failed iLQR-MPC line searches of an arm reach, rolled out on an alpha grid",
        "model": args.model,
        "seed": args.seed,
        "integrator": int(problem.planning_model.opt.integrator),
        "timestep": problem.dt,
        "run": counts,
        "grid": {"points": args.grid, "alpha_max": args.alpha_max, "jump_factor": args.jump_factor},
        "cases": rows,
        "command": "python " + " ".join(sys.argv),
    }
    finish(out, args.out or "", started=started)


if __name__ == "__main__":
    main()
