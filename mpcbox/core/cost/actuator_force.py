r"""Actuator effort: the forces the actuators make, against reference forces.

One residual per actuator, :math:`r_i = f_i(x, u) - f_i^{ref}`, read from MuJoCo's
``actuatorfrc`` sensors (the force after gains, biases and the force range). Unlike a cost on
the control itself, this is the actual effort whatever the actuator: a motor's torque, or a
position servo's :math:`k_p (u - q) - k_v \dot q` rather than its set-point.

For stateless affine actuators (``force = g u + b_0 + b_1 L + b_2 \dot L`` with transmission
length :math:`L`, moment :math:`m_i = \partial L / \partial q`) the Jacobian is analytic,

.. math::
    \partial r_i / \partial u_i = g_i, \qquad \partial r_i / \partial q = b_{1,i}\, m_i,
    \qquad \partial r_i / \partial \dot q = b_{2,i}\, m_i,

and zero where the force sits at its range's limit. Other actuators (activation dynamics,
muscles, several outputs) leave the Jacobian to finite differences.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.actuation import actuator_moment
from mpcbox.core.cost.base import CostTerm, Features, Jacobian, SensorRequest
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, checked_options, finite_array

_AFFINE_BIAS = (int(mujoco.mjtBias.mjBIAS_NONE), int(mujoco.mjtBias.mjBIAS_AFFINE))


class ActuatorForce(CostTerm):
    """Actuator forces against reference forces: ``r = f - f_ref``, one row per actuator.

    The actuators must have names (the sensors refer to them by name).

    Args:
        force_ref: Reference forces ``(nu,)``; zeros by default.
        weight: Scalar or ``(nu,)`` weights (per squared N or N m of actuator force).
        name: Short label used in sensor names and reports.
    """

    @checked_options
    def __init__(
        self,
        force_ref: np.ndarray | None = None,
        *,
        weight: float | np.ndarray,
        name: str = "actuator_force",
    ) -> None:
        super().__init__(weight, name)
        self.force_ref = (
            None if force_ref is None else finite_array("force_ref", force_ref, (None,))
        )
        self._analytic = False

    def size(self, model: mujoco.MjModel) -> int:
        return model.nu

    def _sensor(self, i: int) -> str:
        return f"mpcbox_{self.name}_{i}"

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
        unnamed = [i for i, name in enumerate(names) if not name]
        if unnamed:
            raise InvalidArgumentError(
                f"cost term {self.name!r} (ActuatorForce) reads actuatorfrc sensors, which need "
                f"named actuators; actuators {unnamed} have no name"
            )
        out = []
        for i, actuator in enumerate(names):
            out.append(
                SensorRequest(
                    self._sensor(i),
                    mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                    mujoco.mjtObj.mjOBJ_ACTUATOR,
                    actuator,
                )
            )
        return out

    def bind(self, model: mujoco.MjModel) -> None:
        if self.force_ref is None:
            self.force_ref = np.zeros(model.nu)
        as_array(f"{self.name}.force_ref", self.force_ref, (model.nu,))
        nout = int(getattr(model, "nout", model.nu))
        self._analytic = nout == model.nu and all(
            int(model.actuator_dyntype[i]) == int(mujoco.mjtDyn.mjDYN_NONE)
            and int(model.actuator_gaintype[i]) == int(mujoco.mjtGain.mjGAIN_FIXED)
            and int(model.actuator_biastype[i]) in _AFFINE_BIAS
            for i in range(model.nu)
        )
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        cols = [self.sensor_slice(features, self._sensor(i))[:, 0] for i in range(len(self.weight))]
        return np.stack(cols, axis=-1) - self.force_ref

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian | None:
        """Analytic for stateless affine actuators (module docstring), else ``None``."""
        if not self._analytic:
            return None
        moment = actuator_moment(model, data)
        gain = model.actuator_gainprm[:, 0].copy()
        b1 = model.actuator_biasprm[:, 1] * (model.actuator_biastype != 0)
        b2 = model.actuator_biasprm[:, 2] * (model.actuator_biastype != 0)
        free = np.ones(model.nu)
        limited = model.actuator_forcelimited.astype(bool)
        low, high = model.actuator_forcerange[:, 0], model.actuator_forcerange[:, 1]
        force = data.actuator_force
        free[limited & ((force <= low + 1e-12) | (force >= high - 1e-12))] = 0.0
        clamped = model.actuator_ctrllimited.astype(bool) & (
            (data.ctrl < model.actuator_ctrlrange[:, 0])
            | (data.ctrl > model.actuator_ctrlrange[:, 1])
        )
        du = np.diag(free * gain * ~clamped)
        return Jacobian((free * b1)[:, None] * moment, (free * b2)[:, None] * moment, du)


__all__ = ["ActuatorForce"]
