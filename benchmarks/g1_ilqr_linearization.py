"""Why iLQR-MPC linearized along its trajectories fails on the standing G1: the measurements.

From the G1's standing reference (:class:`~mpcbox.tasks.legged.biped.BipedStand`, two
feet) the planning model is rolled out 0.1 s (50 steps) under the holding control, and the
one-step Jacobians ``A``, ``B`` at its states are compared with those at the reference,
with the G1's joint dry friction (``frictionloss`` 0.3 N m) and without it. The
constraint states of the dof-friction rows (stick: quadratic zone, slip: linear zones) and
of the contact rows are counted along the way. Then the first iLQR iteration from the
reference (the preset's options, the LQR value as terminal cost, no regularization) is run
with the dynamics linearized along the trajectory and at the reference, and each knot's
feedback gain is compared with the LQR gain.

Needs ``MENAGERIE_ROOT``::

    python benchmarks/g1_ilqr_linearization.py --json benchmarks/results/g1_ilqr_linearization.json
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from json_report import finish  # benchmarks/ is not a package

from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.lqr import LQR
from mpcbox.core.dynamics import Dynamics
from mpcbox.tasks.legged.biped import BipedStand

KNOTS = (1, 5, 10, 25, 49)


def without_friction(problem: BipedStand) -> BipedStand:
    """A shallow copy whose planning model has no joint dry friction."""
    clone = copy.copy(problem)
    clone.planning_model = copy.copy(problem.planning_model)
    clone.planning_model.dof_frictionloss[:] = 0.0
    clone.dynamics = Dynamics(clone.planning_model, 1)
    return clone


def constraint_states(problem: BipedStand, state: np.ndarray) -> dict:
    """Counts of dof-friction rows that stick or slip and of active contact rows."""
    model = problem.planning_model
    data = mujoco.MjData(model)
    problem.set_state(data, state)
    data.ctrl[:] = problem.ctrl_ref
    mujoco.mj_forward(model, data)
    kind, state_ = data.efc_type[: data.nefc], data.efc_state[: data.nefc]
    friction = kind == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
    contact = kind == mujoco.mjtConstraint.mjCNSTR_CONTACT_PYRAMIDAL
    quadratic = state_ == mujoco.mjtConstraintState.mjCNSTRSTATE_QUADRATIC
    return {
        "dof_friction_stick": int(np.sum(friction & quadratic)),
        "dof_friction_slip": int(np.sum(friction & ~quadratic)),
        "contact_rows_active": int(np.sum(contact & quadratic)),
    }


def jacobian_changes(problem: BipedStand, states: np.ndarray) -> list[dict]:
    """Relative change of ``A - I`` and ``B`` at rollout states from those at the reference."""
    A0, B0 = problem.linearize(states[0], problem.ctrl_ref)
    eye = np.eye(A0.shape[0])
    out = []
    for t in KNOTS:
        A, B = problem.linearize(states[t], problem.ctrl_ref)
        out.append(
            {
                "knot": t,
                "A_change": round(float(np.linalg.norm(A - A0) / np.linalg.norm(A0 - eye)), 4),
                "B_change": round(float(np.linalg.norm(B - B0) / np.linalg.norm(B0)), 4),
            }
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--json", default="", help="also write the JSON here")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    problem = BipedStand("menagerie:unitree_g1", threads=1)
    x0 = problem.reference_state()
    ctrls = np.tile(problem.ctrl_ref, (50, 1))
    states = problem.rollout(x0, ctrls).states[0]
    lqr = LQR(problem)
    gains = {}
    preset = problem.controller_configs["ilqr"]
    for linearization in ("trajectory", "reference"):
        config = dataclasses.replace(
            preset, linearization=linearization, regularization=0.0, linearize_every=1
        )
        res = ILQR(problem, config).solve(x0, max_iterations=1)
        rel = np.linalg.norm(res.K + lqr.K, axis=(1, 2)) / np.linalg.norm(lqr.K)
        gains[linearization] = {
            "first_knot": round(float(rel[0]), 4),
            "largest": round(float(rel.max()), 4),
            "last_knot": round(float(rel[-1]), 6),
        }
    out = {
        "benchmark": "g1_ilqr_linearization",
        "model": "menagerie:unitree_g1",
        "task": "biped_stand, two feet, planning step 0.002 s",
        "dof_frictionloss_Nm": sorted({float(f) for f in problem.model.dof_frictionloss}),
        "rollout": "0.1 s from the reference under ctrl_ref",
        "largest_drift_rad": round(
            float(np.abs(problem.state_difference(states[-1], x0)[: problem.nv]).max()), 5
        ),
        "constraint_states": {str(t): constraint_states(problem, states[t]) for t in (0, *KNOTS)},
        "jacobian_change_from_reference": {
            "with_frictionloss": jacobian_changes(problem, states),
            "frictionloss_zero": jacobian_changes(without_friction(problem), states),
        },
        "first_iteration_gain_vs_lqr": gains,
    }
    problem.close()
    return finish(out, args.json, started=t0)


if __name__ == "__main__":
    sys.exit(main())
