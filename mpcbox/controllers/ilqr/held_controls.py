r"""Knots that hold their control for several steps of the planning model (move blocking).

With ``ILQRConfig(control_steps=s)`` each of iLQR's ``T`` knots holds its control for ``s``
steps of the planning model, so a plan covers :math:`T s h` seconds at the model's own
timestep :math:`h`. The simulation step stays exact (a stiff position servo that a coarser
timestep would mispredict is still integrated at ``h``), while the backward pass, the cost
quadratization and the feedback gains work on ``T`` knots instead of :math:`T s`.

The knot map :math:`x_{k+1} = f^{s}(x_k, u_k)` is linearized from one finite-difference
step :math:`(A_1, B_1)` at the knot (the Jacobians are taken as constant over the block):

.. math::

    A = A_1^{s}, \qquad B = \sum_{j=0}^{s-1} A_1^{j} B_1,

and the running cost of a knot counts for its ``s`` steps (:math:`s\,\ell(x_k, u_k)`). The
rollouts that the line search compares step every model step and sum the running cost
over all of them, so the accepted cost is the plan's exact cost.
"""

from __future__ import annotations

import numpy as np

from mpcbox.core.derivatives import Quadratization
from mpcbox.core.dynamics import Linearization


def compose_held(lin: Linearization, steps: int) -> Linearization:
    """Jacobians of ``steps`` model steps under one held control, from one step's.

    Args:
        lin: One step's ``A`` ``(..., nx, nx)`` and ``B`` ``(..., nx, nu)``.
        steps: Model steps per knot (``>= 1``).

    Returns:
        ``A_1^s`` and ``(I + A_1 + ... + A_1^{s-1}) B_1``, same shapes.
    """
    if steps == 1:
        return lin
    A1, B1 = np.asarray(lin.A), np.asarray(lin.B)
    total = B1
    for _ in range(steps - 1):  # Horner: B1 + A1 (B1 + A1 (B1 + ...))
        total = B1 + A1 @ total
    return Linearization(np.linalg.matrix_power(A1, steps), total)


def scale_running(quad: Quadratization, steps: int) -> Quadratization:
    """Scale the running rows of a quadratization (all but the last, the terminal cost) by
    ``steps``: each knot's running cost stands for the ``steps`` model steps it holds.

    Args:
        quad: Rows ``T + 1`` (running knots, then the terminal cost).
        steps: Model steps per knot.
    """
    if steps == 1:
        return quad
    scale = np.full(len(quad.value), float(steps))
    scale[-1] = 1.0
    return Quadratization(
        *(
            field * scale.reshape((-1,) + (1,) * (np.ndim(field) - 1))
            for field in (quad.value, quad.lx, quad.lu, quad.lxx, quad.luu, quad.lux)
        )
    )


def held_steps(ctrls: np.ndarray, steps: int) -> np.ndarray:
    """The model-step controls ``(T s, nu)`` of knot controls ``(T, nu)``."""
    return ctrls if steps == 1 else np.repeat(ctrls, steps, axis=0)


__all__ = ["compose_held", "held_steps", "scale_running"]
