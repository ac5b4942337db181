"""MJWarp's per-world overflow bits (``Data.overflow``) in words.

Capacity bits (contacts, broadphase, constraint rows, CCD, ...) mean results were dropped:
a failed gate. The solver's iteration-limit bits only say that the solver stopped at its
``iterations`` or ``ls_iterations`` cap; they are reported, not failed.
"""

from __future__ import annotations

import numpy as np


def _types():
    from mujoco_warp import OverflowType

    return OverflowType


def capacity_mask() -> int:
    """The bits of every capacity overflow (all but the solver's iteration limits)."""
    t = _types()
    return int(t.ALL & ~(t.ITERATIONS | t.LS_ITERATIONS))


def solver_mask() -> int:
    """The bits of the solver's iteration limits."""
    t = _types()
    return int(t.ITERATIONS | t.LS_ITERATIONS)


def overflow_names(bits: int) -> list[str]:
    """Names of the single flags set in ``bits`` (e.g. ``["NARROWPHASE", "NEFC"]``)."""
    return [
        f.name
        for f in _types()
        if f.value and not (f.value & (f.value - 1)) and int(bits) & f.value and f.name
    ]


def summarize_overflow(overflow: np.ndarray) -> dict:
    """Counts of worlds with capacity and solver-limit bits, and the capacity flags seen.

    Args:
        overflow: Per-world bitmasks ``(N,)``.
    """
    overflow = np.asarray(overflow, dtype=np.int64)
    cap = overflow & capacity_mask()
    union = int(np.bitwise_or.reduce(cap)) if cap.size else 0
    return {
        "capacity_overflow_worlds": int(np.count_nonzero(cap)),
        "capacity_flags": overflow_names(union),
        "solver_limit_worlds": int(np.count_nonzero(overflow & solver_mask())),
    }


__all__ = ["capacity_mask", "overflow_names", "solver_mask", "summarize_overflow"]
