r"""Quadratic forms in the whole state as a Warp kernel (the terminal LQR value on the GPU).

A :class:`~mpcbox.core.cost.rows.QuadraticFormRow` contributes
:math:`\tfrac12 w \|F^T dx\|^2` with :math:`dx = (q \ominus q_{ref},\ v - v_{ref})` the
tangent-space deviation of the state (``2 nv``). One thread per (world, column of
:math:`F`) forms :math:`dx` block by block (plain differences and quaternion rotation vectors,
as :func:`~mpcbox.controllers.sampling.backends.warp_costs.quat_log_difference`) and adds
its residual's square to the world's cost.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import warp as wp

from mpcbox.controllers.sampling.backends.warp_costs import quat_log_difference
from mpcbox.core.cost.rows import QuadraticFormRow

wp.set_module_options({"enable_backward": False})


def _ints(values: np.ndarray, device: str) -> wp.array:
    return wp.array(np.asarray(values, dtype=np.int32), dtype=wp.int32, device=device)


def _floats(values: np.ndarray, device: str) -> wp.array:
    return wp.array(np.ascontiguousarray(values, dtype=np.float32), dtype=wp.float32, device=device)


class DeviceForm:
    """One quadratic-form row on a Warp device.

    Attributes:
        columns: Columns ``m`` of the factor (threads per world).
    """

    def __init__(self, form: QuadraticFormRow, device: str) -> None:
        self.columns = int(form.factor.shape[1])
        self.scalar_qpos = _ints(form.scalar_qpos, device)
        self.scalar_dof = _ints(form.scalar_dof, device)
        self.quat_qpos = _ints(form.quat_qpos, device)
        self.quat_dof = _ints(form.quat_dof, device)
        self.qpos_ref = _floats(form.qpos_ref, device)
        self.qvel_ref = _floats(form.qvel_ref, device)
        self.factor = _floats(form.factor, device)
        self.weight = float(form.weight)

    def launch(self, nworld: int, qpos: wp.array, qvel: wp.array, cost: wp.array) -> None:
        """Add the form's cost at the worlds' current state to ``cost`` ``(nworld,)``."""
        wp.launch(
            quadratic_form_kernel,
            dim=(nworld, self.columns),
            inputs=[
                qpos, qvel, self.scalar_qpos, self.scalar_dof, self.quat_qpos, self.quat_dof,
                self.qpos_ref, self.qvel_ref, self.factor, self.weight,
            ],
            outputs=[cost],
        )  # fmt: skip


def device_forms(forms: Sequence[QuadraticFormRow], device: str) -> list[DeviceForm]:
    """The forms of a row table on ``device``."""
    return [DeviceForm(form, device) for form in forms]


@wp.kernel
def quadratic_form_kernel(
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    scalar_qpos: wp.array[wp.int32],
    scalar_dof: wp.array[wp.int32],
    quat_qpos: wp.array[wp.int32],
    quat_dof: wp.array[wp.int32],
    qpos_ref: wp.array[float],
    qvel_ref: wp.array[float],
    factor: wp.array2d[float],
    weight: float,
    cost: wp.array[float],
):
    """Thread ``(world, k)``: :math:`r_k = F_{:,k}^T dx`, adds :math:`\\tfrac12 w r_k^2`."""
    world, k = wp.tid()
    nv = qvel.shape[1]
    r = float(0.0)  # noqa: UP018 - dynamic variable in Warp
    for i in range(scalar_qpos.shape[0]):
        a = scalar_qpos[i]
        r += factor[scalar_dof[i], k] * (qpos[world, a] - qpos_ref[a])
    for i in range(quat_qpos.shape[0]):
        a = quat_qpos[i]
        b = quat_dof[i]
        q = wp.vec4(qpos[world, a], qpos[world, a + 1], qpos[world, a + 2], qpos[world, a + 3])
        ref = wp.vec4(qpos_ref[a], qpos_ref[a + 1], qpos_ref[a + 2], qpos_ref[a + 3])
        d = quat_log_difference(q, ref)
        r += factor[b, k] * d[0] + factor[b + 1, k] * d[1] + factor[b + 2, k] * d[2]
    for i in range(nv):
        r += factor[nv + i, k] * (qvel[world, i] - qvel_ref[i])
    wp.atomic_add(cost, world, 0.5 * weight * r * r)
