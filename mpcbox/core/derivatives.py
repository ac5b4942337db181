r"""Cost evaluation on the planning model and its Gauss-Newton derivatives.

Every cost term is a weighted least-squares residual, :math:`\ell = \tfrac12 r^T W r`. With
residual Jacobians :math:`J_x = \partial r / \partial dx` (``dx`` the tangent-space state
deviation, see :mod:`mpcbox.core.dynamics`) and :math:`J_u = \partial r / \partial u`:

.. math::
    \ell_x = J_x^T W r, \quad \ell_u = J_u^T W r, \quad
    \ell_{xx} = J_x^T W J_x, \quad \ell_{uu} = J_u^T W J_u, \quad \ell_{ux} = J_u^T W J_x.

Terms with an analytic :meth:`~mpcbox.core.cost.CostTerm.jacobian` use it; the others are
differentiated by forward differences in the tangent space. The functions trust their inputs
(:class:`~mpcbox.core.problem.Problem` checks them).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.cost import Cost, CostTerm, Features, forward_stage
from mpcbox.core.dynamics import Dynamics, Rollout, mujoco_errors, write_state
from mpcbox.core.tangent import TangentSpace


class Quadratization(NamedTuple):
    """Second-order (Gauss-Newton) model of a cost about ``(x, u)``.

    Attributes:
        value: Cost value(s), shape ``(...)``.
        lx: Gradient in the state deviation, ``(..., nx)``.
        lu: Gradient in the control, ``(..., nu)``.
        lxx: Hessian block, ``(..., nx, nx)``.
        luu: Hessian block, ``(..., nu, nu)``.
        lux: Hessian block, ``(..., nu, nx)``.
    """

    value: np.ndarray
    lx: np.ndarray
    lu: np.ndarray
    lxx: np.ndarray
    luu: np.ndarray
    lux: np.ndarray


def read_features(data: mujoco.MjData) -> Features:
    """The cost features (a batch of one) held in ``data`` after ``mj_forward``."""
    return Features(
        data.qpos[None].copy(),
        data.qvel[None].copy(),
        data.ctrl[None].copy(),
        data.sensordata[None].copy(),
    )


def _forward(
    dynamics: Dynamics,
    data: mujoco.MjData,
    state: np.ndarray,
    ctrl: np.ndarray,
    stage: str = "acc",
) -> None:
    """Write ``(state, ctrl)`` into ``data`` and run as much of ``mj_forward`` as ``stage``
    (:data:`~mpcbox.core.cost.STAGES`) needs. Below ``"acc"`` the sensors of later stages
    keep stale values; the terms that asked for that stage do not read them."""
    write_state(data, state)
    data.ctrl[:] = ctrl
    model = dynamics.model
    if stage == "acc":
        mujoco.mj_forward(model, data)
    elif stage == "vel":
        mujoco.mj_fwdPosition(model, data)
        mujoco.mj_sensorPos(model, data)
        mujoco.mj_fwdVelocity(model, data)
        mujoco.mj_sensorVel(model, data)
    elif stage == "pos":
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_sensorPos(model, data)


def evaluate_features(dynamics: Dynamics, state: np.ndarray, ctrl: np.ndarray) -> Features:
    """Cost features of one state ``(nstate,)`` and control ``(nu,)`` (after ``mj_forward``)."""
    data = dynamics.scratch_data()
    with mujoco_errors("features"):
        _forward(dynamics, data, state, ctrl)
    return read_features(data)


def rollout_cost(cost: Cost, rollout: Rollout, nq: int, nv: int) -> np.ndarray:
    """Total cost of each rollout: running costs over ``T`` knots plus the terminal cost.

    Args:
        cost: The cost, bound to the model that produced ``rollout``.
        rollout: States ``(B, T + 1, nstate)``, sensor data ``(B, T + 1, nsensordata)`` and
            controls ``(B, T, nu)``.
        nq: Number of positions in a state.
        nv: Number of velocities in a state.

    Returns:
        Costs ``(B,)``; the terminal features reuse the last control.
    """
    states, sens, ctrls = rollout.states, rollout.sensordata, rollout.ctrls
    nb, horizon, nu = ctrls.shape
    flat = Features(
        states[:, :horizon, :nq].reshape(-1, nq),
        states[:, :horizon, nq : nq + nv].reshape(-1, nv),
        ctrls.reshape(-1, nu),
        sens[:, :horizon].reshape(nb * horizon, -1),
    )
    running = cost.running_value(flat).reshape(nb, horizon).sum(axis=1)
    last = Features(
        states[:, horizon, :nq],
        states[:, horizon, nq : nq + nv],
        ctrls[:, -1],
        sens[:, horizon],
    )
    return running + cost.terminal_value(last)


def quadratize_knots(
    dynamics: Dynamics,
    tangent: TangentSpace,
    terms: Sequence[CostTerm],
    states: np.ndarray,
    ctrls: np.ndarray,
    eps: float,
    hessians: bool = True,
) -> Quadratization:
    """Gauss-Newton quadratization of ``terms`` at ``B`` knots, one term type at a time.

    Terms whose Jacobian does not depend on the state (``constant_jacobian``) contribute the
    same Hessian blocks at every knot, computed once; the others are evaluated per knot.

    Args:
        dynamics: The planning model and its scratch data.
        tangent: The tangent space of the model's positions (for finite differences).
        terms: Running or terminal cost terms, bound to ``dynamics.model``.
        states: States ``(B, nstate)``.
        ctrls: Controls ``(B, nu)``.
        eps: Finite-difference step for terms without an analytic Jacobian.
        hessians: Accumulate the Hessian blocks; ``False`` leaves them zero, for a caller
            that brings its own (iLQR's ``cost_hessian="reference"``).

    Returns:
        A :class:`Quadratization` with leading size ``B``.
    """
    nx, nu, nq, nv = dynamics.nx, dynamics.nu, dynamics.nq, dynamics.nv
    nb = len(states)
    value = np.zeros(nb)
    lx, lu = np.zeros((nb, nx)), np.zeros((nb, nu))
    lxx, luu, lux = np.zeros((nb, nx, nx)), np.zeros((nb, nu, nu)), np.zeros((nb, nu, nx))
    if not terms:
        return Quadratization(value, lx, lu, lxx, luu, lux)
    data = dynamics.scratch_data()
    stage = forward_stage(terms)
    varying = [t for t in terms if not t.constant_jacobian]
    sens = np.empty((nb, dynamics.model.nsensordata))
    jacs: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {id(t): [] for t in varying}
    with mujoco_errors("quadratize"):
        for b in range(nb):
            _forward(dynamics, data, states[b], ctrls[b], stage)
            sens[b] = data.sensordata
            for term in varying:
                jacs[id(term)].append(
                    residual_jacobian(dynamics, tangent, term, states[b], ctrls[b], eps, stage)
                )
        constant = {
            id(t): residual_jacobian(dynamics, tangent, t, states[-1], ctrls[-1], eps, stage)
            for t in terms
            if t.constant_jacobian
        }
    feats = Features(states[:, :nq], states[:, nq : nq + nv], ctrls, sens)
    for term in terms:
        r = term.residual(feats)
        w = term.weight
        wr = w * r
        value += 0.5 * np.sum(wr * r, axis=1)
        if term.constant_jacobian:
            jx, ju = constant[id(term)]
            lx += wr @ jx
            lu += wr @ ju
            if hessians:
                wjx = jx * w[:, None]
                lxx += jx.T @ wjx
                luu += ju.T @ (ju * w[:, None])
                lux += ju.T @ wjx
        else:
            jx = np.stack([j[0] for j in jacs[id(term)]])  # (B, k, nx)
            ju = np.stack([j[1] for j in jacs[id(term)]])  # (B, k, nu)
            # Batched matrix products (several times faster than the equivalent einsums).
            lx += np.matmul(wr[:, None, :], jx)[:, 0]
            lu += np.matmul(wr[:, None, :], ju)[:, 0]
            if hessians:
                wjx = jx * w[None, :, None]
                jut = ju.transpose(0, 2, 1)
                lxx += np.matmul(jx.transpose(0, 2, 1), wjx)
                luu += np.matmul(jut, ju * w[None, :, None])
                lux += np.matmul(jut, wjx)
    if hessians:
        lxx = 0.5 * (lxx + lxx.transpose(0, 2, 1))
        luu = 0.5 * (luu + luu.transpose(0, 2, 1))
    return Quadratization(value, lx, lu, lxx, luu, lux)


def quadratize_trajectory(
    dynamics: Dynamics,
    tangent: TangentSpace,
    cost: Cost,
    states: np.ndarray,
    ctrls: np.ndarray,
    eps: float,
    threads: int | None = None,
    hessians: bool = True,
) -> Quadratization:
    """Running cost at ``T`` knots and terminal cost at the last state, in parallel chunks.

    Args:
        dynamics: The planning model, its scratch data and thread pool.
        tangent: The tangent space of the model's positions.
        cost: The cost, bound to ``dynamics.model``.
        states: ``(T + 1, nstate)``.
        ctrls: ``(T, nu)``.
        eps: Finite-difference step.
        threads: Worker threads (default: the pool's).
        hessians: Accumulate the Hessian blocks (``False``: left zero; see
            :func:`quadratize_knots`).

    Returns:
        Stacked arrays with leading size ``T + 1`` (the last row is the terminal cost; its
        control blocks are zero).
    """
    horizon = len(ctrls)
    threads = dynamics.threads if threads is None else threads
    # Chunks of knots: the C calls drop the GIL, the vectorized numpy work is per chunk.
    bounds = np.linspace(0, horizon, min(threads, horizon) + 1).astype(int)
    parts = dynamics.map(
        lambda j: quadratize_knots(
            dynamics,
            tangent,
            cost.running,
            states[bounds[j] : bounds[j + 1]],
            ctrls[bounds[j] : bounds[j + 1]],
            eps,
            hessians,
        ),
        len(bounds) - 1,
        threads,
    )
    last = quadratize_knots(
        dynamics, tangent, cost.terminal, states[-1:], ctrls[-1:], eps, hessians
    )
    return Quadratization(
        *(np.concatenate([getattr(q, f) for q in [*parts, last]]) for f in Quadratization._fields)
    )


def residual_jacobian(
    dynamics: Dynamics,
    tangent: TangentSpace,
    term: CostTerm,
    state: np.ndarray,
    ctrl: np.ndarray,
    eps: float,
    stage: str = "acc",
) -> tuple[np.ndarray, np.ndarray]:
    """``dr/dx`` ``(k, nx)`` and ``dr/du`` ``(k, nu)`` of one term at ``(state, ctrl)``.

    The scratch data of the calling thread must hold ``(state, ctrl)`` after ``mj_forward``
    up to ``stage`` (at least the term's :attr:`~mpcbox.core.cost.CostTerm.stage`); it still
    does on return.
    """
    data = dynamics.scratch_data()
    jac = term.jacobian(dynamics.model, data)
    if jac is None:
        r0 = term.residual(read_features(data))[0]
        jx, ju = residual_fd(dynamics, tangent, term, state, ctrl, r0, eps, stage)
        _forward(dynamics, data, state, ctrl, stage)
        return jx, ju
    nv = dynamics.nv
    jx = np.zeros((jac.dq.shape[0], dynamics.nx))
    jx[:, :nv] = jac.dq
    jx[:, nv : 2 * nv] = jac.dv
    return jx, jac.du


def residual_fd(
    dynamics: Dynamics,
    tangent: TangentSpace,
    term: CostTerm,
    state: np.ndarray,
    ctrl: np.ndarray,
    r0: np.ndarray,
    eps: float,
    stage: str = "acc",
) -> tuple[np.ndarray, np.ndarray]:
    """Forward differences ``(dr/dx (k, nx), dr/du (k, nu))`` of one term's residual.

    State perturbations move along the tangent space (:meth:`TangentSpace.state_add`).

    Args:
        dynamics: The planning model and its scratch data (left at the last perturbation).
        tangent: The tangent space of the model's positions.
        term: A cost term bound to ``dynamics.model``.
        state: State ``(nstate,)``.
        ctrl: Control ``(nu,)``.
        r0: The residual ``(k,)`` at ``(state, ctrl)``.
        eps: Finite-difference step.
        stage: How much of ``mj_forward`` to run at each perturbation (at least the term's
            :attr:`~mpcbox.core.cost.CostTerm.stage`).
    """
    data = dynamics.scratch_data()
    nx, nu = dynamics.nx, dynamics.nu
    jx = np.zeros((len(r0), nx))
    ju = np.zeros((len(r0), nu))

    def residual_at(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        _forward(dynamics, data, x, u, stage)
        return term.residual(read_features(data))[0]

    for i in range(nx):
        dx = np.zeros(nx)
        dx[i] = eps
        x = tangent.state_add(dynamics.model, state, dx)
        jx[:, i] = (residual_at(x, ctrl) - r0) / eps
    for i in range(nu):
        du = np.zeros(nu)
        du[i] = eps
        ju[:, i] = (residual_at(state, ctrl + du) - r0) / eps
    return jx, ju
