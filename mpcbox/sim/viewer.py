r"""What a viewer of a running simulation is: a sink :func:`~mpcbox.simulate` and
:func:`~mpcbox.sim.realtime.simulate_realtime` feed while they run (their ``viewer=``).

The loop calls :meth:`Viewer.start` before its first step, :meth:`Viewer.step` at every
simulation step (after the controller's call, before the world steps) and
:meth:`Viewer.finish` at the end, also when the run fails or raises. The viewer draws a
frame every ``1 / fps`` simulated seconds: the world in the step's state and, for a
sampling controller, its latest :class:`~mpcbox.controllers.sampling.traces.PlannerTrace`.

A viewer never touches the simulation's ``MjData``: it copies the full physics state into
its own data and runs :func:`mujoco.mj_forward` there, so a run with a viewer is the same
run as without. When the controller has ``record_traces`` (the sampling controllers) and
records none yet, :meth:`Viewer.start` turns recording on with the viewer's ``traces``,
``site`` and ``body`` and :meth:`Viewer.finish` turns it off again
(:meth:`~mpcbox.controllers.sampling.SamplingController.record_traces` says what that costs).

Two viewers exist: :class:`~mpcbox.sim.live_viewer.LiveViewer` (a window,
:func:`mujoco.viewer.launch_passive`) and :class:`~mpcbox.sim.offscreen_viewer.OffscreenViewer`
(a GIF or MP4 through an offscreen :class:`mujoco.Renderer`);
:func:`~mpcbox.sim.viewer_choice.make_viewer` picks one.
"""

from __future__ import annotations

import abc
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.controllers.sampling.traces import PlannerTrace
from mpcbox.core.problem import Problem
from mpcbox.sim.trace_geoms import STYLES
from mpcbox.validation import integer, one_of, optional_positive, positive

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


class Viewer(abc.ABC):
    """A sink that draws a running simulation and the planner's traces.

    Args:
        fps: Frames per simulated second.
        traces: Best candidates traced per tick (0: draw the world only).
        site: The site to trace, by name (default: see
            :meth:`~mpcbox.controllers.sampling.SamplingController.record_traces`).
        body: The body (frame origin) to trace instead of a site.
        style: Draw the traces as ``"line"`` (a few pixels wide, cheap) or ``"capsule"``
            (shaded; several times dearer to render with software OpenGL).
        radius: Capsule radius of the best trace (m); default 0.4 % of the model's extent.

    Attributes:
        frames: Frames drawn so far.
        model: The drawn model (set by :meth:`start`).
        data: The viewer's own copy of the world's state (set by :meth:`start`).
    """

    def __init__(
        self,
        *,
        fps: float = 30.0,
        traces: int = 8,
        site: str | None = None,
        body: str | None = None,
        style: str = "line",
        radius: float | None = None,
    ) -> None:
        self.fps = positive("fps", fps)
        self.style = one_of("style", style, STYLES)
        self.traces = integer("traces", traces, 0)
        self.site, self.body = site, body
        self.radius = optional_positive("radius", radius)
        self.frames = 0
        self.model: mujoco.MjModel | None = None
        self.data: mujoco.MjData | None = None
        self.controller: Controller | None = None
        self._own_recorder = False
        self._next = -np.inf
        self._buffer = np.zeros(0)

    # ------------------------------------------------------------------ for the loops
    def start(
        self,
        problem: Problem,
        controller: Controller | None,
        model: mujoco.MjModel,
        data: mujoco.MjData,
    ) -> None:
        """Prepare to draw ``model``; turn the controller's trace recording on if needed.

        Args:
            problem: The Problem simulated.
            controller: The controller (its ``traces`` are drawn when it has any), or
                ``None`` when nothing plans (a replay).
            model: The simulated model (with any mismatch).
            data: The simulation's data (only read).

        Raises:
            BackendUnavailableError: When the viewer cannot draw here (no display, no
                OpenGL context); the message says what to set.
            UnknownNameError: For a traced site or body the planning model lacks.
        """
        self.controller = controller
        self.model = model
        self.data = mujoco.MjData(model)
        self._buffer = np.zeros(mujoco.mj_stateSize(model, _FULL))
        record = getattr(controller, "record_traces", None)
        if (
            self.traces > 0
            and record is not None
            and getattr(controller, "trace_recorder", None) is None
        ):
            record(self.traces, site=self.site, body=self.body)
            self._own_recorder = True
        if self.radius is None:
            self.radius = 0.004 * float(model.stat.extent)
        self._next = float(data.time)
        try:
            self.open(problem, controller)
        except BaseException:
            self._release()
            raise

    def step(self, data: mujoco.MjData) -> None:
        """Draw a frame of ``data`` (the simulation's) when one is due."""
        now = float(data.time)
        if now < self._next - 1e-9:
            return
        while self._next <= now + 1e-9:
            self._next += 1.0 / self.fps
        assert self.model is not None and self.data is not None
        mujoco.mj_getState(self.model, data, self._buffer, _FULL)
        mujoco.mj_setState(self.model, self.data, self._buffer, _FULL)
        mujoco.mj_forward(self.model, self.data)
        self.draw(self.current_trace())
        self.frames += 1

    def finish(self) -> Path | None:
        """Close the viewer; returns the written video, if any."""
        try:
            return self.close()
        finally:
            self._release()

    def current_trace(self) -> PlannerTrace | None:
        """The controller's latest traces (``None`` without any, or with ``traces=0``)."""
        if self.traces == 0:
            return None
        trace = getattr(self.controller, "traces", None)
        return trace if isinstance(trace, PlannerTrace) else None

    def _release(self) -> None:
        if self._own_recorder and self.controller is not None:
            self.controller.record_traces(None)  # type: ignore[attr-defined]
        self._own_recorder = False

    # ------------------------------------------------------------------ for the viewers
    @abc.abstractmethod
    def open(self, problem: Problem, controller: Controller | None) -> None:
        """Make the window or the renderer for :attr:`model` and :attr:`data`."""

    @abc.abstractmethod
    def draw(self, trace: PlannerTrace | None) -> None:
        """Draw :attr:`data` (forwarded) and ``trace``."""

    @abc.abstractmethod
    def close(self) -> Any:
        """Release the window or renderer; return the written file, if any."""


__all__ = ["Viewer"]
