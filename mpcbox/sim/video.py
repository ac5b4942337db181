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
import os
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError
from mpcbox.sim.trajectory import Trajectory
from mpcbox.validation import positive, positive_int

#: Video formats by file suffix.
FORMATS = (".mp4", ".gif")
#: Colour of the frame border while a push acts (RGB).
PUSH_COLOUR = (220, 30, 30)
_BORDER = 6


def check_video_path(path: str | Path) -> str:
    """The format (``".mp4"`` or ``".gif"``) of a video path, checked before rendering.

    Raises:
        InvalidArgumentError: For another suffix.
        BackendUnavailableError: For an MP4 without imageio-ffmpeg.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InvalidArgumentError(
            f"video path {str(path)!r} must end in {' or '.join(FORMATS)}, got {suffix or '(none)'}"
        )
    if suffix == ".mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError as exc:
            raise BackendUnavailableError(
                "writing an MP4 needs imageio-ffmpeg (pip install 'mpcbox[video]'); "
                "a .gif needs nothing more"
            ) from exc
    return suffix


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """An offscreen :class:`mujoco.Renderer` of ``width x height`` pixels.

    Raises:
        BackendUnavailableError: If no OpenGL context can be made; the message names the
            ``MUJOCO_GL`` in force and the values to try.
    """
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # MuJoCo, PyOpenGL and GLFW raise many types here
        gl = os.environ.get("MUJOCO_GL")
        shown = f"MUJOCO_GL={gl!r}" if gl is not None else "MUJOCO_GL unset (GLFW, needs a display)"
        raise BackendUnavailableError(
            f"cannot make an OpenGL context for offscreen rendering ({shown}): "
            f"{type(exc).__name__}: {exc}. Set MUJOCO_GL=egl (GPU or Mesa EGL) or "
            "MUJOCO_GL=osmesa (software, needs libOSMesa) before starting Python"
        ) from exc


def _tracked_body(model: mujoco.MjModel) -> int:
    """The root body of a floating base (its free joint), or 0 for a fixed base."""
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            return int(model.jnt_bodyid[j])
    return 0


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


def _caption(frame: np.ndarray, lines: list[str], border: bool) -> np.ndarray:
    from PIL import Image, ImageDraw

    if border:
        frame[:_BORDER], frame[-_BORDER:] = PUSH_COLOUR, PUSH_COLOUR
        frame[:, :_BORDER], frame[:, -_BORDER:] = PUSH_COLOUR, PUSH_COLOUR
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    for i, line in enumerate(lines):
        colour = PUSH_COLOUR if i else (255, 255, 255)
        draw.text((_BORDER + 6, _BORDER + 4 + 14 * i), line, fill=colour)
    return np.asarray(image)


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
        cam = mujoco.MjvCamera()
        mujoco.mjv_defaultFreeCamera(model, cam)
        if traj.pushes:  # look across the first push, so that its arrow is seen side-on
            force = np.asarray(traj.pushes[0].force, dtype=float)
            cam.azimuth = float(np.degrees(np.arctan2(force[1], force[0]))) + 90.0
    track = _tracked_body(model)
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
            yield _caption(renderer.render().copy(), lines, bool(active))
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
        traj: The run (:func:`~mpcbox.sim.trajectory.load_trajectory`,
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
    path = Path(path)
    suffix = check_video_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidArgumentError(f"cannot create the folder of {str(path)!r}: {exc}") from exc
    frames = render_frames(traj, problem, fps=fps, width=width, height=height, camera=camera)
    if suffix == ".gif":
        from PIL import Image

        images = [Image.fromarray(f).convert("P", palette=Image.Palette.ADAPTIVE) for f in frames]
        images[0].save(
            path,
            save_all=True,
            append_images=images[1:],
            duration=max(20, round(1000 / fps)),
            loop=0,
        )
        return path
    import imageio_ffmpeg

    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, macro_block_size=1)
    writer.send(None)
    try:
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
    finally:
        writer.close()
    return path
