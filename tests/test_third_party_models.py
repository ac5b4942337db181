"""Models nobody here wrote: dm_control's suite (RK4) and mujoco-warp's test data.

dm_control's cart-pole and acrobot integrate with RK4, which ``mjd_transitionFD`` cannot
differentiate. mpcbox plans them on an ``implicitfast`` copy (with a warning) while the
simulation keeps RK4; these tests check that the plan is good enough to control the real
RK4 model.
"""

from __future__ import annotations

import pathlib
import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.errors import PlanningModelWarning

suite = pytest.importorskip("dm_control.suite")
SUITE = pathlib.Path(suite.__file__).parent


def suite_problem(name: str, **kwargs) -> mpcbox.Problem:
    with pytest.warns(PlanningModelWarning, match="RK4"):
        return mpcbox.Problem(str(SUITE / f"{name}.xml"), **kwargs)


@pytest.mark.parametrize("name", ["cartpole", "acrobot"])
def test_rk4_model_is_planned_on_a_supported_integrator(name: str) -> None:
    problem = suite_problem(name)
    assert problem.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert problem.planning_model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
    assert "RK4" in repr(problem)
    A, B = problem.linearize(problem.reference_state(), np.zeros(problem.nu))
    assert A.shape == (problem.nx, problem.nx) and np.all(np.isfinite(A))
    assert np.linalg.norm(B) > 0  # the actuator reaches the dynamics


def test_lqr_from_the_planning_copy_balances_the_rk4_cartpole() -> None:
    # dm_control's cart-pole is upright at hinge angle 0, hanging at pi.
    problem = suite_problem("cartpole", qpos_ref=np.zeros(2))
    lqr = mpcbox.LQR(problem)
    start = problem.reference_state()
    start[1] = 0.15  # rad off upright
    data = mujoco.MjData(problem.model)
    problem.set_state(data, start)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no MuJoCo instability warnings on the way
        for _ in range(int(5.0 / problem.model.opt.timestep)):
            data.ctrl[:] = lqr(problem.get_state(data), data.time)
            mujoco.mj_step(problem.model, data)
    assert abs(data.qpos[1]) < 1e-2, data.qpos
    assert abs(data.qvel[1]) < 1e-2, data.qvel
    # Without control the pole falls: the test is not passing by itself.
    problem.set_state(data, start)
    data.ctrl[:] = 0.0
    for _ in range(int(2.0 / problem.model.opt.timestep)):
        mujoco.mj_step(problem.model, data)
    assert abs(data.qpos[1]) > 1.0
