"""MuJoCo Menagerie robots, through the ``mujoco-menagerie`` package.

``mujoco_menagerie`` downloads a robot on first use and reads ``MENAGERIE_ROOT`` (a folder
holding ``unitree_g1/``, ``franka_emika_panda/``, ...) for an offline copy. mpcbox only adds
one thing on top: a copy exported from a partial mirror may lack large visual meshes, so a
*visual-only* geom (no collisions: ``contype == conaffinity == 0``) whose mesh file is missing
is dropped, with a warning that names it. A missing collision mesh is an error: dropping it
would change the physics.

Install the optional extra with ``pip install "mpcbox[menagerie]"``.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import mujoco

from mpcbox.errors import (
    BackendUnavailableError,
    ModelLoadError,
    ModelNotFoundError,
    UnknownNameError,
)

#: Prefix that :func:`mpcbox.core.model.load_spec` reads as a Menagerie robot name.
PREFIX = "menagerie:"


def model_source(model: str) -> str:
    """A command-line model argument as a model source: a bare Menagerie name
    (``"unitree_g1"``) becomes ``"menagerie:unitree_g1"``; an MJCF path (an existing file,
    or a name containing ``/`` or ending in ``.xml`` in any case) or an already prefixed
    name stays as given."""
    if (
        model.startswith(PREFIX)
        or "/" in model
        or model.lower().endswith(".xml")
        or Path(model).is_file()
    ):
        return model
    return PREFIX + model


class MissingMeshWarning(UserWarning):
    """A visual-only geom was dropped because its mesh file is missing."""


def _package():
    try:
        import mujoco_menagerie
    except ImportError as exc:
        raise BackendUnavailableError(
            "Menagerie robots need the mujoco-menagerie package: pip install 'mpcbox[menagerie]' "
            "(set MENAGERIE_ROOT to use an offline copy)"
        ) from exc
    return mujoco_menagerie


def robot_xml(name: str, entry: str | None = None) -> Path:
    """Path of a Menagerie robot's MJCF (its default scene when ``entry`` is ``None``).

    Args:
        name: Robot name, e.g. ``"unitree_g1"`` or ``"franka_emika_panda"``.
        entry: Entry point, e.g. ``"scene"`` or ``"panda"`` (default: the robot's scene).

    Raises:
        UnknownNameError: If Menagerie has no such robot or entry (lists the valid ones).
        ModelNotFoundError: If the robot cannot be found or downloaded.
        BackendUnavailableError: If ``mujoco-menagerie`` is not installed.
    """
    root = os.environ.get("MENAGERIE_ROOT")
    try:
        mm = _package()
    except BackendUnavailableError:
        if not root:
            raise
        return _from_root(Path(root), name, entry)
    if name not in mm.names():
        raise UnknownNameError("Menagerie robot", name, mm.names())
    robot = mm.get(name)
    if entry is not None and entry not in robot.entry_names:
        raise UnknownNameError(f"entry point of {name}", entry, robot.entry_names)
    try:
        return Path(robot.xml(entry))
    except mm.MenagerieError as exc:
        root = os.environ.get("MENAGERIE_ROOT")
        where = f"MENAGERIE_ROOT={root}" if root else "the download cache (MENAGERIE_ROOT unset)"
        raise ModelNotFoundError(f"Menagerie robot {name!r} not found in {where}: {exc}") from exc


def _from_root(root: Path, name: str, entry: str | None) -> Path:
    """A robot's MJCF in an offline copy (``MENAGERIE_ROOT``) without the package: the
    robot's folder, and ``<entry>.xml`` in it (``scene.xml`` by default)."""
    robots = sorted(p.name for p in root.iterdir() if p.is_dir()) if root.is_dir() else []
    if name not in robots:
        raise UnknownNameError(f"Menagerie robot in MENAGERIE_ROOT={root}", name, robots)
    entries = sorted(p.stem for p in (root / name).glob("*.xml"))
    chosen = entry or "scene"
    if chosen not in entries:
        raise UnknownNameError(f"entry point of {name}", chosen, entries)
    return root / name / f"{chosen}.xml"


def available(name: str, entry: str | None = None) -> bool:
    """Whether the robot's MJCF can be found without error (used to skip tests)."""
    try:
        return robot_xml(name, entry).is_file()
    except Exception:
        return False


def _mesh_path(spec: mujoco.MjSpec, file: str) -> Path:
    path = Path(file)
    if path.is_absolute():
        return path
    return Path(spec.modelfiledir) / (spec.meshdir or "") / path


def drop_missing_visual_meshes(spec: mujoco.MjSpec) -> list[str]:
    """Delete visual-only geoms whose mesh file is missing, and those meshes.

    Args:
        spec: A spec parsed from a file (mesh paths are resolved against its directory).

    Returns:
        The names of the dropped meshes.

    Raises:
        ModelLoadError: If a geom that collides uses a missing mesh.
    """
    missing = {m.name: m for m in spec.meshes if m.file and not _mesh_path(spec, m.file).is_file()}
    if not missing:
        return []
    for geom in list(spec.geoms):
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH or geom.meshname not in missing:
            continue
        if geom.contype or geom.conaffinity:
            raise ModelLoadError(
                f"collision geom {geom.name or '(unnamed)'!r} uses mesh {geom.meshname!r}, whose "
                f"file {str(_mesh_path(spec, missing[geom.meshname].file))!r} is missing"
            )
        spec.delete(geom)
    for mesh in missing.values():
        spec.delete(mesh)
    names = sorted(missing)
    warnings.warn(
        f"dropped {len(names)} visual-only mesh(es) whose files are missing: {', '.join(names)}",
        MissingMeshWarning,
        stacklevel=3,
    )
    return names


def robot_spec(name: str, entry: str | None = None) -> mujoco.MjSpec:
    """An editable spec of a Menagerie robot, with missing visual-only meshes dropped.

    Args:
        name: Robot name (see :func:`robot_xml`).
        entry: Entry point (default: the robot's scene).
    """
    path = robot_xml(name, entry)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise ModelLoadError(f"model: MuJoCo could not parse {str(path)!r}: {exc}") from exc
    drop_missing_visual_meshes(spec)
    return spec
