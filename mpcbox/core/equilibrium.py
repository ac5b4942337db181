"""Controls that hold a posture, from inverse dynamics through the actuator model."""

from __future__ import annotations

import warnings
from typing import NamedTuple

import mujoco
import numpy as np
from scipy.optimize import brentq

from mpcbox.core.actuation import (
    ActuationMap,
    actuation_map,
    actuator_moment,
    actuator_name,
    actuator_state,
    control_owner,
    solve_actuation,
)
from mpcbox.core.equality_span import equality_span
from mpcbox.core.model import check_mjmodel
from mpcbox.errors import EquilibriumWarning, InfeasibleEquilibriumError, SolverError
from mpcbox.validation import checked_keywords, finite_array, one_of, positive

__all__ = ["Equilibrium", "actuator_moment", "find_equilibrium"]

#: What :func:`find_equilibrium` does when the actuators cannot hold the posture.
ON_INFEASIBLE = ("warn", "raise", "ignore")


class Equilibrium(NamedTuple):
    """A posture and the control that holds it.

    Attributes:
        qpos: Posture ``(nq,)`` with the root height adjusted so the contacts carry the weight.
        ctrl: Control ``(nu,)`` that holds it, through each actuator's gain, bias,
            transmission and activation dynamics, within the control and force limits.
        qfrc: Generalized force ``(nv,)`` needed to hold the posture (``qfrc_inverse``).
        residual_wrench: What the actuators cannot supply on the unactuated root dofs, ``(6,)``
            for a free root (zeros for a fixed base): ``residual`` there.
        height_offset: How far the root was moved vertically (m).
        vertical_residual: Remaining vertical root force after the root-find (N).
        act: Activation ``(na,)`` to start from: equal to the control for filter and muscle
            dynamics, the holding value for an integrator (whose control is then 0).
        actuator_force: Actuator forces ``(nout,)`` at ``(qpos, ctrl, act)``.
        residual: What neither the actuators nor the equality constraints supply ``(nv,)``:
            ``qfrc - qfrc_actuator - qfrc_equality``, with MuJoCo's own clamps applied.
        actuated: Dofs some actuator can push ``(nv,)`` (boolean): a nonzero row of the
            actuation map.
        shortfall: Largest ``|residual|`` on actuated dofs; above the tolerance the posture
            cannot be held (limits, or forces outside the span of the actuators).
        qfrc_equality: Generalized force ``(nv,)`` left to the model's active equality
            constraints, :math:`J_{eq}^T \\lambda` (a tendon or joint coupling, a weld): the
            part of ``qfrc - qfrc_actuator`` in the span of their Jacobian rows (zeros
            without equality constraints).
    """

    qpos: np.ndarray
    ctrl: np.ndarray
    qfrc: np.ndarray
    residual_wrench: np.ndarray
    height_offset: float
    vertical_residual: float
    act: np.ndarray
    actuator_force: np.ndarray
    residual: np.ndarray
    actuated: np.ndarray
    shortfall: float
    qfrc_equality: np.ndarray | None = None


def _free_root(model: mujoco.MjModel) -> tuple[int, int] | None:
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and model.jnt_bodyid[j] != 0:
            return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
    return None


