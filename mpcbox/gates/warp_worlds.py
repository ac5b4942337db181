r"""Batched MJWarp worlds replaying a control sequence, with device-side bookkeeping.

:class:`WarpScene` puts a model and its controls ``(T, nu)`` on a Warp device once;
:meth:`WarpScene.worlds` allocates ``N`` worlds (:class:`WarpWorlds`) from start states.
One step of :meth:`WarpWorlds.launch_steps` is, all on the device and without any copy to
the host:

1. ``ctrl[w] = ctrls[min(k, T - 1)]`` for every world ``w``, with the step index ``k`` held
   in a device counter (so the launches can be captured once as a CUDA graph and replayed);
2. ``mujoco_warp.step``;
3. optionally the bookkeeping: contacts per world (from ``contact.worldid`` of the first
   ``nacon`` contacts), the per-world maxima of contacts and of ``nefc``, the pool maxima of
   ``nacon`` and of the broadphase count ``ncollision``, a per-world divergence flag (a
   non-finite or ``|x| > 1e10`` entry of ``qpos``, ``qvel`` or ``qacc``, the limit MuJoCo
   uses), and world 0's ``qpos`` and ``qvel`` after step ``k`` (for the parity gate);
4. ``k += 1``.

MJWarp's own overflow bits (``Data.overflow``, sticky per world until a reset; printing
from kernels is switched off) say whether a capacity was exceeded;
:meth:`WarpWorlds.read` copies everything back once, at the end.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import mujoco_warp as mjw
import numpy as np
import warp as wp

from mpcbox.errors import UnsupportedModelError

# Nothing here is differentiated, so no adjoint (backward) code is generated.
wp.set_module_options({"enable_backward": False})

#: MuJoCo's divergence limit (``mjMAXVAL``) on positions, velocities and accelerations.
MAX_VALUE = 1e10


@wp.kernel
def _set_ctrl(
    ctrls: wp.array2d(dtype=wp.float32),
    counter: wp.array(dtype=wp.int32),
    ctrl: wp.array2d(dtype=wp.float32),
):
    w, j = wp.tid()
    k = wp.min(counter[0], ctrls.shape[0] - 1)
    ctrl[w, j] = ctrls[k, j]


@wp.kernel
def _count_contacts(
    nacon: wp.array(dtype=wp.int32),
    worldid: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
):
    i = wp.tid()
    if i < wp.min(nacon[0], worldid.shape[0]):
        wp.atomic_add(count, worldid[i], 1)


@wp.kernel
def _world_stats(
    count: wp.array(dtype=wp.int32),
    nefc: wp.array(dtype=wp.int32),
    qpos: wp.array2d(dtype=wp.float32),
    qvel: wp.array2d(dtype=wp.float32),
    qacc: wp.array2d(dtype=wp.float32),
    max_ncon: wp.array(dtype=wp.int32),
    max_nefc: wp.array(dtype=wp.int32),
    bad: wp.array(dtype=wp.int32),
):
    w = wp.tid()
    max_ncon[w] = wp.max(max_ncon[w], count[w])
    count[w] = 0
    max_nefc[w] = wp.max(max_nefc[w], nefc[w])
    limit = wp.float32(MAX_VALUE)
    for i in range(qpos.shape[1]):
        x = qpos[w, i]
        if not wp.isfinite(x) or wp.abs(x) > limit:
            bad[w] = 1
    for i in range(qvel.shape[1]):
        v = qvel[w, i]
        a = qacc[w, i]
        if not (wp.isfinite(v) and wp.isfinite(a)) or wp.abs(v) > limit or wp.abs(a) > limit:
            bad[w] = 1


@wp.kernel
def _advance(
    counter: wp.array(dtype=wp.int32),
    nacon: wp.array(dtype=wp.int32),
    ncollision: wp.array(dtype=wp.int32),
    stats: wp.int32,
    qpos: wp.array2d(dtype=wp.float32),
    qvel: wp.array2d(dtype=wp.float32),
    pool: wp.array(dtype=wp.int32),
    rec_qpos: wp.array2d(dtype=wp.float32),
    rec_qvel: wp.array2d(dtype=wp.float32),
):
    k = counter[0] + 1
    if stats != 0:
        pool[0] = wp.max(pool[0], nacon[0])
        pool[1] = wp.max(pool[1], ncollision[0])
        if k < rec_qpos.shape[0]:
            for i in range(qpos.shape[1]):
                rec_qpos[k, i] = qpos[0, i]
            for i in range(qvel.shape[1]):
                rec_qvel[k, i] = qvel[0, i]
    counter[0] = k


class WorldCounts(NamedTuple):
    """What :meth:`WarpWorlds.read` copies back (``N`` worlds).

    Attributes:
        steps: Steps run (the device counter).
        max_ncon: Most contacts seen per world ``(N,)`` (counted among the stored ones).
        max_nefc: Most constraint rows seen per world ``(N,)`` (MJWarp counts rows beyond
            ``njmax`` too, then flags an overflow).
        max_nacon: Most contacts in the shared pool over all worlds (may exceed
            ``naconmax``: then MJWarp dropped some and flagged an overflow).
        max_ncollision: Most broadphase candidates in the pool over all worlds.
        overflow: MJWarp's overflow bitmask per world ``(N,)`` (``OverflowType``).
        diverged: Per-world divergence flag ``(N,)``.
        qpos: Final positions ``(N, nq)``.
        qvel: Final velocities ``(N, nv)``.
        rec_qpos: World 0's positions after each step ``(T + 1, nq)``, or ``None``.
        rec_qvel: World 0's velocities ``(T + 1, nv)``, or ``None``.
    """

    steps: int
    max_ncon: np.ndarray
    max_nefc: np.ndarray
    max_nacon: int
    max_ncollision: int
    overflow: np.ndarray
    diverged: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    rec_qpos: np.ndarray | None
    rec_qvel: np.ndarray | None


class WarpScene:
    """A model and its control sequence on a Warp device.

    Args:
        model: The MuJoCo model.
        ctrls: Controls ``(T, nu)``.
        device: Warp device name (``"cpu"``, ``"cuda:0"``).

    Raises:
        UnsupportedModelError: If MuJoCo Warp cannot run the model.
    """

    def __init__(self, model: mujoco.MjModel, ctrls: np.ndarray, device: str) -> None:
        self.mjw = mjw
        self.model = model
        self.device = device
        self.steps = int(ctrls.shape[0])
        with wp.ScopedDevice(device):
            try:
                self.m = mjw.put_model(model)
            except NotImplementedError as exc:
                raise UnsupportedModelError(
                    f"scene: MuJoCo Warp cannot run this model ({exc})"
                ) from exc
            self.m.opt.warn_overflow = 0  # read back as bits instead of printed per kernel
            # This module's kernels, compiled before any graph capture needs them.
            wp.load_module(__name__, device=device)
            self.ctrls = wp.array(np.ascontiguousarray(ctrls, dtype=np.float32))

    def worlds(
        self,
        qpos: np.ndarray,
        qvel: np.ndarray,
        act: np.ndarray,
        *,
        nconmax: int,
        njmax: int,
        mocap_pos: np.ndarray | None = None,
        mocap_quat: np.ndarray | None = None,
        record: bool = False,
    ) -> WarpWorlds:
        """``N`` worlds starting from ``qpos (N, nq)``, ``qvel (N, nv)``, ``act (N, na)``.

        Args:
            qpos: Start positions per world.
            qvel: Start velocities per world.
            act: Start actuator activations per world.
            nconmax: Contacts per world (MJWarp's pool holds ``N * nconmax``).
            njmax: Constraint rows per world.
            mocap_pos: Mocap body positions ``(nmocap, 3)`` of every world (default: the
                model's).
            mocap_quat: Mocap body orientations ``(nmocap, 4)``.
            record: Keep world 0's ``qpos`` and ``qvel`` after every step.
        """
        return WarpWorlds(self, qpos, qvel, act, nconmax, njmax, mocap_pos, mocap_quat, record)


class WarpWorlds:
    """``N`` MJWarp worlds of a :class:`WarpScene` with their device counters (see module)."""

    def __init__(
        self,
        scene: WarpScene,
        qpos: np.ndarray,
        qvel: np.ndarray,
        act: np.ndarray,
        nconmax: int,
        njmax: int,
        mocap_pos: np.ndarray | None,
        mocap_quat: np.ndarray | None,
        record: bool,
    ) -> None:
        self.scene = scene
        self.nworld = int(qpos.shape[0])
        self.nconmax, self.njmax = int(nconmax), int(njmax)
        model = scene.model
        n = self.nworld
        self.host_reads = 0
        with wp.ScopedDevice(scene.device):
            d = scene.mjw.make_data(model, nworld=n, nconmax=self.nconmax, njmax=self.njmax)
            d.qpos.assign(np.ascontiguousarray(qpos, dtype=np.float32))
            d.qvel.assign(np.ascontiguousarray(qvel, dtype=np.float32))
            if model.na:
                d.act.assign(np.ascontiguousarray(act, dtype=np.float32))
            if model.nmocap and mocap_pos is not None:
                d.mocap_pos.assign(np.tile(mocap_pos, (n, 1, 1)).astype(np.float32))
            if model.nmocap and mocap_quat is not None:
                d.mocap_quat.assign(np.tile(mocap_quat, (n, 1, 1)).astype(np.float32))
            self.d = d
            self.counter = wp.zeros(1, dtype=wp.int32)
            self.count = wp.zeros(n, dtype=wp.int32)
            self.max_ncon = wp.zeros(n, dtype=wp.int32)
            self.max_nefc = wp.zeros(n, dtype=wp.int32)
            self.bad = wp.zeros(n, dtype=wp.int32)
            self.pool = wp.zeros(2, dtype=wp.int32)
            rows = scene.steps + 1 if record else 0
            self.rec_qpos = wp.zeros((rows, model.nq), dtype=wp.float32)
            self.rec_qvel = wp.zeros((rows, model.nv), dtype=wp.float32)
            if record:
                self.rec_qpos[0:1].assign(qpos[:1].astype(np.float32))
                self.rec_qvel[0:1].assign(qvel[:1].astype(np.float32))
        self.record = record

    def launch_steps(self, count: int, *, stats: bool = True) -> None:
        """Launch ``count`` steps (no synchronization, no copy to the host)."""
        scene, d = self.scene, self.d
        m, mjw = scene.m, scene.mjw
        n, nu = self.nworld, scene.model.nu
        with wp.ScopedDevice(scene.device):
            for _ in range(count):
                if nu:
                    wp.launch(
                        _set_ctrl, dim=(n, nu), inputs=[scene.ctrls, self.counter], outputs=[d.ctrl]
                    )
                mjw.step(m, d)
                if stats:
                    if d.naconmax:
                        wp.launch(
                            _count_contacts,
                            dim=d.naconmax,
                            inputs=[d.nacon, d.contact.worldid],
                            outputs=[self.count],
                        )
                    wp.launch(
                        _world_stats,
                        dim=n,
                        inputs=[self.count, d.nefc, d.qpos, d.qvel, d.qacc],
                        outputs=[self.max_ncon, self.max_nefc, self.bad],
                    )
                wp.launch(
                    _advance,
                    dim=1,
                    inputs=[self.counter, d.nacon, d.ncollision, int(stats), d.qpos, d.qvel],
                    outputs=[self.pool, self.rec_qpos, self.rec_qvel],
                )

    def capture(self, count: int, *, stats: bool = False):
        """A CUDA graph of :meth:`launch_steps` (``count`` steps); ``None`` off CUDA."""
        if not wp.get_device(self.scene.device).is_cuda:
            return None
        with wp.ScopedDevice(self.scene.device):
            with wp.ScopedCapture() as capture:
                self.launch_steps(count, stats=stats)
        return capture.graph

    def run(self, steps: int, *, block: int, stats: bool = True) -> bool:
        """Launch ``steps`` steps; on CUDA as replays of captured graphs of ``block`` steps.

        Off a graph, MJWarp's solver loop reads its convergence flag back on every
        iteration; inside one it is a device-side conditional, so a captured run makes no
        copy to the host at all. Does not synchronize.

        Returns:
            Whether graphs were used.
        """
        if not wp.get_device(self.scene.device).is_cuda:
            self.launch_steps(steps, stats=stats)
            return False
        full, rest = divmod(steps, block)
        graphs = []
        if full:
            graphs += [self.capture(block, stats=stats)] * full
        if rest:
            graphs.append(self.capture(rest, stats=stats))
        with wp.ScopedDevice(self.scene.device):
            for graph in graphs:
                wp.capture_launch(graph)
        return True

    def synchronize(self) -> None:
        """Wait for the device."""
        wp.synchronize_device(self.scene.device)

    def restart(self, qpos: np.ndarray, qvel: np.ndarray, act: np.ndarray) -> None:
        """Put the worlds back at the given start states and the controls at ``k = 0``.

        The overflow bits and the counted maxima are kept.
        """
        d = self.d
        with wp.ScopedDevice(self.scene.device):
            d.qpos.assign(np.ascontiguousarray(qpos, dtype=np.float32))
            d.qvel.assign(np.ascontiguousarray(qvel, dtype=np.float32))
            if self.scene.model.na:
                d.act.assign(np.ascontiguousarray(act, dtype=np.float32))
            d.qacc_warmstart.zero_()
            self.counter.zero_()

    def read(self) -> WorldCounts:
        """Copy the counters, flags and final states back to the host (one read)."""
        self.host_reads += 1
        d = self.d
        pool = self.pool.numpy()
        return WorldCounts(
            steps=int(self.counter.numpy()[0]),
            max_ncon=self.max_ncon.numpy().astype(np.int64),
            max_nefc=self.max_nefc.numpy().astype(np.int64),
            max_nacon=int(pool[0]),
            max_ncollision=int(pool[1]),
            overflow=d.overflow.numpy().astype(np.int64),
            diverged=self.bad.numpy().astype(bool),
            qpos=d.qpos.numpy().astype(np.float64),
            qvel=d.qvel.numpy().astype(np.float64),
            rec_qpos=self.rec_qpos.numpy().astype(np.float64) if self.record else None,
            rec_qvel=self.rec_qvel.numpy().astype(np.float64) if self.record else None,
        )


__all__ = ["MAX_VALUE", "WarpScene", "WarpWorlds", "WorldCounts"]
