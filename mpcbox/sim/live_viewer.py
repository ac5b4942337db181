"""A live window on a running simulation: :func:`mujoco.viewer.launch_passive` with the
planner's traces drawn as lines or capsules in the window's ``user_scn``.

The window needs a display. On Linux MuJoCo's viewer (GLFW) ends the whole process when it
finds none, so :class:`LiveViewer` checks ``DISPLAY`` / ``WAYLAND_DISPLAY`` first and
raises :class:`~mpcbox.errors.BackendUnavailableError` instead; on macOS the script must run
under ``mjpython``. Where no display exists, use
:class:`~mpcbox.sim.offscreen_viewer.OffscreenViewer`.
"""

from __future__ import annotations

import os
import sys
import time as _time
from typing import Any

from mpcbox.controllers.base import Controller
from mpcbox.controllers.sampling.traces import PlannerTrace
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError
from mpcbox.sim.rendering import free_camera, tracked_body
from mpcbox.sim.trace_geoms import add_trace_geoms
from mpcbox.sim.viewer import Viewer
from mpcbox.validation import boolean

#: What to use instead of a window, for error messages.
OFFSCREEN_HINT = (
    "use an offscreen viewer instead (OffscreenViewer('run.gif'), or `mpcbox simulate ... "
    "--viewer run.gif`) with MUJOCO_GL=egl or MUJOCO_GL=osmesa"
)


def display_missing() -> str | None:
    """Why no window can open here, or ``None`` when a display seems available.

    On Linux and other X11/Wayland systems a display needs ``DISPLAY`` or
    ``WAYLAND_DISPLAY``; macOS and Windows are assumed to have one.
    """
    if sys.platform in ("darwin", "win32"):
        return None
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return None
    return "DISPLAY and WAYLAND_DISPLAY are unset (no display)"


class LiveViewer(Viewer):
    """A passive MuJoCo viewer window that follows the run, with the planner's traces.

    Args:
        fps: Window updates per simulated second.
        traces: Best candidates traced per tick (0: the world only).
        site: The site to trace, by name.
        body: The body (frame origin) to trace instead.
        style: ``"line"`` or ``"capsule"`` (:mod:`mpcbox.sim.trace_geoms`).
        radius: Capsule radius of the best trace (m), for ``style="capsule"``.
        realtime: Hold the loop to wall-clock time (sleep when the simulation runs ahead), so
            that a fast lock-step run is seen at its own speed. The real-time loop keeps its
            own clock; leave this off with its ``speed`` above 1.
        show_ui: Show MuJoCo's side panels.

    Raises:
        BackendUnavailableError: From :meth:`start`, without a display or when the window
            cannot open.
    """

    def __init__(
        self,
        *,
        fps: float = 60.0,
        traces: int = 8,
        site: str | None = None,
        body: str | None = None,
        style: str = "line",
        radius: float | None = None,
        realtime: bool = True,
        show_ui: bool = False,
    ) -> None:
        super().__init__(fps=fps, traces=traces, site=site, body=body, style=style, radius=radius)
        self.realtime = boolean("realtime", realtime)
        self.show_ui = boolean("show_ui", show_ui)
        self.handle: Any = None
        self._clock: tuple[float, float] | None = None

    def open(self, problem: Problem, controller: Controller | None) -> None:
        reason = display_missing()
        if reason is not None:
            raise BackendUnavailableError(
                f"a live viewer needs a display: {reason}; {OFFSCREEN_HINT}"
            )
        try:
            import mujoco.viewer

            self.handle = mujoco.viewer.launch_passive(
                self.model,
                self.data,
                show_left_ui=self.show_ui,
                show_right_ui=self.show_ui,
            )
        except Exception as exc:  # GLFW, the macOS main-thread rule, ...
            raise BackendUnavailableError(
                f"cannot open a MuJoCo viewer window: {type(exc).__name__}: {exc} (on macOS, "
                f"run the script with mjpython); {OFFSCREEN_HINT}"
            ) from exc
        # Frame the whole model as the offscreen viewer does (the window's own default
        # looked down at the cart-pole's rail with the pole out of view), following a
        # floating base; the mouse still moves the camera.
        default = free_camera(self.model)
        body = tracked_body(self.model)
        with self.handle.lock():
            cam = self.handle.cam
            cam.lookat[:] = default.lookat
            cam.distance, cam.azimuth = default.distance, default.azimuth
            cam.elevation = default.elevation
            if body:
                cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
                cam.trackbodyid = body
        self._clock = None

    def draw(self, trace: PlannerTrace | None) -> None:
        handle = self.handle
        if handle is None or not handle.is_running():
            return  # the window was closed: the run goes on without it
        assert self.data is not None and self.radius is not None
        if self.realtime:
            now, sim = _time.perf_counter(), float(self.data.time)
            if self._clock is None:
                self._clock = (now, sim)
            ahead = (sim - self._clock[1]) - (now - self._clock[0])
            if ahead > 0:
                _time.sleep(ahead)
        with handle.lock():
            scene = handle.user_scn
            scene.ngeom = 0
            if trace is not None:
                add_trace_geoms(scene, trace, style=self.style, radius=self.radius)
        handle.sync()

    def close(self) -> None:
        if self.handle is not None:
            self.handle.close()
            self.handle = None


__all__ = ["OFFSCREEN_HINT", "LiveViewer", "display_missing"]
