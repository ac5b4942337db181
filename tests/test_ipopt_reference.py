"""CasADi/IPOPT reference: agreement with iLQR, cost callbacks, controller, and errors."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.core.cost import ControlCost, Cost, CostTerm, StateCost
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError
from mpcbox.registry import make_controller
from mpcbox.tasks import scene_path
from mpcbox.tasks.swingup import PendulumSwingup

casadi = pytest.importorskip("casadi")

from mpcbox.controllers.ipopt import solve_ipopt  # noqa: E402
from mpcbox.controllers.ipopt_controller import IpoptConfig, IpoptController  # noqa: E402

SLIDER = """
<mujoco>
  <option timestep="0.05" gravity="0 0 0"/>
  <worldbody>
    <body>
      <joint name="x" type="slide" axis="1 0 0" damping="0.5"/>
      <geom type="sphere" size="0.1" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator><motor joint="x" ctrllimited="true" ctrlrange="-0.6 0.6"/></actuator>
</mujoco>
"""


class PositionNoJacobian(CostTerm):
    """``r = qpos`` without an analytic Jacobian or CasADi form (exercises the callbacks)."""

    def size(self, model):
        return model.nq

    def residual(self, features):
        return features.qpos.copy()


def slider(custom: bool) -> mpcbox.Problem:
    position = PositionNoJacobian(1.0, "pos") if custom else StateCost(np.zeros(1), weight_qpos=1.0)
    terminal = (
        PositionNoJacobian(30.0, "pos_T") if custom else StateCost(np.zeros(1), weight_qpos=30.0)
    )
    return mpcbox.Problem(
        SLIDER,
        cost=Cost(
            [
                position,
                StateCost(np.zeros(1), weight_qpos=0.0, weight_qvel=0.1, name="vel"),
                ControlCost(weight=0.1),
            ],
            [terminal],
        ),
        threads=1,
    )


@pytest.mark.parametrize("custom", [False, True])
def test_matches_ilqr_on_control_limited_slider(custom):
    problem = slider(custom)
    x0 = np.array([1.5, 0.0])
    ref = solve_ipopt(problem, x0, 30, tolerance=1e-10)
    res = ILQR(problem, horizon=30, tolerance=1e-10).solve(x0)
    assert ref.defect < 1e-8  # (at tol 1e-10 IPOPT may stop on a tiny search direction)
    assert np.all(np.abs(ref.ctrls) <= 0.6 + 1e-9)
    assert np.any(np.abs(ref.ctrls) > 0.6 - 1e-6)  # the bound is active
    assert res.cost == pytest.approx(ref.cost, rel=1e-5)
    np.testing.assert_allclose(res.ctrls, ref.ctrls, atol=1e-3)


def test_ipopt_controller_tracks_pendulum_swingup():
    problem = PendulumSwingup()
    controller = make_controller("ipopt", problem, horizon=100, planning_timestep=0.03)
    assert isinstance(controller, IpoptController)
    result = mpcbox.simulate(problem, controller, 4.0)
    assert result.failure is None
    assert problem.upright_error(result.states[-1]) < 0.1
    assert controller.stats["fallbacks"] == 0
    assert isinstance(controller.config, IpoptConfig) and controller.config.horizon == 100
    assert controller.config.tolerance == 1e-6  # the task's tuned option


def test_quaternion_models_are_rejected():
    problem = mpcbox.Problem(scene_path("humanoid.xml"), keyframe="stand", threads=1)
    with pytest.raises(InvalidArgumentError, match="nq == nv"):
        solve_ipopt(problem, problem.initial_state(), 5)


def test_bad_shapes_and_missing_casadi(monkeypatch):
    problem = slider(False)
    with pytest.raises(mpcbox.ShapeError, match="ctrls_init"):
        solve_ipopt(problem, np.zeros(2), 5, ctrls_init=np.zeros((4, 1)))
    with pytest.raises(InvalidArgumentError, match="horizon"):
        solve_ipopt(problem, np.zeros(2), 0)
    monkeypatch.setitem(sys.modules, "casadi", None)
    with pytest.raises(BackendUnavailableError, match="pip install"):
        solve_ipopt(problem, np.zeros(2), 5)


def test_config_defaults_and_unknown_options():
    problem = slider(False)
    controller = IpoptController(problem)
    assert controller.horizon == IpoptConfig().horizon == 50
    assert IpoptController.config_class is IpoptConfig
    with pytest.raises(mpcbox.errors.UnknownOptionError, match="nlpsol_options"):
        IpoptController(problem, options={"ipopt.acceptable_tol": 1e-6})
    with pytest.raises(InvalidArgumentError, match="horizon"):
        IpoptConfig(horizon=0)
