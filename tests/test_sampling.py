"""Sampling controllers on the CPU backend: algorithms, risk, bookkeeping, bad input."""

from __future__ import annotations

import importlib.util
from typing import ClassVar

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.sampling import (
    CEM,
    MPPI,
    PredictiveSampling,
    Randomization,
    RolloutCosts,
    aggregate_risk,
    mppi_weights,
)
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError, MpcboxError
from mpcbox.tasks import scene_path
from mpcbox.tasks.swingup import CartpoleSwingup


@pytest.fixture(scope="module")
def cartpole() -> CartpoleSwingup:
    return CartpoleSwingup()


class FixedBackend:
    """A backend returning given costs, to test the controller's bookkeeping."""

    def __init__(self, costs, overflow=None, nonfinite=None):
        self.costs = np.asarray(costs, dtype=float)
        shape = self.costs.shape
        self.overflow = np.zeros(shape, bool) if overflow is None else np.asarray(overflow)
        self.nonfinite = np.zeros(shape, bool) if nonfinite is None else np.asarray(nonfinite)

    def evaluate(self, state, candidates):
        return RolloutCosts(self.costs, self.overflow, self.nonfinite)

    stats: ClassVar[dict] = {}

    def close(self):
        pass


def test_predictive_sampling_keeps_the_best_candidate_and_never_gets_worse(cartpole):
    ctrl = PredictiveSampling(cartpole, num_samples=32, horizon=0.5, num_knots=3, seed=1)
    x0 = cartpole.initial_state()
    ctrl.plan(x0, 0.0)
    best = ctrl.last.best_cost
    # Re-planning from the same state at the same time: the nominal is candidate 0.
    for _ in range(3):
        ctrl.plan(x0, 0.0)
        assert ctrl.last.nominal_cost == pytest.approx(best)
        assert ctrl.last.best_cost <= best + 1e-9
        best = ctrl.last.best_cost
    costs = ctrl.evaluate(x0, ctrl.knots[None])
    assert costs[0] == pytest.approx(best)


def test_mppi_weights_closed_form():
    costs = np.array([1.0, 2.0, np.inf, 4.0])
    w = mppi_weights(costs, temperature=0.5)
    std = np.std([1.0, 2.0, 4.0])
    want = np.exp(-(np.array([0.0, 1.0, 3.0])) / (0.5 * std))
    np.testing.assert_allclose(w[[0, 1, 3]], want / want.sum())
    assert w[2] == 0.0


def test_mppi_update_is_the_weighted_mean(cartpole):
    ctrl = MPPI(cartpole, num_samples=4, horizon=0.2, num_knots=2, temperature=1.0)
    cand = np.arange(4 * 2).reshape(4, 2, 1).astype(float) / 10
    costs = np.array([3.0, 1.0, 2.0, np.inf])
    ctrl.update(cand, costs)
    w = mppi_weights(costs, 1.0)
    np.testing.assert_allclose(ctrl.knots, np.einsum("n,nkj->kj", w, cand))


def test_cem_refits_mean_and_std_to_the_elites(cartpole):
    ctrl = CEM(cartpole, num_samples=5, horizon=0.2, num_knots=2, num_elites=2, std_min=0.01)
    ctrl.knots = np.zeros((2, 1))
    cand = np.array([[[0.0], [0.0]], [[0.2], [0.4]], [[0.9], [0.9]], [[0.4], [0.2]], [[1], [1]]])
    ctrl.update(cand, np.array([5.0, 1.0, 4.0, 2.0, np.inf]))
    np.testing.assert_allclose(ctrl.knots, [[0.3], [0.3]])
    np.testing.assert_allclose(ctrl.std, [[0.1], [0.1]])


def test_risk_aggregation_closed_forms():
    costs = np.array([[1.0, 2.0, 3.0, 10.0], [4.0, 4.0, 4.0, 4.0]])
    np.testing.assert_allclose(aggregate_risk(costs, "mean"), [4.0, 4.0])
    np.testing.assert_allclose(aggregate_risk(costs, "worst"), [10.0, 4.0])
    np.testing.assert_allclose(aggregate_risk(costs, "cvar", 0.5), [6.5, 4.0])
    np.testing.assert_allclose(aggregate_risk(costs, "cvar", 0.1), [10.0, 4.0])


