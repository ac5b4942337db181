"""Offscreen rendering helpers shared by the videos of saved runs (:mod:`mpcbox.sim.video`)
and of running ones (:mod:`mpcbox.sim.offscreen_viewer`): the renderer, the default camera
and the caption.

:class:`mujoco.Renderer` needs an OpenGL context without a window. MuJoCo picks the backend
from the environment variable ``MUJOCO_GL`` when it is first imported: ``MUJOCO_GL=egl``
(GPU or Mesa's EGL) or ``MUJOCO_GL=osmesa`` (software, needs libOSMesa) on a headless
machine; where no context can be made, :func:`make_renderer` raises
:class:`~mpcbox.errors.BackendUnavailableError` naming ``MUJOCO_GL``.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from mpcbox.errors import BackendUnavailableError

#: Colour of the frame border while a push acts (RGB).
PUSH_COLOUR = (220, 30, 30)
_BORDER = 6

#: Why the first offscreen renderer of this process could not be made, if it could not: later
#: attempts raise at once (after a failed GLFW start a second one aborts the interpreter).
_GL_FAILURE: str | None = None


def make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """An offscreen :class:`mujoco.Renderer` of ``width x height`` pixels.

    Raises:
        BackendUnavailableError: If no OpenGL context can be made; the message names the
            ``MUJOCO_GL`` in force and the values to try.
    """
    global _GL_FAILURE
    if _GL_FAILURE is not None:  # a second try can abort the interpreter inside GLFW
        raise BackendUnavailableError(_GL_FAILURE)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # MuJoCo, PyOpenGL and GLFW raise many types here
        gl = os.environ.get("MUJOCO_GL")
        shown = f"MUJOCO_GL={gl!r}" if gl is not None else "MUJOCO_GL unset (GLFW, needs a display)"
        _GL_FAILURE = (
            f"cannot make an OpenGL context for offscreen rendering ({shown}): "
            f"{type(exc).__name__}: {exc}. Set MUJOCO_GL=egl (GPU or Mesa EGL) or "
            "MUJOCO_GL=osmesa (software, needs libOSMesa) before starting Python"
        )
        raise BackendUnavailableError(_GL_FAILURE) from exc


def tracked_body(model: mujoco.MjModel) -> int:
    """The root body of a floating base (its free joint), or 0 for a fixed base."""
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            return int(model.jnt_bodyid[j])
    return 0


def free_camera(model: mujoco.MjModel) -> mujoco.MjvCamera:
    """MuJoCo's default free camera of ``model``, looking at the whole model."""
    cam = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, cam)
    return cam


def caption(frame: np.ndarray, lines: list[str], border: bool) -> np.ndarray:
    """``frame`` ``(H, W, 3)`` with ``lines`` of text at its top left (the first white, the
    others in :data:`PUSH_COLOUR`) and, when ``border``, a :data:`PUSH_COLOUR` border."""
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


__all__ = ["PUSH_COLOUR", "caption", "free_camera", "make_renderer", "tracked_body"]
