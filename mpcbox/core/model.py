"""Loading MuJoCo models and resolving names, with errors that list the valid names."""

from __future__ import annotations

from pathlib import Path

import mujoco

from mpcbox.errors import InvalidArgumentError, ModelLoadError, ModelNotFoundError, UnknownNameError

ModelSource = str | Path | mujoco.MjSpec | mujoco.MjModel

_OBJ_KINDS = {
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "joint": mujoco.mjtObj.mjOBJ_JOINT,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "keyframe": mujoco.mjtObj.mjOBJ_KEY,
    "geom": mujoco.mjtObj.mjOBJ_GEOM,
    "sensor": mujoco.mjtObj.mjOBJ_SENSOR,
}
_COUNTS = {
    "body": "nbody",
    "site": "nsite",
    "joint": "njnt",
    "actuator": "nu",
    "keyframe": "nkey",
    "geom": "ngeom",
    "sensor": "nsensor",
}


def load_spec(source: str | Path | mujoco.MjSpec) -> mujoco.MjSpec:
    """An editable :class:`mujoco.MjSpec` from an MJCF path, an XML string or a spec.

    Raises:
        ModelNotFoundError: If a path does not exist.
        ModelLoadError: If MuJoCo cannot parse the file.
    """
    if isinstance(source, mujoco.MjSpec):
        return source.copy()
    if isinstance(source, str) and source.lstrip().startswith("<"):
        try:
            return mujoco.MjSpec.from_string(source)
        except Exception as exc:
            raise ModelLoadError(f"model: MuJoCo could not parse the XML string: {exc}") from exc
    path = Path(source)
    if not path.is_file():
        raise ModelNotFoundError(f"model: no MJCF file at {str(path)!r}")
    try:
        return mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise ModelLoadError(f"model: MuJoCo could not load {str(path)!r}: {exc}") from exc


def compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """Compile a spec, turning MuJoCo's exception into :class:`ModelLoadError`."""
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelLoadError(f"model: MuJoCo could not compile the model: {exc}") from exc


def names(model: mujoco.MjModel, kind: str) -> list[str]:
    """All names of one object kind (``"body"``, ``"site"``, ``"joint"``, ...)."""
    if kind not in _OBJ_KINDS:
        raise InvalidArgumentError(f"kind must be one of {sorted(_OBJ_KINDS)}, got {kind!r}")
    count = getattr(model, _COUNTS[kind])
    out = []
    for i in range(count):
        name = mujoco.mj_id2name(model, _OBJ_KINDS[kind], i)
        if name:
            out.append(name)
    return out


def object_id(model: mujoco.MjModel, kind: str, name: str | int) -> int:
    """The id of a named object; an integer is checked and returned.

    Raises:
        UnknownNameError: If no object of that kind has that name (lists the valid names).
    """
    if kind not in _OBJ_KINDS:
        raise InvalidArgumentError(f"kind must be one of {sorted(_OBJ_KINDS)}, got {kind!r}")
    count = getattr(model, _COUNTS[kind])
    if isinstance(name, int):
        if not 0 <= name < count:
            raise InvalidArgumentError(f"{kind} id must be in [0, {count}), got {name}")
        return name
    idx = mujoco.mj_name2id(model, _OBJ_KINDS[kind], name)
    if idx < 0:
        raise UnknownNameError(kind, name, names(model, kind))
    return idx


def frame_object(model: mujoco.MjModel, name: str) -> tuple[str, int]:
    """Resolve a point-like frame: a site if one has this name, else a body.

    Returns:
        ``("site", id)`` or ``("body", id)``.
    """
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return "site", sid
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid >= 0:
        return "body", bid
    raise UnknownNameError("site or body", name, names(model, "site") + names(model, "body"))
