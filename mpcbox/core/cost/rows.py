r"""Elementary residual rows: the form of a cost term that the GPU cost kernels evaluate.

A term with a row form (:meth:`~mpcbox.core.cost.CostTerm.rows`) is the sum of its rows'
:math:`\tfrac12 w r^2`, each row reading one or two numbers of the state, the control or
``sensordata`` (a :class:`QuadraticFormRow` reads the whole state). The kinds below are the
whole vocabulary of :mod:`mpcbox.controllers.sampling.backends.warp_costs` and
:mod:`~mpcbox.controllers.sampling.backends.warp_value`; the weight is always the last field.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PositionRow(NamedTuple):
    """:math:`r = q_i - \\mathrm{ref}` (hinge, slide, free-joint translation).

    Attributes:
        index: Address ``i`` in ``qpos``.
        ref: Reference position.
        weight: Weight ``w``.
    """

    index: int
    ref: float
    weight: float


class QuaternionRow(NamedTuple):
    r""":math:`r = \log(q_{ref}^{-1} q_{a:a+4})`, the rotation vector of
    :func:`mpcbox.core.tangent.quat_difference` (angle wrapped to :math:`(-\pi, \pi]`).

    Attributes:
        address: Address ``a`` of the quaternion (w, x, y, z) in ``qpos``.
        ref: Reference quaternion ``(4,)``.
        weight: Weights of the three rotation-vector components ``(3,)``.
    """

    address: int
    ref: np.ndarray
    weight: np.ndarray


class VelocityRow(NamedTuple):
    """:math:`r = v_i - \\mathrm{ref}`.

    Attributes:
        index: Address ``i`` in ``qvel``.
        ref: Reference velocity.
        weight: Weight ``w``.
    """

    index: int
    ref: float
    weight: float


class ControlRow(NamedTuple):
    """:math:`r = u_i - \\mathrm{ref}`.

    Attributes:
        index: Actuator ``i``.
        ref: Reference control.
        weight: Weight ``w``.
    """

    index: int
    ref: float
    weight: float


class AngleRow(NamedTuple):
    r""":math:`r = 2 \sin((q_i - \mathrm{ref}) / 2)`, a :math:`2\pi`-periodic angle distance.

    Attributes:
        index: Address ``i`` of a hinge angle in ``qpos``.
        ref: Target angle (rad).
        weight: Weight ``w``.
    """

    index: int
    ref: float
    weight: float


class SensorRow(NamedTuple):
    """:math:`r = s_a - s_b - c` with :math:`s_b = 0` when ``b < 0``.

    Attributes:
        a: Address in ``sensordata``.
        b: Address in ``sensordata`` subtracted, or ``-1`` for none.
        offset: Constant ``c``.
        weight: Weight ``w``.
    """

    a: int
    b: int
    offset: float
    weight: float


class QuadraticFormRow(NamedTuple):
    r""":math:`r = F^T dx`, a vector of residuals linear in the whole tangent-space state
    deviation :math:`dx = (q \ominus q_{ref},\ v - v_{ref})` (the form of
    :class:`~mpcbox.core.cost.QuadraticValue`, :math:`\tfrac12 w \|F^T dx\|^2`).

    Attributes:
        scalar_qpos, scalar_dof: ``qpos`` and dof addresses of the coordinates differenced as
            plain numbers ``(n_s,)`` (:attr:`~mpcbox.core.tangent.TangentSpace.scalar_addresses`).
        quat_qpos, quat_dof: Addresses of the quaternions ``(n_b,)``, differenced as rotation
            vectors like :class:`QuaternionRow`.
        qpos_ref: Reference positions ``(nq,)``.
        qvel_ref: Reference velocities ``(nv,)``.
        factor: ``F`` ``(2 nv, m)``.
        weight: Weight ``w``.
    """

    scalar_qpos: np.ndarray
    scalar_dof: np.ndarray
    quat_qpos: np.ndarray
    quat_dof: np.ndarray
    qpos_ref: np.ndarray
    qvel_ref: np.ndarray
    factor: np.ndarray
    weight: float


#: One row of any kind.
Row = (
    PositionRow | QuaternionRow | VelocityRow | ControlRow | AngleRow | SensorRow | QuadraticFormRow
)

#: The row kinds, in the order the GPU kernels store them.
ROW_KINDS: tuple[type, ...] = (
    PositionRow,
    QuaternionRow,
    VelocityRow,
    ControlRow,
    AngleRow,
    SensorRow,
    QuadraticFormRow,
)
