r"""Finite-difference Jacobians of one ``mj_step`` for any integrator, RK4 included.

MuJoCo's ``mjd_transitionFD`` refuses RK4. :func:`step_jacobians` differentiates the step
itself: each tangent direction of the state ``dx = [dq (nv), dv (nv), da (na)]`` and each
control is perturbed by ``eps`` (positions through ``mj_integratePos``, so quaternions stay
on their manifold), one ``mj_step`` is taken, and the next state's tangent deviation
(``mj_differentiatePos`` for positions) is divided by the step:

.. math::

    A_{:, i} = \frac{x_{t+1}(x \oplus \epsilon e_i) \ominus x_{t+1}(x \ominus \epsilon e_i)}
    {2 \epsilon}, \qquad
    B_{:, j} = \frac{x_{t+1}(u + \epsilon e_j) \ominus x_{t+1}(u - \epsilon e_j)}{2 \epsilon}

(forward differences use the unperturbed step in place of the minus side). It costs
``2 (2 nv + na + nu)`` steps centred, half that plus one forward. The warm start of the
constraint solver is restored before every step, so each perturbed step starts alike.
"""

from __future__ import annotations

import mujoco
import numpy as np


def step_jacobians(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    eps: float,
    centered: bool,
    A: np.ndarray,
    B: np.ndarray,
) -> None:
    """Fill ``A`` ``(nx, nx)`` and ``B`` ``(nx, nu)`` with one step's Jacobians, in place.

    Args:
        model: The model (any integrator).
        data: Holds the state and ``ctrl`` to linearize about; restored on return.
        eps: Finite-difference step.
        centered: Centred (True) or forward (False) differences.
        A: Output ``(2 nv + na, 2 nv + na)``.
        B: Output ``(2 nv + na, nu)``.
    """
    nv, na, nu = model.nv, model.na, model.nu
    qpos, qvel, act = data.qpos.copy(), data.qvel.copy(), data.act.copy()
    ctrl, warm, time = data.ctrl.copy(), data.qacc_warmstart.copy(), data.time
    nx = 2 * nv + na

    def next_state(dx: np.ndarray, du: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        data.qpos[:] = qpos
        mujoco.mj_integratePos(model, data.qpos, dx[:nv], 1.0)
        data.qvel[:] = qvel + dx[nv : 2 * nv]
        data.act[:] = act + dx[2 * nv :]
        data.ctrl[:] = ctrl + du
        data.qacc_warmstart[:] = warm
        data.time = time
        mujoco.mj_step(model, data)
        return data.qpos.copy(), np.concatenate([data.qvel, data.act])

    def difference(plus: tuple, minus: tuple, width: float) -> np.ndarray:
        out = np.empty(nx)
        mujoco.mj_differentiatePos(model, out[:nv], 1.0, minus[0], plus[0])
        out[nv:] = plus[1] - minus[1]
        return out / width

    zero_x, zero_u = np.zeros(nx), np.zeros(nu)
    base = None if centered else next_state(zero_x, zero_u)
    width = 2 * eps if centered else eps
    for i in range(nx + nu):
        dx, du = np.zeros(nx), np.zeros(nu)
        (dx if i < nx else du)[i if i < nx else i - nx] = eps
        plus = next_state(dx, du)
        minus = next_state(-dx, -du) if centered else base
        column = difference(plus, minus, width)
        if i < nx:
            A[:, i] = column
        else:
            B[:, i - nx] = column
    data.qpos[:], data.qvel[:], data.act[:] = qpos, qvel, act
    data.ctrl[:], data.qacc_warmstart[:], data.time = ctrl, warm, time
