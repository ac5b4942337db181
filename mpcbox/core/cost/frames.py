"""Cost terms on site and body frames: position, height (absolute or above another frame)
and uprightness."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, Jacobian, SensorRequest
from mpcbox.core.cost.rows import Row, SensorRow
from mpcbox.core.model import frame_object, object_id
from mpcbox.validation import checked_options, finite, finite_array


def frame_sensor(
    model: mujoco.MjModel, name: str, argument: str = "frame"
) -> tuple[mujoco.mjtObj, str]:
    """Sensor object type and name of a site or body frame called ``name``."""
    kind, _ = frame_object(model, name, argument)
    return (mujoco.mjtObj.mjOBJ_SITE if kind == "site" else mujoco.mjtObj.mjOBJ_XBODY), name


def point_jacobian(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """Translational Jacobian ``(3, nv)`` of a site or body frame's origin."""
    kind, idx = frame_object(model, name)
    jac = np.zeros((3, model.nv))
    if kind == "site":
        mujoco.mj_jacSite(model, data, jac, None, idx)
    else:
        mujoco.mj_jacBody(model, data, jac, None, idx)
    return jac


class FramePosition(CostTerm):
    """Position of a site or body frame against a target: ``r = S (p - p_target)``.

    Args:
        frame: Site or body name.
        target: Target position ``(3,)``.
        weight: Scalar or ``(3,)`` weights; set an axis's weight to zero to ignore it.
        name: Short label used in sensor names and reports.
    """

    stage = "pos"

    @checked_options
    def __init__(
        self, frame: str, target: np.ndarray, *, weight: float | np.ndarray, name: str = ""
    ) -> None:
        super().__init__(weight, name or f"pos_{frame}")
        self.frame = frame
        self.target = finite_array("target", target, (3,))

    def size(self, model: mujoco.MjModel) -> int:
        return 3

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        objtype, objname = frame_sensor(model, self.frame)
        return (
            SensorRequest(
                f"mpcbox_{self.name}", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}") - self.target

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        return Jacobian(
            point_jacobian(model, data, self.frame),
            np.zeros((3, model.nv)),
            np.zeros((3, model.nu)),
        )

    def rows(self) -> list[Row]:
        """One sensor row per axis."""
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        return [SensorRow(adr + i, -1, self.target[i], self.weight[i]) for i in range(3)]


class FrameHeight(CostTerm):
    """Height of a site or body frame against a target: ``r = z - z_target``.

    Args:
        frame: Site or body name.
        target: Target height in meters.
        weight: Scalar weight.
        name: Short label used in sensor names and reports.
    """

    stage = "pos"

    @checked_options
    def __init__(self, frame: str, target: float, *, weight: float, name: str = "") -> None:
        super().__init__(weight, name or f"height_{frame}")
        self.frame = frame
        self.target = finite("target", target)

    def size(self, model: mujoco.MjModel) -> int:
        return 1

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        objtype, objname = frame_sensor(model, self.frame)
        return (
            SensorRequest(
                f"mpcbox_{self.name}", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, 2:3] - self.target

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jq = point_jacobian(model, data, self.frame)[2:3]
        return Jacobian(jq, np.zeros((1, model.nv)), np.zeros((1, model.nu)))

    def rows(self) -> list[Row]:
        """One sensor row on the z coordinate."""
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        return [SensorRow(adr + 2, -1, self.target, self.weight[0])]


class HeightAbove(FrameHeight):
    """Height of a frame above another against a target: ``r = z - z_base - target``.

    For example a humanoid's torso above a foot: unlike :class:`FrameHeight` it is not
    met by lifting the foot.

    Args:
        frame: Site or body name.
        base: Site or body name of the frame it is measured from.
        target: Target height difference in meters.
        weight: Scalar weight.
        name: Short label used in sensor names and reports.
    """

    @checked_options
    def __init__(
        self, frame: str, base: str, target: float, *, weight: float, name: str = ""
    ) -> None:
        super().__init__(frame, target, weight=weight, name=name or f"height_{frame}_above_{base}")
        self.base = base

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        base_type, base_name = frame_sensor(model, self.base, "base")
        return (
            *super().sensors(model),
            SensorRequest(
                f"mpcbox_{self.name}_base", mujoco.mjtSensor.mjSENS_FRAMEPOS, base_type, base_name
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        z_base = self.sensor_slice(features, f"mpcbox_{self.name}_base")[:, 2:3]
        return super().residual(features) - z_base

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jac = super().jacobian(model, data)
        jq = jac.dq - point_jacobian(model, data, self.base)[2:3]
        return jac._replace(dq=jq)

    def rows(self) -> list[Row]:
        """One sensor row: the two z coordinates' difference."""
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        base = self.sensor_address(f"mpcbox_{self.name}_base").start
        return [SensorRow(adr + 2, base + 2, self.target, self.weight[0])]


class Upright(CostTerm):
    """Tilt of a body: the horizontal components of its z axis, zero when upright.

    Args:
        body: Body name.
        weight: Scalar or ``(2,)`` weights.
        name: Short label used in sensor names and reports.
    """

    stage = "pos"

    @checked_options
    def __init__(self, body: str, *, weight: float | np.ndarray, name: str = "") -> None:
        super().__init__(weight, name or f"upright_{body}")
        self.body = body

    def size(self, model: mujoco.MjModel) -> int:
        return 2

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        object_id(model, "body", self.body)
        return (
            SensorRequest(
                f"mpcbox_{self.name}",
                mujoco.mjtSensor.mjSENS_FRAMEZAXIS,
                mujoco.mjtObj.mjOBJ_XBODY,
                self.body,
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, :2]

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        bid = object_id(model, "body", self.body)
        jacr = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, None, jacr, bid)
        z = data.xmat[bid].reshape(3, 3)[:, 2]
        skew = np.array([[0.0, -z[2], z[1]], [z[2], 0.0, -z[0]], [-z[1], z[0], 0.0]])
        jq = (-skew @ jacr)[:2]
        return Jacobian(jq, np.zeros((2, model.nv)), np.zeros((2, model.nu)))

    def rows(self) -> list[Row]:
        """Sensor rows on the x and y components of the z axis."""
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        return [SensorRow(adr + i, -1, 0.0, self.weight[i]) for i in range(2)]
