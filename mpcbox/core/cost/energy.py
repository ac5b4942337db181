"""Total mechanical energy against a target: the energy-shaping term of swing-ups."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.cost.base import CostTerm, Features, SensorRequest
from mpcbox.validation import checked_options, finite


class Energy(CostTerm):
    r"""Total mechanical energy's distance from a target: :math:`r = T(q, v) + U(q) - E^*`.

    :math:`T` and :math:`U` are MuJoCo's kinetic and potential energy (``e_kinetic`` and
    ``e_potential`` sensors, computed whatever ``mjENBL_ENERGY`` says; the potential includes
    gravity and springs), in joules. With :math:`E^*` the energy of an upright at rest, the
    term pumps an underactuated chain's energy toward the level from which it can coast up,
    the classic energy-shaping swing-up, where a cost on the distance to the goal alone has a
    local minimum (one link up and the other hanging).

    Args:
        target: :math:`E^*` (J), for example :func:`rest_energy` of the goal posture.
        weight: Scalar weight ``w`` (per J squared).
        name: Short label used in sensor names and reports.
    """

    @checked_options
    def __init__(self, target: float, *, weight: float, name: str = "energy") -> None:
        super().__init__(weight, name)
        self.target = finite("target", target)

    def size(self, model: mujoco.MjModel) -> int:
        return 1

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        none = mujoco.mjtObj.mjOBJ_UNKNOWN
        return (
            SensorRequest(
                f"mpcbox_{self.name}_kinetic", mujoco.mjtSensor.mjSENS_E_KINETIC, none, ""
            ),
            SensorRequest(
                f"mpcbox_{self.name}_potential", mujoco.mjtSensor.mjSENS_E_POTENTIAL, none, ""
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        kinetic = self.sensor_slice(features, f"mpcbox_{self.name}_kinetic")
        potential = self.sensor_slice(features, f"mpcbox_{self.name}_potential")
        return kinetic + potential - self.target


def rest_energy(model: mujoco.MjModel, qpos: np.ndarray) -> float:
    """MuJoCo's potential energy (J) of ``model`` at rest in posture ``qpos`` ``(nq,)``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_fwdPosition(model, data)
    mujoco.mj_energyPos(model, data)
    return float(data.energy[0])


__all__ = ["Energy", "rest_energy"]
