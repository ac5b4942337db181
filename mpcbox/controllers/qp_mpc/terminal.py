r"""Terminal cost matrices of the QP-MPC (``QPMPCConfig.terminal``).

* ``"lqr"`` (default): the Riccati matrix of the soft-contact model at the QP step ``dt``
  (``substeps`` steps of its own timestep composed), with the running cost;
* ``"stance"``: the Riccati matrix of the prediction model with the forces as extra inputs
  (weight :math:`w_f`) and the rigid stance constraint as the penalty
  :math:`w_s \|J_s v\|^2`; without friction limits this is the infinite-horizon cost of the
  linear model the QP uses;
* ``"cost"``: the running ``Q``;
* an ``(nx, nx)`` matrix, symmetrized.

A Riccati equation without a solution falls back to ``Q``. The result is projected to the
nearest positive semidefinite matrix and scaled by ``terminal_scale``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.controllers.lqr import dlqr, nearest_psd
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.controllers.qp_mpc.dynamics import ContactDynamics, Linearization, compose
from mpcbox.controllers.qp_mpc.formulation import QuadraticCost
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, SolverError
from mpcbox.validation import as_array


def terminal_matrix(
    problem: Problem,
    config: QPMPCConfig,
    dynamics: ContactDynamics,
    lin: Linearization,
    cost: QuadraticCost,
    state_ref: np.ndarray,
    ctrl_ref: np.ndarray,
) -> np.ndarray:
    """The terminal matrix ``(nx, nx)`` chosen by ``config.terminal``, PSD and scaled.

    Args:
        problem: The Problem.
        config: The controller's options (``terminal``, ``terminal_scale``, weights).
        dynamics: The prediction's models (the soft-contact one and its substeps).
        lin: The linearization at the reference.
        cost: The running cost.
        state_ref: Reference state.
        ctrl_ref: Reference control ``(nu,)``.

    Raises:
        ShapeError: If ``config.terminal`` is a matrix of the wrong shape.
    """
    terminal = config.terminal
    if isinstance(terminal, str):
        if terminal == "cost":
            P = cost.Q.copy()
        elif terminal == "stance":
            P = stance_riccati(problem, config, lin, cost)
        else:
            P = soft_lqr_riccati(problem, dynamics, cost, state_ref, ctrl_ref)
    else:
        P = as_array("terminal", terminal, (problem.nx, problem.nx))
        P = 0.5 * (P + P.T)
    return nearest_psd(P) * config.terminal_scale


def soft_lqr_riccati(
    problem: Problem,
    dynamics: ContactDynamics,
    cost: QuadraticCost,
    state_ref: np.ndarray,
    ctrl_ref: np.ndarray,
) -> np.ndarray:
    """Riccati matrix of the soft-contact model about the reference, one QP step composed
    of substeps (centered differences)."""
    nx, nu = problem.nx, problem.nu
    soft = dynamics.soft_model
    data = mujoco.MjData(soft)
    problem.set_state(data, state_ref)
    data.ctrl[:] = ctrl_ref
    Ah = np.zeros((nx, nx))
    Bh = np.zeros((nx, nu))
    mujoco.mjd_transitionFD(soft, data, problem.fd_eps, True, Ah, Bh, None, None)
    A, S = compose(Ah, dynamics.substeps)
    B = S @ Bh
    N = cost.N_ux.T if np.any(cost.N_ux) else None
    try:
        _, P = dlqr(A, B, cost.Q, cost.R, N)
    except (SolverError, InvalidArgumentError):
        return cost.Q.copy()
    return 0.5 * (P + P.T)


def stance_riccati(
    problem: Problem, config: QPMPCConfig, lin: Linearization, cost: QuadraticCost
) -> np.ndarray:
    r"""Riccati matrix of the prediction model ``lin`` with the forces as extra inputs and
    the penalty :math:`w_s \|J_s v\|^2` (``w_s = stance_weight``, 1e4 when ``None``)."""
    nv, nx, nu = problem.nv, problem.nx, problem.nu
    Sv = np.zeros((lin.Js.shape[0], nx))
    Sv[:, nv : 2 * nv] = lin.Js
    ws = 1e4 if config.stance_weight is None else config.stance_weight
    Q = cost.Q + ws * Sv.T @ Sv
    Bc = np.zeros((nx, lin.Bc.shape[1]))
    Bc[: 2 * nv] = lin.Bc
    B = np.hstack([lin.B, Bc])
    nf = lin.Bc.shape[1]
    R = np.zeros((nu + nf, nu + nf))
    R[:nu, :nu] = cost.R
    R[nu:, nu:] = config.force_weight * np.eye(nf)
    N = np.zeros((nx, nu + nf))
    N[:, :nu] = cost.N_ux.T
    try:
        _, P = dlqr(lin.A, B, Q, R, N)
    except (SolverError, InvalidArgumentError):
        return cost.Q.copy()
    return 0.5 * (P + P.T)
