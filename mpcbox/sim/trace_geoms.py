r"""Draws a planner's traces (:class:`~mpcbox.controllers.sampling.traces.PlannerTrace`) as
lines or capsules in a MuJoCo scene.

Trace :math:`i` of ``k`` (best first) is the polyline through its points
:math:`p^{(i)}_0, \dots, p^{(i)}_T`; each segment :math:`[p_t, p_{t+1}]` becomes one geom
(:func:`mujoco.mjv_connector`): a line of a fixed width in pixels (``style="line"``, cheap
to render) or a capsule of a radius in metres (``style="capsule"``, shaded and lit like the
model, several times dearer with software OpenGL). A trace longer than ``max_segments``
segments is drawn through evenly spaced points of it (its ends kept), so ``k`` traces cost
at most ``k * max_segments`` geoms of the scene (about 25 us each to fill from Python). The
best trace is green and drawn last; the others are orange, fading with their rank.
Segments with a non-finite end are skipped; drawing stops when the scene is full.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from mpcbox.controllers.sampling.traces import PlannerTrace
from mpcbox.validation import one_of, positive, positive_int

#: RGBA of the best trace.
BEST_RGBA = (0.15, 0.9, 0.25, 1.0)
#: RGB of the other traces (their alpha fades from 0.8 to 0.25 with rank).
ELITE_RGB = (1.0, 0.55, 0.1)
#: Geom kinds the traces can be drawn with.
STYLES: tuple[str, ...] = ("line", "capsule")
#: Line width of the best trace (pixels); the others get 2/3 of it.
LINE_WIDTH = 3.0

_IDENTITY = np.eye(3).ravel()
_ZERO = np.zeros(3)
_GEOM = {"line": mujoco.mjtGeom.mjGEOM_LINE, "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE}


def trace_colour(rank: int, count: int) -> np.ndarray:
    """RGBA ``(4,)`` (float32) of the trace of ``rank`` (0: best) among ``count``."""
    if rank == 0:
        return np.asarray(BEST_RGBA, dtype=np.float32)
    fade = (rank - 1) / max(1, count - 2)
    return np.asarray((*ELITE_RGB, 0.8 - 0.55 * fade), dtype=np.float32)


def add_trace_geoms(
    scene: mujoco.MjvScene,
    trace: PlannerTrace,
    *,
    style: str = "line",
    radius: float = 0.01,
    max_segments: int = 25,
) -> int:
    """Append the segments of ``trace`` to ``scene`` (after ``scene.ngeom``).

    Args:
        scene: A scene after :func:`mujoco.mjv_updateScene` (or a viewer's ``user_scn``).
        trace: The traces to draw, positions ``(k, T + 1, 3)``.
        style: ``"line"`` (:data:`LINE_WIDTH` pixels for the best trace, 2/3 of it for the
            others) or ``"capsule"``.
        radius: Capsule radius of the best trace (m); the others get 0.6 of it.
        max_segments: Most segments per trace.

    Returns:
        The number of geoms added.
    """
    one_of("style", style, STYLES)
    radius, max_segments = positive("radius", radius), positive_int("max_segments", max_segments)
    kind = _GEOM[style]
    positions = np.asarray(trace.positions, dtype=np.float64)
    count, points = positions.shape[:2]
    keep = np.unique(np.linspace(0, points - 1, min(points, max_segments + 1)).round().astype(int))
    positions = positions[:, keep]
    added = 0
    for rank in reversed(range(count)):  # the best last
        rgba = trace_colour(rank, count)
        if style == "line":
            width = LINE_WIDTH if rank == 0 else LINE_WIDTH * 2.0 / 3.0
        else:
            width = radius if rank == 0 else 0.6 * radius
        for a, b in itertools.pairwise(positions[rank]):
            if scene.ngeom >= scene.maxgeom:
                return added
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or np.array_equal(a, b):
                continue
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(geom, kind, _ZERO, _ZERO, _IDENTITY, rgba)
            mujoco.mjv_connector(geom, kind, width, a, b)
            scene.ngeom += 1
            added += 1
    return added


__all__ = ["BEST_RGBA", "ELITE_RGB", "LINE_WIDTH", "STYLES", "add_trace_geoms", "trace_colour"]
