"""LQR: closed-form scalar case, python-control cross-check, checks, and humanoid balance."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.lqr import LQRConfig, dlqr
from mpcbox.controllers.uncontrollable import uncontrollable_marginal_projector
from mpcbox.errors import InvalidTypeError, UnknownOptionError
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.balance import HumanoidBalance, classic_humanoid_path


def test_scalar_closed_form():
    a, b, q, r = 1.2, 0.5, 2.0, 0.3
    K, P = dlqr(np.array([[a]]), np.array([[b]]), np.array([[q]]), np.array([[r]]))
    # P solves b^2 P^2 + (r - a^2 r - q b^2) P - q r = 0 (the scalar DARE), positive root.
    c2, c1, c0 = b * b, r - a * a * r - q * b * b, -q * r
    p = (-c1 + np.sqrt(c1 * c1 - 4 * c2 * c0)) / (2 * c2)
    assert P[0, 0] == pytest.approx(p, rel=1e-12)
    assert K[0, 0] == pytest.approx(a * b * p / (r + b * b * p), rel=1e-12)
    assert abs(a - b * K[0, 0]) < 1.0


@pytest.fixture(scope="module")
def balance() -> HumanoidBalance:
    return HumanoidBalance()


def test_an_unweighted_mode_on_the_unit_circle_still_gets_a_stabilizing_gain():
    """A double integrator that Q does not see (a robot yawing about one foot) beside a
    weighted unstable mode: SciPy's solver alone rejects the pencil (before 1.17) or returns
    a gain that leaves the double integrator on the unit circle (1.17); dlqr's gain leaves
    the weighted mode where the scalar closed form puts it and the unweighted one inside."""
    scipy_linalg = pytest.importorskip("scipy.linalg")
    A = np.array([[1.0, 0.01, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.1]])
    B = np.array([[0.0, 0.0], [0.01, 0.0], [0.0, 0.1]])
    Q, R = np.diag([0.0, 0.0, 1.0]), np.eye(2)
    try:
        P_scipy = scipy_linalg.solve_discrete_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError):
        pass
    else:
        K_scipy = np.linalg.solve(R + B.T @ P_scipy @ B, B.T @ P_scipy @ A)
        assert np.max(np.abs(np.linalg.eigvals(A - B @ K_scipy))) >= 1.0 - 1e-12
    K, _ = dlqr(A, B, Q, R)
    eig = np.linalg.eigvals(A - B @ K)
    assert np.max(np.abs(eig)) < 1.0
    # The third mode is decoupled: its closed loop is the scalar problem's.
    a, b = 1.1, 0.1
    p = scipy_linalg.solve_discrete_are(np.array([[a]]), np.array([[b]]), np.eye(1), np.eye(1))
    k = (b * p[0, 0] * a) / (1.0 + b * b * p[0, 0])
    assert np.min(np.abs(eig - (a - b * k))) < 1e-6


def test_humanoid_gain_matches_python_control(balance):
    control = pytest.importorskip("control")
    lqr = mpcbox.LQR(balance)
    # Cart-pole upright: an unstable, fully controllable pair.
    cart = mpcbox.Problem(scene_path("cartpole.xml"), qpos_ref=np.array([0.0, np.pi]))
    ours = mpcbox.LQR(cart)
    K_ctrl, S_ctrl, _ = control.dlqr(ours.A, ours.B, ours.Q, ours.R)
    np.testing.assert_allclose(ours.K, K_ctrl, rtol=1e-8, atol=1e-10 * np.abs(K_ctrl).max())
    np.testing.assert_allclose(ours.P, S_ctrl, rtol=1e-8, atol=1e-10 * np.abs(S_ctrl).max())
    # The humanoid on one leg (54 states, with the floating base's marginal modes): sliding
    # and turning the whole body are uncontrollable, so dlqr weighs the rest of the state,
    # (I - Pi_u) x; python-control solves the same weights to the same gain.
    keep = np.eye(len(lqr.A)) - uncontrollable_marginal_projector(lqr.A, lqr.B)
    Q = keep.T @ lqr.Q @ keep
    K_h, _, _ = control.dlqr(lqr.A, lqr.B, 0.5 * (Q + Q.T), lqr.R, method="scipy")
    np.testing.assert_allclose(lqr.K, K_h @ keep, rtol=1e-6, atol=1e-7 * np.abs(K_h).max())
    assert lqr.spectral_radius <= 1.0 + 1e-6


def test_checks_name_the_failing_condition():
    A = np.diag([1.5, 0.5])
    B = np.array([[0.0], [1.0]])
    with pytest.raises(mpcbox.NotStabilizableError, match=r"1\.5"):
        dlqr(A, B, np.eye(2), np.eye(1))
    A2 = np.diag([0.5, 0.9])
    with pytest.raises(mpcbox.CostDefinitionError, match="Q must be symmetric"):
        dlqr(A2, B, np.array([[1.0, 0.5], [0.0, 1.0]]), np.eye(1))
    with pytest.raises(mpcbox.CostDefinitionError, match="R must be positive definite"):
        dlqr(A2, B, np.eye(2), np.zeros((1, 1)))
    with pytest.raises(mpcbox.CostDefinitionError, match="Q must be positive semidefinite"):
        dlqr(A2, B, -np.eye(2), np.eye(1))
    with pytest.raises(mpcbox.ShapeError, match="R must have shape"):
        dlqr(A2, B, np.eye(2), np.eye(2))
    # Symmetry tolerance scales with the matrix: tiny relative asymmetry is accepted.
    Q = 1e6 * np.eye(2)
    Q[0, 1] += 1e-6
    dlqr(A2, B, Q, np.eye(1))


def test_lqr_holds_one_leg_12s_under_recipe_noise(balance):
    lqr = mpcbox.LQR(balance)
    res = mpcbox.simulate(balance, lqr, 12.0, noise=balance.noise(), seed=1)
    assert res.survived, res.failure
    assert res.metrics.measures["com_deviation_rms_m"] < 0.02

    # Without a controller (holding the equilibrium control) the humanoid falls.
    class Hold(mpcbox.Controller):
        def __call__(self, state, time):
            return balance.ctrl_ref

    fall = mpcbox.simulate(balance, Hold(), 12.0, noise=balance.noise(), seed=1)
    assert not fall.survived and fall.metrics.time_to_fall < 12.0


def test_right_leg_posture_from_mink_is_balanced_by_lqr():
    right = HumanoidBalance("right")
    assert right.posture.com_error < 1e-3
    assert right.posture.swing_height > 0.05
    res = mpcbox.simulate(right, mpcbox.LQR(right), 6.0, noise=right.noise(), seed=1)
    assert res.survived, res.failure


def test_classic_humanoid_from_mujoco_warp_test_data():
    path = classic_humanoid_path()
    if path is None:
        pytest.skip("mujoco-warp's classic humanoid test model is not installed")
    classic = HumanoidBalance(model=path)
    assert (classic.nq, classic.nv, classic.nu) == (28, 27, 21)
    assert abs(classic.equilibrium.vertical_residual) <= 1e-3
    res = mpcbox.simulate(classic, mpcbox.LQR(classic), 6.0, noise=classic.noise(), seed=1)
    assert res.survived, res.failure


def test_config_object_and_option_errors():
    cart = mpcbox.Problem(scene_path("cartpole.xml"), qpos_ref=np.array([0.0, np.pi]))
    base = mpcbox.LQR(cart)
    config = LQRConfig(R=10.0 * base.R)
    heavy = mpcbox.LQR(cart, config)
    np.testing.assert_array_equal(mpcbox.LQR(cart, R=10.0 * base.R).K, heavy.K)
    assert np.abs(heavy.K).max() < np.abs(base.K).max()
    assert mpcbox.LQR.config_class is LQRConfig
    with pytest.raises(UnknownOptionError, match="centered"):
        mpcbox.LQR(cart, weights=1.0)
    with pytest.raises(InvalidTypeError, match="problem"):
        mpcbox.LQR("cartpole.xml")


def test_a_held_period_gets_the_gain_of_the_held_step():
    """At an exact fixed point (the cart-pole upright) the held step is A^n and
    sum_i A^i B; the gain designed for a hold of 0.16 s keeps the pole up, the one-step gain
    held as long does not (its closed loop A^n - B_n K has modes outside the unit circle)."""
    cart = mpcbox.Problem(scene_path("cartpole.xml"), qpos_ref=np.array([0.0, np.pi]))
    one = mpcbox.LQR(cart)
    n = 16
    held = mpcbox.LQR(cart, period=n * cart.dt)
    assert held.period == pytest.approx(n * cart.dt)
    A_n = np.linalg.matrix_power(one.A, n)
    B_n = sum(np.linalg.matrix_power(one.A, i) for i in range(n)) @ one.B
    np.testing.assert_allclose(held.A, A_n, atol=1e-12)
    np.testing.assert_allclose(held.B, B_n, atol=1e-12)
    assert held.spectral_radius < 1.0
    assert np.abs(np.linalg.eigvals(A_n - B_n @ one.K)).max() > 1.0
    start = cart.reference_state()
    start[1] += 0.1
    one.period = held.period  # the one-step gain, held as long
    for ctrl, stays_up in ((held, True), (one, False)):
        res = mpcbox.simulate(cart, ctrl, 3.0, initial_state=start, stop_on_failure=False)
        assert bool(np.abs(res.states[-50:, 1] - np.pi).max() < 0.01) is stays_up
    with pytest.raises(mpcbox.InvalidArgumentError, match="period"):
        mpcbox.LQR(cart, period=1.5 * cart.dt)
    with pytest.raises(mpcbox.InvalidArgumentError, match="period"):
        LQRConfig(period=-0.1)


def test_wrap_regulates_to_the_nearest_whole_turn_of_unlimited_hinges():
    """``wrap=True`` takes the unlimited hinge's deviation modulo 2 pi (closed form against
    the plain LQR at the wrapped state); the cart's slide joint is left alone."""
    from mpcbox.controllers.lqr import unlimited_hinges

    cart = mpcbox.Problem(scene_path("cartpole.xml"), qpos_ref=np.array([0.0, np.pi]))
    plain, wrapped = mpcbox.LQR(cart), mpcbox.LQR(cart, wrap=True)
    np.testing.assert_array_equal(unlimited_hinges(cart.model), [1])
    np.testing.assert_array_equal(wrapped.wrapped, [1])
    np.testing.assert_array_equal(wrapped.K, plain.K)
    ref = cart.reference_state()
    small = ref + np.array([0.01, 0.02, 0.03, -0.01])
    for turns in (-2, 1, 3):
        shifted = small + np.array([0.0, 2 * np.pi * turns, 0.0, 0.0])
        np.testing.assert_allclose(wrapped(shifted, 0.0), plain(small, 0.0), atol=1e-9)
        assert abs(plain(shifted, 0.0)[0] - plain(small, 0.0)[0]) > 0.01
    # Past half a turn the nearest copy is the next one: pi + 0.01 acts as -pi + 0.01.
    over = ref + np.array([0.0, np.pi + 0.01, 0.0, 0.0])
    under = ref + np.array([0.0, -np.pi + 0.01, 0.0, 0.0])
    np.testing.assert_allclose(wrapped(over, 0.0), plain(under, 0.0), atol=1e-9)
    # The slide joint is not wrapped.
    slid = small + np.array([2 * np.pi, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(wrapped(slid, 0.0), plain(slid, 0.0), atol=1e-12)
    with pytest.raises(InvalidTypeError, match="wrap"):
        mpcbox.LQR(cart, wrap=1)