@checked_keywords
def find_equilibrium(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    tolerance: float = 1e-3,
    search_range: float = 0.2,
    feasibility_tolerance: float = 1e-6,
    on_infeasible: str = "warn",
) -> Equilibrium:
    """Adjust the root height until the contacts carry the weight, then solve for the control.

    For a floating base the vertical root force from inverse dynamics,
    :math:`f_z(h)` (with :math:`\\ddot q = 0`), decreases as the body is lowered by :math:`h`
    into the soft contacts. A bracketing root-find (Brent) solves :math:`f_z(h) = 0` to
    ``tolerance`` newtons.

    The control then goes through each actuator's full model. At the posture, with zero
    velocity, MuJoCo's actuation is affine in one variable per control
    (:func:`~mpcbox.core.actuation.actuation_map`): :math:`\\tau_{act} = A x + a_0`, where
    :math:`x` is the control of a stateless actuator (so a position servo's
    ``force = kp (ctrl - q)`` gives ``ctrl = q + tau / kp``, a motor's ``ctrl = tau / gear``)
    or the resting activation of one with activation dynamics. The variables solve the
    bounded least-squares problem
    :math:`\\min_x \\lVert A x + a_0 - \\tau \\rVert` within the control, activation and
    force ranges (:func:`~mpcbox.core.actuation.solve_actuation`); when the unbounded
    solution is inside them it is the plain least-squares one.

    Whatever the actuators cannot supply is the ``residual``. On unactuated dofs (a floating
    root) it is expected; on actuated dofs above ``feasibility_tolerance`` the posture cannot
    be held, and ``on_infeasible`` decides what happens: the message names the worst joint,
    its shortfall and the actuators there that sit at a limit.

    Args:
        model: The model.
        qpos: Posture ``(nq,)``.
        tolerance: Target vertical residual force (N).
        search_range: Largest height change tried in either direction (m).
        feasibility_tolerance: Largest residual generalized force on an actuated dof that
            still counts as held (N or N m).
        on_infeasible: ``"warn"`` (an :class:`~mpcbox.errors.EquilibriumWarning`),
            ``"raise"`` (:class:`~mpcbox.errors.InfeasibleEquilibriumError`) or ``"ignore"``.

    Returns:
        An :class:`Equilibrium`.

    Raises:
        SolverError: If no height within ``search_range`` brings the vertical force to zero.
        InfeasibleEquilibriumError: With ``on_infeasible="raise"``, if the actuators cannot
            hold the posture.
        UnsupportedModelError: If an actuator's force is not affine in its control at rest
            (e.g. user dynamics, delays).
    """
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,)).copy()
    tolerance = positive("tolerance", tolerance)
    search_range = positive("search_range", search_range)
    feasibility_tolerance = positive("feasibility_tolerance", feasibility_tolerance)
    on_infeasible = one_of("on_infeasible", on_infeasible, ON_INFEASIBLE)
    data = mujoco.MjData(model)
    root = _free_root(model)

    def inverse(offset: float) -> np.ndarray:
        data.qpos[:] = qpos
        if root is not None:
            data.qpos[root[0] + 2] += offset
        data.qvel[:] = 0
        mujoco.mj_forward(model, data)
        data.qacc[:] = 0
        mujoco.mj_inverse(model, data)
        return data.qfrc_inverse.copy()

    offset, vertical = 0.0, 0.0
    if root is not None:
        zdof = root[1] + 2

        def f(h: float) -> float:
            return float(inverse(h)[zdof])

        f0 = f(0.0)
        if abs(f0) > tolerance:
            # Walk away from 0 in growing steps until the sign changes, then bracket-solve.
            direction = -1.0 if f0 > 0 else 1.0
            lo, flo, step = 0.0, f0, 1e-4
            hi, fhi = lo, flo
            while abs(hi) < search_range:
                hi = direction * min(abs(hi) + step, search_range)
                fhi = f(hi)
                if np.sign(fhi) != np.sign(flo):
                    break
                lo, flo, step = hi, fhi, step * 2.0
            if np.sign(fhi) == np.sign(flo):
                raise SolverError(
                    f"find_equilibrium: the vertical root force stays {fhi:+.3g} N within "
                    f"±{search_range} m of the given height; is the body touching the floor?"
                )
            offset = brentq(f, min(lo, hi), max(lo, hi), xtol=1e-14, rtol=1e-15, maxiter=200)
            vertical = f(offset)
        else:
            vertical = f0
    qfrc = inverse(offset)
    amap = actuation_map(model, data)
    # Active equality constraints (a tendon coupling of joints, a weld) carry load at any
    # force along their Jacobian rows: only the part of the needed force outside that span
    # is asked of the actuators.
    free = equality_span(model, data)
    x = solve_actuation(
        amap._replace(matrix=free.project(amap.matrix), offset=free.project(amap.offset)),
        free.project(qfrc),
    )
    ctrl, act = actuator_state(model, x)
    data.ctrl[:], data.act[:] = ctrl, act
    mujoco.mj_fwdActuation(model, data)
    qfrc_equality = qfrc - data.qfrc_actuator - free.project(qfrc - data.qfrc_actuator)
    residual = qfrc - data.qfrc_actuator - qfrc_equality
    actuated = np.any(amap.matrix != 0.0, axis=1)
    shortfall = float(np.max(np.abs(residual[actuated]), initial=0.0))
    if shortfall > feasibility_tolerance and on_infeasible != "ignore":
        message = _diagnose(model, amap, x, residual, actuated)
        if on_infeasible == "raise":
            raise InfeasibleEquilibriumError(message)
        warnings.warn(message, EquilibriumWarning, stacklevel=2)
    wrench = residual[root[1] : root[1] + 6].copy() if root is not None else np.zeros(6)
    return Equilibrium(
        qpos=data.qpos.copy(),
        ctrl=ctrl,
        qfrc=qfrc,
        residual_wrench=wrench,
        height_offset=float(offset),
        vertical_residual=float(vertical),
        act=act,
        actuator_force=data.actuator_force.copy(),
        residual=residual,
        actuated=actuated,
        shortfall=shortfall,
        qfrc_equality=qfrc_equality,
    )


def _dof_name(model: mujoco.MjModel, dof: int) -> str:
    jnt = int(model.dof_jntid[dof])
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, jnt) or f"joint {jnt}"
    ndof = {mujoco.mjtJoint.mjJNT_FREE: 6, mujoco.mjtJoint.mjJNT_BALL: 3}.get(
        int(model.jnt_type[jnt]), 1
    )
    return name if ndof == 1 else f"{name}[{dof - int(model.jnt_dofadr[jnt])}]"


def _diagnose(
    model: mujoco.MjModel,
    amap: ActuationMap,
    x: np.ndarray,
    residual: np.ndarray,
    actuated: np.ndarray,
) -> str:
    """Why the posture cannot be held: the worst actuated dof and the limits that bind."""
    dof = int(np.argmax(np.where(actuated, np.abs(residual), -1.0)))
    owner = control_owner(model)
    limits = []
    for j in np.flatnonzero(amap.matrix[dof]):
        for side, bound, source in (
            ("lower", amap.lower[j], amap.lower_source[j]),
            ("upper", amap.upper[j], amap.upper_source[j]),
        ):
            if source and abs(x[j] - bound) <= 1e-9 * (1.0 + abs(bound)):
                name = actuator_name(model, int(owner[j]))
                limits.append(f"actuator {name!r} is at its {side} {source} limit {bound:.6g}")
    jnt = int(model.dof_jntid[dof])
    if not limits and model.jnt_actfrclimited[jnt]:
        limits.append(f"the joint's actuatorfrcrange {tuple(model.jnt_actfrcrange[jnt])} clamps")
    why = (
        "; ".join(limits)
        if limits
        else "no actuator is at a limit: the force lies outside the span of the actuator "
        "moments (underactuated)"
    )
    return (
        f"find_equilibrium: the actuators cannot hold the posture: joint {_dof_name(model, dof)!r}"
        f" (dof {dof}) lacks {residual[dof]:+.6g} of generalized force (N or N m); {why}"
    )
