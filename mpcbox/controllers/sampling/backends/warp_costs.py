r"""The Problem's cost terms as Warp kernels, one thread per world.

Every term with a row form (:meth:`mpcbox.core.cost.CostTerm.rows`) is a sum of elementary
rows (:mod:`mpcbox.core.cost.rows`), each contributing :math:`\tfrac12 w r^2`. The rows of a
set of terms are gathered into *row tables*, one per row kind:

* position rows ``(i, ref, w)``: :math:`r = q_i - \mathrm{ref}` (hinge, slide, free-joint
  translation);
* quaternion rows ``(a, q_{ref}, w_{1:3})``: :math:`r = \log(q_{ref}^{-1} q_{a:a+4})`, the
  rotation vector of :func:`mpcbox.core.tangent.quat_difference` (angle wrapped to
  :math:`(-\pi, \pi]`);
* velocity rows ``(i, ref, w)``: :math:`r = v_i - \mathrm{ref}`;
* control rows ``(i, ref, w)``: :math:`r = u_i - \mathrm{ref}`;
* wrapped-angle rows ``(i, ref, w)``: :math:`r = 2 \sin((q_i - \mathrm{ref}) / 2)`;
* sensor rows ``(a, b, c, w)``: :math:`r = s_a - s_b - c` (:math:`s_b = 0` when ``b < 0``);
  the sensors are in MJWarp's ``Data.sensordata`` at the same addresses as on the CPU.

A term without a row form raises :class:`~mpcbox.errors.UnsupportedCostTermError`. Rows with
zero weight are dropped.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import warp as wp

from mpcbox.core.cost import CostTerm
from mpcbox.core.cost.rows import ROW_KINDS, QuadraticFormRow

# Nothing here is differentiated, so no adjoint (backward) code is generated.
wp.set_module_options({"enable_backward": False})


class RowTables(NamedTuple):
    """Host-side row tables of one set of cost terms (see the module docstring).

    Attributes:
        q_idx, q_ref, q_w: Position rows ``(nq_rows,)``.
        quat_adr, quat_ref, quat_w: Quaternion rows ``(n,)``, ``(n, 4)``, ``(n, 3)``.
        v_idx, v_ref, v_w: Velocity rows.
        u_idx, u_ref, u_w: Control rows.
        a_idx, a_ref, a_w: Wrapped-angle rows.
        s_a, s_b, s_c, s_w: Sensor rows.
        forms: Quadratic-form rows (:class:`~mpcbox.core.cost.rows.QuadraticFormRow`), each
            evaluated by its own launch (:mod:`.warp_value`).
    """

    q_idx: np.ndarray
    q_ref: np.ndarray
    q_w: np.ndarray
    quat_adr: np.ndarray
    quat_ref: np.ndarray
    quat_w: np.ndarray
    v_idx: np.ndarray
    v_ref: np.ndarray
    v_w: np.ndarray
    u_idx: np.ndarray
    u_ref: np.ndarray
    u_w: np.ndarray
    a_idx: np.ndarray
    a_ref: np.ndarray
    a_w: np.ndarray
    s_a: np.ndarray
    s_b: np.ndarray
    s_c: np.ndarray
    s_w: np.ndarray
    forms: tuple = ()

    @property
    def has_sensors(self) -> bool:
        """Whether any row reads ``sensordata``."""
        return self.s_a.size > 0


def build_rows(terms: Sequence[CostTerm]) -> RowTables:
    """Gather the rows of bound cost terms into row tables.

    Args:
        terms: Bound terms (running or terminal) of a Problem's cost.

    Raises:
        UnsupportedCostTermError: For a term without a row form.
    """
    groups: dict[type, list[tuple]] = {kind: [] for kind in ROW_KINDS}
    for term in terms:
        for row in term.rows():
            groups[type(row)].append(tuple(row))
    q, quat, v, u, a, s, forms = (_nonzero(groups[kind]) for kind in ROW_KINDS)
    i32 = lambda rows, i: np.array([r[i] for r in rows], dtype=np.int32)  # noqa: E731
    f32 = lambda rows, i, *shape: np.array(  # noqa: E731
        [r[i] for r in rows], dtype=np.float32
    ).reshape(-1, *shape)
    return RowTables(
        i32(q, 0), f32(q, 1), f32(q, 2),
        i32(quat, 0), f32(quat, 1, 4), f32(quat, 2, 3),
        i32(v, 0), f32(v, 1), f32(v, 2),
        i32(u, 0), f32(u, 1), f32(u, 2),
        i32(a, 0), f32(a, 1), f32(a, 2),
        i32(s, 0), i32(s, 1), f32(s, 2), f32(s, 3),
        tuple(QuadraticFormRow(*f) for f in forms),
    )  # fmt: skip


def _nonzero(rows: list[tuple]) -> list[tuple]:
    return [r for r in rows if np.any(np.asarray(r[-1]) != 0.0)]


@wp.struct
class RowArrays:
    """The row tables of :class:`RowTables` on a device, as one kernel argument. The control
    rows are dense, one per actuator (weight 0 where there is no row), so that thread
    ``j < nu`` of :func:`fused_stage_kernel` owns actuator ``j``."""

    u_ref: wp.array[float]
    u_w: wp.array[float]
    q_idx: wp.array[wp.int32]
    q_ref: wp.array[float]
    q_w: wp.array[float]
    quat_adr: wp.array[wp.int32]
    quat_ref: wp.array[wp.vec4]
    quat_w: wp.array[wp.vec3]
    v_idx: wp.array[wp.int32]
    v_ref: wp.array[float]
    v_w: wp.array[float]
    a_idx: wp.array[wp.int32]
    a_ref: wp.array[float]
    a_w: wp.array[float]
    s_a: wp.array[wp.int32]
    s_b: wp.array[wp.int32]
    s_c: wp.array[float]
    s_w: wp.array[float]


class DeviceRows:
    """Row tables on a Warp device.

    Attributes:
        arrays: The rows (:class:`RowArrays`).
        has_state, has_sensors: Whether any state/control or sensor row exists.
        num_state_rows, num_sensor_rows: Rows handled by one thread each in
            :func:`fused_stage_kernel` (besides the controls).
    """

    def __init__(self, rows: RowTables, device: str, nu_hint: int = 0) -> None:
        self.has_sensors = rows.has_sensors
        self.has_state = any(
            getattr(rows, f).size for f in ("q_idx", "quat_adr", "v_idx", "u_idx", "a_idx")
        )
        self.arrays = RowArrays()
        for field in RowTables._fields:
            if field.startswith("u_") or field == "forms":  # dense, below; warp_value
                continue
            arr = getattr(rows, field)
            if field == "quat_ref":
                dev = wp.array(arr.reshape(-1, 4), dtype=wp.vec4, device=device)
            elif field == "quat_w":
                dev = wp.array(arr.reshape(-1, 3), dtype=wp.vec3, device=device)
            elif arr.dtype == np.int32:
                dev = wp.array(arr, dtype=wp.int32, device=device)
            else:
                dev = wp.array(arr, dtype=wp.float32, device=device)
            setattr(self.arrays, field, dev)
        nu = int(rows.u_idx.max()) + 1 if rows.u_idx.size else 0
        nu = max(nu, int(nu_hint))
        u_ref = np.zeros(nu, dtype=np.float32)
        u_w = np.zeros(nu, dtype=np.float32)
        u_ref[rows.u_idx] = rows.u_ref
        u_w[rows.u_idx] = rows.u_w
        self.arrays.u_ref = wp.array(u_ref, dtype=wp.float32, device=device)
        self.arrays.u_w = wp.array(u_w, dtype=wp.float32, device=device)
        self.num_state_rows = int(
            rows.q_idx.size + rows.quat_adr.size + rows.v_idx.size + rows.a_idx.size
        )
        self.num_sensor_rows = int(rows.s_a.size)


@wp.func
def quat_log_difference(q: wp.vec4, ref: wp.vec4) -> wp.vec3:
    """Rotation vector of ``ref^-1 q`` with the angle wrapped to (-pi, pi] (wxyz order)."""
    aw, ax, ay, az = ref[0], -ref[1], -ref[2], -ref[3]
    bw, bx, by, bz = q[0], q[1], q[2], q[3]
    w = aw * bw - ax * bx - ay * by - az * bz
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    norm = wp.sqrt(w * w + x * x + y * y + z * z)
    w = w / norm
    x = x / norm
    y = y / norm
    z = z / norm
    s = wp.sqrt(x * x + y * y + z * z)
    angle = 2.0 * wp.atan2(s, w)
    if angle > wp.pi:
        angle = angle - 2.0 * wp.pi
    scale = float(2.0)  # noqa: UP018 - dynamic variable in Warp
    if s > 1.0e-15:
        scale = angle / s
    return wp.vec3(x * scale, y * scale, z * scale)


#: MuJoCo's ``mjMAXVAL``: a ``qpos``, ``qvel`` or ``qacc`` entry beyond it makes MuJoCo warn
#: and reset, and :func:`mujoco.rollout` return NaN; MJWarp does not check, so the kernels do.
MAX_VALUE = wp.constant(1.0e10)

#: Bits of the per-world flags.
FLAG_CAPACITY = wp.constant(1)
FLAG_DIVERGED = wp.constant(2)
FLAG_SOLVER_LIMIT = wp.constant(4)


@wp.kernel
def broadcast_kernel(
    state: wp.array[float],
    nq: int,
    nv: int,
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    act: wp.array2d[float],
    time: wp.array[float],
    qacc_warmstart: wp.array2d[float],
    overflow: wp.array[int],
    cost: wp.array[float],
    flags: wp.array[wp.int32],
):
    """Start of a tick: every world gets the measured state; clear costs and flags."""
    world = wp.tid()
    for i in range(nq):
        qpos[world, i] = state[i]
    for i in range(nv):
        qvel[world, i] = state[nq + i]
        qacc_warmstart[world, i] = 0.0
    for i in range(act.shape[1]):
        act[world, i] = state[nq + nv + i]
    time[world] = 0.0
    overflow[world] = 0
    cost[world] = 0.0
    flags[world] = wp.int32(0)


@wp.func
def diverged(world: int, values: wp.array2d[float]) -> bool:
    """Whether a row of ``values`` holds a non-finite entry or one beyond :data:`MAX_VALUE`."""
    for i in range(values.shape[1]):
        x = values[world, i]
        if not wp.isfinite(x) or wp.abs(x) > MAX_VALUE:
            return True
    return False


@wp.kernel
def finalize_kernel(
    cost: wp.array[float],
    overflow: wp.array[int],
    capacity_mask: int,
    solver_mask: int,
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    qacc: wp.array2d[float],
    flags: wp.array[wp.int32],
):
    """Per-world flags (:data:`FLAG_CAPACITY`, :data:`FLAG_DIVERGED`, :data:`FLAG_SOLVER_LIMIT`):
    adds to the divergence bit set during the horizon by :func:`fused_stage_kernel`."""
    world = wp.tid()
    f = int(flags[world])
    if (overflow[world] & capacity_mask) != 0:
        f = f | FLAG_CAPACITY
    if (overflow[world] & solver_mask) != 0:
        f = f | FLAG_SOLVER_LIMIT
    if (
        not wp.isfinite(cost[world])
        or diverged(world, qpos)
        or diverged(world, qvel)
        or diverged(world, qacc)
    ):
        f = f | FLAG_DIVERGED
    flags[world] = wp.int32(f)


@wp.func
def row_cost(
    world: int,
    row: int,
    with_state: int,
    with_sensors: int,
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    sensordata: wp.array2d[float],
    rows: RowArrays,
) -> float:
    """``0.5 w r^2`` of one row: position, quaternion, velocity, wrapped-angle or sensor rows
    in this order (``row`` indexes their concatenation; rows of a disabled group give 0)."""
    i = row
    n = rows.q_idx.shape[0]
    if i < n:
        if with_state == 0:
            return 0.0
        r = qpos[world, rows.q_idx[i]] - rows.q_ref[i]
        return 0.5 * rows.q_w[i] * r * r
    i -= n
    n = rows.quat_adr.shape[0]
    if i < n:
        if with_state == 0:
            return 0.0
        a = rows.quat_adr[i]
        q = wp.vec4(qpos[world, a], qpos[world, a + 1], qpos[world, a + 2], qpos[world, a + 3])
        d = quat_log_difference(q, rows.quat_ref[i])
        ww = rows.quat_w[i]
        return 0.5 * (ww[0] * d[0] * d[0] + ww[1] * d[1] * d[1] + ww[2] * d[2] * d[2])
    i -= n
    n = rows.v_idx.shape[0]
    if i < n:
        if with_state == 0:
            return 0.0
        r = qvel[world, rows.v_idx[i]] - rows.v_ref[i]
        return 0.5 * rows.v_w[i] * r * r
    i -= n
    n = rows.a_idx.shape[0]
    if i < n:
        if with_state == 0:
            return 0.0
        r = 2.0 * wp.sin(0.5 * (qpos[world, rows.a_idx[i]] - rows.a_ref[i]))
        return 0.5 * rows.a_w[i] * r * r
    i -= n
    n = rows.s_a.shape[0]
    if i < n:
        if with_sensors == 0:
            return 0.0
        r = sensordata[world, rows.s_a[i]] - rows.s_c[i]
        b = rows.s_b[i]
        if b >= 0:
            r = r - sensordata[world, b]
        return 0.5 * rows.s_w[i] * r * r
    return 0.0


@wp.kernel
def fused_stage_kernel(
    step: int,
    per_candidate: int,
    with_state: int,
    with_sensors: int,
    weights: wp.array2d[float],
    knots: wp.array3d[float],
    ctrl_low: wp.array[float],
    ctrl_high: wp.array[float],
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    qacc: wp.array2d[float],
    sensordata: wp.array2d[float],
    rows: RowArrays,
    ctrl: wp.array2d[float],
    cost: wp.array[float],
    flags: wp.array[wp.int32],
):
    """One launch per planning step, one thread per (world, actuator or cost row).

    Before step ``t``: thread ``j < nu`` interpolates, clamps and writes :math:`u_{t,j}` and
    its control row; the other threads add one state row at :math:`x_t` (``with_state``)
    or one sensor row of the previous step (``with_sensors``: ``sensordata`` still holds
    the values MJWarp computed at :math:`x_{t-1}` inside step ``t - 1``). Thread 0 also
    checks the accelerations of step ``t - 1`` as MuJoCo does after each step, setting
    :data:`FLAG_DIVERGED` (a diverging rollout can come back to finite, huge states).
    """
    world, j = wp.tid()
    nu = ctrl.shape[1]
    if j == 0 and step > 0 and diverged(world, qacc):
        flags[world] = flags[world] | wp.int32(FLAG_DIVERGED)
    acc = float(0.0)  # noqa: UP018 - dynamic variable in Warp
    if j < nu:
        if step < weights.shape[0]:
            cand = world // per_candidate
            u = float(0.0)  # noqa: UP018 - dynamic variable in Warp
            for k in range(weights.shape[1]):
                u += weights[step, k] * knots[cand, k, j]
            u = wp.clamp(u, ctrl_low[j], ctrl_high[j])
            ctrl[world, j] = u
            if with_state != 0:
                r = u - rows.u_ref[j]
                acc = 0.5 * rows.u_w[j] * r * r
    else:
        acc = row_cost(world, j - nu, with_state, with_sensors, qpos, qvel, sensordata, rows)
    if acc != 0.0:
        wp.atomic_add(cost, world, acc)


@wp.kernel
def terminal_kernel(
    with_state: int,
    with_sensors: int,
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    sensordata: wp.array2d[float],
    rows: RowArrays,
    ctrl: wp.array2d[float],
    cost: wp.array[float],
):
    """Terminal rows at :math:`x_T`, one thread per world: the control rows (with the last
    control) and the state rows (``with_state``), the sensor rows (``with_sensors``, after
    ``mjw.forward``), each through :func:`row_cost`."""
    world = wp.tid()
    acc = float(0.0)  # noqa: UP018 - dynamic variable in Warp
    if with_state != 0:
        for j in range(rows.u_w.shape[0]):
            r = ctrl[world, j] - rows.u_ref[j]
            acc += 0.5 * rows.u_w[j] * r * r
    n = (
        rows.q_idx.shape[0]
        + rows.quat_adr.shape[0]
        + rows.v_idx.shape[0]
        + rows.a_idx.shape[0]
        + rows.s_a.shape[0]
    )
    for i in range(n):
        acc += row_cost(world, i, with_state, with_sensors, qpos, qvel, sensordata, rows)
    cost[world] += acc
