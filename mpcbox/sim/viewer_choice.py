"""Which viewer to use: a window where there is a display, a video file where there is none.

:func:`make_viewer` picks :class:`~mpcbox.sim.live_viewer.LiveViewer` or
:class:`~mpcbox.sim.offscreen_viewer.OffscreenViewer`; :func:`as_viewer` turns the
``viewer=`` argument of :func:`~mpcbox.simulate` (a viewer, ``"live"``, ``"auto"`` or a
video path) into a viewer.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.live_viewer import OFFSCREEN_HINT, LiveViewer, display_missing
from mpcbox.sim.offscreen_viewer import OffscreenViewer
from mpcbox.sim.viewer import Viewer
from mpcbox.validation import one_of

#: Modes of :func:`make_viewer`.
MODES: tuple[str, ...] = ("auto", "live", "offscreen")

#: Options that only the offscreen viewer takes.
_OFFSCREEN_ONLY = ("width", "height", "camera")


def make_viewer(path: str | Path | None = None, *, mode: str = "auto", **options: Any) -> Viewer:
    """A live viewer when a display exists, otherwise an offscreen one writing ``path``.

    Args:
        path: The video file (``.gif`` / ``.mp4``) of the offscreen viewer.
        mode: ``"auto"`` (a window when :func:`~mpcbox.sim.live_viewer.display_missing`
            finds a display, else the video), ``"live"`` or ``"offscreen"``.
        **options: Options of the chosen viewer (``fps``, ``traces``, ``site``, ``body``,
            ``radius``; ``width``, ``height``, ``camera`` for the video, which the window
            ignores).

    Raises:
        InvalidArgumentError: For another mode, or no ``path`` where a video is needed.
        BackendUnavailableError: For ``mode="live"`` without a display.
    """
    one_of("mode", mode, MODES)
    missing = display_missing()
    if mode == "live" or (mode == "auto" and missing is None):
        if mode == "live" and missing is not None:
            from mpcbox.errors import BackendUnavailableError

            raise BackendUnavailableError(
                f"mode='live' needs a display: {missing}; {OFFSCREEN_HINT}"
            )
        live = {k: v for k, v in options.items() if k not in _OFFSCREEN_ONLY}
        return LiveViewer(**live)
    if path is None:
        why = f"there is no display ({missing})" if mode == "auto" else "mode='offscreen'"
        raise InvalidArgumentError(
            f"path is needed: {why}, so the viewer writes a video; give a .gif or .mp4 path"
        )
    note = f"no live viewer: {missing}" if mode == "auto" else ""
    return OffscreenViewer(path, note=note, **options)


def as_viewer(viewer: Viewer | str | Path | None) -> Viewer | None:
    """The viewer that a ``viewer=`` argument asks for.

    Args:
        viewer: ``None``; a :class:`~mpcbox.sim.viewer.Viewer`; ``"live"`` (a window);
            ``"auto"`` (a window where there is a display; an error otherwise, since no
            video path is given); or a ``.gif`` / ``.mp4`` path (an offscreen video).

    Raises:
        InvalidTypeError: For another type.
        InvalidArgumentError: For a string that is neither a mode nor a video path.
    """
    if viewer is None or isinstance(viewer, Viewer):
        return viewer
    if isinstance(viewer, str) and viewer in ("live", "auto"):
        return make_viewer(None, mode=viewer)
    if isinstance(viewer, (str, Path)):
        if Path(viewer).suffix.lower() not in (".gif", ".mp4"):
            raise InvalidArgumentError(
                f"viewer must be 'live', 'auto' or a .gif/.mp4 path, got {str(viewer)!r}"
            )
        return OffscreenViewer(viewer)
    raise InvalidTypeError(
        "viewer must be a Viewer (LiveViewer, OffscreenViewer), 'live', 'auto' or a "
        f".gif/.mp4 path, got {type(viewer).__name__}"
    )


__all__ = ["MODES", "as_viewer", "make_viewer"]