def test_domain_randomization_rolls_out_every_model(cartpole):
    rand = Randomization(num_models=3, mass_scale=(0.5, 1.5), friction_scale=(1.0, 1.0))
    ctrl = PredictiveSampling(cartpole, num_samples=4, horizon=0.3, randomization=rand)
    assert len(ctrl.models) == 3 and ctrl.models[0] is cartpole.planning_model
    assert not np.allclose(ctrl.models[1].body_mass, cartpole.planning_model.body_mass)
    cand = np.full((4, ctrl.spline.num_knots, 1), 0.5)
    ev = ctrl.backend.evaluate(np.array([0.0, 0.3, 0.0, 0.0]), cand)
    assert ev.costs.shape == (4, 3)
    assert np.ptp(ev.costs[0]) > 1e-6  # the models differ
    nominal = cartpole.rollout_cost(
        cartpole.rollout(np.array([0.0, 0.3, 0.0, 0.0]), ctrl.backend.controls(cand[:1]))
    )
    assert ev.costs[0, 0] == pytest.approx(nominal[0])
    worst = PredictiveSampling(
        cartpole, num_samples=4, horizon=0.3, randomization=rand, risk="worst"
    )
    got = worst.evaluate(np.array([0.0, 0.3, 0.0, 0.0]), cand)
    np.testing.assert_allclose(got, ev.costs.max(axis=1))


def test_excluded_samples_are_counted_and_never_chosen(cartpole):
    ctrl = PredictiveSampling(cartpole, num_samples=4, horizon=0.2, num_knots=2)
    ctrl.backend = FixedBackend(
        [[1.0], [0.5], [np.nan], [0.1]],
        overflow=[[False], [False], [False], [True]],
    )
    ctrl.plan(cartpole.initial_state(), 0.0)
    assert ctrl.last.best_cost == 0.5 and ctrl.last.valid == 2
    stats = ctrl.stats
    assert stats["excluded_samples"] == 2
    assert stats["overflow_samples"] == 1 and stats["nonfinite_samples"] == 1
    ctrl.backend = FixedBackend([[np.inf]] * 4, nonfinite=[[True]] * 4)
    before = ctrl.knots.copy()
    ctrl.plan(cartpole.initial_state(), 0.0)
    np.testing.assert_array_equal(ctrl.knots, before)  # all excluded: keep the nominal
    assert ctrl.stats["failed_iterations"] == 1 and ctrl.stats["fallbacks"] == 1


def test_warm_start_shifts_the_nominal_spline(cartpole):
    ctrl = PredictiveSampling(
        cartpole, num_samples=1, horizon=1.0, num_knots=3, interpolation="linear"
    )
    ctrl.plan(cartpole.initial_state(), 0.0)
    ctrl.knots = np.array([[0.0], [0.5], [1.0]])
    ctrl.plan(cartpole.initial_state(), 0.25)  # N = 1: only the shifted nominal
    np.testing.assert_allclose(ctrl.knots[:, 0], [0.25, 0.75, 1.0])


def test_least_squares_warm_start_refits_the_shifted_nominal(cartpole):
    ctrl = PredictiveSampling(
        cartpole, num_samples=1, horizon=1.0, num_knots=5, shift="least_squares"
    )
    ctrl.plan(cartpole.initial_state(), 0.0)
    knots = np.array([[0.0], [0.8], [-0.4], [0.6], [0.2]])
    ctrl.knots = knots.copy()
    ctrl.plan(cartpole.initial_state(), 0.1)  # N = 1: only the shifted nominal
    expected = ctrl.spline.refit(knots, 0.1, ctrl.step_times)
    np.testing.assert_allclose(ctrl.knots, expected)
    resampled = ctrl.spline.shift(knots, 0.1)
    old_rest = ctrl.spline.evaluate(knots, ctrl.step_times + 0.1)
    assert np.sum((ctrl.weights @ ctrl.knots - old_rest) ** 2) < np.sum(
        (ctrl.weights @ resampled - old_rest) ** 2
    )


