"""Time-varying LQR gains started from a terminal value matrix (``riccati_gains``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from mpcbox.controllers.trajectory.reference import riccati_gains
from mpcbox.errors import MpcboxError


def _system(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = np.eye(4) + 0.05 * rng.standard_normal((4, 4))
    B = 0.1 * rng.standard_normal((4, 1))
    Q = np.diag(rng.uniform(1.0, 10.0, 4))
    R = np.array([[rng.uniform(0.1, 1.0)]])
    return A, B, Q, R


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_terminal_lqr_value_makes_every_gain_the_lqr_gain(seed: int) -> None:
    A, B, Q, R = _system(seed)
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    steps = 30
    gains = riccati_gains(np.tile(A, (steps, 1, 1)), np.tile(B, (steps, 1, 1)), Q, R, P)
    np.testing.assert_allclose(gains, np.tile(K, (steps, 1, 1)), rtol=1e-8, atol=1e-10)
    # The default terminal weight Q is not the fixed point: the last gain differs from LQR's.
    default = riccati_gains(np.tile(A, (steps, 1, 1)), np.tile(B, (steps, 1, 1)), Q, R)
    assert np.max(np.abs(default[-1] - K)) > 1e-3 * np.max(np.abs(K))


def test_terminal_of_the_wrong_shape_is_rejected() -> None:
    A, B, Q, R = _system(0)
    with pytest.raises(MpcboxError, match="terminal"):
        riccati_gains(A[None], B[None], Q, R, np.eye(3))
