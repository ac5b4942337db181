r"""Box-constrained quadratic programs by projected Newton steps.

Solves

.. math:: \min_{x}\ \tfrac12 x^T H x + g^T x \quad \text{s.t.}\quad l \le x \le u

for a symmetric positive-definite ``H`` of size ``n`` (``n`` small: the number of actuators).
This is the inner solver of control-limited DDP (Tassa, Mansard and Todorov, ICRA 2014): each
iteration splits the variables into *clamped* ones (at a bound, with the gradient pushing
outwards) and *free* ones, takes a Newton step on the free ones with the Cholesky factor of
``H_ff`` and a projected Armijo line search. The factor of the final free block is returned
so that the caller can build feedback gains on the free controls only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, positive, positive_int

#: Status codes of :class:`BoxQPResult`.
STATUS = {
    -1: "Hessian not positive definite",
    0: "no descent direction",
    1: "maximum iterations",
    2: "line search failed",
    3: "all variables clamped",
    4: "converged (small gradient)",
    5: "converged (small improvement)",
}


class BoxQPResult(NamedTuple):
    """Solution of a box QP.

    Attributes:
        x: Minimizer ``(n,)``, inside the bounds.
        free: Boolean mask ``(n,)`` of variables not clamped at a bound.
        factor: Cholesky factor of ``H[free][:, free]`` as ``(L, True)``, ready for
            ``scipy.linalg.cho_solve`` (``None`` when no variable is free or ``H`` is not
            positive definite).
        status: Key of :data:`STATUS`; negative means failure.
        iterations: Newton iterations taken.
    """

    x: np.ndarray
    free: np.ndarray
    factor: tuple[np.ndarray, bool] | None
    status: int
    iterations: int

    @property
    def ok(self) -> bool:
        """Whether ``x`` is a usable solution (every status except a non-definite Hessian)."""
        return self.status >= 0


def _cholesky(H: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """Lower Cholesky factor in ``scipy.linalg.cho_solve`` format, or ``None``."""
    try:
        L = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    return (L, True) if np.all(np.isfinite(L)) else None


def solve_box_qp(
    H: np.ndarray,
    g: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    x0: np.ndarray | None = None,
    *,
    max_iterations: int = 100,
    min_gradient: float = 1e-8,
    min_relative_improvement: float = 1e-8,
    step_decrease: float = 0.6,
    min_step: float = 1e-22,
    armijo: float = 0.1,
    check: bool = True,
) -> BoxQPResult:
    r"""Minimize :math:`\tfrac12 x^T H x + g^T x` subject to ``lower <= x <= upper``.

    Args:
        H: Symmetric positive-definite Hessian ``(n, n)``.
        g: Linear term ``(n,)``.
        lower: Lower bounds ``(n,)``; ``-inf`` for none.
        upper: Upper bounds ``(n,)``; ``+inf`` for none. Must satisfy ``lower <= upper``.
        x0: Warm start ``(n,)`` (clipped into the box); zeros by default.
        max_iterations: Newton iterations at most.
        min_gradient: Stop when the norm of the free gradient falls below this.
        min_relative_improvement: Stop when an accepted step improves the objective by less
            than this fraction.
        step_decrease: Backtracking factor of the projected line search, in (0, 1).
        min_step: Smallest step before the line search gives up.
        armijo: Sufficient-decrease constant of the line search, in (0, 1).
        check: Validate shapes and values (the iLQR inner loop turns this off).

    Returns:
        A :class:`BoxQPResult`.

    Raises:
        ShapeError: If an array has the wrong shape.
        InvalidArgumentError: If a bound pair is inverted or a value is not finite.
    """
    if check:
        g = as_array("g", g, (None,))
        n = g.shape[0]
        H = as_array("H", H, (n, n))
        lower = as_array("lower", lower, (n,))
        upper = as_array("upper", upper, (n,))
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(g))):
            raise InvalidArgumentError("H and g must be finite")
        if np.any(np.isnan(lower)) or np.any(np.isnan(upper)) or np.any(lower > upper):
            raise InvalidArgumentError(
                f"lower must be <= upper elementwise, got lower={lower}, upper={upper}"
            )
        max_iterations = positive_int("max_iterations", max_iterations)
        if not 0.0 < step_decrease < 1.0:
            raise InvalidArgumentError(f"step_decrease must be in (0, 1), got {step_decrease}")
        if not 0.0 < armijo < 1.0:
            raise InvalidArgumentError(f"armijo must be in (0, 1), got {armijo}")
        positive("min_step", min_step)
        if x0 is not None:
            x0 = as_array("x0", x0, (n,))
    n = g.shape[0]
    x = np.zeros(n) if x0 is None else np.asarray(x0, dtype=np.float64)
    x = np.clip(np.where(np.isfinite(x), x, 0.0), lower, upper)
    free = np.ones(n, dtype=bool)
    factor = None
    if n == 0:
        return BoxQPResult(x, free, None, 4, 0)

    # Fast path: the unconstrained minimizer is often inside the box.
    full = _cholesky(H)
    if full is None:
        return BoxQPResult(x, free, None, -1, 0)
    x_unc = -np.linalg.solve(H, g)
    if np.all(x_unc >= lower) and np.all(x_unc <= upper):
        return BoxQPResult(x_unc, free, full, 4, 0)

    value = x @ g + 0.5 * x @ H @ x
    old_free = None
    status = 1
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        grad = g + H @ x
        clamped = ((x <= lower) & (grad > 0)) | ((x >= upper) & (grad < 0))
        free = ~clamped
        if clamped.all():
            status = 3
            factor = None
            break
        if old_free is None or np.any(free != old_free):
            h_free = H[np.ix_(free, free)]
            factor = _cholesky(h_free)
            if factor is None:
                return BoxQPResult(x, free, None, -1, iteration)
            old_free = free
        grad_free = grad[free]
        if np.linalg.norm(grad_free) < min_gradient:
            status = 4
            break
        # Newton step on the free block with the clamped variables held fixed.
        search = np.zeros(n)
        # (np.linalg.solve: SciPy's cho_solve is slow for tiny systems on busy machines.)
        search[free] = -np.linalg.solve(h_free, grad_free)
        slope = float(search @ grad)
        if slope >= 0.0:
            status = 0
            break
        step = 1.0
        while True:
            # Armijo rule along the projection arc (Bertsekas 1982): compare with the
            # gradient times the projected step, not the unprojected direction.
            trial = np.clip(x + step * search, lower, upper)
            trial_value = trial @ g + 0.5 * trial @ H @ trial
            if (value - trial_value) >= armijo * float(grad @ (x - trial)) and (
                trial_value < value or step * np.abs(search).max() < min_step
            ):
                break
            step *= step_decrease
            if step < min_step:
                return BoxQPResult(x, free, factor, 2, iteration)
        improvement = value - trial_value
        x, value = trial, trial_value
        if improvement < min_relative_improvement * max(abs(value), 1e-12):
            status = 5
            break
    # The factor must describe the final free set (it may have changed on the last step).
    grad = g + H @ x
    final_free = ~(((x <= lower) & (grad > 0)) | ((x >= upper) & (grad < 0)))
    if final_free.any() and (old_free is None or np.any(final_free != old_free)):
        factor = _cholesky(H[np.ix_(final_free, final_free)])
        if factor is None:
            return BoxQPResult(x, final_free, None, -1, iteration)
    elif not final_free.any():
        factor = None
    return BoxQPResult(x, final_free, factor, status, iteration)


__all__ = ["STATUS", "BoxQPResult", "solve_box_qp"]
