"""The saddle probe of iLQR: does a small change of the controls lower the cost where the
Gauss-Newton model predicts no decrease?"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Random directions (each tried with both signs) of the saddle probe at a stationary point.
PROBES = 4


def descent_probe(
    cost_of: Callable[[np.ndarray], float],
    ctrls: np.ndarray,
    ctrl_low: np.ndarray,
    ctrl_high: np.ndarray,
    cost: float,
) -> bool:
    r"""Whether a small change of the controls ``(T, nu)`` lowers ``cost``, their cost, at a
    stationary point; ``cost_of`` rolls controls out from the same start and returns theirs.

    The Gauss-Newton model is convex, so it sees no decrease at a saddle or maximum of the
    true cost, e.g. at the hanging rest of a swing-up whose cost is periodic in the angle.
    Tries smooth directions :math:`\pm\delta` (a constant per control, and
    :data:`PROBES` random ones interpolated between four knots), scaled to ``1e-3`` of each
    control's bound range (of 1 when unbounded) and kept within the bounds.
    """
    horizon, nu = ctrls.shape
    span = ctrl_high - ctrl_low
    span = np.where(np.isfinite(span), span, 1.0)
    rng = np.random.default_rng(0)
    knots = np.linspace(0.0, 1.0, 4)
    grid = np.linspace(0.0, 1.0, horizon)
    directions = [np.tile(np.eye(nu)[j], (horizon, 1)) for j in range(nu)]
    for _ in range(PROBES):
        values = rng.standard_normal((knots.size, nu))
        directions.append(np.stack([np.interp(grid, knots, v) for v in values.T], axis=1))
    threshold = cost - 1e-10 * max(1.0, abs(cost))
    for direction in directions:
        for sign in (1.0, -1.0):
            trial = np.clip(ctrls + sign * 1e-3 * span * direction, ctrl_low, ctrl_high)
            if cost_of(trial) < threshold:
                return True
    return False


__all__ = ["PROBES", "descent_probe"]
