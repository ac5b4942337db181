"""Writes frames to a video file as they come: GIF (Pillow) or MP4 (``imageio-ffmpeg``).

Shared by :func:`~mpcbox.sim.video.render_video` (a saved run) and the offscreen viewer
(:class:`~mpcbox.sim.offscreen_viewer.OffscreenViewer`, a running one). An MP4 streams each
frame to ffmpeg; a GIF keeps each frame reduced to its own 256-colour palette (octree
quantization; ``width x height`` bytes a frame) until :meth:`FrameWriter.close` writes the
file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mpcbox.errors import InvalidArgumentError, ShapeError
from mpcbox.validation import positive, positive_int

#: Video formats by file suffix.
FORMATS = (".mp4", ".gif")


def check_video_path(path: str | Path) -> str:
    """The format (``".mp4"`` or ``".gif"``) of a video path, checked before rendering.

    Raises:
        InvalidArgumentError: For another suffix.
        BackendUnavailableError: For an MP4 without imageio-ffmpeg.
    """
    from mpcbox.errors import BackendUnavailableError

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


class FrameWriter:
    """A video file that takes RGB frames ``(height, width, 3)`` (uint8) one at a time.

    Args:
        path: Output file; the suffix (``.gif`` or ``.mp4``) picks the format; folders are
            created.
        fps: Frames per second.
        width: Frame width (pixels).
        height: Frame height (pixels).

    Attributes:
        frames: Frames written so far.

    Raises:
        InvalidArgumentError: For another suffix or a folder that cannot be created.
        BackendUnavailableError: For an MP4 without imageio-ffmpeg.
    """

    def __init__(self, path: str | Path, *, fps: float, width: int, height: int) -> None:
        self.path = Path(path)
        self.suffix = check_video_path(self.path)
        self.fps = positive("fps", fps)
        self.width, self.height = positive_int("width", width), positive_int("height", height)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InvalidArgumentError(
                f"cannot create the folder of {str(self.path)!r}: {exc}"
            ) from exc
        self.frames = 0
        self._images: list[Any] = []
        self._ffmpeg: Any = None
        if self.suffix == ".mp4":
            import imageio_ffmpeg

            self._ffmpeg = imageio_ffmpeg.write_frames(
                str(self.path), (self.width, self.height), fps=self.fps, macro_block_size=1
            )
            self._ffmpeg.send(None)

    def write(self, frame: np.ndarray) -> None:
        """Append one frame ``(height, width, 3)`` (uint8 RGB)."""
        frame = np.asarray(frame)
        if frame.shape != (self.height, self.width, 3):
            raise ShapeError(
                f"frame must have shape ({self.height}, {self.width}, 3), got {frame.shape}"
            )
        if self._ffmpeg is not None:
            self._ffmpeg.send(np.ascontiguousarray(frame, dtype=np.uint8))
        else:
            from PIL import Image

            image = Image.fromarray(frame.astype(np.uint8, copy=False))
            # Octree keeps small patches of a vivid colour (thin trace lines) that median cut
            # merges into their surroundings.
            self._images.append(image.quantize(256, method=Image.Quantize.FASTOCTREE))
        self.frames += 1

    def close(self) -> Path | None:
        """Finish the file; returns its path, or ``None`` for a GIF without frames."""
        if self._ffmpeg is not None:
            self._ffmpeg.close()
            self._ffmpeg = None
            return self.path
        images, self._images = self._images, []
        if not images:
            return None
        images[0].save(
            self.path,
            save_all=True,
            append_images=images[1:],
            duration=max(20, round(1000 / self.fps)),
            loop=0,
        )
        return self.path


__all__ = ["FORMATS", "FrameWriter", "check_video_path"]
