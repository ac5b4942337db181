"""Models a Problem must reject at load, and RK4 models planned with a differentiable integrator."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.model import PLANNING_INTEGRATOR
from mpcbox.tasks import scene_path

PENDULUM_SCENE = scene_path("pendulum.xml")

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


def test_plan_rk4_linearizes_the_rk4_step_itself():
    # plan_rk4 keeps RK4, silently; its Jacobians are central differences of the RK4 step.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        problem = mpcbox.Problem(pendulum(integrator="RK4", timestep="0.05"), plan_rk4=True)
    assert problem.planning_model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert "planning_integrator" not in repr(problem)
    x, u = np.array([0.7, -0.3]), np.array([0.5])
    lin = problem.linearize(x, u)
    eps = 1e-5

    def step(state, ctrl):
        return problem.step(state, ctrl)

    A = np.stack([(step(x + eps * e, u) - step(x - eps * e, u)) / (2 * eps) for e in np.eye(2)], 1)
    B = ((step(x, u + eps) - step(x, u - eps)) / (2 * eps))[:, None]
    np.testing.assert_allclose(lin.A, A, atol=1e-7)
    np.testing.assert_allclose(lin.B, B, atol=1e-7)
    # ... unlike the implicitfast copy's at this 0.05 s step.
    with pytest.warns(mpcbox.PlanningModelWarning):
        copied = mpcbox.Problem(pendulum(integrator="RK4", timestep="0.05"))
    assert np.abs(copied.linearize(x, u).A - A).max() > 1e-3
    lin3 = problem.linearize_trajectory(np.tile(x, (3, 1)), np.tile(u, (3, 1)))
    np.testing.assert_allclose(lin3.A[1], lin.A, atol=1e-12)


def test_step_jacobians_match_mjd_transition_fd_on_a_free_body():
    # On a model mjd_transitionFD handles (a free body: quaternion positions) both agree.
    from mpcbox.core.step_fd import step_jacobians

    model = mujoco.MjModel.from_xml_string(
        """<mujoco><option integrator="implicitfast" gravity="0 0 -9.81"/><worldbody>
        <body pos="0 0 1"><freejoint/><geom type="box" size=".1 .2 .3" mass="1"/>
        <body pos="0 0 .4"><joint name="j" axis="1 0 0" damping=".1"/>
        <geom type="capsule" fromto="0 0 0 0 0 .4" size=".05"/></body></body></worldbody>
        <actuator><motor joint="j"/></actuator></mujoco>"""
    )
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    data.qpos[3:7] = rng.normal(size=4) / 2.0
    data.qpos[3:7] /= np.linalg.norm(data.qpos[3:7])
    data.qvel[:] = rng.normal(size=model.nv)
    data.ctrl[:] = 0.3
    nx = 2 * model.nv
    A, B, A_ref, B_ref = (
        np.zeros((nx, nx)),
        np.zeros((nx, 1)),
        np.zeros((nx, nx)),
        np.zeros((nx, 1)),
    )
    before = data.qpos.copy()
    step_jacobians(model, data, 1e-6, True, A, B)
    np.testing.assert_array_equal(data.qpos, before)  # the state is restored
    mujoco.mjd_transitionFD(model, data, 1e-6, True, A_ref, B_ref, None, None)
    np.testing.assert_allclose(A, A_ref, atol=1e-6)
    np.testing.assert_allclose(B, B_ref, atol=1e-6)


def test_a_mujoco_fatal_error_becomes_an_mpcbox_error(monkeypatch):
    with pytest.warns(mpcbox.PlanningModelWarning):
        problem = mpcbox.Problem(pendulum(integrator="RK4"))
    x, u = np.array([0.1, 0.0]), np.array([0.0])

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
        (compiled(body_inertia=np.array([[0.0, 0, 0], [0.1, -0.1, 0.1]])), "body_inertia"),
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
        "inertia-negative",
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
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"no actuators \(nu = 0\).*'hinge'"):
        mpcbox.Problem(pendulum(actuated=False))


# ---------------------------------------------------------------------- names and controls
def test_an_unknown_keyframe_or_site_lists_what_exists():
    with pytest.raises(mpcbox.UnknownNameError, match=r"keyframe 'nope'.*'down', 'up'"):
        mpcbox.Problem(str(PENDULUM_SCENE), keyframe="nope")
    with pytest.raises(mpcbox.UnknownNameError, match=r"frame: unknown site or body 'nope'.*'tip'"):
        mpcbox.Problem(
            str(PENDULUM_SCENE),
            cost=mpcbox.Cost([mpcbox.FramePosition("nope", np.zeros(3), weight=1.0)]),
        )
    with pytest.raises(mpcbox.InvalidTypeError, match="keyframe"):
        mpcbox.Problem(str(PENDULUM_SCENE), keyframe=[0])  # a list used to reach MuJoCo


@pytest.fixture(scope="module")
def pendulum_problem():
    return mpcbox.Problem(str(PENDULUM_SCENE))


def test_states_beyond_mujocos_limit_are_divergence_not_a_silent_reset(pendulum_problem):
    # MuJoCo resets a state beyond mjMAXVAL (BADQVEL) and steps on from qpos0.
    problem, u = pendulum_problem, np.zeros(1)
    huge = np.array([0.0, 1e11])
    with pytest.raises(mpcbox.DivergenceError, match=r"state has a magnitude .*mjMAXVAL"):
        problem.step(huge, u)
    with pytest.raises(mpcbox.DivergenceError, match="mjMAXVAL"):
        problem.linearize(huge, u)
    with pytest.raises(mpcbox.DivergenceError, match="mjMAXVAL"):
        problem.rollout(huge, np.zeros((3, 1)))
    assert np.all(np.isfinite(problem.step(np.array([0.0, 1e9]), u)))  # below it: stepped


def test_state_arrays_that_do_not_fit_are_named_errors(pendulum_problem):
    problem = pendulum_problem
    x = np.array([0.3, 0.0])
    with pytest.raises(mpcbox.InvalidTypeError, match="real"):
        problem.step(x + 0.1j, np.zeros(1))
    with pytest.raises(mpcbox.ShapeError, match="float64"):
        problem.state_difference(x, x, out=np.zeros(2, dtype=int))
    other = mujoco.MjModel.from_xml_path(str(scene_path("cartpole.xml")))
    with pytest.raises(mpcbox.ShapeError, match=r"data must be of this Problem's model"):
        problem.get_state(mujoco.MjData(other))
    np.testing.assert_array_equal(problem.get_state(mujoco.MjData(problem.model)), [0.0, 0.0])


@pytest.mark.parametrize("ctrl", [1.5e10, -1e12])
def test_controls_beyond_mujocos_limit_are_refused_not_zeroed(pendulum_problem, ctrl):
    # MuJoCo would zero them (BADCTRL) and step/linearize as if the control were 0.
    problem, x = pendulum_problem, np.array([0.3, 0.0])
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"ctrl has a magnitude .*mjMAXVAL"):
        problem.step(x, [ctrl])
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"ctrl has a magnitude"):
        problem.linearize(x, [ctrl])
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"ctrls has a magnitude"):
        problem.rollout(x, np.full((3, 1), ctrl))
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"ctrls has a magnitude"):
        problem.linearize_trajectory(np.tile(x, (2, 1)), np.full((2, 1), ctrl))
    # Below the limit a large control is applied: on this unlimited motor the step moves.
    unlimited = mpcbox.Problem(pendulum())
    moved = unlimited.step(np.zeros(2), [1e8])[1] - unlimited.step(np.zeros(2), [0.0])[1]
    assert moved > 1e6


def test_lqr_at_an_operating_point_outside_ctrlrange_is_an_error(pendulum_problem):
    # It used to return K = 0: the clamped control has no effect in the finite differences.
    with pytest.raises(
        mpcbox.InvalidArgumentError, match=r"ctrl\[0\] = 100 is outside .*ctrlrange"
    ):
        mpcbox.LQR(pendulum_problem, ctrl=[100.0])
    # At the limit itself MuJoCo differentiates one-sidedly: a working gain.
    K = mpcbox.LQR(pendulum_problem, ctrl=[2.0], state=np.array([np.pi, 0.0])).K
    assert np.all(np.isfinite(K)) and np.any(K != 0)


def test_a_linearization_without_control_authority_is_an_error():
    problem = mpcbox.Problem(compiled(actuator_gear=np.array([[0.0, 0, 0, 0, 0, 0]])))
    with pytest.raises(mpcbox.NoControlAuthorityError, match="B = 0"):
        problem.linearize(np.zeros(2), np.zeros(1))
    with pytest.raises(mpcbox.NoControlAuthorityError, match="B = 0"):
        problem.linearize_trajectory(np.zeros((3, 2)), np.zeros((3, 1)))
    with pytest.raises(mpcbox.NoControlAuthorityError):
        mpcbox.LQR(problem)


# ---------------------------------------------------------------------- disturbances
@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"force": [np.nan, 0, 0]}, "force"),
        ({"force": [np.inf, 0, 0]}, "force"),
        ({"force": [1e9, 0, 0]}, "force"),
        ({"force": [1e12, 0, 0]}, "force"),
        ({"force": [1, 0, 0], "duration": 0.0}, "duration"),
        ({"force": [1, 0, 0], "duration": -0.1}, "duration"),
        ({"force": [1, 0, 0], "start": np.nan}, "start"),
        ({"force": [1, 0, 0], "torque": [0, np.nan, 0]}, "torque"),
    ],
)
def test_bad_pushes_are_refused_naming_the_argument(kwargs, argument):
    with pytest.raises(mpcbox.InvalidArgumentError, match=argument):
        mpcbox.Push(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"std": np.nan}, "std"),
        ({"std": -0.1}, "std"),
        ({"std": [0.1, np.nan]}, "std"),
        ({"std": 0.1, "scale": np.nan}, "scale"),
        ({"std": 0.1, "width": 0.0}, "width"),
    ],
)
def test_bad_actuator_noise_is_refused_naming_the_argument(kwargs, argument):
    with pytest.raises(mpcbox.InvalidArgumentError, match=argument):
        mpcbox.ActuatorNoise(**kwargs)


@pytest.mark.parametrize("fall_height", [np.nan, np.inf, "low"])
def test_a_non_finite_fall_height_is_refused(fall_height):
    from mpcbox.registry import task_class

    with pytest.raises(mpcbox.InvalidArgumentError, match="fall_height"):
        task_class("humanoid_balance")(fall_height=fall_height)


def test_push_searches_are_bounded():
    from mpcbox.comparison.push_limits import push_grid
    from mpcbox.comparison.scenario import PushTest
    from mpcbox.sim.disturbances import MAX_FORCE

    with pytest.raises(mpcbox.InvalidArgumentError, match="max_force"):
        PushTest(max_force=1e300)
    PushTest(max_force=MAX_FORCE)  # the bound itself is allowed
    problem = mpcbox.Problem(str(PENDULUM_SCENE))
    with pytest.raises(mpcbox.InvalidArgumentError, match="forces"):
        push_grid(problem, mpcbox.LQR(problem), [1.0, 1e300], PushTest(body="pole"))
