r"""Where a floating body rests on its contacts: the root height, and its tilt, at which the
contacts carry the weight and balance its moments.

For a model with a free root body, inverse dynamics at rest (:math:`\dot q = 0`,
:math:`\ddot q = 0`) gives the generalized force :math:`\tau(q)` that would hold posture
:math:`q`. Its six root components are a wrench nothing but the contacts can supply: the
actuators do not reach the root. A posture is a static equilibrium only when that wrench is
zero. Friction does not act at rest, so the horizontal forces and the moment about the
vertical vanish already; the three that remain are the vertical force :math:`f_z` and the
horizontal moments :math:`m_x, m_y` about the root's origin (world frame).

:func:`support_root` moves the root of a given posture, keeping its joints, until they
vanish:

- ``"height"``: the root is lowered or raised by :math:`h` until :math:`f_z(h) = 0`
  (a bracketing root-find: the contacts push harder the deeper the body sinks);
- ``"pose"``: then the root is also tilted, by angles :math:`(\alpha, \beta)` about the
  world's x and y axes through its origin, until :math:`(m_x, m_y) = 0` too (one axis at a
  time, bracketed in the direction the body would fall, the height re-solved at every tilt
  tried; see :func:`_balance`). A keyframe whose feet are not level, or whose center of
  mass is not over the middle of its contacts' load, is then leaned until the contacts
  balance it, as the robot would settle on the floor. When no tilt within
  :data:`MAX_TILT` does, the height-only posture is kept and reported as not balanced.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np
from scipy.optimize import brentq

from mpcbox.core.model import free_body
from mpcbox.errors import SolverError

#: How :func:`support_root` moves the root.
ROOT_ADJUSTMENTS = ("height", "pose")

#: Moments up to the weight times this length (m) count as balanced (see
#: :func:`support_root`'s ``balance_offset``).
BALANCE_OFFSET = 1e-3

#: Largest tilt :func:`support_root` tries (rad) before it gives up on balancing the moments.
MAX_TILT = 0.35

_SWEEPS = 30

#: Largest step (rad) of the tilt's bracketing walk: a foot touching or lifting makes the
#: moment non-monotone (Unitree's H1 crosses zero at -0.0157 rad and is positive again at
#: -0.0255), and a longer step can jump over both crossings.
_MAX_TILT_STEP = 0.004


class RootSupport(NamedTuple):
    """A posture with its root moved onto its contacts.

    Attributes:
        qpos: The posture ``(nq,)`` with the root moved.
        height_offset: Vertical move of the root (m).
        tilt: Rotations ``(2,)`` about the world's x and y axes through the root's origin
            (rad), applied after the height change (zeros with ``"height"``).
        wrench: The root's residual ``(3,)``: vertical force (N) and the horizontal moments
            about the root's origin in the world frame (N m).
        balanced: Whether every adjusted component of ``wrench`` is within its tolerance
            (the vertical force for ``"height"``, all three for ``"pose"``).
    """

    qpos: np.ndarray
    height_offset: float
    tilt: np.ndarray
    wrench: np.ndarray
    balanced: bool


def free_root(model: mujoco.MjModel) -> tuple[int, int, int] | None:
    """``(qpos address, dof address, body)`` of the floating root
    (:func:`~mpcbox.core.model.free_body`; a free joint is its body's only joint)."""
    body = free_body(model)
    if body is None:
        return None
    joint = int(model.body_jntadr[body])
    return int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint]), body


