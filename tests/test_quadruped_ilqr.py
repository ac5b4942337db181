"""iLQR-MPC on a quadruped nobody here wrote: dm_control's, whose actuators are filters."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.lqr import LQR, nearest_psd, with_lqr_terminal_value


@pytest.fixture(scope="module")
def dm_quadruped():
    pytest.importorskip("dm_control")
    from mpcbox.tasks.legged.quadruped import QuadrupedStand, dm_control_quadruped

    problem = QuadrupedStand(dm_control_quadruped(), threads=1)
    yield problem
    problem.close()


def test_lqr_terminal_value_keeps_the_position_velocity_block_of_a_model_with_activations(
    dm_quadruped,
) -> None:
    problem = dm_quadruped
    nv, na = problem.model.nv, problem.model.na
    assert na > 0 and problem.nx == 2 * nv + na
    full = nearest_psd(LQR(problem).P)
    value = with_lqr_terminal_value(problem).cost.terminal[-1]
    np.testing.assert_allclose(value.P, full[: 2 * nv, : 2 * nv])
    # At a deviation with the activations at their reference, the term is the value.
    rng = np.random.default_rng(0)
    dx = np.concatenate([0.01 * rng.standard_normal(2 * nv), np.zeros(na)])
    state = problem.state_add(problem.reference_state(), dx)
    residual = value.residual(problem.features(state, problem.ctrl_ref))
    assert float(np.sum(residual**2)) == pytest.approx(dx @ full @ dx, rel=1e-6)


def test_ilqr_mpc_with_the_task_config_stands_it_under_noise(dm_quadruped) -> None:
    problem = dm_quadruped
    controller = mpcbox.make_controller("ilqr", problem)
    assert controller.config.terminal_value == "lqr"  # it raised a ShapeError before
    run = mpcbox.simulate(problem, controller, 1.5, noise=problem.noise(1.0), seed=0)
    assert run.metrics.success, run.failure
    assert controller.stats["fallbacks"] <= 0.05 * controller.stats["replans"]
    assert run.metrics.measures["tilt_rms_deg"] < 2.0
