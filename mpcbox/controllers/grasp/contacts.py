r"""Measured finger contacts: where each finger touches the object, how hard, how fast it slips.

MuJoCo reports every contact point with its frame (normal first, from ``geom1`` to
``geom2``) and, through ``mj_contactForce``, its force in that frame. The points of one
finger (any of its pad geoms against any geom of the object's body) are merged into one:
the force-weighted mean point (the plain mean while the forces are zero) and the unit sum of
the normals, oriented from the finger into the object. The slip speed is the tangential
speed of the object's material point there relative to the finger's,
:math:`\lVert (I - n n^T)(J_{obj}(p) - J_{pad}(p))\,\dot q \rVert`.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np


class FingerContacts(NamedTuple):
    """The fingers' contacts with the object at one instant.

    Attributes:
        touching: Whether each finger touches the object ``(k,)``.
        position: Merged contact point of each finger ``(k, 3)`` (m; zero if not touching).
        normal: Unit normal from each finger into the object ``(k, 3)``.
        normal_force: Measured normal force of each finger ``(k,)`` (N).
        tangential_force: Measured tangential force of each finger ``(k,)`` (N).
        slip_speed: Tangential speed of the object relative to each finger ``(k,)`` (m/s).
        count: Contact points of each finger ``(k,)``.
    """

    touching: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    slip_speed: np.ndarray
    count: np.ndarray

    @property
    def friction_ratio(self) -> np.ndarray:
        """Measured tangential over normal force of each finger ``(k,)`` (0 where no force)."""
        fn = self.normal_force
        return np.where(fn > 1e-9, self.tangential_force / np.maximum(fn, 1e-9), 0.0)


def finger_contacts(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    pads: list[np.ndarray],
    body: int,
) -> FingerContacts:
    """Measure the fingers' contacts with body ``body`` (after ``mj_forward`` or a step).

    Args:
        model: The model.
        data: The data (contacts, kinematics and ``qvel``).
        pads: Geom ids of each finger's pads, one array per finger.
        body: Body id of the object.

    Returns:
        The :class:`FingerContacts` of the ``len(pads)`` fingers.
    """
    k = len(pads)
    position = np.zeros((k, 3))
    weights = np.zeros(k)
    normal = np.zeros((k, 3))
    fn = np.zeros(k)
    tangent = np.zeros((k, 3))
    count = np.zeros(k, dtype=int)
    plain = np.zeros((k, 3))
    wrench = np.zeros(6)
    pad_body = np.full(k, -1)
    if data.ncon:
        finger_of = np.full(model.ngeom, -1)
        for i, geoms in enumerate(pads):
            finger_of[geoms] = i
        g1, g2 = data.contact.geom1, data.contact.geom2
        finger1 = np.where(model.geom_bodyid[g2] == body, finger_of[g1], -1)
        finger2 = np.where(model.geom_bodyid[g1] == body, finger_of[g2], -1)
        frames, points = data.contact.frame, data.contact.pos
        for c in np.flatnonzero((finger1 >= 0) | (finger2 >= 0)):
            sign = 1.0 if finger1[c] >= 0 else -1.0
            i = int(finger1[c] if sign > 0 else finger2[c])
            mujoco.mj_contactForce(model, data, int(c), wrench)
            frame = frames[c].reshape(3, 3)
            pad_body[i] = model.geom_bodyid[g1[c] if sign > 0 else g2[c]]
            f_n = max(float(wrench[0]), 0.0)
            normal[i] += sign * frame[0]
            position[i] += f_n * points[c]
            plain[i] += points[c]
            weights[i] += f_n
            fn[i] += f_n
            tangent[i] += sign * (wrench[1] * frame[1] + wrench[2] * frame[2])
            count[i] += 1
    touching = count > 0
    slip = np.zeros(k)
    jac_a, jac_b = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for i in np.flatnonzero(touching):
        normal[i] /= max(np.linalg.norm(normal[i]), 1e-12)
        position[i] = position[i] / weights[i] if weights[i] > 1e-9 else plain[i] / count[i]
        mujoco.mj_jac(model, data, jac_a, None, position[i], body)
        mujoco.mj_jac(model, data, jac_b, None, position[i], int(pad_body[i]))
        v = (jac_a - jac_b) @ data.qvel
        slip[i] = np.linalg.norm(v - (v @ normal[i]) * normal[i])
    ft = np.linalg.norm(tangent, axis=1)
    return FingerContacts(touching, position, normal, fn, ft, slip, count)
