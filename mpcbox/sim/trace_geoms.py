r"""Draws a planner's traces (:class:`~mpcbox.controllers.sampling.traces.PlannerTrace`) as
capsules in a MuJoCo scene.

Trace :math:`i` of ``k`` (best first) is the polyline through its points
:math:`p^{(i)}_0, \dots, p^{(i)}_T`; each segment :math:`[p_t, p_{t+1}]` becomes one capsule
(:func:`mujoco.mjv_connector`). A trace longer than ``max_segments`` segments is drawn
through evenly spaced points of it (its ends kept), so ``k`` traces cost at most
``k * max_segments`` geoms of the scene (about 15 us each to fill from Python). The best
trace is green and drawn last (on top); the others are orange, fading with their rank.
Segments with a non-finite end are skipped; drawing stops when the scene is full.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from mpcbox.controllers.sampling.traces import PlannerTrace

#: RGBA of the best trace.
BEST_RGBA = (0.15, 0.9, 0.25, 1.0)
#: RGB of the other traces (their alpha fades from 0.8 to 0.25 with rank).
ELITE_RGB = (1.0, 0.55, 0.1)

_IDENTITY = np.eye(3).ravel()
_ZERO = np.zeros(3)


def trace_colour(rank: int, count: int) -> np.ndarray:
    """RGBA ``(4,)`` (float32) of the trace of ``rank`` (0: best) among ``count``."""
    if rank == 0:
        return np.asarray(BEST_RGBA, dtype=np.float32)
    fade = (rank - 1) / max(1, count - 2)
    return np.asarray((*ELITE_RGB, 0.8 - 0.55 * fade), dtype=np.float32)


def add_trace_geoms(
    scene: mujoco.MjvScene, trace: PlannerTrace, radius: float, max_segments: int = 25
) -> int:
    """Append the capsules of ``trace`` to ``scene`` (after ``scene.ngeom``).

    Args:
        scene: A scene after :func:`mujoco.mjv_updateScene` (or a viewer's ``user_scn``).
        trace: The traces to draw, positions ``(k, T + 1, 3)``.
        radius: Capsule radius of the best trace (m); the others get 0.6 of it.
        max_segments: Most capsules per trace.

    Returns:
        The number of geoms added.
    """
    positions = np.asarray(trace.positions, dtype=np.float64)
    count, points = positions.shape[:2]
    keep = np.unique(np.linspace(0, points - 1, min(points, max_segments + 1)).round().astype(int))
    positions = positions[:, keep]
    added = 0
    for rank in reversed(range(count)):  # the best last, on top
        rgba = trace_colour(rank, count)
        width = radius if rank == 0 else 0.6 * radius
        path = positions[rank]
        for a, b in itertools.pairwise(path):
            if scene.ngeom >= scene.maxgeom:
                return added
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or np.array_equal(a, b):
                continue
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, _ZERO, _ZERO, _IDENTITY, rgba)
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width, a, b)
            scene.ngeom += 1
            added += 1
    return added


__all__ = ["BEST_RGBA", "ELITE_RGB", "add_trace_geoms", "trace_colour"]
