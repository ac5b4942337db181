"""A planning timestep at which the model diverges is caught when it is built, silently.

The model: a 10 g link on a hinge driven by a stiff position servo (kp 1000 N m/rad, no
damping) with the Euler integrator. Its natural frequency is ``sqrt(kp / I) ~ 5500 rad/s``
(``I = m l^2 / 3`` for a 0.1 m rod), so an explicit step of 0.02 s (``omega dt ~ 110``)
blows up within a few steps while 1e-4 s (``omega dt ~ 0.55``) is stable.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.sampling import MPPI
from mpcbox.core.divergence import captured_warnings, check_planning_step
from mpcbox.errors import DivergenceError, PlanningDivergenceError

STIFF_SERVO = """
<mujoco>
  <option timestep="0.0001" integrator="Euler"/>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" size="0.01" fromto="0 0 0 0 0 -0.1" mass="0.01"/>
    </body>
  </worldbody>
  <actuator><position joint="hinge" kp="1000" ctrlrange="-1 1"/></actuator>
  <keyframe><key qpos="0.3" ctrl="0.5"/></keyframe>
</mujoco>
"""


def problem(**kwargs) -> mpcbox.Problem:
    return mpcbox.Problem(STIFF_SERVO, keyframe=0, **kwargs)


def test_problem_with_a_diverging_planning_timestep_raises_naming_it(capfd) -> None:
    with pytest.raises(PlanningDivergenceError, match=r"planning_timestep=0\.02 s.*smaller"):
        problem(planning_timestep=0.02)
    assert "QACC" not in capfd.readouterr().err  # read from the counters, never printed
    assert issubclass(PlanningDivergenceError, DivergenceError)


def test_stable_steps_pass_and_coarse_copies_and_controllers_raise(capfd) -> None:
    fine = problem(planning_timestep=2e-4)  # omega dt ~ 1.1 < 2: stable
    check_planning_step(fine)
    with pytest.raises(PlanningDivergenceError, match=r"planning_timestep=0\.01 s"):
        fine.with_planning_timestep(0.01)
    with pytest.raises(PlanningDivergenceError, match=r"planning_timestep=0\.01 s"):
        ILQR(fine, horizon=5, planning_timestep=0.01)
    with pytest.raises(PlanningDivergenceError, match=r"planning_timestep=0\.01 s"):
        MPPI(fine, horizon=0.05, planning_timestep=0.01)
    ILQR(fine, horizon=5)  # the Problem's own step passes
    assert "QACC" not in capfd.readouterr().err


def test_captured_warnings_collects_and_restores_the_handler() -> None:
    model = mujoco.MjModel.from_xml_string(STIFF_SERVO)
    model.opt.timestep = 0.02
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.5
    before = mujoco.get_mju_user_warning()
    with captured_warnings() as messages:
        for _ in range(20):
            mujoco.mj_step(model, data)
    assert mujoco.get_mju_user_warning() is before
    assert any("QACC" in m for m in messages)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number >= 1
    assert np.all(np.isfinite(data.qpos))  # MuJoCo reset the data after the bad step
