r"""The cost's sensors in one Warp kernel, in place of MJWarp's sensor pipeline.

MJWarp computes sensors inside every step through a chain of launches (position, velocity
and acceleration stages, each with kernels for contact, touch, limit, tendon and energy
sensors, launched whether or not the model has any). A sampling rollout reads only the
sensors its cost requested (:class:`~mpcbox.core.cost.SensorRequest`): frame positions and
axes, subtree centres of mass and subtree velocities. When those are all it reads, the
planning model is put on the device with sensors disabled (``mjDSBL_SENSOR``; a robot's own
sensors go too) and :func:`sensor_kernel` writes the requested ones into
``Data.sensordata`` at their usual addresses, one launch per step, from arrays every step
computes anyway (``xpos``, ``xmat``, ``xipos``, ``ximat``, ``geom_xpos``, ``geom_xmat``,
``site_xpos``, ``site_xmat``, ``subtree_com``, ``cvel``). Not with RK4: its step leaves the
kinematics of its last stage in ``Data``, and MJWarp then computes the sensors.

The subtree linear velocity of body :math:`b` is MuJoCo's (``mj_subtreeVel``)

.. math:: \bar v_b = \frac{\sum_{j \in T(b)} m_j \left(v_j + \omega_j \times
   (p_j - c_{r(j)})\right)}{\sum_{j \in T(b)} m_j},

with :math:`(\omega_j, v_j)` body :math:`j`'s ``cvel``, :math:`p_j` its centre of mass
``xipos`` and :math:`c_{r(j)}` the ``subtree_com`` of its tree's root.

On Menagerie's G1 getting up (512 samples x 30 planning steps, one H200) a tick's CUDA graph
replays in 20.9 ms with this kernel against 23.2 ms with MJWarp's sensors
(``benchmarks/own_sensors_ab.py``).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import mujoco
import numpy as np
import warp as wp

from mpcbox.core.free_bodies import subtree

wp.set_module_options({"enable_backward": False})

#: Sensor kinds this kernel computes, by MuJoCo sensor type.
KINDS: dict[int, int] = {
    int(mujoco.mjtSensor.mjSENS_FRAMEPOS): 0,
    int(mujoco.mjtSensor.mjSENS_FRAMEXAXIS): 1,
    int(mujoco.mjtSensor.mjSENS_FRAMEYAXIS): 2,
    int(mujoco.mjtSensor.mjSENS_FRAMEZAXIS): 3,
    int(mujoco.mjtSensor.mjSENS_SUBTREECOM): 4,
    int(mujoco.mjtSensor.mjSENS_SUBTREELINVEL): 5,
}
_FRAME_KINDS = (0, 1, 2, 3)
#: Frames of the frame sensors, by MuJoCo object type.
FRAMES: dict[int, int] = {
    int(mujoco.mjtObj.mjOBJ_SITE): 0,
    int(mujoco.mjtObj.mjOBJ_XBODY): 1,
    int(mujoco.mjtObj.mjOBJ_BODY): 2,
    int(mujoco.mjtObj.mjOBJ_GEOM): 3,
}


class SensorPlan(NamedTuple):
    """Host-side table of the sensors :func:`sensor_kernel` computes.

    Attributes:
        kind: Kind per sensor ``(n,)`` (values of :data:`KINDS`).
        frame: Frame per sensor ``(n,)`` (values of :data:`FRAMES`; 0 for subtree sensors).
        objid: Site, body or geom id per sensor ``(n,)``.
        adr: Address in ``sensordata`` per sensor ``(n,)``.
        start: First entry of ``bodies`` per sensor ``(n,)`` (subtree velocities).
        count: Number of entries of ``bodies`` per sensor ``(n,)``.
        bodies: The bodies of each subtree whose velocity is sensed, concatenated ``(k,)``.
    """

    kind: np.ndarray
    frame: np.ndarray
    objid: np.ndarray
    adr: np.ndarray
    start: np.ndarray
    count: np.ndarray
    bodies: np.ndarray


def sensor_plan(model: mujoco.MjModel, sensors: Iterable[int]) -> SensorPlan | None:
    """The table for ``sensors`` of ``model``, or ``None`` if the kernel cannot compute one.

    A sensor is computed here when it is one of :data:`KINDS`, a frame sensor has no
    reference frame and a frame of :data:`FRAMES`, and it has no cutoff, delay or
    sampling interval (MuJoCo would then change or hold its value).

    Args:
        model: The planning model.
        sensors: Sensor ids (the ones the cost reads).
    """
    rows: list[tuple[int, int, int, int, int, int]] = []
    bodies: list[int] = []
    delay = getattr(model, "sensor_delay", np.zeros(model.nsensor))
    interval = getattr(model, "sensor_interval", np.zeros((model.nsensor, 2)))
    for s in sorted(set(sensors)):
        kind = KINDS.get(int(model.sensor_type[s]))
        if kind is None or model.sensor_cutoff[s] != 0 or np.any(delay[s] != 0):
            return None
        if np.any(np.asarray(interval[s]) != 0):
            return None
        objid, frame, start, count = int(model.sensor_objid[s]), 0, len(bodies), 0
        if kind in _FRAME_KINDS:
            frame = FRAMES.get(int(model.sensor_objtype[s]), -1)
            if frame < 0 or int(model.sensor_reftype[s]) != int(mujoco.mjtObj.mjOBJ_UNKNOWN):
                return None
        elif kind == KINDS[int(mujoco.mjtSensor.mjSENS_SUBTREELINVEL)]:
            tree = sorted(subtree(model, objid))
            bodies += tree
            count = len(tree)
        rows.append((kind, frame, objid, int(model.sensor_adr[s]), start, count))
    table = np.array(rows, dtype=np.int32).reshape(-1, 6)
    return SensorPlan(*table.T.copy(), np.asarray(bodies, dtype=np.int32))


def own_sensor_plan(problem: object, model: mujoco.MjModel) -> SensorPlan | None:
    """The :class:`SensorPlan` of the sensors ``problem``'s cost reads in ``model`` (empty
    when it reads none), or ``None`` when MJWarp must compute them (:func:`sensor_plan`; and
    with RK4, whose step leaves the kinematics of its last stage in ``Data``, not those of
    the step's start, at which MJWarp computes the sensors)."""
    if int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
        return None
    kind = mujoco.mjtObj.mjOBJ_SENSOR
    ids = {mujoco.mj_name2id(model, kind, r.name) for r in problem.cost.sensors(model)}
    if min(ids, default=0) < 0:
        return None
    return sensor_plan(model, ids)


class DeviceSensors:
    """A :class:`SensorPlan` on a Warp device."""

    def __init__(self, plan: SensorPlan, device: str) -> None:
        self.size = int(plan.kind.size)
        with wp.ScopedDevice(device):
            self.arrays = [
                wp.array(np.ascontiguousarray(a), dtype=wp.int32)
                for a in (*plan[:6], np.r_[plan.bodies, 0])  # never an empty array
            ]

    def launch(self, m, d, nworld: int) -> None:
        """Write the sensors of every world into ``d.sensordata``."""
        wp.launch(
            sensor_kernel,
            dim=(nworld, self.size),
            inputs=[
                *self.arrays, m.body_mass, m.body_rootid, d.xpos, d.xmat, d.xipos, d.ximat,
                d.geom_xpos, d.geom_xmat, d.site_xpos, d.site_xmat, d.subtree_com, d.cvel,
            ],
            outputs=[d.sensordata],
        )  # fmt: skip


@wp.kernel
def sensor_kernel(
    kind: wp.array[wp.int32],
    frame: wp.array[wp.int32],
    objid: wp.array[wp.int32],
    adr: wp.array[wp.int32],
    start: wp.array[wp.int32],
    count: wp.array[wp.int32],
    bodies: wp.array[wp.int32],
    body_mass: wp.array2d[float],
    body_rootid: wp.array[int],
    xpos: wp.array2d[wp.vec3],
    xmat: wp.array2d[wp.mat33],
    xipos: wp.array2d[wp.vec3],
    ximat: wp.array2d[wp.mat33],
    geom_xpos: wp.array2d[wp.vec3],
    geom_xmat: wp.array2d[wp.mat33],
    site_xpos: wp.array2d[wp.vec3],
    site_xmat: wp.array2d[wp.mat33],
    subtree_com: wp.array2d[wp.vec3],
    cvel: wp.array2d[wp.spatial_vector],
    sensordata: wp.array2d[float],
):
    world, s = wp.tid()
    k = kind[s]
    i = objid[s]
    value = wp.vec3(0.0)
    if k <= 3:
        # Only the arrays of the frame's kind are read: a model may have no sites, or
        # fewer sites than bodies.
        f = frame[s]
        mat = wp.identity(3, dtype=float)
        if f == 0:
            value = site_xpos[world, i]
            mat = site_xmat[world, i]
        elif f == 1:
            value = xpos[world, i]
            mat = xmat[world, i]
        elif f == 2:
            value = xipos[world, i]
            mat = ximat[world, i]
        else:
            value = geom_xpos[world, i]
            mat = geom_xmat[world, i]
        if k > 0:  # an axis of the frame instead of its position
            value = wp.vec3(mat[0, k - 1], mat[1, k - 1], mat[2, k - 1])
    elif k == 4:
        value = subtree_com[world, i]
    else:
        mass_row = world % body_mass.shape[0]
        momentum = wp.vec3(0.0)
        total = wp.float32(0.0)
        for n in range(start[s], start[s] + count[s]):
            j = bodies[n]
            mass = body_mass[mass_row, j]
            v = cvel[world, j]
            r = xipos[world, j] - subtree_com[world, body_rootid[j]]
            momentum += mass * (wp.spatial_bottom(v) + wp.cross(wp.spatial_top(v), r))
            total += mass
        if total > 1.0e-15:
            value = momentum / total
    a = adr[s]
    sensordata[world, a] = value[0]
    sensordata[world, a + 1] = value[1]
    sensordata[world, a + 2] = value[2]


__all__ = [
    "FRAMES",
    "KINDS",
    "DeviceSensors",
    "SensorPlan",
    "own_sensor_plan",
    "sensor_kernel",
    "sensor_plan",
]
