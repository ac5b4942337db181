"""Linearizations difference a copy of the planning model whose constraint solver runs to a
tight tolerance (``Dynamics.fd_model``)."""

from __future__ import annotations

import mujoco
import numpy as np

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
