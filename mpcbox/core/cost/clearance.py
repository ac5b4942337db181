r"""Clearance from a spherical obstacle: a hinge on the distance of frames to its centre.

For frames :math:`p_i(q)` (sites or bodies) and a sphere of centre :math:`c` and radius
:math:`\rho` (the obstacle's radius plus a safety margin), one residual per frame

.. math::
    r_i = \max(0,\ \rho - \lVert p_i - c \rVert),

zero outside the sphere and growing linearly with the depth inside it, so
:math:`\tfrac12 w r_i^2` is a smooth (:math:`C^1`) barrier. Its Jacobian inside is
:math:`-n_i^T J_i` with :math:`n_i = (p_i - c) / \lVert p_i - c \rVert` and :math:`J_i` the
frame's translational Jacobian.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian, SensorRequest
from mpcbox.core.cost.frames import frame_sensor, point_jacobian
from mpcbox.core.model import frame_position
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import checked_options, finite_array, positive


class SphereClearance(CostTerm):
    r"""Keep frames out of a sphere: ``r_i = max(0, radius - |p_i - center|)``.

    Args:
        frames: Site or body names whose origins must stay clear.
        center: Centre of the sphere ``(3,)`` in the world frame (m).
        radius: Radius :math:`\rho` (m) the frames must keep from the centre: the
            obstacle's radius plus a margin.
        weight: Scalar or per-frame weights.
        name: Short label used in sensor names and reports.
    """

    stage = "pos"

    @checked_options
    def __init__(
        self,
        frames: Sequence[str],
        center: np.ndarray,
        radius: float,
        *,
        weight: float | np.ndarray,
        name: str = "clearance",
    ) -> None:
        super().__init__(weight, name)
        if isinstance(frames, str) or not frames or not all(isinstance(f, str) for f in frames):
            raise InvalidArgumentError(
                f"frames must be a non-empty sequence of site or body names, got {frames!r}"
            )
        self.frames = tuple(frames)
        self.center = finite_array("center", center, (3,))
        self.radius = positive("radius", radius)

    def size(self, model: mujoco.MjModel) -> int:
        return len(self.frames)

    def _sensor(self, i: int) -> str:
        return f"mpcbox_{self.name}_{i}"

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        out = []
        for i, frame in enumerate(self.frames):
            objtype, objname = frame_sensor(model, frame, "frames")
            out.append(
                SensorRequest(self._sensor(i), mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname)
            )
        return out

    def residual(self, features: Features) -> np.ndarray:
        cols = [
            np.linalg.norm(self.sensor_slice(features, self._sensor(i)) - self.center, axis=-1)
            for i in range(len(self.frames))
        ]
        return np.maximum(0.0, self.radius - np.stack(cols, axis=-1))

    def distances(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """Distances ``(n,)`` (m) of the frames from the centre at the state in ``data``."""
        return np.array(
            [np.linalg.norm(frame_position(model, data, f) - self.center) for f in self.frames]
        )

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jq = np.zeros((len(self.frames), model.nv))
        for i, frame in enumerate(self.frames):
            offset = frame_position(model, data, frame) - self.center
            distance = float(np.linalg.norm(offset))
            if 0.0 < distance < self.radius:
                jq[i] = -(offset / distance) @ point_jacobian(model, data, frame)
        nf = len(self.frames)
        return Jacobian(jq, np.zeros((nf, model.nv)), np.zeros((nf, model.nu)))


__all__ = ["SphereClearance"]
