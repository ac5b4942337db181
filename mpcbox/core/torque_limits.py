r"""Joint torque limits of a model's actuators, and the torque a motion needs (inverse dynamics).

A planned motion :math:`(q, \dot q, \ddot q)` needs the generalized force
:math:`\tau = M(q)\ddot q + c(q, \dot q) - \tau_{passive}` (MuJoCo's ``mj_inverse``,
``qfrc_inverse``). The actuators can supply at most their limits on each joint they drive
alone: the ``forcerange`` of a force-limited actuator times its gear, otherwise the
``ctrlrange`` of a motor-like actuator (constant gain, no bias) times gain and gear, and in
any case within the joint's ``actuatorfrcrange``. :func:`torque_ratio` is the largest
:math:`|\tau_j| / \tau_j^{max}` over the motion: above 1, the arm cannot follow it.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.actuation import motor_actuators
from mpcbox.validation import as_array

_SCALAR_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class TorqueLimits(NamedTuple):
    """Per-dof bounds on the actuator force (N m on a hinge, N on a slide).

    Attributes:
        lower: Lower bounds ``(nv,)`` (``-inf`` where none is known).
        upper: Upper bounds ``(nv,)`` (``+inf`` where none is known).
    """

    lower: np.ndarray
    upper: np.ndarray


def _actuator_range(model: mujoco.MjModel, i: int) -> tuple[float, float] | None:
    """The force interval of actuator ``i`` (before its gear), or ``None`` when unbounded."""
    if model.actuator_forcelimited[i]:
        lo, hi = model.actuator_forcerange[i]
        return float(lo), float(hi)
    if (
        motor_actuators(model)[i]
        and model.actuator_ctrllimited[i]
        and model.actuator_dyntype[i] == 0
    ):
        gain = float(model.actuator_gainprm[i, 0])
        ends = sorted(gain * float(c) for c in model.actuator_ctrlrange[i])
        return ends[0], ends[1]
    return None


def torque_limits(model: mujoco.MjModel) -> TorqueLimits:
    """The :class:`TorqueLimits` of the hinge and slide dofs driven through joint transmissions.

    A dof driven by several actuators adds their intervals; a dof with any unbounded
    actuator stays unbounded unless its joint has an ``actuatorfrcrange``.
    """
    lower, upper = np.zeros(model.nv), np.zeros(model.nv)
    driven = np.zeros(model.nv, dtype=bool)
    unbounded = np.zeros(model.nv, dtype=bool)
    for i in range(model.nu):
        if model.actuator_trntype[i] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        jnt = int(model.actuator_trnid[i, 0])
        if int(model.jnt_type[jnt]) not in _SCALAR_JOINTS:
            continue
        dof = int(model.jnt_dofadr[jnt])
        driven[dof] = True
        interval = _actuator_range(model, i)
        if interval is None:
            unbounded[dof] = True
            continue
        gear = float(model.actuator_gear[i, 0])
        ends = sorted((gear * interval[0], gear * interval[1]))
        lower[dof] += ends[0]
        upper[dof] += ends[1]
    lower = np.where(driven & ~unbounded, lower, -np.inf)
    upper = np.where(driven & ~unbounded, upper, np.inf)
    for jnt in range(model.njnt):
        if model.jnt_actfrclimited[jnt] and int(model.jnt_type[jnt]) in _SCALAR_JOINTS:
            dof = int(model.jnt_dofadr[jnt])
            lower[dof] = max(lower[dof], float(model.jnt_actfrcrange[jnt, 0]))
            upper[dof] = min(upper[dof], float(model.jnt_actfrcrange[jnt, 1]))
    return TorqueLimits(lower, upper)


def inverse_dynamics(
    model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray
) -> np.ndarray:
    r"""Generalized forces :math:`\tau_k` ``(T, nv)`` that realize a sampled motion.

    Args:
        model: The model.
        qpos: Positions ``(T, nq)``.
        qvel: Velocities ``(T, nv)``.
        qacc: Accelerations ``(T, nv)``.
    """
    qpos = as_array("qpos", qpos, (None, model.nq))
    qvel = as_array("qvel", qvel, (qpos.shape[0], model.nv))
    qacc = as_array("qacc", qacc, (qpos.shape[0], model.nv))
    data = mujoco.MjData(model)
    out = np.empty((qpos.shape[0], model.nv))
    for k in range(qpos.shape[0]):
        data.qpos[:], data.qvel[:], data.qacc[:] = qpos[k], qvel[k], qacc[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse
    return out


def actuator_torques(model: mujoco.MjModel, states: np.ndarray, ctrls: np.ndarray) -> np.ndarray:
    """Generalized forces ``(T, nv)`` the actuators apply (``qfrc_actuator``) at states
    ``(T, nstate)`` ``[qpos, qvel, act]`` under controls ``(T, nu)``, after MuJoCo's clamps.
    """
    states = as_array("states", states, (None, model.nq + model.nv + model.na))
    ctrls = as_array("ctrls", ctrls, (states.shape[0], model.nu))
    data = mujoco.MjData(model)
    out = np.empty((states.shape[0], model.nv))
    nq, nv = model.nq, model.nv
    for k in range(states.shape[0]):
        data.qpos[:], data.qvel[:] = states[k, :nq], states[k, nq : nq + nv]
        data.act[:], data.ctrl[:] = states[k, nq + nv :], ctrls[k]
        mujoco.mj_forward(model, data)
        out[k] = data.qfrc_actuator
    return out


def torque_ratio(torques: np.ndarray, limits: TorqueLimits) -> float:
    r"""Largest :math:`\tau_{k,j} / \tau_j^{max}` of the torques ``(T, nv)`` (the bound on
    the side of each torque's sign); 0 where no dof is bounded."""
    torques = as_array("torques", torques, (None, limits.lower.size))
    bound = np.where(torques >= 0, limits.upper, -limits.lower)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.isfinite(bound) & (bound > 0), np.abs(torques) / bound, 0.0)
    return float(np.max(ratio)) if ratio.size else 0.0


__all__ = ["TorqueLimits", "actuator_torques", "inverse_dynamics", "torque_limits", "torque_ratio"]