def _tilted(quat: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """``quat`` rotated by ``tilt[0]`` about world x, then ``tilt[1]`` about world y."""
    out = np.empty(4)
    qx = np.array([np.cos(tilt[0] / 2), np.sin(tilt[0] / 2), 0.0, 0.0])
    qy = np.array([np.cos(tilt[1] / 2), 0.0, np.sin(tilt[1] / 2), 0.0])
    rot = np.empty(4)
    mujoco.mju_mulQuat(rot, qy, qx)
    mujoco.mju_mulQuat(out, rot, quat)
    return out / np.linalg.norm(out)


class _RootWrench:
    """The root's residual ``(f_z, m_x, m_y)`` as a function of its height offset and tilt."""

    def __init__(self, model: mujoco.MjModel, qpos: np.ndarray, root: tuple[int, int, int]):
        self.model, self.qpos, self.root = model, qpos, root
        self.data = mujoco.MjData(model)
        gravity = float(np.linalg.norm(model.opt.gravity))
        #: The body's weight (N).
        self.weight = float(mujoco.mj_getTotalmass(model)) * gravity

    def posture(self, height: float, tilt: np.ndarray) -> np.ndarray:
        qpos = self.qpos.copy()
        adr = self.root[0]
        qpos[adr + 2] += height
        if np.any(tilt != 0.0):
            qpos[adr + 3 : adr + 7] = _tilted(qpos[adr + 3 : adr + 7], tilt)
        return qpos

    def __call__(self, height: float, tilt: np.ndarray) -> np.ndarray:
        model, data = self.model, self.data
        data.qpos[:] = self.posture(height, tilt)
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        data.qacc[:] = 0.0
        mujoco.mj_inverse(model, data)
        dof, body = self.root[1], self.root[2]
        force = data.qfrc_inverse[dof : dof + 3]
        moment = data.xmat[body].reshape(3, 3) @ data.qfrc_inverse[dof + 3 : dof + 6]
        return np.array([force[2], moment[0], moment[1]])


def _height(
    wrench: _RootWrench,
    tilt: np.ndarray,
    tolerance: float,
    search_range: float,
    start: float = 0.0,
) -> float:
    """Height offset (within ``search_range`` of 0) at which the vertical root force
    vanishes at ``tilt``: walk from ``start`` in growing steps until the sign changes, then
    bracket-solve (Brent).

    Raises:
        SolverError: If no height within ``search_range`` brings it to zero.
    """

    def f(h: float) -> float:
        return float(wrench(h, tilt)[0])

    f0 = f(start)
    if abs(f0) <= tolerance:
        return start
    direction = -1.0 if f0 > 0 else 1.0
    lo, flo, step = start, f0, 1e-4
    hi, fhi = lo, flo
    while abs(hi) < search_range:
        hi = float(np.clip(hi + direction * step, -search_range, search_range))
        fhi = f(hi)
        if np.sign(fhi) != np.sign(flo):
            break
        lo, flo, step = hi, fhi, step * 2.0
    if np.sign(fhi) == np.sign(flo):
        raise SolverError(
            f"find_equilibrium: the vertical root force stays {fhi:+.3g} N within "
            f"±{search_range} m of the given height; is the body touching the floor?"
        )
    return float(brentq(f, min(lo, hi), max(lo, hi), xtol=1e-14, rtol=1e-15, maxiter=200))


def _balance(
    wrench: _RootWrench,
    height: float,
    tolerance: float,
    moment_tolerance: float,
    search_range: float,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Tilt the root until the horizontal moments vanish, the height re-solved for a zero
    vertical force at every tilt tried (so the body stays on its contacts).

    The moments are piecewise smooth in the tilt, and flat while a foot is in the air (a
    slab on two of its three legs needs the same moment until the third touches), where
    gradient methods stall. So each axis in turn is bracketed the way the body would fall:
    stepping the tilt against the sign of the moment that holds it, in growing steps (up to
    :data:`_MAX_TILT_STEP`), until
    the moment changes sign, then Brent's method; sweeps over the two axes repeat until both
    moments are within ``moment_tolerance`` (the vertical force within ``tolerance``).

    Returns:
        The height, the tilt ``(2,)`` and the residual ``(f_z, m_x, m_y)`` found.
    """
    tilt = np.zeros(2)
    residual = wrench(height, tilt)
    for _ in range(_SWEEPS):
        before = np.abs(residual[1:]).max()
        for axis in np.argsort(-np.abs(residual[1:])):  # the larger moment first
            if abs(residual[1 + axis]) <= moment_tolerance:
                continue

            def moment(angle: float, axis: int = axis) -> float:
                nonlocal height
                trial = tilt.copy()
                trial[axis] = angle
                height = _height(wrench, trial, tolerance, search_range, start=height)
                return float(wrench(height, trial)[1 + axis])

            lo, mlo = float(tilt[axis]), float(residual[1 + axis])
            direction, step = -np.sign(mlo), 1e-4
            hi, mhi = lo, mlo
            try:
                while abs(hi) < MAX_TILT:
                    hi = float(np.clip(hi + direction * step, -MAX_TILT, MAX_TILT))
                    mhi = moment(hi)
                    if np.sign(mhi) != np.sign(mlo):
                        break
                    lo, mlo, step = hi, mhi, min(2.0 * step, _MAX_TILT_STEP)
                if np.sign(mhi) != np.sign(mlo):
                    tilt[axis] = brentq(moment, min(lo, hi), max(lo, hi), xtol=1e-13, maxiter=200)
            except SolverError:  # no height carries the body at some tilt: leave this axis
                pass
            height = _height(wrench, tilt, tolerance, search_range, start=height)
            residual = wrench(height, tilt)
        if np.abs(residual[1:]).max() <= moment_tolerance or np.abs(residual[1:]).max() >= before:
            break
    return height, tilt, residual


def support_root(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    adjust: str = "pose",
    tolerance: float = 1e-3,
    search_range: float = 0.2,
    balance_offset: float = BALANCE_OFFSET,
) -> RootSupport | None:
    """Move the free root of ``qpos`` until the contacts carry the body (see the module).

    Args:
        model: The model.
        qpos: Posture ``(nq,)`` (not changed).
        adjust: ``"height"`` or ``"pose"`` (:data:`ROOT_ADJUSTMENTS`).
        tolerance: Residual force (N) that counts as zero, and the least moment (N m).
        balance_offset: Moments up to the weight times this length (m) count as zero: the
            center of mass that far from balanced. Contacts switching on and off (a flat
            mesh sole on the floor) make the moments jump as the tilt changes by 1e-13 rad,
            so no tilt brings them exactly to zero.
        search_range: Largest height change tried in either direction (m).

    Returns:
        The :class:`RootSupport`, or ``None`` for a model without a free root.

    Raises:
        SolverError: If no height within ``search_range`` brings the vertical force to zero.
    """
    root = free_root(model)
    if root is None:
        return None
    wrench = _RootWrench(model, np.asarray(qpos, dtype=float), root)
    tilt = np.zeros(2)
    height = _height(wrench, tilt, tolerance, search_range)
    residual = wrench(height, tilt)
    moment_tolerance = max(tolerance, balance_offset * wrench.weight)
    limits = np.array([tolerance, moment_tolerance, moment_tolerance])
    if adjust == "pose" and np.any(np.abs(residual) > limits):
        h, t, r = _balance(wrench, height, tolerance, moment_tolerance, search_range)
        if np.all(np.abs(r) <= limits):
            height, tilt, residual = h, t, r
        # else: no tilt balances the moments (a posture whose center of mass no tilt brings
        # over its support): keep the height-only posture, reported as not balanced.
    adjusted = np.abs(residual) <= limits if adjust == "pose" else np.abs(residual[:1]) <= tolerance
    return RootSupport(
        qpos=wrench.posture(height, tilt),
        height_offset=float(height),
        tilt=tilt,
        wrench=residual,
        balanced=bool(np.all(adjusted)),
    )
