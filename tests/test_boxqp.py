"""Projected-Newton box QP against a reference QP solver."""

from __future__ import annotations

import numpy as np
import pytest

from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.errors import InvalidArgumentError, MpcboxError, ShapeError


def _random_qp(rng: np.random.Generator, n: int):
    M = rng.normal(size=(n, n))
    H = M @ M.T + 0.05 * np.eye(n)
    g = 3.0 * rng.normal(size=n)
    lower = -rng.uniform(0.0, 1.5, n)
    upper = rng.uniform(0.0, 1.5, n)
    return H, g, lower, upper


def test_matches_reference_solver_on_random_problems():
    qpsolvers = pytest.importorskip("qpsolvers")
    rng = np.random.default_rng(3)
    active_seen = 0
    for _ in range(150):
        n = int(rng.integers(1, 9))
        H, g, lower, upper = _random_qp(rng, n)
        x0 = rng.uniform(lower, upper) if rng.random() < 0.5 else None
        res = solve_box_qp(H, g, lower, upper, x0)
        ref = qpsolvers.solve_qp(H, g, lb=lower, ub=upper, solver="daqp")
        assert res.ok
        assert np.all(res.x >= lower) and np.all(res.x <= upper)
        obj = 0.5 * res.x @ H @ res.x + g @ res.x
        obj_ref = 0.5 * ref @ H @ ref + g @ ref
        assert obj <= obj_ref + 1e-9 * max(1.0, abs(obj_ref))
        np.testing.assert_allclose(res.x, ref, atol=1e-6)
        # Free set: exactly the variables the reference leaves strictly inside the box
        # (or at a bound with zero gradient).
        at_bound = (np.abs(ref - lower) < 1e-7) | (np.abs(ref - upper) < 1e-7)
        active_seen += int(at_bound.any())
        assert np.all(res.free | at_bound)
        if res.free.any():
            L, lower_flag = res.factor
            Hf = H[np.ix_(res.free, res.free)]
            np.testing.assert_allclose(L @ L.T if lower_flag else L.T @ L, Hf, atol=1e-9)
    assert active_seen > 50  # the test exercises clamped variables


def test_unbounded_is_newton_step():
    rng = np.random.default_rng(0)
    H, g, _, _ = _random_qp(rng, 5)
    inf = np.full(5, np.inf)
    res = solve_box_qp(H, g, -inf, inf)
    np.testing.assert_allclose(res.x, -np.linalg.solve(H, g), rtol=1e-10)
    assert res.free.all()


def test_all_clamped_and_degenerate_box():
    H = np.eye(2)
    res = solve_box_qp(H, np.array([10.0, -10.0]), np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    np.testing.assert_allclose(res.x, [-1.0, 1.0])
    assert not res.free.any() and res.factor is None
    # lower == upper pins the variable.
    res = solve_box_qp(H, np.array([1.0, 1.0]), np.array([0.5, -2.0]), np.array([0.5, 2.0]))
    np.testing.assert_allclose(res.x, [0.5, -1.0])


def test_not_positive_definite_reports_failure():
    H = np.array([[1.0, 0.0], [0.0, -1.0]])
    res = solve_box_qp(H, np.ones(2), -np.ones(2), np.ones(2))
    assert not res.ok and res.status == -1


def test_bad_arguments_raise_named_errors():
    H = np.eye(2)
    with pytest.raises(InvalidArgumentError, match="lower must be <= upper"):
        solve_box_qp(H, np.zeros(2), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    with pytest.raises(ShapeError, match="H must have shape"):
        solve_box_qp(np.eye(3), np.zeros(2), -np.ones(2), np.ones(2))
    with pytest.raises(ShapeError, match="lower"):
        solve_box_qp(H, np.zeros(2), -np.ones(3), np.ones(2))
    with pytest.raises(MpcboxError, match="finite"):
        solve_box_qp(H, np.array([np.nan, 0.0]), -np.ones(2), np.ones(2))
