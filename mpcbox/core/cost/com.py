"""Center of mass: over a support point, and its horizontal velocity."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian, SensorRequest
from mpcbox.core.cost.frames import frame_sensor, point_jacobian
from mpcbox.core.cost.rows import Row, SensorRow
from mpcbox.core.model import object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import checked_options, finite_array, string


class _SubtreeTerm(CostTerm):
    """Base of the terms on the center of mass of a body's subtree: two horizontal
    residuals, and the subtree sensor they read."""

    def __init__(self, weight: float | np.ndarray, name: str, root: str | None) -> None:
        super().__init__(weight, name)
        self.root = None if root is None else string("root", root)

    def _root(self, model: mujoco.MjModel) -> str:
        """``root``, or body 1 (the first body after the world) when it is ``None``."""
        if self.root is not None:
            return self.root
        if model.nbody < 2:
            raise InvalidArgumentError(f"{self.name}: the model has no body but the world")
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, 1)
        if not name:
            raise InvalidArgumentError(
                f"{self.name}: root defaults to the model's first body, which has no name; "
                "name it in the MJCF or give root=<a body name>"
            )
        return name

    def size(self, model: mujoco.MjModel) -> int:
        return 2

    def _subtree_sensor(
        self, model: mujoco.MjModel, kind: mujoco.mjtSensor, name: str
    ) -> SensorRequest:
        """A subtree sensor of type ``kind`` on the root, which must exist."""
        root = self._root(model)
        object_id(model, "body", root, "root")
        return SensorRequest(name, kind, mujoco.mjtObj.mjOBJ_BODY, root)


class ComOverSupport(_SubtreeTerm):
    """Horizontal distance of a subtree's center of mass from a support point.

    ``r = com_xy(root) - p_xy(support)``: zero when the center of mass is above the support
    (for example a stance foot).

    Args:
        support: Site or body name of the support point.
        weight: Scalar or ``(2,)`` weights.
        root: Body whose subtree center of mass is used (default: body 1, the first body).
        name: Short label used in sensor names and reports.
    """

    stage = "pos"

    @checked_options
    def __init__(
        self,
        support: str,
        *,
        weight: float | np.ndarray,
        root: str | None = None,
        offset: Sequence[float] | np.ndarray = (0.0, 0.0),
        name: str = "",
    ) -> None:
        super().__init__(weight, name or f"com_over_{support}", root)
        self.support = support
        self.offset = finite_array("offset", offset, (2,))

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        com = self._subtree_sensor(
            model, mujoco.mjtSensor.mjSENS_SUBTREECOM, f"mpcbox_{self.name}_com"
        )
        objtype, objname = frame_sensor(model, self.support, "support")
        return (
            com,
            SensorRequest(
                f"mpcbox_{self.name}_support", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        com = self.sensor_slice(features, f"mpcbox_{self.name}_com")
        foot = self.sensor_slice(features, f"mpcbox_{self.name}_support")
        return com[:, :2] - foot[:, :2] - self.offset

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jac_com = np.zeros((3, model.nv))
        mujoco.mj_jacSubtreeCom(model, data, jac_com, object_id(model, "body", self._root(model)))
        jq = (jac_com - point_jacobian(model, data, self.support))[:2]
        return Jacobian(jq, np.zeros((2, model.nv)), np.zeros((2, model.nu)))

    def rows(self) -> list[Row]:
        """Sensor rows ``com_i - support_i - offset_i`` for ``i = x, y``."""
        com = self.sensor_address(f"mpcbox_{self.name}_com").start
        foot = self.sensor_address(f"mpcbox_{self.name}_support").start
        return [
            SensorRow(com + i, foot + i, float(self.offset[i]), self.weight[i]) for i in range(2)
        ]


class ComVelocity(_SubtreeTerm):
    r"""Horizontal velocity of a subtree's center of mass: :math:`r = \dot c_{xy}`.

    Damps the drift of the whole body (MJPC's humanoid tasks weigh it beside the balance
    of the center of mass over the feet).

    Args:
        weight: Scalar or ``(2,)`` weights.
        root: Body whose subtree's center of mass is used (default: body 1, the first body).
        name: Short label used in sensor names and reports.
    """

    stage = "vel"

    @checked_options
    def __init__(
        self, *, weight: float | np.ndarray, root: str | None = None, name: str = ""
    ) -> None:
        super().__init__(weight, name or "com_velocity", root)

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        kind = mujoco.mjtSensor.mjSENS_SUBTREELINVEL
        return (self._subtree_sensor(model, kind, f"mpcbox_{self.name}"),)

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, :2]

    def rows(self) -> list[Row]:
        """Sensor rows on the x and y components of the velocity."""
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        return [SensorRow(adr + i, -1, 0.0, self.weight[i]) for i in range(2)]
