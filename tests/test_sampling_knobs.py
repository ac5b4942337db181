"""Sampler knobs: C2 cubic splines, per-knot noise schedules, absolute MPPI temperature,
CEM's initial standard deviation."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.sampling import CEM, MPPI, PredictiveSampling, Spline
from mpcbox.controllers.sampling.mppi import mppi_weights
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.swingup import CartpoleSwingup


@pytest.fixture(scope="module")
def problem():
    return CartpoleSwingup()


# ------------------------------------------------------------------ C2 cubic splines
def test_c2_spline_interpolates_the_knots_and_matches_the_natural_spline():
    spline = Spline(6, 1.0, "cubic_c2")
    np.testing.assert_allclose(spline.weights(spline.knot_times), np.eye(6), atol=1e-12)
    rng = np.random.default_rng(3)
    knots = rng.normal(size=(6, 2))
    t = np.linspace(0.0, 1.0, 201)
    got = spline.evaluate(knots, t)
    interpolate = pytest.importorskip("scipy.interpolate")
    ref = interpolate.CubicSpline(spline.knot_times, knots, bc_type="natural")(t)
    np.testing.assert_allclose(got, ref, atol=1e-12)
    # Linear functions are reproduced exactly.
    line = (0.5 - 2.0 * spline.knot_times)[:, None]
    np.testing.assert_allclose(spline.evaluate(line, t)[:, 0], 0.5 - 2.0 * t, atol=1e-12)


def test_c2_spline_has_continuous_slope_and_curvature_at_the_knots():
    spline = Spline(5, 2.0, "cubic_c2")
    knots = np.random.default_rng(0).normal(size=(5, 1))
    eps = 1e-4

    def derivatives(t0, side):
        # One-sided finite differences on one cubic piece (side -1: left, +1: right).
        ts = t0 + side * eps * np.arange(4)
        u = spline.evaluate(knots, ts)[:, 0]
        d1 = side * (-11 * u[0] + 18 * u[1] - 9 * u[2] + 2 * u[3]) / (6 * eps)
        d2 = (2 * u[0] - 5 * u[1] + 4 * u[2] - u[3]) / eps**2
        return d1, d2

    for t0 in spline.knot_times[1:-1]:
        left, right = derivatives(t0, -1), derivatives(t0, +1)
        assert left[0] == pytest.approx(right[0], abs=1e-6)
        assert left[1] == pytest.approx(right[1], abs=1e-3)
    # Natural ends: no curvature at the first and last knot.
    assert derivatives(0.0, +1)[1] == pytest.approx(0.0, abs=1e-3)
    assert derivatives(2.0, -1)[1] == pytest.approx(0.0, abs=1e-3)
    # The C1 Hermite spline's curvature jumps at an interior knot for the same knots.
    hermite = Spline(5, 2.0, "cubic")
    u = [hermite.evaluate(knots, 0.5 + s * eps * np.arange(4))[:, 0] for s in (-1, 1)]
    jumps = [(2 * v[0] - 5 * v[1] + 4 * v[2] - v[3]) / eps**2 for v in u]
    assert abs(jumps[0] - jumps[1]) > 1e-2


def test_c2_spline_with_two_knots_is_linear():
    spline = Spline(2, 1.0, "cubic_c2")
    np.testing.assert_allclose(spline.weights([0.25]), [[0.75, 0.25]])


# ------------------------------------------------------------------ noise schedule
@pytest.mark.parametrize(
    ("schedule", "gains"),
    [
        ("constant", [1, 1, 1, 1]),
        ("linear", [0.25, 0.5, 0.75, 1.0]),
        ("ramp", [0.0, 1 / 3, 2 / 3, 1.0]),
        ([0, 1, 2, 0.5], None),
    ],
)
def test_noise_schedule_scales_the_sample_std_per_knot(problem, schedule, gains):
    gains = np.asarray(schedule if gains is None else gains, dtype=float)
    ctrl = PredictiveSampling(
        problem, num_samples=4001, num_knots=4, noise_scale=0.05, noise_schedule=schedule
    )
    ctrl.knots = ctrl.nominal_knots()
    cand = ctrl.sample()
    np.testing.assert_array_equal(cand[0], ctrl.knots)
    std = (cand[1:] - ctrl.knots).std(axis=0)[:, 0]  # (K,), one actuator
    np.testing.assert_allclose(std, 0.05 * gains, rtol=0.06, atol=1e-15)
    np.testing.assert_allclose(ctrl.knot_noise[:, 0], 0.05 * gains)


def test_default_schedule_draws_the_same_candidates_as_explicit_ones(problem):
    a = MPPI(problem, num_samples=16, num_knots=3)
    b = MPPI(problem, num_samples=16, num_knots=3, noise_schedule=[1.0, 1.0, 1.0])
    for ctrl in (a, b):
        ctrl.knots = ctrl.nominal_knots()
    np.testing.assert_array_equal(a.sample(), b.sample())


@pytest.mark.parametrize("schedule", ["cosine", [1.0, 1.0], [1.0, -1.0, 1.0], [1.0, np.nan, 1]])
def test_bad_noise_schedules_are_rejected(problem, schedule):
    with pytest.raises(InvalidArgumentError, match="noise_schedule"):
        MPPI(problem, num_knots=3, noise_schedule=schedule)


def test_a_ramp_over_one_knot_would_sample_no_noise_and_is_rejected(problem):
    with pytest.raises(InvalidArgumentError, match=r"ramp.*num_knots >= 2"):
        MPPI(problem, num_knots=1, noise_schedule="ramp")


# ------------------------------------------------------------------ MPPI temperature
def test_absolute_temperature_weights_are_the_softmax_of_minus_cost_over_lambda():
    costs = np.array([3.0, 1.0, 2.5, np.inf, 10.0])
    lam = 0.7
    w = mppi_weights(costs, lam, normalized=False)
    e = np.exp(-costs[[0, 1, 2, 4]] / lam)
    np.testing.assert_allclose(w[[0, 1, 2, 4]], e / e.sum(), rtol=1e-12)
    assert w[3] == 0.0
    # Absolute weights depend on the cost scale; normalized ones do not.
    normalized = mppi_weights(costs, lam)
    np.testing.assert_allclose(mppi_weights(10 * costs, lam), normalized, rtol=1e-12)
    assert not np.allclose(mppi_weights(10 * costs, lam, normalized=False), w)


def test_mppi_update_uses_the_configured_temperature_mode(problem):
    ctrl = MPPI(problem, num_samples=5, num_knots=2, temperature=2.0, temperature_mode="absolute")
    cand = np.random.default_rng(1).normal(size=(5, 2, problem.nu))
    costs = np.array([1.0, 4.0, 2.0, 3.0, 0.5])
    ctrl.update(cand, costs)
    w = np.exp(-costs / 2.0)
    np.testing.assert_allclose(ctrl.knots, np.einsum("n,nkj->kj", w / w.sum(), cand))
    with pytest.raises(InvalidArgumentError, match="temperature_mode"):
        MPPI(problem, temperature_mode="relative")


# ------------------------------------------------------------------ CEM std_init
def test_cem_starts_from_std_init_and_is_capped_by_the_larger_scale(problem):
    ctrl = CEM(problem, num_knots=3, noise_scale=0.2, std_init=0.5, noise_schedule="linear")
    gains = np.array([1, 2, 3]) / 3
    np.testing.assert_allclose(ctrl.std[:, 0], 0.5 * gains)
    ctrl.knots = ctrl.nominal_knots()
    wide = np.random.default_rng(0).normal(0, 5.0, size=(ctrl.num_samples, 3, problem.nu))
    ctrl.update(wide, np.arange(ctrl.num_samples, dtype=float))
    np.testing.assert_allclose(ctrl.std[:, 0], 0.5 * gains)  # clipped at max(0.5, 0.2)
    small = CEM(problem, num_knots=3, noise_scale=0.2, std_init=0.01, std_min=0.0)
    np.testing.assert_allclose(small.std, 0.01)
    small.knots = small.nominal_knots()
    small.update(wide, np.arange(small.num_samples, dtype=float))
    np.testing.assert_allclose(small.std, 0.2)  # may widen up to noise_scale
    default = CEM(problem, num_knots=3, noise_scale=0.2)
    np.testing.assert_array_equal(default.std, np.full((3, problem.nu), 0.2))
    with pytest.raises(InvalidArgumentError, match="std_init"):
        CEM(problem, std_init=-1.0)


def test_knobs_close_the_loop_on_the_cpu(problem):
    ctrl = mpcbox.make_controller(
        "mppi",
        problem,
        num_samples=16,
        horizon=0.3,
        interpolation="cubic_c2",
        noise_schedule="linear",
        temperature_mode="absolute",
        temperature=5.0,
    )
    res = mpcbox.simulate(problem, ctrl, 0.3)
    assert res.survived and np.all(np.isfinite(res.ctrls))


# ------------------------------------------------------------------ warp backend
def test_warp_backend_supports_the_knobs(problem, warp_device):
    """The knobs live on the host (noise, weights, refits) and in the interpolation matrix,
    which the warp backend applies as given: C2 rollout costs match the CPU backend."""
    pytest.importorskip("mujoco_warp")
    opts = dict(
        num_samples=8,
        horizon=10 * problem.dt,
        num_knots=4,
        interpolation="cubic_c2",
        noise_schedule="linear",
        temperature_mode="absolute",
        temperature=1.0,
    )
    cpu = MPPI(problem, **opts)
    warp = MPPI(problem, backend="warp", device=warp_device, **opts)
    cand = problem.clip_ctrl(
        problem.ctrl_ref + np.random.default_rng(0).normal(0, 0.3, (8, 4, problem.nu))
    )
    state = problem.initial_state()
    a, b = cpu.backend.evaluate(state, cand), warp.backend.evaluate(state, cand)
    np.testing.assert_allclose(b.costs, a.costs, rtol=2e-3)
    out = warp(state, 0.0)
    assert np.all(np.isfinite(out)) and np.all(np.isfinite(warp.knots))
    cem = CEM(
        problem,
        backend="warp",
        device=warp_device,
        std_init=0.1,
        **{k: v for k, v in opts.items() if not k.startswith("temperature")},
        num_elites=4,
    )
    np.testing.assert_allclose(cem.std[:, 0], 0.1 * np.arange(1, 5) / 4)
    assert np.all(np.isfinite(cem(state, 0.0)))


# ------------------------------------------------------------------ the task's guess
def test_guess_candidate_scores_the_tasks_guess_at_every_tick(problem):
    seen: list = []

    class Recording(MPPI):
        def evaluate(self, state, candidates, **kwargs):
            seen.append((np.array(state), np.array(candidates)))
            return super().evaluate(state, candidates, **kwargs)

    ctrl = Recording(problem, num_samples=8, horizon=0.2, num_knots=3, guess_candidate=True)
    state = problem.initial_state()
    for tick in range(3):
        ctrl(state, 0.02 * tick)
        state = state + 0.01  # another measured state each tick
    assert len(seen) == 3
    for measured, cand in seen:
        np.testing.assert_array_equal(cand[-1], ctrl.nominal_knots(measured))
    # Off (the default), the last candidate is noise like the others.
    seen.clear()
    plain = Recording(problem, num_samples=8, horizon=0.2, num_knots=3)
    plain(problem.initial_state(), 0.0)
    assert not np.allclose(seen[0][1][-1], plain.nominal_knots(problem.initial_state()))
    with pytest.raises(InvalidArgumentError, match="guess_candidate"):
        MPPI(problem, guess_candidate="yes")
