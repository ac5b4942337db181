r"""Gate 5: world-steps per second against the number of worlds, measured properly.

For each world count ``N`` (fresh worlds from :func:`~mpcbox.gates.starts.world_starts`,
the capacities of gate 3), steps are launched in blocks of ``block_steps`` (controls and
``mujoco_warp.step`` only; no bookkeeping, no host copies):

* **first call** (once, before any other MJWarp work of the gates:
  :func:`measure_first_call`): one step of one world, synchronized, which includes compiling
  (or loading from Warp's kernel cache) every kernel of the step;
* **cold**: the first block at this ``N``, synchronized, from launch to completion (first
  launches at that size, memory first touched);
* on CUDA the block is then captured once as a CUDA graph (``wp.ScopedCapture``, the
  pattern of MJWarp's own ``testspeed``; capture time reported) and replayed once to warm
  up; off CUDA the block is launched directly;
* **warm**: from the start states again, ``ceil(throughput_steps / block_steps)`` blocks
  back to back (but no more than fit in the recorded ``T`` steps, on which the capacities
  were sized; at least one), with one synchronization before the clock starts and one
  before it stops:

.. math:: \text{world-steps/s} = \frac{N \cdot \text{blocks} \cdot \text{block\_steps}}
          {t_{\text{warm}}}.

Each row also reads MJWarp's overflow bits (checked by gate 3) and whether every world's
final state is finite. The gate passes when every row has no capacity overflow and no
non-finite world.
"""

from __future__ import annotations

import math
import time as _time
from typing import NamedTuple

import numpy as np
import warp as wp

from mpcbox.gates.capacity import CapacitySizing
from mpcbox.gates.config import GatesConfig
from mpcbox.gates.controls import GateInput
from mpcbox.gates.overflow import capacity_mask, summarize_overflow
from mpcbox.gates.starts import world_starts
from mpcbox.gates.warp_worlds import WarpScene, WorldCounts


class ThroughputRow(NamedTuple):
    """One world count.

    Attributes:
        nworld: Worlds ``N``.
        cold_seconds: First block, launch to completion (s).
        capture_seconds: CUDA graph capture (s), or ``None`` without a graph.
        graph: Whether the warm blocks replayed a CUDA graph.
        warm_steps: Steps per world timed warm.
        warm_seconds: Their wall-clock time, synchronized (s).
        world_steps_per_second: ``N * warm_steps / warm_seconds``.
        realtime_factor: Simulated seconds per wall-clock second over all worlds.
        nonfinite_worlds: Worlds whose final state is not finite.
        counts: The read-back counts (overflow bits, final states).
    """

    nworld: int
    cold_seconds: float
    capture_seconds: float | None
    graph: bool
    warm_steps: int
    warm_seconds: float
    world_steps_per_second: float
    realtime_factor: float
    nonfinite_worlds: int
    counts: WorldCounts

    @property
    def passed(self) -> bool:
        """No capacity overflow and every world finite."""
        overflow = np.count_nonzero(self.counts.overflow & capacity_mask())
        return overflow == 0 and self.nonfinite_worlds == 0

    def summary(self) -> dict:
        """JSON-ready figures."""
        out = {k: v for k, v in self._asdict().items() if k != "counts"}
        return {**out, **summarize_overflow(self.counts.overflow), "passed": self.passed}


class Throughput(NamedTuple):
    """Gate 5: one :class:`ThroughputRow` per world count.

    Attributes:
        passed: Every row passed.
        device: Warp device name.
        first_call_seconds: One step of one world as the first MJWarp call of the process
            (compilation or kernel-cache loading included), or ``None`` when not measured.
        block_steps: Steps per launch block (per graph).
        rows: The rows, by increasing ``N``.
    """

    passed: bool
    device: str
    first_call_seconds: float | None
    block_steps: int
    rows: tuple[ThroughputRow, ...]

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {
            "passed": self.passed,
            "device": self.device,
            "first_call_seconds": self.first_call_seconds,
            "block_steps": self.block_steps,
            "rows": [r.summary() for r in self.rows],
        }


