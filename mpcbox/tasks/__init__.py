"""Ready-made Problems (tasks) for the scenes in ``scenes/``; see :mod:`mpcbox.registry`."""

from __future__ import annotations

from pathlib import Path

from mpcbox.errors import ModelNotFoundError

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def scene_path(name: str) -> Path:
    """Path of a scene shipped in the repository's ``scenes/`` folder."""
    path = SCENES / name
    if not path.is_file():
        raise ModelNotFoundError(
            f"scene {name!r} not found in {SCENES}; mpcbox's tasks need a source checkout "
            "(pip install -e .)"
        )
    return path
