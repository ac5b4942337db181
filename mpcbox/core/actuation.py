"""The controls that make the actuators supply a generalized force, through MuJoCo's actuator model.

At a fixed posture with zero velocity every supported actuator's force is affine in one
scalar per control: the control itself for stateless actuators (``force = gain * ctrl +
bias`` with the gain and bias of position, velocity, motor and general actuators), and the
activation for actuators with activation dynamics (filters and muscles hold ``act = ctrl``
at rest, an integrator holds any ``act`` with ``ctrl = 0``). MuJoCo itself evaluates that
map (``mj_fwdActuation``), so gains, biases, muscle curves, gears and tendon or site
transmissions are all taken from the model rather than re-derived here.
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import mujoco
import numpy as np
from scipy.optimize import lsq_linear

from mpcbox.errors import UnsupportedModelError

_Dyn = mujoco.mjtDyn
#: Dynamics whose rest state is ``act = ctrl`` (``act_dot`` vanishes there).
_FOLLOWS_CTRL = (_Dyn.mjDYN_FILTER, _Dyn.mjDYN_FILTEREXACT, _Dyn.mjDYN_MUSCLE)
_SCALAR_JOINTS = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)


class ActuationMap(NamedTuple):
    """The affine map from the actuator variables to forces at one posture (zero velocity).

    There is one variable per control (``nu``): the control of a stateless actuator, or the
    activation of an actuator with activation dynamics (see :func:`actuator_state`). With
    the variables ``x``, and before any clamping,

    .. math::

        \\tau_{act} = A x + a_0, \\qquad f = G x + f_0 .

    The bounds collect, per variable, the tightest of its control range, activation range,
    force range, and the ``actuatorfrcrange`` of a joint it drives alone.

    Attributes:
        matrix: :math:`A`, ``(nv, nu)``: generalized force per unit of each variable.
        offset: :math:`a_0`, ``(nv,)``: generalized force at ``x = 0`` (biases, e.g. the
            ``-kp * q`` of position servos, muscle passive forces, actuator gravcomp).
        force_matrix: :math:`G`, ``(nout, nu)``: actuator force per unit of each variable.
        force_offset: :math:`f_0`, ``(nout,)``: actuator forces at ``x = 0``.
        lower: Lower bound of each variable ``(nu,)`` (``-inf`` if none).
        upper: Upper bound of each variable ``(nu,)`` (``+inf`` if none).
        lower_source: What sets each lower bound (e.g. ``"ctrlrange"``), ``""`` if none.
        upper_source: What sets each upper bound, ``""`` if none.
    """

    matrix: np.ndarray
    offset: np.ndarray
    force_matrix: np.ndarray
    force_offset: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lower_source: tuple[str, ...]
    upper_source: tuple[str, ...]


class _Layout(NamedTuple):
    """Per-actuator control and output slots; MuJoCo 3 has one of each per actuator."""

    ctrladr: np.ndarray
    ctrlnum: np.ndarray
    outadr: np.ndarray
    outnum: np.ndarray
    delay: np.ndarray


def _layout(model: mujoco.MjModel) -> _Layout:
    index, one = np.arange(model.nu), np.ones(model.nu, dtype=int)
    fields = zip(_Layout._fields, (index, one, index, one, np.zeros(model.nu)))
    return _Layout(*(np.asarray(getattr(model, f"actuator_{f}", d)) for f, d in fields))


def _nout(model: mujoco.MjModel) -> int:
    return int(getattr(model, "nout", model.nu))


def actuator_moment(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Dense actuator moment matrix ``(nout, nv)`` (``qfrc_actuator = moment^T force``)."""
    dense = np.zeros((_nout(model), model.nv))
    mujoco.mju_sparse2dense(
        dense, data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind
    )
    return dense


def actuator_name(model: mujoco.MjModel, i: int) -> str:
    """The actuator's name, or ``actuator <i>`` when it has none."""
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator {i}"


