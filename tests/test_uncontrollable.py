"""Uncontrollable modes on the unit circle: found without the PBH test's blind spot, and taken
out of the LQR's cost (closed forms)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import mpcbox
from mpcbox.controllers.lqr import check_stabilizable, dlqr
from mpcbox.controllers.uncontrollable import (
    uncontrollable_marginal_projector,
    uncontrollable_modes,
)

# z-coordinates: z1 on the unit circle and unreachable, z2 unstable and actuated; x = T z.
T = np.array([[1.0, 0.5], [0.3, 1.0]])
A_Z = np.diag([1.0, 1.2])
B_Z = np.array([[0.0], [1.0]])


def system() -> tuple[np.ndarray, np.ndarray]:
    return T @ A_Z @ np.linalg.inv(T), T @ B_Z


def test_projector_is_the_unreachable_mode_along_the_reachable_one():
    A, B = system()
    proj = uncontrollable_marginal_projector(A, B)
    assert proj is not None
    np.testing.assert_allclose(proj @ proj, proj, atol=1e-12)  # a projector
    np.testing.assert_allclose(proj @ B, 0.0, atol=1e-12)  # along a complement holding B
    np.testing.assert_allclose(proj @ A, A @ proj, atol=1e-12)  # onto an invariant subspace
    np.testing.assert_allclose(proj @ T[:, 0], T[:, 0], atol=1e-12)  # onto z1's direction


def test_a_weighted_unreachable_mode_leaves_the_scalar_riccati_solution():
    """With Q = I on both modes the full Riccati equation has no solution (z1's cost never
    decays); without z1 it is the scalar one of z2: a = 1.2, b = 1, q = |T e2|^2, r."""
    A, B = system()
    r = 0.5
    K, P = dlqr(A, B, np.eye(2), np.array([[r]]))
    w = np.linalg.inv(T)[1]  # z2 = w . x
    q = float(T[:, 1] @ T[:, 1])
    p = scipy.linalg.solve_discrete_are(np.array([[1.2]]), np.array([[1.0]]), [[q]], [[r]])[0, 0]
    k = 1.2 * p / (r + p)
    np.testing.assert_allclose(K, k * w[None, :], rtol=1e-9)
    # SciPy's Riccati solvers differ in the last digits (1.3e-9 apart with scipy 1.17).
    np.testing.assert_allclose(P, p * np.outer(w, w), rtol=1e-8, atol=1e-12)
    # The unreachable mode stays on the unit circle; the reachable one is stabilized.
    closed = np.sort(np.abs(np.linalg.eigvals(A - B @ K)))
    np.testing.assert_allclose(closed, [abs(1.2 - k), 1.0], atol=1e-9)


def test_clustered_controllable_eigenvalues_are_not_taken_for_uncontrollable():
    """Three slightly unstable modes 2e-6 apart, each driven by its own input, beside a fast
    mode coupled by 500 (so |A| ~ 870): the smallest singular value of [A - lambda I, B] is
    only the eigenvalues' spacing, below the PBH test's tolerance 1e-8 |A|, yet each mode's
    left eigenvector meets the inputs head on."""
    A = np.diag([1 + 1e-5, 1 + 1.2e-5, 1 + 1.4e-5, 0.5])
    A[:3, 3] = 500.0
    B = np.vstack([0.01 * np.eye(3), np.zeros((1, 3))])
    lam = A[0, 0]
    pbh = np.linalg.svd(np.hstack([A - lam * np.eye(4), B]), compute_uv=False)[-1]
    assert pbh <= 1e-8 * np.linalg.norm(A, 2)  # what the rank test alone saw
    assert uncontrollable_modes(A, B) == []
    assert check_stabilizable(A, B) == 0
    K, _ = dlqr(A, B, np.eye(4), np.eye(3))
    assert np.max(np.abs(np.linalg.eigvals(A - B @ K))) < 1.0


def test_a_double_integrator_is_defective_and_controllable():
    """A motor on a free joint: eigenvalue 1 twice with one eigenvector. No projector; the
    gain is python-control's."""
    control = pytest.importorskip("control")
    dt = 0.01
    A = np.array([[1.0, dt], [0.0, 1.0]])
    B = np.array([[0.5 * dt * dt], [dt]])
    assert uncontrollable_marginal_projector(A, B) is None
    K, _ = dlqr(A, B, np.eye(2), np.eye(1))
    K_ref, _, _ = control.dlqr(A, B, np.eye(2), np.eye(1))
    np.testing.assert_allclose(K, K_ref, rtol=1e-9)


