r"""Gate 4: the same controls in ``N`` MJWarp worlds at once, without per-step host copies.

The ``N`` worlds start from :func:`~mpcbox.gates.starts.world_starts` (world 0
unperturbed) with the capacities of gate 3, and run the whole control sequence as device
launches only (:class:`~mpcbox.gates.warp_worlds.WarpWorlds`): the step index, the
contact and row maxima and the divergence flags stay on the device, and everything is read
back once at the end (``host_reads`` counts those reads). The gate passes when no world
diverged and no capacity overflowed. The report also gives the spread of the final
positions over the worlds (how far the perturbations carried them apart) and how far world 0
ended from the one-world run (MJWarp's contact ordering over many worlds is not bitwise
deterministic, so contact scenes may differ there as well).
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from mpcbox.gates.capacity import CapacitySizing
from mpcbox.gates.config import GatesConfig
from mpcbox.gates.controls import GateInput
from mpcbox.gates.overflow import capacity_mask, summarize_overflow
from mpcbox.gates.starts import world_starts

if TYPE_CHECKING:
    from mpcbox.gates.parity import Parity
    from mpcbox.gates.warp_worlds import WarpScene, WorldCounts


class Scaling(NamedTuple):
    r"""Gate 4 (``N`` worlds, ``S`` steps).

    Attributes:
        passed: No world diverged and none overflowed a capacity.
        nworld: ``N``.
        steps: ``S``.
        perturbation: Noise of the start states (see :mod:`mpcbox.gates.starts`).
        diverged_worlds: Worlds flagged as diverged.
        host_reads: Copies back to the host over the run (one, after the last step).
        graph: Whether the steps ran as CUDA graph replays (on CUDA; then MJWarp's solver
            loop does not read back its convergence flag either).
        final_spread: :math:`\max_i \operatorname{std}_w q_{w,i}` of the final positions.
        world0_vs_single: :math:`\max_i |q_{0,i} - q^{\text{one world}}_i|` at the end.
        counts: The read-back counts.
        seconds: Wall-clock time of the run (s), allocation and the final read included.
    """

    passed: bool
    nworld: int
    steps: int
    perturbation: float
    diverged_worlds: int
    host_reads: int
    graph: bool
    final_spread: float
    world0_vs_single: float
    counts: WorldCounts
    seconds: float

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {
            "passed": self.passed,
            "nworld": self.nworld,
            "steps": self.steps,
            "perturbation": self.perturbation,
            "diverged_worlds": self.diverged_worlds,
            **summarize_overflow(self.counts.overflow),
            "host_reads": self.host_reads,
            "per_step_host_copies": 0,
            "graph": self.graph,
            "max_ncon_per_world": int(self.counts.max_ncon.max(initial=0)),
            "max_nefc_per_world": int(self.counts.max_nefc.max(initial=0)),
            "max_nacon_pool": self.counts.max_nacon,
            "final_spread": self.final_spread,
            "world0_vs_single": self.world0_vs_single,
            "wall_seconds": self.seconds,
        }


def scaling_worlds(config: GatesConfig, worlds: tuple[int, ...]) -> int:
    """``config.scaling_worlds``, else the largest throughput world count."""
    return config.scaling_worlds or max(worlds)


def run_scaling(
    scene: WarpScene,
    gate_input: GateInput,
    parity: Parity,
    sizing: CapacitySizing,
    config: GatesConfig,
    nworld: int,
) -> Scaling:
    """Run gate 4: ``nworld`` worlds over the whole control sequence."""
    starts = world_starts(
        gate_input.model, gate_input.initial_state, nworld, config.perturbation, config.seed
    )
    t0 = _time.perf_counter()
    worlds = scene.worlds(
        *starts,
        nconmax=sizing.nconmax,
        njmax=sizing.njmax,
        mocap_pos=gate_input.mocap_pos,
        mocap_quat=gate_input.mocap_quat,
    )
    steps = parity.counts.steps
    graph = worlds.run(steps, block=config.block_steps)
    worlds.synchronize()
    counts = worlds.read()
    seconds = _time.perf_counter() - t0
    qpos = counts.qpos
    finite = np.all(np.isfinite(qpos), axis=1) & np.all(np.isfinite(counts.qvel), axis=1)
    diverged = int(np.count_nonzero(counts.diverged | ~finite))
    spread = float(np.max(np.std(qpos, axis=0), initial=0.0)) if np.all(finite) else np.nan
    single = parity.counts.qpos[0]
    overflow = int(np.count_nonzero(counts.overflow & capacity_mask()))
    return Scaling(
        passed=diverged == 0 and overflow == 0,
        nworld=nworld,
        steps=counts.steps,
        perturbation=config.perturbation,
        diverged_worlds=diverged,
        host_reads=worlds.host_reads,
        graph=graph,
        final_spread=spread,
        world0_vs_single=float(np.max(np.abs(qpos[0] - single), initial=0.0)),
        counts=counts,
        seconds=seconds,
    )


__all__ = ["Scaling", "run_scaling", "scaling_worlds"]
