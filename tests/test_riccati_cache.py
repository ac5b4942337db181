"""The backward pass with a Riccati cache equals the full recursion (clamped knots, defects,
changed Hessians, several regularizations), and reuses the chain when it can."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.backward_pass import backward_pass, dynamics_blocks
from mpcbox.controllers.ilqr.riccati_cache import RiccatiCache
from mpcbox.core.problem import Linearization, Quadratization
from mpcbox.errors import InvalidArgumentError

T, NX, NU = 15, 6, 3


def _system(rng):
    A = np.eye(NX) + 0.05 * rng.standard_normal((NX, NX))
    B = 0.1 * rng.standard_normal((NX, NU))
    lin = Linearization(np.broadcast_to(A, (T, NX, NX)), np.broadcast_to(B, (T, NX, NU)))
    return lin, dynamics_blocks(lin)


def _hessians(rng):
    M = rng.standard_normal((NX + NU, NX + NU))
    H = M @ M.T + np.eye(NX + NU)
    lxx = np.broadcast_to(H[:NX, :NX], (T + 1, NX, NX)).copy()
    luu = np.broadcast_to(H[NX:, NX:], (T + 1, NU, NU)).copy()
    lux = np.broadcast_to(H[NX:, :NX], (T + 1, NU, NX)).copy()
    luu[T], lux[T] = 0.0, 0.0
    return lxx, luu, lux


def _quad(rng, hessians, scale=1.0):
    lxx, luu, lux = hessians
    return Quadratization(
        np.zeros(T + 1),
        scale * rng.standard_normal((T + 1, NX)),
        scale * rng.standard_normal((T + 1, NU)),
        lxx,
        luu,
        lux,
    )


def _same(a, b):
    np.testing.assert_allclose(a.k, b.k, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(a.K, b.K, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(a.expected, b.expected, rtol=1e-9, atol=1e-11)
    np.testing.assert_array_equal(a.free, b.free)


@pytest.mark.parametrize("bounded", [False, True])
@pytest.mark.parametrize("defects", [False, True])
def test_cached_passes_equal_full_recursion(bounded, defects):
    rng = np.random.default_rng(3)
    lin, blocks = _system(rng)
    hessians = _hessians(rng)
    cache = RiccatiCache()
    ctrls = np.zeros((T, NU))
    low = np.full(NU, -0.3 if bounded else -np.inf)
    high = -low
    clamped = 0
    for i in range(6):
        quad = _quad(rng, hessians, scale=3.0 if bounded and i % 2 else 0.3)
        gaps = 0.01 * rng.standard_normal((T, NX)) if defects else None
        full = backward_pass(lin, quad, ctrls, low, high, 1e-3, gaps=gaps, blocks=blocks)
        cached = backward_pass(
            lin, quad, ctrls, low, high, 1e-3, gaps=gaps, blocks=blocks, cache=cache
        )
        _same(cached, full)
        clamped += int((~full.free).any())
    assert cache.misses == 1 and cache.hits == 5
    if bounded:
        assert clamped >= 2  # the large gradients clamp some knots
    else:
        assert cache.chain(blocks, quad, 1e-3, NU).lowest == 0  # every knot held


def test_new_hessians_or_regularization_start_a_new_chain():
    rng = np.random.default_rng(4)
    lin, blocks = _system(rng)
    cache = RiccatiCache(size=2)
    ctrls, low, high = np.zeros((T, NU)), np.full(NU, -np.inf), np.full(NU, np.inf)
    first = _hessians(rng)
    for hessians, mu in [(first, 1e-3), (first, 1e-2), (_hessians(rng), 1e-3), (first, 1e-2)]:
        quad = _quad(rng, hessians)
        full = backward_pass(lin, quad, ctrls, low, high, mu, blocks=blocks)
        _same(backward_pass(lin, quad, ctrls, low, high, mu, blocks=blocks, cache=cache), full)
    # Only the second visit of (first, 1e-2) repeats a chain; equal copies of the Hessians
    # match too, other dynamics blocks do not.
    assert (cache.hits, cache.misses) == (1, 3)
    quad = _quad(rng, tuple(h.copy() for h in first))
    backward_pass(lin, quad, ctrls, low, high, 1e-2, blocks=blocks, cache=cache)
    assert cache.hits == 2
    backward_pass(lin, quad, ctrls, low, high, 1e-2, blocks=dynamics_blocks(lin), cache=cache)
    assert cache.misses == 4


def test_cache_size_is_checked():
    with pytest.raises(InvalidArgumentError, match="size"):
        RiccatiCache(size=0)


def _swingup(**options):
    from mpcbox.controllers.ilqr.controller import ILQR
    from mpcbox.tasks.swingup import PendulumSwingup

    problem = PendulumSwingup(threads=1)
    return problem, ILQR(problem, horizon=40, linearization="reference", **options)


def test_solver_keeps_the_chain_and_plans_as_without_it():
    """A pendulum planned on its reference Jacobians with the reference's cost Hessians: the
    solves and a receding-horizon run are the same with the cache as without it."""
    problem, cached = _swingup(cost_hessian="reference", max_iterations=8)
    _, plain = _swingup(cost_hessian="reference", max_iterations=8)
    assert cached.riccati_cache is not None
    plain.riccati_cache = None
    x0 = problem.initial_state()
    x0[problem.nq :] += 0.3  # a swing, so the plan moves
    a, b = cached.solve(x0), plain.solve(x0)
    assert a.iterations == b.iterations >= 2
    np.testing.assert_allclose(a.ctrls, b.ctrls, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(a.K, b.K, rtol=1e-7, atol=1e-9)
    assert cached.riccati_cache.hits >= 1  # a new mu starts a chain; the schedule revisits
    runs = [mpcbox.simulate(problem, c, 0.3).states for c in (cached, plain)]
    np.testing.assert_allclose(runs[0], runs[1], atol=1e-8)


def test_reference_hessians_and_when_the_solver_keeps_a_cache():
    problem, solver = _swingup(cost_hessian="reference")
    x = np.tile(problem.reference_state(), (41, 1))
    u = np.tile(np.clip(problem.ctrl_ref, solver.ctrl_low, solver.ctrl_high), (40, 1))
    at_reference = problem.quadratize_trajectory(x, u)
    states = x + 0.2  # elsewhere: the angle cost's Hessian differs there
    _, quad = solver._derivatives(states, u)
    np.testing.assert_allclose(quad.lxx, at_reference.lxx)
    assert not np.allclose(quad.lx, at_reference.lx)  # gradients stay the knots'
    # The angle term's Jacobian varies, so only cost_hessian="reference" makes a cache.
    assert _swingup()[1].riccati_cache is None
    with pytest.raises(InvalidArgumentError, match="cost_hessian"):
        _swingup(cost_hessian="knots")
