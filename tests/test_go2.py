"""Unitree's Go2 (MuJoCo Menagerie, 12 torque motors) standing under LQR and QP-MPC.

Needs an offline Menagerie copy with the Go2 (``MENAGERIE_ROOT``); skips without one.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.qp_mpc.controller import QPMPC
from mpcbox.controllers.qp_mpc.solvers import OSQP_DEFAULTS

pytestmark = [
    pytest.mark.menagerie,
    pytest.mark.parametrize("menagerie_quadruped", ["unitree_go2"], indirect=True),
]


@pytest.fixture(scope="module")
def go2(menagerie_quadruped):
    return menagerie_quadruped


def test_go2_holds_its_posture_on_motor_torques(go2) -> None:
    m = go2.model
    assert m.nu == 12 and go2.root == "base"
    assert go2.contacts == ("geom:FR", "geom:FL", "geom:RR", "geom:RL")
    assert np.all(m.actuator_biastype == mujoco.mjtBias.mjBIAS_NONE)  # motors, no servo
    # The recipe: 5 % of each motor's range (23.7 N m hips and thighs, 45.43 N m knees).
    np.testing.assert_allclose(go2.noise().std[:3], 0.05 * np.array([23.7, 23.7, 45.43]))
    # The holding torques keep the robot still at the reference posture.
    d = mujoco.MjData(m)
    go2.set_state(d, go2.reference_state())
    d.ctrl[:] = go2.ctrl_ref
    mujoco.mj_forward(m, d)
    assert np.all(np.abs(go2.ctrl_ref) < m.actuator_ctrlrange[:, 1])
    assert np.max(np.abs(d.qacc)) < 0.5  # m/s^2 or rad/s^2; gravity alone is 9.81
    res = mpcbox.simulate(go2, mpcbox.LQR(go2), 2.0, noise=go2.noise(), seed=3)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 3.0


def test_qp_mpc_stands_the_go2_on_four_friction_cones(go2) -> None:
    qp = mpcbox.make_controller("qp", go2)
    # Torque motors: replanning at 100 Hz with the LQR gain about the plan at every step.
    assert qp.points.count == 4 and qp.replan_period == pytest.approx(0.01)
    assert qp.config.between_ticks == "lqr" and qp.period == go2.model.opt.timestep
    res = mpcbox.simulate(go2, qp, 1.0, noise=go2.noise(), seed=0)
    assert res.survived, res.failure
    assert res.metrics.fallbacks == 0 and qp.stats["solver_iterations_max"] < 400
    assert res.metrics.solve_ticks == 100 and res.metrics.held_ticks == 400


def test_scaled_controls_same_plan_fewer_iterations(go2) -> None:
    """Scaling the control variables by their cost changes the QP OSQP sees, not its
    solution: the same first control as unscaled (both solved by Clarabel to its tolerance),
    in fewer of OSQP's iterations from a cold start, with the quadrupeds' OSQP settings and
    (under half) with OSQP_DEFAULTS."""
    state = go2.reference_state()
    state[go2.nq + 3] = 0.3  # roll rate of the trunk (rad/s)
    state[go2.nq + 0] = 0.1  # forward speed (m/s)
    config = go2.controller_configs["qp"]
    ctrls, iters = {}, {}
    for scale in (True, False):
        exact = QPMPC(go2, config, scale_controls=scale, solver="clarabel")
        ctrls[scale] = exact.solve(state).ctrls[0]
        for settings in ("quadruped", "defaults"):
            osqp = QPMPC(go2, config, scale_controls=scale, warm_start=False)
            if settings == "defaults":
                osqp.backend.settings = dict(OSQP_DEFAULTS)
            osqp.backend.settings["max_iter"] = 10000
            plan = osqp.solve(state)
            assert plan is not None
            iters[scale, settings] = plan.iterations
        if scale:
            u_block = osqp.formulation.P.diagonal()[osqp.layout.ou : osqp.layout.ou + go2.nu]
            np.testing.assert_allclose(u_block, 1.0)  # one unit of u~ costs one unit
    np.testing.assert_allclose(ctrls[True], ctrls[False], atol=1e-3)  # N m
    assert iters[True, "quadruped"] < iters[False, "quadruped"], iters
    assert iters[True, "defaults"] < 0.5 * iters[False, "defaults"], iters


def test_inspect_suggests_a_compare_command_that_runs_for_a_bare_name(go2, capsys) -> None:
    from mpcbox.cli.inspect_model import run_inspect

    run_inspect(["unitree_go2", "--hold", "0", "--no-servo-test"])
    out = " ".join(capsys.readouterr().out.split())
    # `compare --model` takes a path or "menagerie:NAME", not the bare name inspect took.
    assert "mpcbox compare quadruped_stand --model menagerie:unitree_go2" in out
