"""Linearizations difference a copy of the planning model whose constraint solver runs to a
tight tolerance (``Dynamics.fd_model``)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.core.dynamics import FD_SOLVER_TOLERANCE
from mpcbox.tasks.humanoid.stand import HumanoidStand


def test_the_copy_has_the_tight_tolerance_and_follows_option_changes():
    problem = HumanoidStand(threads=1)
    dyn = problem.dynamics
    assert dyn.model.opt.tolerance > FD_SOLVER_TOLERANCE
    fd = dyn.fd_model()
    assert fd is not dyn.model and fd.opt.tolerance == FD_SOLVER_TOLERANCE
    assert dyn.fd_model() is fd  # made once
    dyn.model.opt.timestep *= 2.0
    again = dyn.fd_model()
    assert again is not fd and again.opt.timestep == dyn.model.opt.timestep
    dyn.model.opt.tolerance = 0.0  # already tight: the model itself
    assert dyn.fd_model() is dyn.model


def test_on_the_standing_humanoid_the_jacobians_are_those_of_the_default_tolerance():
    """Where the default tolerance already converges, the tight one changes nothing (its
    Newton iterations converge quadratically): the same A and B to rounding."""
    problem = HumanoidStand(threads=1)
    x, u = problem.reference_state(), problem.ctrl_ref
    lin = problem.linearize(x, u)
    model = problem.planning_model
    data = mujoco.MjData(model)
    problem.set_state(data, x)
    data.ctrl[:] = u
    A = np.zeros((problem.nx, problem.nx))
    B = np.zeros((problem.nx, problem.nu))
    mujoco.mjd_transitionFD(model, data, problem.fd_eps, problem.fd_centered, A, B, None, None)
    np.testing.assert_allclose(lin.A, A, atol=1e-6 * np.abs(A).max())
    np.testing.assert_allclose(lin.B, B, atol=1e-6 * np.abs(B).max())


# ------------------------------------------------------------------ dry friction
WHEEL = """
<mujoco>
  <option timestep="0.01" integrator="implicitfast"/>
  <worldbody>
    <body name="wheel">
      <joint name="spin" axis="0 0 1" frictionloss="{friction}"/>
      <geom type="cylinder" size="0.1 0.02" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor name="m" joint="spin" ctrlrange="-5 5"/></actuator>
</mujoco>
"""
#: Inertia of the wheel about its axis (solid cylinder, m r^2 / 2).
INERTIA = 0.5 * 1.0 * 0.1**2


def test_dry_friction_is_left_out_of_the_derivatives_on_request():
    """A torque on a free wheel changes its speed by dt / I per N m; with 1 N m of dry
    friction at rest MuJoCo's soft friction constraint absorbs most of a small torque, so
    differencing the model with it (the default) sees a wheel the motor hardly turns."""
    from mpcbox import Problem

    problem = Problem(WHEEL.format(friction=1.0), dry_friction="drop", threads=1)
    x, u = problem.reference_state(), np.zeros(1)
    exact = problem.dt / INERTIA
    assert problem.linearize(x, u).B[1, 0] == pytest.approx(exact, rel=1e-6)
    kept = Problem(WHEEL.format(friction=1.0), threads=1)
    assert kept.dry_friction == "keep"
    assert abs(kept.linearize(x, u).B[1, 0]) < 0.5 * exact
    # The simulation keeps the friction: 0.5 N m does not start the wheel.
    data = mujoco.MjData(problem.model)
    data.ctrl[:] = 0.5
    for _ in range(20):
        mujoco.mj_step(problem.model, data)
    assert abs(data.qvel[0]) < 0.1 * 0.5 / INERTIA * 0.2
    assert not problem.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS


def test_a_model_without_dry_friction_is_differenced_as_it_is():
    from mpcbox import Problem

    problem = Problem(WHEEL.format(friction=0.0), dry_friction="drop", threads=1)
    fd = problem.dynamics.fd_model()
    assert not fd.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    lin = problem.linearize(problem.reference_state(), np.zeros(1))
    assert lin.B[1, 0] == pytest.approx(problem.dt / INERTIA, rel=1e-6)


def test_qp_prediction_models_leave_dry_friction_out_with_the_problem():
    from mpcbox import Problem
    from mpcbox.controllers.qp_mpc.dynamics import prediction_models

    flag = mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    for mode, dropped in (("drop", True), ("keep", False)):
        problem = Problem(WHEEL.format(friction=1.0), dry_friction=mode, threads=1)
        for model in prediction_models(problem, 0.02, 2):
            assert bool(model.opt.disableflags & flag) == dropped


def test_a_bad_dry_friction_choice_names_the_valid_ones():
    from mpcbox import Problem
    from mpcbox.errors import InvalidArgumentError

    with pytest.raises(InvalidArgumentError, match=r"dry_friction.*drop.*keep"):
        Problem(WHEEL.format(friction=1.0), dry_friction="smooth")


def test_a_planner_can_drop_dry_friction_from_its_own_copy_of_the_problem():
    """``Problem.with_dry_friction`` changes the copy's derivatives only; ``ILQR(...,
    dry_friction="drop")`` plans on such a copy (its LQR terminal value included) and leaves
    the user's Problem, which the simulation steps, as it was."""
    from mpcbox import ILQR, Problem
    from mpcbox.errors import InvalidArgumentError

    kept = Problem(WHEEL.format(friction=1.0), threads=1)
    x, u = kept.reference_state(), np.zeros(1)
    dropped = kept.with_dry_friction("drop")
    assert dropped is not kept and dropped.dry_friction == "drop"
    assert dropped.linearize(x, u).B[1, 0] == pytest.approx(kept.dt / INERTIA, rel=1e-6)
    assert abs(kept.linearize(x, u).B[1, 0]) < 0.5 * kept.dt / INERTIA  # unchanged
    assert kept.with_dry_friction("keep") is kept
    with pytest.raises(InvalidArgumentError, match=r"dry_friction.*drop.*keep"):
        kept.with_dry_friction("smooth")

    for choice, exact in (("drop", True), ("keep", False), (None, False)):
        ilqr = ILQR(kept, horizon=5, dry_friction=choice, terminal_value="lqr")
        assert ilqr.problem.dry_friction == (choice or "keep")
        b = ilqr.problem.linearize(x, u).B[1, 0]
        assert (b == pytest.approx(kept.dt / INERTIA, rel=1e-6)) == exact
    assert kept.dry_friction == "keep"
    with pytest.raises(InvalidArgumentError, match=r"dry_friction.*keep.*drop"):
        ILQR(kept, horizon=5, dry_friction="slip")
