r"""Gate 3: contact and constraint capacity, sized from the most contact-dense moment.

The observed need per world is the largest of what the CPU baseline saw (``ncon``,
``nefc``) and what the one-world MJWarp run saw (its stored contacts, its broadphase
candidates ``ncollision``, which share the contact pool, and ``nefc``). The suggestion is

.. math:: n_{\text{conmax}} = \lceil h \, \max(\text{contacts}) \rceil, \qquad
          n_{\text{jmax}} = \lceil h \, \max(n_{\text{efc}}) \rceil

with headroom :math:`h` (at least 1 each). The N-world and throughput runs use these (or
the user's ``nconmax``/``njmax``), and the gate fails when any of them sets one of
MJWarp's capacity overflow bits (contacts, broadphase, constraint rows, CCD, ...): MJWarp
then drops contacts or rows, so its worlds no longer simulate the scene.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from mpcbox.gates.config import GatesConfig
from mpcbox.gates.cpu_baseline import CpuBaseline
from mpcbox.gates.overflow import summarize_overflow

if TYPE_CHECKING:
    from mpcbox.gates.parity import Parity
    from mpcbox.gates.warp_worlds import WorldCounts


class CapacityCheck(NamedTuple):
    """One MJWarp run checked against its capacities.

    Attributes:
        run: Which run (``"scaling"``, ``"throughput N=1024"``).
        nworld: Worlds of the run.
        nconmax: Contacts per world it had.
        njmax: Constraint rows per world it had.
        overflow: What its overflow bits say (:func:`~mpcbox.gates.overflow.summarize_overflow`).
        max_ncon: Most contacts in one world (``None`` when not counted).
        max_nefc: Most constraint rows in one world (``None`` when not counted).
        max_nacon: Most contacts in the shared pool of ``nworld * nconmax`` (``None`` when
            not counted).
    """

    run: str
    nworld: int
    nconmax: int
    njmax: int
    overflow: dict
    max_ncon: int | None = None
    max_nefc: int | None = None
    max_nacon: int | None = None

    @property
    def passed(self) -> bool:
        """No capacity overflow bit set in any world."""
        return self.overflow["capacity_overflow_worlds"] == 0


class CapacitySizing(NamedTuple):
    """What the scene needs per world, and the capacities suggested and used.

    Attributes:
        cpu_max_ncon: Most contacts in the CPU baseline.
        cpu_max_nefc: Most constraint rows in the CPU baseline.
        cpu_densest_time: Time of the CPU's most contacts (s from the start), or ``None``.
        warp_max_ncon: Most stored contacts in the one-world MJWarp run.
        warp_max_ncollision: Most broadphase candidates in the one-world MJWarp run.
        warp_max_nefc: Most constraint rows in the one-world MJWarp run.
        headroom: The headroom factor.
        suggested_nconmax: Suggested contacts per world.
        suggested_njmax: Suggested constraint rows per world.
        nconmax: Contacts per world used by the N-world runs (the user's or the suggestion).
        njmax: Constraint rows per world used by the N-world runs.
    """

    cpu_max_ncon: int
    cpu_max_nefc: int
    cpu_densest_time: float | None
    warp_max_ncon: int
    warp_max_ncollision: int
    warp_max_nefc: int
    headroom: float
    suggested_nconmax: int
    suggested_njmax: int
    nconmax: int
    njmax: int


class Capacity(NamedTuple):
    """Gate 3: the sizing and every run checked against it.

    Attributes:
        passed: No checked run overflowed.
        sizing: The :class:`CapacitySizing`.
        checks: The checked runs.
    """

    passed: bool
    sizing: CapacitySizing
    checks: tuple[CapacityCheck, ...]

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {
            "passed": self.passed,
            **self.sizing._asdict(),
            "checks": [{**c._asdict(), "passed": c.passed} for c in self.checks],
        }


def size_capacity(cpu: CpuBaseline, parity: Parity, config: GatesConfig) -> CapacitySizing:
    """The observed maxima and the capacities the N-world runs will use."""
    counts = parity.counts
    cpu_ncon = int(cpu.ncon.max(initial=0))
    cpu_nefc = int(cpu.nefc.max(initial=0))
    warp_ncon = int(counts.max_ncon.max(initial=0))
    warp_efc = int(counts.max_nefc.max(initial=0))
    contacts = max(cpu_ncon, warp_ncon, counts.max_ncollision, counts.max_nacon)
    rows = max(cpu_nefc, warp_efc)
    nconmax = max(1, math.ceil(config.headroom * contacts))
    njmax = max(1, math.ceil(config.headroom * rows))
    densest = None
    if cpu.steps and cpu_ncon > 0:
        densest = float(cpu.time[int(np.argmax(cpu.ncon)) + 1] - cpu.time[0])
    return CapacitySizing(
        cpu_max_ncon=cpu_ncon,
        cpu_max_nefc=cpu_nefc,
        cpu_densest_time=densest,
        warp_max_ncon=warp_ncon,
        warp_max_ncollision=counts.max_ncollision,
        warp_max_nefc=warp_efc,
        headroom=config.headroom,
        suggested_nconmax=nconmax,
        suggested_njmax=njmax,
        nconmax=nconmax if config.nconmax is None else config.nconmax,
        njmax=njmax if config.njmax is None else config.njmax,
    )


def check_run(
    run: str, counts: WorldCounts, nconmax: int, njmax: int, *, counted: bool = True
) -> CapacityCheck:
    """A :class:`CapacityCheck` of a run's read-back counts."""
    return CapacityCheck(
        run=run,
        nworld=len(counts.overflow),
        nconmax=nconmax,
        njmax=njmax,
        overflow=summarize_overflow(counts.overflow),
        max_ncon=int(counts.max_ncon.max(initial=0)) if counted else None,
        max_nefc=int(counts.max_nefc.max(initial=0)) if counted else None,
        max_nacon=counts.max_nacon if counted else None,
    )


def capacity_gate(sizing: CapacitySizing, checks: list[CapacityCheck]) -> Capacity:
    """Gate 3's verdict over the checked runs."""
    return Capacity(all(c.passed for c in checks), sizing, tuple(checks))


__all__ = [
    "Capacity",
    "CapacityCheck",
    "CapacitySizing",
    "capacity_gate",
    "check_run",
    "size_capacity",
]
