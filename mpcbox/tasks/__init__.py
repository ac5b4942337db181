"""Ready-made Problems (tasks) and the MJCF scenes they ship with; see :mod:`mpcbox.registry`."""

from __future__ import annotations

from pathlib import Path

from mpcbox.errors import ModelNotFoundError

#: Folder of the MJCF scenes installed with the package.
SCENES = Path(__file__).resolve().parent / "scenes"


def scene_path(name: str) -> Path:
    """Path of a scene installed with mpcbox (``mpcbox/tasks/scenes/NAME``)."""
    path = SCENES / name
    if not path.is_file():
        raise ModelNotFoundError(
            f"scene {name!r} not found in {SCENES}; shipped scenes: "
            + ", ".join(sorted(p.name for p in SCENES.glob("*.xml")))
        )
    return path
