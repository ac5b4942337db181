"""A video of a running simulation with the planner's traces, rendered offscreen.

Where no window can open (a server, CI), :class:`OffscreenViewer` renders each frame with an
offscreen :class:`mujoco.Renderer` (``MUJOCO_GL=egl`` or ``MUJOCO_GL=osmesa`` on a headless
machine, set before MuJoCo is imported), adds the traces to the renderer's scene as lines
or capsules (:func:`~mpcbox.sim.trace_geoms.add_trace_geoms`, after ``update_scene``) and
writes the frames to a GIF or MP4 (:class:`~mpcbox.sim.video_writer.FrameWriter`). The
caption gives the controller, the simulated time and the best trace's cost.

Rendering is done in the loop's thread: each frame costs the renderer's time (tens of ms
with software OpenGL), which a real-time run sees as world lag.
"""

from __future__ import annotations

import copy
from pathlib import Path

import mujoco

from mpcbox.controllers.base import Controller
from mpcbox.controllers.sampling.traces import PlannerTrace
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError
from mpcbox.sim.rendering import caption, free_camera, make_renderer, tracked_body
from mpcbox.sim.trace_geoms import add_trace_geoms
from mpcbox.sim.video_writer import FrameWriter, check_video_path
from mpcbox.sim.viewer import Viewer
from mpcbox.validation import positive_int


class OffscreenViewer(Viewer):
    """Writes a video of the run, with the planner's traces, to ``path``.

    Args:
        path: ``.gif`` or ``.mp4`` file (checked here; folders are created at the start).
        fps: Frames per simulated second.
        width: Frame width (pixels; MP4 wants a multiple of 16).
        height: Frame height (pixels).
        camera: A camera of the model, by name, or a :class:`mujoco.MjvCamera` (a free
            camera: ``lookat``, ``distance``, ``azimuth``, ``elevation``); default: MuJoCo's
            free camera of the model, following a floating base horizontally.
        traces: Best candidates traced per tick (0: the world only).
        site: The site to trace, by name.
        body: The body (frame origin) to trace instead.
        style: ``"line"`` or ``"capsule"`` (:mod:`mpcbox.sim.trace_geoms`).
        radius: Capsule radius of the best trace (m), for ``style="capsule"``.
        note: Text put before the message of a rendering error (the automatic choice says
            why no window was tried).

    Attributes:
        path: The video file.

    Raises:
        InvalidArgumentError: For a suffix other than ``.gif`` / ``.mp4``.
        BackendUnavailableError: For an MP4 without imageio-ffmpeg; from :meth:`start`,
            when no OpenGL context can be made (the message names ``MUJOCO_GL``).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        fps: float = 30.0,
        width: int = 640,
        height: int = 480,
        camera: str | mujoco.MjvCamera | None = None,
        traces: int = 8,
        site: str | None = None,
        body: str | None = None,
        style: str = "line",
        radius: float | None = None,
        note: str = "",
    ) -> None:
        super().__init__(fps=fps, traces=traces, site=site, body=body, style=style, radius=radius)
        check_video_path(path)
        self.path = Path(path)
        self.width, self.height = positive_int("width", width), positive_int("height", height)
        self.camera = camera
        self.note = str(note)
        self.renderer: mujoco.Renderer | None = None
        self.writer: FrameWriter | None = None
        self._cam: int | mujoco.MjvCamera = -1
        self._track = 0
        self._name = ""

    def open(self, problem: Problem, controller: Controller | None) -> None:
        assert self.model is not None
        model = copy.copy(self.model)
        model.vis.global_.offwidth = max(self.width, model.vis.global_.offwidth)
        model.vis.global_.offheight = max(self.height, model.vis.global_.offheight)
        if isinstance(self.camera, mujoco.MjvCamera):
            self._cam = self.camera
        elif self.camera is not None:
            self._cam = object_id(model, "camera", self.camera, "camera")
        else:
            self._cam = free_camera(model)
            self._track = tracked_body(model)
        try:
            self.renderer = make_renderer(model, self.width, self.height)
        except BackendUnavailableError as exc:
            if not self.note:
                raise
            raise BackendUnavailableError(f"{self.note}; and {exc}") from exc
        if controller is None:
            self._name = "replay"
        else:
            self._name = str(getattr(controller, "name", type(controller).__name__))
        try:
            self.writer = FrameWriter(self.path, fps=self.fps, width=self.width, height=self.height)
        except BaseException:
            self.renderer.close()
            self.renderer = None
            raise

    def draw(self, trace: PlannerTrace | None) -> None:
        assert self.renderer is not None and self.writer is not None and self.data is not None
        assert self.radius is not None
        data = self.data
        if isinstance(self._cam, mujoco.MjvCamera) and self._track:
            self._cam.lookat[:2] = data.subtree_com[self._track][:2]
        self.renderer.update_scene(data, camera=self._cam)
        line = f"{self._name}  t = {data.time:5.2f} s"
        if trace is not None:
            add_trace_geoms(self.renderer.scene, trace, style=self.style, radius=self.radius)
            line += f"  best J = {trace.costs[0]:.4g}"
        self.writer.write(caption(self.renderer.render().copy(), [line], False))

    def close(self) -> Path | None:
        out = None
        try:
            if self.writer is not None:
                out = self.writer.close()
        finally:
            self.writer = None
            if self.renderer is not None:
                self.renderer.close()
                self.renderer = None
        return out


__all__ = ["OffscreenViewer"]
