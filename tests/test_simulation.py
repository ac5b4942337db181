"""Closed-loop simulation: disturbances, failure detection, metrics."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push

FREE_BODY = """
<mujoco>
  <option gravity="0 0 0" timestep="0.001"/>
  <worldbody>
    <body name="box" pos="0 0 1"><freejoint/><geom type="box" size=".1 .1 .1" mass="2"/></body>
    <body name="arm" pos="0 0 3"><joint name="h" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -.5" size=".02" mass="1"/></body>
  </worldbody>
  <actuator><motor joint="h" ctrlrange="-1 1"/></actuator>
</mujoco>
"""


class Zero(mpcbox.Controller):
    def __call__(self, state, time):
        return np.zeros(1)


def test_recipe_noise_uses_legacy_generator_and_unit_norm_kernel():
    noise = ActuatorNoise(std=[0.01, 0.08])
    seq = noise.sample(4000, 2, 0.005, seed=1)
    np.random.seed(1)  # noqa: NPY002 - the recipe uses the legacy global generator
    white = np.random.randn(4000, 2)  # noqa: NPY002
    kernel = np.exp(-0.5 * np.linspace(-3, 3, 160) ** 2)
    kernel /= np.linalg.norm(kernel)
    np.testing.assert_allclose(seq[:, 1], 0.08 * np.convolve(white[:, 1], kernel, "same"))
    # The unit-norm kernel keeps the standard deviation; smoothing makes it correlated.
    assert np.std(seq[200:-200, 1]) == pytest.approx(0.08, rel=0.25)
    lag1 = np.corrcoef(seq[:-1, 0], seq[1:, 0])[0, 1]
    assert lag1 > 0.95


def test_balance_recipe_assigns_low_noise_to_balance_joints():
    from mpcbox.tasks.humanoid.balance import HumanoidBalance

    problem = HumanoidBalance()
    std = np.asarray(problem.noise().std)
    names = [problem.model.actuator(i).name for i in range(problem.nu)]
    low = {n for n, s in zip(names, std) if s == 0.01}
    assert low == {
        "abdomen_y",
        "abdomen_x",
        "hip_x_left",
        "hip_y_left",
        "knee_left",
        "ankle_y_left",
        "ankle_x_left",
    }


def test_humanoid_measures_are_sampled_and_summarized():
    from mpcbox.tasks.humanoid.balance import HumanoidBalance

    problem = HumanoidBalance(threads=1)
    res = mpcbox.simulate(problem, mpcbox.LQR(problem), 0.2, noise=problem.noise(), seed=0)
    assert [m.name for m in res.measures] == ["com_deviation", "tilt"]
    assert set(res.series) == {"com_deviation", "tilt"}
    assert all(v.shape == res.time.shape for v in res.series.values())
    assert set(res.metrics.measures) == {"com_deviation_rms_m", "tilt_rms_deg"}
    tilt = res.series["tilt"]
    assert res.metrics.measures["tilt_rms_deg"] == pytest.approx(np.sqrt(np.mean(tilt**2)))
    assert res.metrics.cost > 0


def test_generic_problem_has_no_measures_noise_or_contacts():
    problem = mpcbox.Problem(FREE_BODY)
    res = mpcbox.simulate(problem, Zero(), 0.05)
    assert res.series == {} and res.metrics.measures == {} and res.measures == ()
    assert problem.contacts == ()
    with pytest.raises(mpcbox.InvalidArgumentError, match="no noise model"):
        problem.noise(1.0)


def test_push_impulse_changes_momentum_by_force_times_duration():
    problem = mpcbox.Problem(FREE_BODY)
    push = Push(force=(30.0, 0.0, 0.0), start=0.01, duration=0.1, body="box")
    res = mpcbox.simulate(problem, Zero(), 0.2, pushes=[push])
    vx = res.states[-1][problem.nq + 0]
    assert vx == pytest.approx(push.impulse / 2.0, rel=1e-2)


def test_mismatch_scales_the_simulated_model_only():
    problem = mpcbox.Problem(FREE_BODY)
    mis = ModelMismatch(mass_scale=2.0, friction_scale=0.5)
    model = mis.apply(problem.model)
    np.testing.assert_allclose(model.body_mass, 2.0 * problem.model.body_mass)
    np.testing.assert_allclose(model.geom_friction[:, 0], 0.5 * problem.model.geom_friction[:, 0])
    push = Push(force=(30.0, 0.0, 0.0), start=0.01, duration=0.1, body="box")
    res = mpcbox.simulate(problem, Zero(), 0.2, pushes=[push], mismatch=mis)
    assert res.states[-1][problem.nq] == pytest.approx(push.impulse / 4.0, rel=1e-2)


def test_invalid_controls_and_nan_states_are_reported():
    problem = mpcbox.Problem(FREE_BODY)

    class Bad(mpcbox.Controller):
        def __call__(self, state, time):
            return np.array([np.nan]) if time > 0.05 else np.zeros(1)

    res = mpcbox.simulate(problem, Bad(), 0.2)
    assert not res.survived and "invalid control" in res.failure
    assert res.metrics.time_to_fall == pytest.approx(0.051, abs=2e-3)

    class Explode(mpcbox.Controller):
        def __call__(self, state, time):
            return np.zeros(1)

    start = problem.reference_state()
    start[problem.nq] = np.inf
    with pytest.raises(mpcbox.DivergenceError):
        problem.linearize(start, np.zeros(1))


def test_controller_rate_and_metrics():
    problem = mpcbox.Problem(FREE_BODY)
    calls = []

    class Counting(mpcbox.Controller):
        period = 0.01

        def __call__(self, state, time):
            calls.append(time)
            return np.array([0.5])

    res = mpcbox.simulate(problem, Counting(), 0.1)
    assert len(calls) == 10
    np.testing.assert_allclose(np.diff(calls), 0.01, atol=1e-9)
    assert res.survived and res.metrics.time_to_fall == 0.1
    assert res.metrics.control_effort == pytest.approx(0.5, rel=1e-6)
    assert res.metrics.compute_p99_ms >= res.metrics.compute_p50_ms > 0


def test_argument_errors():
    problem = mpcbox.Problem(FREE_BODY)
    with pytest.raises(mpcbox.InvalidArgumentError, match="duration"):
        mpcbox.simulate(problem, Zero(), -1.0)
    dt = problem.model.opt.timestep
    with pytest.raises(mpcbox.InvalidArgumentError, match="duration must be at least one"):
        mpcbox.simulate(problem, Zero(), 0.5 * dt)
    assert len(mpcbox.simulate(problem, Zero(), dt).time) == 2  # one step is a run
    with pytest.raises(mpcbox.InvalidArgumentError, match="pushes"):
        mpcbox.simulate(problem, Zero(), 0.1, pushes=[(1, 2, 3)])
    with pytest.raises(mpcbox.UnknownNameError, match="box"):
        mpcbox.simulate(problem, Zero(), 0.1, pushes=[Push(force=(1, 0, 0), body="boxx")])
    with pytest.raises(mpcbox.ShapeError, match="initial_state"):
        mpcbox.simulate(problem, Zero(), 0.1, initial_state=np.zeros(2))


def test_a_period_between_whole_steps_is_rounded_with_a_warning():
    import warnings

    from mpcbox.errors import PeriodWarning

    problem = mpcbox.Problem(FREE_BODY)
    calls = []

    class Every(mpcbox.Controller):
        def __init__(self, period):
            self.period = period

        def __call__(self, state, time):
            calls.append(time)
            return np.zeros(1)

    with pytest.warns(PeriodWarning, match=r"controller.period 0.0123 s .* every 0.012 s"):
        mpcbox.simulate(problem, Every(0.0123), 0.06)
    np.testing.assert_allclose(np.diff(calls), 0.012, atol=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PeriodWarning)
        mpcbox.simulate(problem, Every(0.01), 0.05)  # a whole number of steps: no warning