def test_an_unreachable_unstable_mode_still_raises():
    A = np.diag([1.5, 0.5, 1.0])
    B = np.array([[0.0], [1.0], [0.0]])
    with pytest.raises(mpcbox.NotStabilizableError, match=r"1\.5"):
        dlqr(A, B, np.eye(3), np.eye(1))


def _double_integrator(dt: float = 0.01) -> np.ndarray:
    return np.array([[1.0, dt], [0.0, 1.0]])


def test_an_unreachable_double_integrator_is_left_out_beside_a_driven_oscillator():
    """A free spin no motor drives (angle and rate: a Jordan block at 1) beside a driven,
    damped oscillator: the block's spectral projector takes it out of the cost, and the gain
    is the oscillator's alone (python-control on the 2x2 subsystem)."""
    control = pytest.importorskip("control")
    dt = 0.01
    osc = np.array([[1.0, dt], [-0.04, 0.99]])
    A = scipy.linalg.block_diag(osc, _double_integrator(dt))
    B = np.array([[0.0], [dt], [0.0], [0.0]])
    proj = uncontrollable_marginal_projector(A, B)
    np.testing.assert_allclose(proj, np.diag([0.0, 0.0, 1.0, 1.0]), atol=1e-9)
    K, P = dlqr(A, B, np.eye(4), np.eye(1))
    K_ref, P_ref, _ = control.dlqr(osc, B[:2], np.eye(2), np.eye(1))
    np.testing.assert_allclose(K[:, :2], K_ref, rtol=1e-8)
    np.testing.assert_allclose(K[:, 2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(P[:2, :2], P_ref, rtol=1e-8)


def test_a_partly_reached_double_integrator_is_not_stabilizable():
    """Two double integrators with one input: eigenvalue 1 four times, one block driven and
    one not. No projector separates them, and the undriven one drifts: a named error."""
    dt = 0.01
    A = scipy.linalg.block_diag(_double_integrator(dt), _double_integrator(dt))
    B = np.array([[0.0], [0.0], [0.0], [dt]])
    with pytest.raises(mpcbox.NotStabilizableError, match="Jordan block"):
        dlqr(A, B, np.eye(4), np.eye(1))


def test_no_input_at_all_gives_a_zero_gain_on_a_neutral_system():
    K, P = dlqr(np.eye(2), np.zeros((2, 1)), np.eye(2), np.eye(1))
    np.testing.assert_array_equal(K, 0.0)
    np.testing.assert_array_equal(P, 0.0)


def test_a_ball_joint_pendulum_with_one_driven_axis_is_regulated():
    """A hanging ball-joint pendulum whose motor drives one axis: the spin about the vertical
    is a free, undamped double integrator no input reaches (a Jordan block), the swing about
    the other horizontal axis an undamped oscillator no input reaches. LQR leaves both out
    (four closed-loop eigenvalues stay on the unit circle), and a tilt about the driven axis
    decays."""
    xml = """<mujoco><worldbody><body name="b" pos="0 0 1"><joint name="j" type="ball"/>
      <geom type="capsule" fromto="0 0 0 0 0 -1" size=".05" mass="1"/></body></worldbody>
      <actuator><motor joint="j" gear="1 0 0" ctrlrange="-5 5"/></actuator></mujoco>"""
    problem = mpcbox.Problem(xml)
    lqr = mpcbox.LQR(problem)
    driven = np.abs(lqr.closed_loop_eigenvalues)
    assert np.sum(driven > 1.0 - 1e-9) == 4  # the spin's block and the free swing
    assert np.sum(driven < 0.999) == 2  # the driven swing is damped
    state = problem.reference_state()
    state[:4] = [np.cos(0.1), np.sin(0.1), 0.0, 0.0]  # tilted 0.2 rad about the driven axis
    run = mpcbox.simulate(problem, lqr, 3.0, initial_state=state)
    tilt = [2 * np.arcsin(min(1.0, abs(s[1]))) for s in run.states]
    assert tilt[-1] < 0.2 * tilt[0]
