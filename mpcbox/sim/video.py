"""Offscreen videos of a run: :func:`render_video` writes an MP4 or a GIF of a Trajectory.

Frames are rendered with :class:`mujoco.Renderer`, which needs an OpenGL context without a
window. MuJoCo picks the backend from the environment variable ``MUJOCO_GL`` when it is
first imported: ``MUJOCO_GL=egl`` (GPU or Mesa's EGL) or ``MUJOCO_GL=osmesa`` (software,
needs libOSMesa) on a headless machine; where no context can be made,
:class:`~mpcbox.errors.BackendUnavailableError` says so and names ``MUJOCO_GL``.

While a push acts, the frame gets a red border, an arrow at the pushed body along the force
and a caption with the force; every frame shows the simulated time. With pushes, the
free camera looks across the first push's direction.

Writers: GIF with Pillow (installed with matplotlib); MP4 with ``imageio-ffmpeg``
(``pip install 'mpcbox[video]'``), imported only when an MP4 is asked for.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.sim.rendering import PUSH_COLOUR, caption, free_camera, make_renderer, tracked_body
from mpcbox.sim.trajectory import Trajectory
from mpcbox.sim.video_writer import FORMATS, FrameWriter, check_video_path
from mpcbox.validation import positive, positive_int


def _arrow(scene: mujoco.MjvScene, tip: np.ndarray, force: np.ndarray, extent: float) -> None:
    norm = float(np.linalg.norm(force))
    if norm == 0.0 or scene.ngeom >= scene.maxgeom:
        return
    length = 0.4 * extent
    tail = tip - length * force / norm
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        geom,
        mujoco.mjtGeom.mjGEOM_ARROW,
        np.zeros(3),
        np.zeros(3),
        np.eye(3).ravel(),
        np.array([0.86, 0.12, 0.12, 1.0], dtype=np.float32),
    )
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, 0.03 * extent, tail, tip)
    scene.ngeom += 1


def render_frames(
    traj: Trajectory,
    problem: Problem,
    *,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    camera: str | None = None,
) -> Iterator[np.ndarray]:
    """Frames ``(height, width, 3)`` (uint8 RGB) of ``traj``, one every ``1 / fps`` seconds.

    Each frame shows the recorded state at or just before its time. Without ``camera``, a
    free camera looks at the model and follows a floating base horizontally.

    Args:
        traj: The run.
        problem: The Problem it ran on (its simulation model is drawn).
        fps: Frames per simulated second.
        width: Frame width (pixels).
        height: Frame height (pixels).
        camera: A camera of the model, by name.

    Raises:
        BackendUnavailableError: If no OpenGL context can be made (names ``MUJOCO_GL``).
    """
    fps = positive("fps", fps)
    width, height = positive_int("width", width), positive_int("height", height)
    model = copy.copy(problem.model)
    model.vis.global_.offwidth = max(width, model.vis.global_.offwidth)
    model.vis.global_.offheight = max(height, model.vis.global_.offheight)
    cam: int | mujoco.MjvCamera
    if camera is not None:
        cam = object_id(model, "camera", camera)
    else:
        cam = free_camera(model)
        if traj.pushes:  # look across the first push, so that its arrow is seen side-on
            force = np.asarray(traj.pushes[0].force, dtype=float)
            cam.azimuth = float(np.degrees(np.arctan2(force[1], force[0]))) + 90.0
    track = tracked_body(model)
    push_ids = [object_id(model, "body", p.body) for p in traj.pushes]
    extent = float(model.stat.extent)
    renderer = make_renderer(model, width, height)
    data = mujoco.MjData(model)
    nq, nv = problem.nq, problem.nv
    try:
        count = int(np.floor((traj.time[-1] - traj.time[0]) * fps + 1e-9)) + 1
        for f in range(count):
            t = traj.time[0] + f / fps
            k = max(0, int(np.searchsorted(traj.time, t + 1e-9, side="right")) - 1)
            state = traj.states[k]
            if np.all(np.isfinite(state)):
                data.qpos[:], data.qvel[:] = state[:nq], state[nq : nq + nv]
            data.time = float(traj.time[k])
            mujoco.mj_forward(model, data)
            if isinstance(cam, mujoco.MjvCamera) and track:
                cam.lookat[:2] = data.subtree_com[track][:2]
            renderer.update_scene(data, camera=cam)
            active = [(p, b) for p, b in zip(traj.pushes, push_ids) if p.active(data.time)]
            lines = [f"{traj.controller}  t = {data.time:5.2f} s"]
            for push, bid in active:
                force = np.asarray(push.force, dtype=float)
                _arrow(renderer.scene, data.xipos[bid].copy(), force, extent)
                lines.append(f"push {np.linalg.norm(force):.0f} N on {push.body}")
            yield caption(renderer.render().copy(), lines, bool(active))
    finally:
        renderer.close()


def render_video(
    traj: Trajectory,
    problem: Problem,
    path: str | Path,
    *,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    camera: str | None = None,
) -> Path:
    """Write a video of ``traj`` to ``path`` (``.mp4`` or ``.gif``), in real time.

    Args:
        traj: The run (:func:`~mpcbox.sim.trajectory_files.load_trajectory`,
            :func:`~mpcbox.sim.trajectory.trajectory_from_result`).
        problem: The Problem it ran on.
        path: Output file; the suffix picks the format; folders are created.
        fps: Frames per second.
        width: Frame width (pixels; MP4 wants a multiple of 16).
        height: Frame height (pixels).
        camera: A camera of the model, by name (default: a free camera).

    Returns:
        The written path.

    Raises:
        InvalidArgumentError: For another suffix.
        BackendUnavailableError: If no OpenGL context can be made (names ``MUJOCO_GL``), or
            an MP4 is asked for without imageio-ffmpeg.
    """
    writer = FrameWriter(path, fps=fps, width=width, height=height)
    try:
        for frame in render_frames(
            traj, problem, fps=fps, width=width, height=height, camera=camera
        ):
            writer.write(frame)
    finally:
        out = writer.close()
    return out or Path(path)


__all__ = [
    "FORMATS",
    "PUSH_COLOUR",
    "caption",
    "check_video_path",
    "free_camera",
    "make_renderer",
    "render_frames",
    "render_video",
    "tracked_body",
]
