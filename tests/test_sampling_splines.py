"""Control splines: closed forms of zero-order, linear and cubic interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from mpcbox.controllers.sampling import Spline
from mpcbox.errors import InvalidArgumentError


def test_zero_order_hold_takes_the_knot_at_or_before_t():
    s = Spline(4, 3.0, "zero")  # knots at 0, 1, 2, 3
    knots = np.array([[1.0], [2.0], [3.0], [4.0]])
    u = s.evaluate(knots, [0.0, 0.5, 0.999, 1.0, 1.7, 2.5, 3.0])
    np.testing.assert_allclose(u[:, 0], [1, 1, 1, 2, 2, 3, 4])


def test_linear_matches_the_chord_between_knots():
    s = Spline(3, 2.0, "linear")
    knots = np.array([[0.0, 1.0], [2.0, 1.0], [-2.0, 0.0]])
    t = np.array([0.0, 0.25, 1.0, 1.5, 2.0])
    u = s.evaluate(knots, t)
    np.testing.assert_allclose(u[:, 0], [0.0, 0.5, 2.0, 0.0, -2.0])
    np.testing.assert_allclose(u[:, 1], [1.0, 1.0, 1.0, 0.5, 0.0])


def test_cubic_reproduces_quadratics_and_passes_through_knots():
    s = Spline(5, 2.0, "cubic")
    f = lambda t: 3.0 - 2.0 * t + 1.5 * t**2  # noqa: E731
    knots = f(s.knot_times)[:, None]
    t = np.linspace(0.0, 2.0, 41)
    np.testing.assert_allclose(s.evaluate(knots, t)[:, 0], f(t), atol=1e-12)
    rng = np.random.default_rng(0)
    rand = rng.normal(size=(5, 3))
    np.testing.assert_allclose(s.evaluate(rand, s.knot_times), rand, atol=1e-12)


def test_cubic_hermite_closed_form_inside_an_interval():
    s = Spline(4, 3.0, "cubic")  # h = 1
    u = np.array([0.0, 1.0, 0.0, 2.0])
    m1 = (u[2] - u[0]) / 2  # central slopes
    m2 = (u[3] - u[1]) / 2
    x = 0.3
    h00, h10 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x
    h01, h11 = -2 * x**3 + 3 * x**2, x**3 - x**2
    want = h00 * u[1] + h10 * m1 + h01 * u[2] + h11 * m2
    assert s.evaluate(u[:, None], [1.3])[0, 0] == pytest.approx(want, abs=1e-12)
    # C1: the derivative is continuous at an interior knot.
    eps = 1e-6
    left = (s.evaluate(u[:, None], [2.0])[0, 0] - s.evaluate(u[:, None], [2.0 - eps])[0, 0]) / eps
    right = (s.evaluate(u[:, None], [2.0 + eps])[0, 0] - s.evaluate(u[:, None], [2.0])[0, 0]) / eps
    assert left == pytest.approx(right, abs=1e-4)


def test_weights_rows_sum_to_one_and_times_are_clamped():
    for kind in ("zero", "linear", "cubic"):
        s = Spline(6, 1.0, kind)
        w = s.weights(np.linspace(-0.5, 1.5, 50))
        np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(w[0], s.weights([0.0])[0])
        np.testing.assert_allclose(w[-1], s.weights([1.0])[0])


def test_shift_reevaluates_at_later_times_and_holds_the_end():
    s = Spline(3, 1.0, "linear")
    knots = np.array([[0.0], [1.0], [3.0]])
    shifted = s.shift(knots, 0.25)
    np.testing.assert_allclose(shifted[:, 0], [0.5, 2.0, 3.0])
    single = Spline(1, 1.0, "cubic")
    np.testing.assert_allclose(single.evaluate(np.array([[2.0]]), [0.0, 0.7]), [[2.0], [2.0]])


def test_refit_is_exact_on_knot_multiples_and_least_squares_in_between():
    times = np.arange(50) * 0.02
    rng = np.random.default_rng(0)
    knots = rng.uniform(-1.0, 1.0, (11, 2))
    for kind in ("zero", "linear", "cubic", "cubic_c2"):
        s = Spline(11, 1.0, kind)
        if kind in ("zero", "linear"):
            # A shift by one spacing moves every knot one place and holds the last: exact.
            moved = s.refit(knots, 0.1, times)
            np.testing.assert_allclose(moved, np.vstack([knots[1:], knots[-1:]]), atol=1e-9)
        # Off the knot grid: no spline of these knots is closer to the old plan's rest.
        fit = s.refit(knots, 0.03, times)
        target = s.evaluate(knots, times + 0.03)
        best = np.sum((s.evaluate(fit, times) - target) ** 2)
        for _ in range(20):
            other = fit + 1e-3 * rng.standard_normal(fit.shape)
            assert best <= np.sum((s.evaluate(other, times) - target) ** 2)
        assert best <= np.sum((s.evaluate(s.shift(knots, 0.03), times) - target) ** 2)


def test_bad_spline_arguments():
    with pytest.raises(InvalidArgumentError, match="interpolation"):
        Spline(3, 1.0, "quintic")
    with pytest.raises(InvalidArgumentError, match="num_knots"):
        Spline(0, 1.0)
    with pytest.raises(InvalidArgumentError, match="horizon"):
        Spline(3, 0.0)