def test_registry_builds_sampling_controllers(cartpole):
    for name, cls in (("ps", PredictiveSampling), ("mppi", MPPI), ("cem", CEM)):
        ctrl = mpcbox.make_controller(name, cartpole)
        assert isinstance(ctrl, cls) and ctrl.name == name
        u = ctrl(cartpole.initial_state(), 0.0)
        assert u.shape == (1,) and np.all(np.abs(u) <= 1.0)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        (dict(num_samples=0), "num_samples"),
        (dict(horizon=0.001), "horizon"),
        (dict(horizon=-1.0), "horizon"),
        (dict(backend="tpu"), "backend"),
        (dict(noise_scale=[0.1, 0.2]), "noise_scale"),
        (dict(risk="median"), "risk"),
        (dict(interpolation="quadratic"), "interpolation"),
        (dict(shift="exact"), r"shift.*least_squares"),
        (dict(terminal_value="riccati"), r"terminal_value.*lqr"),
        (dict(num_knots=0), "num_knots"),
        (dict(device="cuda"), "device"),
        (dict(bogus=1), "bogus"),
        (dict(randomization=Randomization(num_models=0)), "num_models"),
    ],
)
def test_bad_input_raises_clear_errors(cartpole, options, match):
    with pytest.raises(InvalidArgumentError, match=match):
        PredictiveSampling(cartpole, **options)


def test_algorithm_specific_bad_input(cartpole):
    with pytest.raises(InvalidArgumentError, match="temperature"):
        MPPI(cartpole, temperature=0.0)
    with pytest.raises(InvalidArgumentError, match="num_elites"):
        CEM(cartpole, num_samples=8, num_elites=9)


def test_warp_backend_without_gpu_errors_or_falls_back(cartpole):
    wp = pytest.importorskip("warp")
    if wp.is_cuda_available():
        pytest.skip("a GPU is present")
    with pytest.raises(BackendUnavailableError, match="CUDA"):
        PredictiveSampling(cartpole, backend="warp", device="cuda")
    with pytest.warns(RuntimeWarning, match="without CUDA"):
        PredictiveSampling(cartpole, num_samples=2, horizon=0.05, backend="warp")


def test_warp_backend_rejects_custom_cost_terms():
    pytest.importorskip("mujoco_warp")

    class Tip(mpcbox.CostTerm):
        def size(self, model):
            return 1

        def residual(self, features):
            return features.qpos[:, :1] ** 3

    problem = mpcbox.Problem(scene_path("cartpole.xml"), cost=mpcbox.Cost([Tip(1.0, "tip")]))
    with pytest.raises(MpcboxError, match=r"Tip.*backend='cpu'"):
        PredictiveSampling(problem, backend="warp", device="cpu")


class AsyncBackend:
    """The CPU backend behind the submit/collect interface of the warp backend."""

    def __init__(self, inner):
        self.inner = inner
        self.stats = inner.stats

    def submit(self, state, candidates):
        self._result = self.inner.evaluate(state, candidates)

    def collect(self):
        return self._result

    def close(self):
        pass


@pytest.mark.parametrize("cls", [MPPI, CEM])
def test_noise_prefetch_during_async_evaluation_keeps_the_draws(cartpole, cls):
    """Drawing the next noise block while the backend computes changes no result."""
    opts = dict(num_samples=16, horizon=0.3, num_knots=3, iterations=2, seed=3)
    sync, overlapped = cls(cartpole, **opts), cls(cartpole, **opts)
    overlapped.backend = AsyncBackend(overlapped.backend)
    x = cartpole.initial_state()
    for k in range(3):
        np.testing.assert_array_equal(sync.plan(x, 0.01 * k), overlapped.plan(x, 0.01 * k))