def velocity_gain(model: mujoco.MjModel, i: int, x: float = 0.0) -> float:
    """Magnitude of actuator ``i``'s force per unit of its velocity (a servo's ``kv``) at
    variable ``x`` (the control, or the activation); 0 when the force does not fall with it."""
    gain = 0.0
    if model.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_AFFINE:
        gain -= float(model.actuator_biasprm[i, 2])
    if model.actuator_gaintype[i] == mujoco.mjtGain.mjGAIN_AFFINE:
        gain -= float(model.actuator_gainprm[i, 2]) * x
    return max(gain, 0.0)


def motor_actuators(model: mujoco.MjModel) -> np.ndarray:
    """Which actuators are motors, one flag per actuator: a fixed gain and no bias, so that
    the force is the gain times the control (or the activation) whatever the state."""
    fixed = model.actuator_gaintype == mujoco.mjtGain.mjGAIN_FIXED
    return fixed & (model.actuator_biastype == mujoco.mjtBias.mjBIAS_NONE)


def position_servo_actuators(model: mujoco.MjModel) -> np.ndarray:
    """Which actuators are position servos, one flag per actuator: an affine bias that pulls
    the actuator's length toward its control (``biasprm[1] < 0``, e.g. ``<position
    kp=...>``), so that the control is a set-point rather than a force."""
    affine = model.actuator_biastype == mujoco.mjtBias.mjBIAS_AFFINE
    return affine & (model.actuator_biasprm[:, 1] < 0)


def position_servos(model: mujoco.MjModel) -> np.ndarray:
    """Which controls ``(nu,)`` drive a position servo (:func:`position_servo_actuators`)."""
    return position_servo_actuators(model)[control_owner(model)]


def control_owner(model: mujoco.MjModel) -> np.ndarray:
    """The actuator of each control ``(nu,)``.

    Raises:
        UnsupportedModelError: If an actuator has a delay, several controls with activation
            dynamics, or dynamics other than none, filter, filterexact, muscle, integrator.
    """
    layout = _layout(model)
    owner = np.full(model.nu, -1, dtype=int)
    for i in range(len(layout.ctrladr)):
        dyn = int(model.actuator_dyntype[i])
        nctrl, nact = int(layout.ctrlnum[i]), int(model.actuator_actnum[i])
        stateless = dyn == _Dyn.mjDYN_NONE and nact == 0
        scalar = nctrl == 1 and nact == 1 and (dyn in _FOLLOWS_CTRL or dyn == _Dyn.mjDYN_INTEGRATOR)
        if not (stateless or scalar) or layout.delay[i] > 0:
            raise UnsupportedModelError(
                f"actuator {actuator_name(model, i)!r}: equilibrium controls need no delay and "
                f"dynamics none, filter, filterexact, muscle or integrator with one control; "
                f"it has dynamics {_Dyn(dyn).name}, delay {layout.delay[i]}, "
                f"{nctrl} control(s) and {nact} activation(s)"
            )
        adr = int(layout.ctrladr[i])
        owner[adr : adr + nctrl] = i
    return owner