def _sync(device: str) -> None:
    wp.synchronize_device(device)


def measure_row(
    scene: WarpScene,
    gate_input: GateInput,
    sizing: CapacitySizing,
    config: GatesConfig,
    nworld: int,
) -> ThroughputRow:
    """Time ``nworld`` worlds (see module)."""
    device = scene.device
    starts = world_starts(
        gate_input.model, gate_input.initial_state, nworld, config.perturbation, config.seed
    )
    worlds = scene.worlds(
        *starts,
        nconmax=sizing.nconmax,
        njmax=sizing.njmax,
        mocap_pos=gate_input.mocap_pos,
        mocap_quat=gate_input.mocap_quat,
    )
    block = config.block_steps
    _sync(device)
    t0 = _time.perf_counter()
    worlds.launch_steps(block, stats=False)
    _sync(device)
    cold = _time.perf_counter() - t0
    graph = None
    capture = None
    if wp.get_device(device).is_cuda:
        t0 = _time.perf_counter()
        graph = worlds.capture(block, stats=False)
        capture = _time.perf_counter() - t0
        with wp.ScopedDevice(device):
            wp.capture_launch(graph)
    # Time the recorded sequence from its start (the capacities were sized on it).
    worlds.restart(*starts)
    blocks = math.ceil(config.throughput_steps / block)
    blocks = max(1, min(blocks, scene.steps // block))
    _sync(device)
    t0 = _time.perf_counter()
    with wp.ScopedDevice(device):
        for _ in range(blocks):
            if graph is not None:
                wp.capture_launch(graph)
            else:
                worlds.launch_steps(block, stats=False)
    _sync(device)
    warm = _time.perf_counter() - t0
    counts = worlds.read()
    finite = np.all(np.isfinite(counts.qpos), axis=1) & np.all(np.isfinite(counts.qvel), axis=1)
    steps = blocks * block
    rate = nworld * steps / warm if warm > 0 else math.inf
    return ThroughputRow(
        nworld=nworld,
        cold_seconds=cold,
        capture_seconds=capture,
        graph=graph is not None,
        warm_steps=steps,
        warm_seconds=warm,
        world_steps_per_second=rate,
        realtime_factor=rate * float(gate_input.model.opt.timestep),
        nonfinite_worlds=int(np.count_nonzero(~finite)),
        counts=counts,
    )


def measure_first_call(scene: WarpScene, gate_input: GateInput, nconmax: int, njmax: int) -> float:
    """Seconds of one step of one world, synchronized; call it before other MJWarp work."""
    state = gate_input.initial_state
    nq, nv = gate_input.model.nq, gate_input.model.nv
    worlds = scene.worlds(
        state[None, :nq], state[None, nq : nq + nv], state[None, nq + nv :],
        nconmax=nconmax, njmax=njmax,
    )  # fmt: skip
    _sync(scene.device)
    t0 = _time.perf_counter()
    worlds.launch_steps(1, stats=False)
    _sync(scene.device)
    return _time.perf_counter() - t0


def run_throughput(
    scene: WarpScene,
    gate_input: GateInput,
    sizing: CapacitySizing,
    config: GatesConfig,
    worlds: tuple[int, ...],
    first_call_seconds: float | None = None,
) -> Throughput:
    """Run gate 5 over ``worlds`` (increasing order)."""
    rows = [
        measure_row(scene, gate_input, sizing, config, nworld) for nworld in sorted(set(worlds))
    ]
    return Throughput(
        all(r.passed for r in rows),
        scene.device,
        first_call_seconds,
        config.block_steps,
        tuple(rows),
    )


__all__ = [
    "Throughput",
    "ThroughputRow",
    "measure_first_call",
    "measure_row",
    "run_throughput",
]
