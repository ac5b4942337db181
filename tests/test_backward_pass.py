"""The LAPACK backward pass against a plain per-knot Riccati recursion (the pass it replaced)."""

from __future__ import annotations

import numpy as np
import pytest

from mpcbox.controllers.ilqr.backward_pass import (
    _guessed_active_set,
    backward_pass,
    dynamics_blocks,
)
from mpcbox.controllers.ilqr.boxqp import solve_box_qp
from mpcbox.core.problem import Linearization, Quadratization
from mpcbox.errors import SolverError


def _reference(lin, quad, ctrls, low, high, reg, k_init=None, gaps=None):
    """Per-knot recursion with numpy.linalg (LU solves) and the general box QP at every knot."""
    A, B = lin
    horizon, nx, nu = B.shape
    k, K = np.zeros((horizon, nu)), np.zeros((horizon, nu, nx))
    free = np.ones((horizon, nu), dtype=bool)
    vx, vxx = quad.lx[horizon].copy(), quad.lxx[horizon].copy()
    dv1 = dv2 = 0.0
    for t in range(horizon - 1, -1, -1):
        At, Bt = A[t], B[t]
        if gaps is not None:
            vx = vx + vxx @ gaps[t]
        qx, qu = quad.lx[t] + At.T @ vx, quad.lu[t] + Bt.T @ vx
        qxx = quad.lxx[t] + At.T @ vxx @ At
        quu = quad.luu[t] + Bt.T @ vxx @ Bt
        qux = quad.lux[t] + Bt.T @ vxx @ At
        quu = 0.5 * (quu + quu.T)
        quu_reg = quu + reg * np.eye(nu)
        start = None if k_init is None else k_init[t]
        res = solve_box_qp(quu_reg, qu, low - ctrls[t], high - ctrls[t], start, check=False)
        assert res.ok
        kt, Kt, f = res.x, np.zeros((nu, nx)), res.free
        if res.factor is not None:
            Kt[f] = -np.linalg.solve(quu_reg[np.ix_(f, f)], qux[f])
        k[t], K[t], free[t] = kt, Kt, f
        dv1 += kt @ qu
        dv2 += 0.5 * kt @ quu @ kt
        vx = qx + Kt.T @ quu @ kt + Kt.T @ qu + qux.T @ kt
        vxx = qxx + Kt.T @ quu @ Kt + Kt.T @ qux + qux.T @ Kt
        vxx = 0.5 * (vxx + vxx.T)
    return k, K, (dv1, dv2), free


def _problem(rng, horizon, nx, nu):
    A = np.eye(nx) + 0.1 * rng.normal(size=(horizon, nx, nx))
    B = 0.3 * rng.normal(size=(horizon, nx, nu))
    M = rng.normal(size=(horizon + 1, nx, nx))
    N = rng.normal(size=(horizon + 1, nu, nu))
    quad = Quadratization(
        value=np.zeros(horizon + 1),
        lx=rng.normal(size=(horizon + 1, nx)),
        lu=rng.normal(size=(horizon + 1, nu)),
        lxx=M @ M.transpose(0, 2, 1) / nx,
        luu=N @ N.transpose(0, 2, 1) / nu + 0.1 * np.eye(nu),
        lux=0.05 * rng.normal(size=(horizon + 1, nu, nx)),
    )
    return Linearization(A, B), quad, 0.2 * rng.normal(size=(horizon, nu))


def _relative(x, y):
    return np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-300)


@pytest.mark.parametrize(
    ("nu", "bound", "with_gaps"), [(1, 0.5, False), (3, 0.4, True), (3, np.inf, False)]
)
def test_lapack_pass_equals_the_per_knot_recursion(nu, bound, with_gaps):
    rng = np.random.default_rng(nu)
    horizon, nx = 30, 5
    lin, quad, ctrls = _problem(rng, horizon, nx, nu)
    low, high = np.full(nu, -bound), np.full(nu, bound)
    gaps = 0.1 * rng.normal(size=(horizon, nx)) if with_gaps else None
    warm = rng.uniform(-0.1, 0.1, size=(horizon, nu))
    got = backward_pass(lin, quad, ctrls, low, high, 1e-3, warm, gaps)
    k, K, expected, free = _reference(lin, quad, ctrls, low, high, 1e-3, warm, gaps)
    assert np.array_equal(got.free, free)
    if np.isfinite(bound):  # the data were made to clamp some controls (and leave some free)
        assert 0 < np.count_nonzero(~free) < free.size
    assert _relative(got.k, k) < 1e-12
    assert _relative(got.K, K) < 1e-12
    assert np.allclose(got.expected, expected, rtol=1e-12, atol=0.0)
    # The linearization's blocks kept by a solver give the same pass.
    kept = backward_pass(lin, quad, ctrls, low, high, 1e-3, warm, gaps, dynamics_blocks(lin))
    assert np.array_equal(kept.k, got.k) and np.array_equal(kept.K, got.K)


def test_non_definite_q_uu_raises_a_solver_error_naming_the_knot():
    rng = np.random.default_rng(0)
    lin, quad, ctrls = _problem(rng, 5, 3, 2)
    luu = quad.luu.copy()
    luu[3] = -np.eye(2) * 1e3
    quad = quad._replace(luu=luu)
    with pytest.raises(SolverError, match="knot 3"):
        backward_pass(lin, quad, ctrls, np.full(2, -1.0), np.full(2, 1.0), 0.0)


def test_guessed_active_set_is_the_box_qp_minimizer_or_declines():
    """The fast path that clamps the bounds the unconstrained step crosses returns the box
    QP's minimizer (checked against the projected-Newton solver run to a tight tolerance)
    and its gains, or declines and leaves the gains alone."""
    rng = np.random.default_rng(7)
    accepted = declined = 0
    for _ in range(400):
        n, nx = int(rng.integers(2, 8)), 4
        M = rng.normal(size=(n, n))
        H = M @ M.T + 0.1 * np.eye(n)
        Q = rng.normal(size=(n, 1 + nx))
        low, high = -rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
        gain = -np.linalg.solve(H, Q)
        if np.all((gain[:, 0] >= low) & (gain[:, 0] <= high)):
            continue  # the backward pass only asks when the step leaves the box
        before = gain.copy()
        free = _guessed_active_set(gain, H, Q, low, high)
        if free is None:
            declined += 1
            assert np.array_equal(gain, before)
            continue
        accepted += 1
        res = solve_box_qp(
            H, Q[:, 0], low, high, check=False, min_gradient=1e-13, min_relative_improvement=0
        )
        assert np.allclose(gain[:, 0], res.x, rtol=0, atol=1e-9)
        assert np.array_equal(free, res.free)
        gains = np.zeros((n, nx))
        gains[free] = -np.linalg.solve(H[np.ix_(free, free)], Q[free, 1:])
        assert np.allclose(gain[:, 1:], gains, rtol=1e-12, atol=1e-12)
    assert accepted > 50 and declined > 50
