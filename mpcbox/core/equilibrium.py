"""Controls that hold a posture, from inverse dynamics through the actuator model."""

from __future__ import annotations

import warnings
from typing import NamedTuple

import mujoco
import numpy as np

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
from mpcbox.core.root_support import MAX_TILT, ROOT_ADJUSTMENTS, free_root, support_root
from mpcbox.errors import EquilibriumWarning, InfeasibleEquilibriumError
from mpcbox.validation import checked_keywords, finite_array, one_of, positive

__all__ = ["Equilibrium", "actuator_moment", "find_equilibrium"]

#: What :func:`find_equilibrium` does when the actuators cannot hold the posture.
ON_INFEASIBLE = ("warn", "raise", "ignore")


class Equilibrium(NamedTuple):
    """A posture and the control that holds it.

    Attributes:
        qpos: Posture ``(nq,)`` with the root moved so the contacts carry the weight (its
            height, and with ``root_adjust="pose"`` its tilt).
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
        root_tilt: Rotations ``(2,)`` of the root about the world's x and y axes through
            its origin (rad) that balance the contacts' moments (``root_adjust="pose"``;
            zeros otherwise).
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
    root_tilt: np.ndarray | None = None


@checked_keywords
def find_equilibrium(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    tolerance: float = 1e-3,
    search_range: float = 0.2,
    feasibility_tolerance: float = 1e-6,
    on_infeasible: str = "warn",
    root_adjust: str = "pose",
) -> Equilibrium:
    """Move the root until the contacts carry the body, then solve for the control.

    For a floating base, inverse dynamics at rest leaves a wrench on the root that only the
    contacts can supply (:mod:`mpcbox.core.root_support`). With ``root_adjust="height"``
    the root is lowered or raised until the vertical force vanishes (a bracketing root-find
    to ``tolerance`` newtons); with ``"pose"`` (the default) it is then also tilted about
    the world's x and y axes until the horizontal moments vanish too, so the posture is a
    static equilibrium even when the keyframe's feet are not level or its center of mass
    is off the middle of their load. The joints are kept as given.

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
        tolerance: Target residual root force (N); with ``"pose"`` the moments count as
            balanced within the larger of this (N m) and the weight times 1 mm
            (:data:`~mpcbox.core.root_support.BALANCE_OFFSET`).
        search_range: Largest height change tried in either direction (m).
        feasibility_tolerance: Largest residual generalized force on an actuated dof that
            still counts as held (N or N m).
        on_infeasible: ``"warn"`` (an :class:`~mpcbox.errors.EquilibriumWarning`),
            ``"raise"`` (:class:`~mpcbox.errors.InfeasibleEquilibriumError`) or ``"ignore"``;
            also when tilting the root cannot balance the contacts' moments.
        root_adjust: ``"pose"`` (height and tilt) or ``"height"`` (height only: the root
            keeps the keyframe's orientation and any moment is left in
            ``residual_wrench``).

    Returns:
        An :class:`Equilibrium`.

    Raises:
        SolverError: If no height within ``search_range`` brings the vertical force to zero.
        InfeasibleEquilibriumError: With ``on_infeasible="raise"``, if the actuators cannot
            hold the posture, or the contacts cannot balance it.
        UnsupportedModelError: If an actuator's force is not affine in its control at rest
            (e.g. user dynamics, delays).
    """
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,)).copy()
    tolerance = positive("tolerance", tolerance)
    search_range = positive("search_range", search_range)
    feasibility_tolerance = positive("feasibility_tolerance", feasibility_tolerance)
    on_infeasible = one_of("on_infeasible", on_infeasible, ON_INFEASIBLE)
    root_adjust = one_of("root_adjust", root_adjust, ROOT_ADJUSTMENTS)
    data = mujoco.MjData(model)
    root = free_root(model)
    support = support_root(
        model, qpos, adjust=root_adjust, tolerance=tolerance, search_range=search_range
    )
    if support is not None:
        qpos = support.qpos
        if not support.balanced and on_infeasible != "ignore":
            message = (
                "find_equilibrium: the contacts cannot balance the posture: tilting the root "
                f"by up to {MAX_TILT} rad leaves a vertical force of {support.wrench[0]:+.4g} N"
                f" and moments of ({support.wrench[1]:+.4g}, {support.wrench[2]:+.4g}) N m "
                "about the world's x and y axes; it is not a static equilibrium"
            )
            if on_infeasible == "raise":
                raise InfeasibleEquilibriumError(message)
            warnings.warn(message, EquilibriumWarning, stacklevel=2)

    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)  # at rest: qvel = 0
    data.qacc[:] = 0
    mujoco.mj_inverse(model, data)
    qfrc = data.qfrc_inverse.copy()
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
        height_offset=0.0 if support is None else support.height_offset,
        vertical_residual=0.0 if support is None else float(support.wrench[0]),
        act=act,
        actuator_force=data.actuator_force.copy(),
        residual=residual,
        actuated=actuated,
        shortfall=shortfall,
        qfrc_equality=qfrc_equality,
        root_tilt=np.zeros(2) if support is None else support.tilt,
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
