"""Tangent-space arithmetic on joint positions and states, vectorized over a batch.

Free and ball joints store orientations as unit quaternions (4 numbers) but move in a
3-dimensional tangent space; :class:`TangentSpace` maps ``nq``-sized positions to
``nv``-sized differences like :func:`mujoco.mj_differentiatePos` (tested against it to
round-off), but for a whole batch of positions at once.

A state is ``[qpos (nq), qvel (nv), act (na)]`` and a state deviation
``dx = [dq (nv), dv (nv), da (na)]``; only the positions need the tangent space.
"""

from __future__ import annotations

import mujoco
import numpy as np

from mpcbox.errors import InvalidArgumentError


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions ``(..., 4)`` in (w, x, y, z) order."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def quat_difference(q2: np.ndarray, q1: np.ndarray) -> np.ndarray:
    r"""Rotation vector taking ``q1`` to ``q2`` in ``q1``'s local frame.

    Computes :math:`\log(q_1^{-1} q_2)` as axis times angle with the angle wrapped to
    :math:`(-\pi, \pi]`, the convention of ``mju_subQuat``.

    Args:
        q2: Quaternions, shape ``(..., 4)``.
        q1: Quaternions, shape ``(..., 4)``.

    Returns:
        Rotation vectors, shape ``(..., 3)``.
    """
    q1c = q1 * np.array([1.0, -1.0, -1.0, -1.0])
    q = quat_multiply(q1c, q2)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w = q[..., 0]
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, w)
    angle = np.where(angle > np.pi, angle - 2.0 * np.pi, angle)
    scale = np.where(s > 1e-15, angle / np.maximum(s, 1e-300), 2.0)
    return v * scale[..., None]


class TangentSpace:
    """Differences of joint positions in the ``nv``-dimensional tangent space of a model.

    Args:
        model: The model whose joint layout is used.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.nq = model.nq
        self.nv = model.nv
        scal_q, scal_v, quat_q, quat_v = [], [], [], []
        for j in range(model.njnt):
            qa, va = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
            jtype = model.jnt_type[j]
            if jtype == mujoco.mjtJoint.mjJNT_FREE:
                scal_q += [qa, qa + 1, qa + 2]
                scal_v += [va, va + 1, va + 2]
                quat_q.append(qa + 3)
                quat_v.append(va + 3)
            elif jtype == mujoco.mjtJoint.mjJNT_BALL:
                quat_q.append(qa)
                quat_v.append(va)
            else:
                scal_q.append(qa)
                scal_v.append(va)
        self._scal_q = np.array(scal_q, dtype=int)
        self._scal_v = np.array(scal_v, dtype=int)
        self._quat_q = np.array(quat_q, dtype=int)
        self._quat_v = np.array(quat_v, dtype=int)

    @property
    def scalar_addresses(self) -> tuple[np.ndarray, np.ndarray]:
        """``(qpos addresses, dof addresses)`` of the coordinates differenced as plain numbers
        (hinge, slide and free-joint translation), each ``(n,)``."""
        return self._scal_q, self._scal_v

    @property
    def quaternion_addresses(self) -> tuple[np.ndarray, np.ndarray]:
        """``(qpos addresses, dof addresses)`` of the quaternions (ball joints and free-joint
        rotation), each ``(n,)``: four positions and three dofs from each address."""
        return self._quat_q, self._quat_v

    def check_quaternions(self, name: str, x: np.ndarray) -> np.ndarray:
        """Return ``x`` (positions ``(nq,)`` or a state beginning with them) unchanged after
        checking that no quaternion is zero (MuJoCo cannot normalize one).

        Raises:
            InvalidArgumentError: Naming ``name`` and the quaternion's positions.
        """
        for a in self._quat_q:
            if not np.linalg.norm(x[a : a + 4]) > 1e-10:
                raise InvalidArgumentError(
                    f"{name}[{a}:{a + 4}] is a zero quaternion; the orientations of ball and "
                    "free joints are unit quaternions [w, x, y, z] (e.g. [1, 0, 0, 0])"
                )
        return x

    def unit_quaternions(self, name: str, qpos: np.ndarray) -> np.ndarray:
        """A copy of ``qpos`` ``(nq,)`` with each quaternion scaled to unit norm, as MuJoCo
        does when it steps (:meth:`check_quaternions` first)."""
        qpos = self.check_quaternions(name, np.array(qpos, dtype=float))
        for a in self._quat_q:
            qpos[a : a + 4] /= np.linalg.norm(qpos[a : a + 4])
        return qpos

    def difference(
        self, qpos: np.ndarray, qpos_ref: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Tangent vector ``dq`` such that integrating ``qpos_ref`` by ``dq`` gives ``qpos``.

        Args:
            qpos: Positions, shape ``(..., nq)``.
            qpos_ref: Reference positions, shape ``(nq,)`` or ``(..., nq)``.
            out: Optional output ``(..., nv)`` to write into.

        Returns:
            Differences, shape ``(..., nv)`` (``out`` when given).
        """
        qpos = np.asarray(qpos, dtype=np.float64)
        qpos_ref = np.broadcast_to(np.asarray(qpos_ref, dtype=np.float64), qpos.shape)
        if out is None:
            out = np.empty((*qpos.shape[:-1], self.nv))
        out[..., self._scal_v] = qpos[..., self._scal_q] - qpos_ref[..., self._scal_q]
        for qa, va in zip(self._quat_q, self._quat_v):
            out[..., va : va + 3] = quat_difference(
                qpos[..., qa : qa + 4], qpos_ref[..., qa : qa + 4]
            )
        return out

    def integrate(self, model: mujoco.MjModel, qpos: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``qpos`` moved by the tangent vector ``dq`` (one position, ``mj_integratePos``)."""
        out = np.array(qpos, dtype=np.float64)
        mujoco.mj_integratePos(model, out, np.asarray(dq, dtype=np.float64), 1.0)
        return out

    def state_difference(
        self, state: np.ndarray, state_ref: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Deviation ``dx = state ⊖ state_ref`` of states ``[qpos, qvel, act]``.

        Args:
            state: States, shape ``(..., nstate)``.
            state_ref: Reference state(s), shape ``(nstate,)`` or ``(..., nstate)``.
            out: Optional output ``(..., nx)`` to write into.

        Returns:
            Deviations ``[dq, dv, da]``, shape ``(..., nx)`` (``out`` when given).
        """
        nq, nv = self.nq, self.nv
        if out is None:
            out = np.empty((*state.shape[:-1], state.shape[-1] - nq + nv))
        self.difference(state[..., :nq], state_ref[..., :nq], out[..., :nv])
        np.subtract(state[..., nq:], state_ref[..., nq:], out=out[..., nv:])
        return out

    def state_add(self, model: mujoco.MjModel, state: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """One state ``(nstate,)`` moved by a deviation ``dx`` ``(nx,)`` (a new array)."""
        out = np.array(state, dtype=np.float64)
        out[: self.nq] = self.integrate(model, state[: self.nq], dx[: self.nv])
        out[self.nq :] += dx[self.nv :]
        return out
