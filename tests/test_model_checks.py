"""Models a Problem must reject at load, and RK4 models planned with a differentiable integrator."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.model import PLANNING_INTEGRATOR

PENDULUM = """
<mujoco>
  <option timestep="{timestep}" gravity="{gravity}" integrator="{integrator}"/>
  <worldbody>
    <body name="pole">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="1"/>
    </body>
  </worldbody>
  {actuators}
</mujoco>
"""
MOTOR = '<actuator><motor name="torque" joint="hinge" gear="{gear}"/></actuator>'


def pendulum(
    timestep="0.01", gravity="0 0 -9.81", integrator="Euler", gear="1", actuated=True
) -> str:
    return PENDULUM.format(
        timestep=timestep,
        gravity=gravity,
        integrator=integrator,
        actuators=MOTOR.format(gear=gear) if actuated else "",
    )


def compiled(**fields) -> mujoco.MjModel:
    """A compiled pendulum with some fields overwritten (MuJoCo's compiler rejects some)."""
    model = mujoco.MjModel.from_xml_string(pendulum())
    for name, value in fields.items():
        getattr(model, name)[...] = value
    return model


# ---------------------------------------------------------------------- RK4 models
def test_rk4_model_is_planned_with_a_differentiable_integrator():
    with pytest.warns(mpcbox.PlanningModelWarning, match="RK4.*implicitfast"):
        problem = mpcbox.Problem(pendulum(integrator="RK4"))
    assert problem.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert problem.planning_model.opt.integrator == PLANNING_INTEGRATOR
    assert problem.planning_model is not problem.model
    assert "planning_integrator='implicitfast' (model: RK4)" in repr(problem)
    x, u = np.array([0.7, -0.3]), np.array([0.5])
    lin = problem.linearize(x, u)
    assert np.all(np.isfinite(lin.A)) and np.all(np.isfinite(lin.B))
    # The implicitfast Jacobians are close to those of the RK4 step (finite differences).
    eps, data = 1e-6, mujoco.MjData(problem.model)

    def rk4_step(state, ctrl):
        problem.set_state(data, state)
        data.ctrl[:] = ctrl
        mujoco.mj_step(problem.model, data)
        return problem.get_state(data)

    A = np.stack(
        [(rk4_step(x + eps * e, u) - rk4_step(x - eps * e, u)) / (2 * eps) for e in np.eye(2)], 1
    )
    np.testing.assert_allclose(lin.A, A, atol=0.02 * np.abs(A).max())
    # The other methods work on the planning model too; copies keep the replaced integrator.
    lin3 = problem.linearize_trajectory(np.tile(x, (3, 1)), np.tile(u, (3, 1)))
    np.testing.assert_array_equal(lin3.A[2], lin.A)
    coarse = problem.with_planning_timestep(0.02)
    assert coarse.planning_model.opt.integrator == PLANNING_INTEGRATOR
    assert "model: RK4" in repr(coarse)
    assert problem.model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4


def test_models_without_rk4_are_planned_unchanged_and_silently():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        problem = mpcbox.Problem(pendulum(integrator="implicitfast"))
    assert problem.planning_model is problem.model
    assert "planning_integrator" not in repr(problem)


def test_a_mujoco_fatal_error_becomes_an_mpcbox_error(monkeypatch):
    with pytest.warns(mpcbox.PlanningModelWarning):
        problem = mpcbox.Problem(pendulum(integrator="RK4"))
    problem.planning_model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4  # undo the fix
    x, u = np.array([0.1, 0.0]), np.array([0.0])
    with pytest.raises(mpcbox.UnsupportedModelError, match="RK4"):
        problem.linearize(x, u)
    with pytest.raises(mpcbox.UnsupportedModelError, match="RK4"):
        problem.linearize_trajectory(x[None], u[None])

    # A fatal error that the Problem does not foresee is wrapped as well.
    def fatal(*args):
        raise mujoco.FatalError("mj_step: simulated failure")

    monkeypatch.setattr(mujoco, "mj_step", fatal)
    with pytest.raises(mpcbox.MujocoError, match=r"step: .*simulated failure") as err:
        problem.step(x, u)
    assert isinstance(err.value, mpcbox.MpcboxError) and isinstance(err.value, RuntimeError)


# ---------------------------------------------------------------------- broken models
@pytest.mark.parametrize(
    ("source", "field"),
    [
        (pendulum(timestep="0"), "timestep"),
        (pendulum(timestep="-0.01"), "timestep"),
        (pendulum(timestep="nan"), "timestep"),
        (pendulum(gravity="0 0 nan"), "gravity"),
        (compiled(body_mass=np.array([0.0, np.nan])), "body_mass"),
        (pendulum(gear="nan"), "actuator_gear"),
        (compiled(body_mass=np.array([0.0, -1.0])), "body_mass"),
        (compiled(body_inertia=np.inf), "body_inertia"),
        (compiled(actuator_gainprm=np.nan), "actuator_gainprm"),
        (compiled(actuator_biasprm=np.inf), "actuator_biasprm"),
    ],
    ids=[
        "timestep-zero",
        "timestep-negative",
        "timestep-nan",
        "gravity-nan",
        "mass-nan",
        "gear-nan",
        "mass-negative",
        "inertia-inf",
        "gain-nan",
        "bias-inf",
    ],
)
def test_broken_models_are_rejected_naming_the_field(source, field):
    with pytest.raises(mpcbox.InvalidArgumentError, match=field):
        mpcbox.Problem(source)


def test_a_broken_planning_model_is_rejected_too():
    planning = compiled()
    planning.opt.timestep = 0.0
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"planning_model: opt\.timestep"):
        mpcbox.Problem(pendulum(), planning_model=planning)


def test_a_model_without_actuators_gets_a_clear_error():
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"no actuators \(nu = 0\)"):
        mpcbox.Problem(pendulum(actuated=False))