def test_replan_period_returns_the_spline_between_replans(cartpole):
    ctrl = MPPI(cartpole, num_samples=16, horizon=0.5, num_knots=4, replan_period=0.03)
    assert ctrl.period is None
    x = cartpole.initial_state()
    u0 = ctrl(x, 0.0)
    knots = ctrl.knots.copy()
    assert ctrl.stats["ticks"] == 1
    u1 = ctrl(x, 0.01)
    u2 = ctrl(x, 0.02)
    assert ctrl.stats["ticks"] == 1  # no replan before 0.03 s
    expect = cartpole.clip_ctrl(ctrl.spline.evaluate(knots, [0.0, 0.01, 0.02]))
    np.testing.assert_allclose([u0, u1, u2], expect, atol=1e-12)
    ctrl(x, 0.03)
    assert ctrl.stats["ticks"] == 2
    with pytest.raises(InvalidArgumentError, match="replan_period"):
        MPPI(cartpole, replan_period=-1.0)


def test_planning_timestep_and_solver_options_use_a_private_planning_model(warp_device):
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = HumanoidStand()
    iterations = problem.planning_model.opt.iterations
    integrator = problem.planning_model.opt.integrator
    ctrl = PredictiveSampling(
        problem,
        num_samples=4,
        horizon=0.1,
        planning_timestep=0.01,
        solver_iterations=2,
        planning_integrator="euler",
    )
    assert ctrl.problem is not problem and ctrl.problem.dt == pytest.approx(0.01)
    assert ctrl.horizon_steps == 10
    # The CPU backend ignores the solver cap (MuJoCo's CPU solver diverges when capped low).
    assert ctrl.problem.planning_model.opt.iterations == iterations
    assert ctrl.problem.planning_model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    assert problem.planning_model.opt.iterations == iterations
    assert problem.planning_model.opt.integrator == integrator
    if importlib.util.find_spec("mujoco_warp") is not None:
        warp = PredictiveSampling(
            problem, num_samples=4, horizon=0.1, solver_iterations=2, backend="warp",
            device=warp_device,
        )  # fmt: skip
        assert warp.problem.planning_model.opt.iterations == 2
        assert warp.backend.models[0].opt.iterations == 2
    with pytest.raises(InvalidArgumentError, match="solver_iterations"):
        PredictiveSampling(problem, num_samples=4, horizon=0.1, solver_iterations=0)
    ctrl = PredictiveSampling(
        problem, num_samples=4, horizon=0.1, planning_disable=("constraint", "EulerDamp")
    )
    bits = mujoco.mjtDisableBit.mjDSBL_CONSTRAINT | mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    assert ctrl.problem.planning_model.opt.disableflags & bits == bits
    assert problem.planning_model.opt.disableflags & bits == 0
    with pytest.raises(InvalidArgumentError, match=r"planning_disable.*'eulerdamp'"):
        PredictiveSampling(problem, num_samples=4, horizon=0.1, planning_disable=("damping",))
    with pytest.raises(InvalidArgumentError, match="planning_disable"):
        PredictiveSampling(problem, num_samples=4, horizon=0.1, planning_disable="contact")
    with pytest.raises(InvalidArgumentError, match=r"planning_integrator.*'euler'"):
        PredictiveSampling(problem, num_samples=4, horizon=0.1, planning_integrator="verlet")
    assert problem.dt == pytest.approx(0.005)
    ctrl.plan(problem.initial_state(), 0.0)
    assert np.isfinite(ctrl.last.best_cost)


def test_humanoid_stand_balance_cost_terms():
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    names = {t.name for t in HumanoidStand().cost.running}
    assert {"com_left", "com_right"} <= names
    names = {t.name for t in HumanoidStand(balance_cost=0.0).cost.running}
    assert not names & {"com_left", "com_right"}


def test_collidable_pairs_detection():
    pytest.importorskip("mujoco_warp")
    from mpcbox.controllers.sampling.backends.warp import has_collidable_pairs
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    assert not has_collidable_pairs(CartpoleSwingup().planning_model)
    assert has_collidable_pairs(HumanoidStand().planning_model)