def actuator_state(model: mujoco.MjModel, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The resting control and activation that realize the variables ``x``.

    Stateless actuators take ``ctrl = x``; filter, filterexact and muscle dynamics rest at
    ``ctrl = act = x`` (:math:`\\dot a = (u - a)/\\tau = 0`); an integrator rests at
    ``ctrl = 0`` with the activation state holding ``act = x``.

    Args:
        model: The model.
        x: One variable per control ``(nu,)``.

    Returns:
        ``(ctrl, act)`` of shapes ``(nu,)`` and ``(na,)`` (activations of other actuators 0).
    """
    ctrl = np.array(x, dtype=float)
    act = np.zeros(model.na)
    ctrladr = _layout(model).ctrladr
    for i in np.flatnonzero(model.actuator_actadr >= 0):
        c, a = int(ctrladr[i]), int(model.actuator_actadr[i])
        act[a] = x[c]
        if model.actuator_dyntype[i] == _Dyn.mjDYN_INTEGRATOR:
            ctrl[c] = 0.0
    return ctrl, act


def _evaluate(
    model: mujoco.MjModel, data: mujoco.MjData, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    data.ctrl[:], data.act[:] = actuator_state(model, x)
    mujoco.mj_fwdActuation(model, data)
    return data.qfrc_actuator.copy(), data.actuator_force.copy()


def _interval(lo: float, hi: float, slope: float, offset: float) -> tuple[float, float] | None:
    """Values of ``x`` with ``lo <= slope * x + offset <= hi``; ``None`` if ``slope`` is 0."""
    if slope == 0.0:
        return None
    a, b = (lo - offset) / slope, (hi - offset) / slope
    return (a, b) if slope > 0 else (b, a)


def actuation_map(model: mujoco.MjModel, data: mujoco.MjData) -> ActuationMap:
    """Evaluate the actuators' affine map at the posture in ``data`` (velocity taken as 0).

    MuJoCo evaluates the actuation of a copy of the model with the control, activation,
    force and joint-actuator-force clamps switched off, at ``x = 0``, at each unit vector
    and at one mixed point that checks the map is affine.

    Args:
        model: The model.
        data: Data holding the posture ``qpos`` (its other fields are not changed).

    Returns:
        An :class:`ActuationMap`.

    Raises:
        UnsupportedModelError: If an actuator has dynamics without a resting state used here,
            a delay, or a force that is not affine in its variable (e.g. user callbacks).
    """
    owner = control_owner(model)
    layout = _layout(model)
    free = copy.copy(model)
    free.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
    free.actuator_forcelimited[:] = 0
    free.actuator_actlimited[:] = 0
    free.jnt_actfrclimited[:] = 0
    fdata = mujoco.MjData(free)
    fdata.qpos[:] = data.qpos
    fdata.mocap_pos[:], fdata.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    mujoco.mj_forward(free, fdata)

    nu = model.nu
    offset, force_offset = _evaluate(free, fdata, np.zeros(nu))
    matrix = np.zeros((model.nv, nu))
    force_matrix = np.zeros((_nout(model), nu))
    for j in range(nu):
        qfrc, force = _evaluate(free, fdata, np.eye(nu)[j])
        matrix[:, j], force_matrix[:, j] = qfrc - offset, force - force_offset
    probe = np.linspace(-0.7, 0.9, nu)
    qfrc, _ = _evaluate(free, fdata, probe)
    scale = 1.0 + np.abs(matrix) @ np.abs(probe) + np.abs(offset)
    if np.any(np.abs(qfrc - offset - matrix @ probe) > 1e-8 * scale):
        bad = [
            actuator_name(model, int(owner[j]))
            for j in range(nu)
            if np.any(
                np.abs(_evaluate(free, fdata, 2.0 * np.eye(nu)[j])[0] - offset - 2 * matrix[:, j])
                > 1e-8 * (1.0 + 2 * np.abs(matrix[:, j]) + np.abs(offset))
            )
        ]
        raise UnsupportedModelError(
            "the actuator forces are not affine in the controls at this posture"
            + (f" (actuators {', '.join(map(repr, bad))})" if bad else "")
        )

    lower, upper = np.full(nu, -np.inf), np.full(nu, np.inf)
    lower_source, upper_source = [""] * nu, [""] * nu

    def tighten(j: int, interval: tuple[float, float] | None, source: str) -> None:
        if interval is None:
            return
        if interval[0] > upper[j] or interval[1] < lower[j]:
            # Disjoint from the range found so far (the control's own range comes first):
            # MuJoCo clamps the control into its range, so the force stays at its limit; the
            # control is pinned at the end of its range nearest the force limits.
            if interval[0] > upper[j]:
                value, side = upper[j], upper_source[j]
            else:
                value, side = lower[j], lower_source[j]
            lower[j] = upper[j] = value
            lower_source[j] = upper_source[j] = side
            return
        if interval[0] > lower[j]:
            lower[j], lower_source[j] = interval[0], source
        if interval[1] < upper[j]:
            upper[j], upper_source[j] = interval[1], source

    for j in range(nu):
        i = int(owner[j])
        integrator = model.actuator_dyntype[i] == _Dyn.mjDYN_INTEGRATOR
        if model.actuator_ctrllimited[j] and not integrator:
            tighten(j, tuple(model.actuator_ctrlrange[j]), "ctrlrange")
        if model.actuator_actadr[i] >= 0 and model.actuator_actlimited[i]:
            tighten(j, tuple(model.actuator_actrange[i]), "actrange")
    # Force and joint-force limits become bounds where one variable alone drives them.
    for i in np.flatnonzero(model.actuator_forcelimited):
        lo, hi = model.actuator_forcerange[i]
        start = int(layout.outadr[i])
        for o in range(start, start + int(layout.outnum[i])):
            cols = np.flatnonzero(force_matrix[o])
            if cols.size == 1:
                j = int(cols[0])
                tighten(j, _interval(lo, hi, force_matrix[o, j], force_offset[o]), "forcerange")
    for jnt in range(model.njnt):
        if not model.jnt_actfrclimited[jnt] or int(model.jnt_type[jnt]) not in _SCALAR_JOINTS:
            continue
        dof = int(model.jnt_dofadr[jnt])
        cols = np.flatnonzero(matrix[dof])
        if cols.size == 1:
            lo, hi = model.jnt_actfrcrange[jnt]
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, jnt) or f"joint {jnt}"
            tighten(
                int(cols[0]),
                _interval(lo, hi, matrix[dof, cols[0]], offset[dof]),
                f"actuatorfrcrange of joint {name!r}",
            )
    return ActuationMap(
        matrix,
        offset,
        force_matrix,
        force_offset,
        lower,
        upper,
        tuple(lower_source),
        tuple(upper_source),
    )


def solve_actuation(amap: ActuationMap, qfrc: np.ndarray) -> np.ndarray:
    """Variables whose generalized force is closest to ``qfrc`` within the bounds.

    Solves :math:`\\min_x \\lVert A x + a_0 - \\tau \\rVert_2` subject to
    ``lower <= x <= upper``. When the unbounded least-squares solution (minimum norm,
    ``numpy.linalg.lstsq``) lies within the bounds it is returned as is; otherwise a
    bounded-variable least-squares solve (``scipy.optimize.lsq_linear``, BVLS) takes over.
    Variables without any effect (zero columns) take the value in their bounds nearest 0.

    Args:
        amap: The actuation map at the posture.
        qfrc: Generalized force to supply ``(nv,)``.

    Returns:
        The variables ``x`` ``(nu,)`` (see :func:`actuator_state`).
    """
    A, lower, upper = amap.matrix, amap.lower, amap.upper
    target = qfrc - amap.offset
    x = np.linalg.lstsq(A, target, rcond=None)[0]
    if np.all(x >= lower) and np.all(x <= upper):
        return x
    x = np.clip(np.zeros_like(x), lower, upper)
    # A variable pinned by its bounds (lower == upper) is fixed; BVLS needs lower < upper.
    pinned = lower >= upper
    x[pinned] = lower[pinned]
    target = target - A[:, pinned] @ x[pinned]
    used = np.flatnonzero(np.any(A != 0.0, axis=0) & ~pinned)
    if used.size:
        fit = lsq_linear(
            A[:, used], target, bounds=(lower[used], upper[used]), method="bvls", tol=1e-12
        )
        x[used] = np.clip(fit.x, lower[used], upper[used])
    return x
