r"""Gate 2: one MJWarp world against the CPU baseline, step by step.

The same start and controls run in one MJWarp world (float32) with generous capacities
(at least 4 times the CPU's largest ``ncon`` and ``nefc``, doubled and rerun on an
overflow). World 0's state after every step is kept on the device and read back once. The
error curve is

.. math:: e_k = \max_i |q^{\text{warp}}_{k,i} - q^{\text{cpu}}_{k,i}|, \quad k = 0 .. S,

with the same for :math:`\dot q`. The gate passes when the MJWarp world does not diverge
and :math:`e_k \le` ``parity_tolerance`` for every step within ``parity_window`` seconds of
the start. Contact-rich scenes drift apart chaotically (different float precision, and
MJWarp generates some contacts differently), so the report gives the time at which
:math:`e_k` first exceeds the tolerance rather than only pass or fail.
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from mpcbox.gates.config import GatesConfig
from mpcbox.gates.controls import GateInput
from mpcbox.gates.cpu_baseline import CpuBaseline
from mpcbox.gates.overflow import capacity_mask, summarize_overflow

if TYPE_CHECKING:
    from mpcbox.gates.warp_worlds import WarpScene, WorldCounts

#: Times an overflowing parity run is rerun with doubled capacities.
MAX_RETRIES = 4

#: Multiples of the tolerance whose first crossing times the JSON report lists.
SCALES_REPORTED = (1.0, 10.0, 100.0)

#: Points of the error curve kept in the JSON report.
CURVE_POINTS = 50


class Parity(NamedTuple):
    """The one-world comparison (``S`` steps compared).

    Attributes:
        passed: Within tolerance over the window, not diverged, no capacity overflow.
        tolerance: ``parity_tolerance`` (rad or m).
        window: Seconds from the start that had to stay within tolerance (``parity_window``,
            at most the run's length).
        time: Times ``(S + 1,)`` (s).
        qpos_error: :math:`e_k` ``(S + 1,)``.
        qvel_error: The same for velocities ``(S + 1,)``.
        time_beyond_tolerance: Time of the first step with :math:`e_k >` tolerance (s from
            the start), or ``None`` when the whole run stays within it.
        diverged: The MJWarp world diverged (non-finite or beyond 1e10).
        counts: What the MJWarp run saw (contacts, rows, overflow bits).
        nconmax: Contacts per world of the run.
        njmax: Constraint rows per world of the run.
        reruns: Runs repeated after a capacity overflow.
        seconds: Wall-clock time of the last run (s), first-call compilation included.
    """

    passed: bool
    tolerance: float
    window: float
    time: np.ndarray
    qpos_error: np.ndarray
    qvel_error: np.ndarray
    time_beyond_tolerance: float | None
    diverged: bool
    counts: WorldCounts
    nconmax: int
    njmax: int
    reruns: int
    seconds: float

    def first_time_beyond(self, scale: float) -> float | None:
        """Seconds from the start to the first error above ``scale * tolerance``, or ``None``."""
        beyond = np.nonzero(self.qpos_error > scale * self.tolerance)[0]
        return float(self.time[beyond[0]] - self.time[0]) if beyond.size else None

    def summary(self) -> dict:
        """JSON-ready figures, with the error curve at up to :data:`CURVE_POINTS` times."""
        t = self.time - self.time[0]
        idx = np.unique(np.linspace(0, len(t) - 1, min(CURVE_POINTS, len(t))).astype(int))
        return {
            "passed": self.passed,
            "tolerance": self.tolerance,
            "window_seconds": self.window,
            "steps": len(t) - 1,
            "max_qpos_error": float(self.qpos_error.max()),
            "final_qpos_error": float(self.qpos_error[-1]),
            "max_qvel_error": float(np.nanmax(self.qvel_error)),
            "time_beyond_tolerance": self.time_beyond_tolerance,
            "time_beyond": {f"{s:g}": self.first_time_beyond(s) for s in SCALES_REPORTED},
            "diverged": self.diverged,
            "nconmax": self.nconmax,
            "njmax": self.njmax,
            "reruns": self.reruns,
            "warp_max_ncon": int(self.counts.max_ncon.max(initial=0)),
            "warp_max_ncollision": self.counts.max_ncollision,
            "warp_max_nefc": int(self.counts.max_nefc.max(initial=0)),
            **summarize_overflow(self.counts.overflow),
            "wall_seconds": self.seconds,
            "curve": {
                "time": t[idx].tolist(),
                "qpos_error": self.qpos_error[idx].tolist(),
                "qvel_error": self.qvel_error[idx].tolist(),
            },
        }


def run_parity(
    scene: WarpScene, gate_input: GateInput, cpu: CpuBaseline, config: GatesConfig
) -> Parity:
    """Run gate 2 on ``scene`` (one world) against ``cpu``."""
    state = gate_input.initial_state
    model = gate_input.model
    nq, nv = model.nq, model.nv
    nconmax = max(64, 4 * int(cpu.ncon.max(initial=0)))
    njmax = max(256, 4 * int(cpu.nefc.max(initial=0)))
    reruns = 0
    while True:
        start = _time.perf_counter()
        worlds = scene.worlds(
            state[None, :nq],
            state[None, nq : nq + nv],
            state[None, nq + nv :],
            nconmax=nconmax,
            njmax=njmax,
            mocap_pos=gate_input.mocap_pos,
            mocap_quat=gate_input.mocap_quat,
            record=True,
        )
        worlds.run(cpu.steps, block=config.block_steps)
        worlds.synchronize()
        counts = worlds.read()
        seconds = _time.perf_counter() - start
        overflow = bool(counts.overflow[0] & capacity_mask())
        if not overflow or reruns >= MAX_RETRIES:
            break
        nconmax, njmax, reruns = 2 * nconmax, 2 * njmax, reruns + 1
    assert counts.rec_qpos is not None and counts.rec_qvel is not None
    rows = cpu.steps + 1
    qpos_error = np.max(np.abs(counts.rec_qpos[:rows] - cpu.qpos), axis=1, initial=0.0)
    qvel_error = np.max(np.abs(counts.rec_qvel[:rows] - cpu.qvel), axis=1, initial=0.0)
    qpos_error = np.where(np.isfinite(qpos_error), qpos_error, np.inf)
    t = cpu.time - cpu.time[0]
    beyond = np.nonzero(qpos_error > config.parity_tolerance)[0]
    time_beyond = float(t[beyond[0]]) if beyond.size else None  # first_time_beyond(1)
    in_window = t <= config.parity_window + 1e-12
    within = bool(np.all(qpos_error[in_window] <= config.parity_tolerance))
    diverged = bool(counts.diverged[0])
    return Parity(
        passed=within and not diverged and not overflow,
        tolerance=config.parity_tolerance,
        window=min(config.parity_window, float(t[-1])),  # what was checked (run length)
        time=cpu.time,
        qpos_error=qpos_error,
        qvel_error=qvel_error,
        time_beyond_tolerance=time_beyond,
        diverged=diverged,
        counts=counts,
        nconmax=nconmax,
        njmax=njmax,
        reruns=reruns,
        seconds=seconds,
    )


__all__ = ["CURVE_POINTS", "MAX_RETRIES", "SCALES_REPORTED", "Parity", "run_parity"]
