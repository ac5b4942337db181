"""Loading and checking MuJoCo models, and resolving names with errors that list valid names."""

from __future__ import annotations

import copy
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from mpcbox.core import menagerie
from mpcbox.errors import (
    InvalidArgumentError,
    InvalidTypeError,
    ModelLoadError,
    ModelNotFoundError,
    PlanningModelWarning,
    ShapeError,
    UnknownNameError,
)
from mpcbox.validation import positive

ModelSource = str | Path | mujoco.MjSpec | mujoco.MjModel

#: The integrator that replaces RK4 in planning models (:func:`plannable`):
#: ``mjd_transitionFD`` cannot differentiate RK4, and on damped, actuated test models the
#: implicitfast step's ``A`` and ``B`` are as close to the RK4 step's as implicit's and much
#: closer than Euler's.
PLANNING_INTEGRATOR = mujoco.mjtIntegrator.mjINT_IMPLICITFAST

#: Per-body and per-actuator model fields that must be finite.
_FINITE_FIELDS = (
    "body_mass",
    "body_inertia",
    "actuator_gainprm",
    "actuator_biasprm",
    "actuator_gear",
)

_OBJ_KINDS = {
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "joint": mujoco.mjtObj.mjOBJ_JOINT,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "keyframe": mujoco.mjtObj.mjOBJ_KEY,
    "geom": mujoco.mjtObj.mjOBJ_GEOM,
    "sensor": mujoco.mjtObj.mjOBJ_SENSOR,
    "camera": mujoco.mjtObj.mjOBJ_CAMERA,
}
_COUNTS = {
    "body": "nbody",
    "site": "nsite",
    "joint": "njnt",
    "actuator": "nu",
    "keyframe": "nkey",
    "geom": "ngeom",
    "sensor": "nsensor",
    "camera": "ncam",
}


def load_spec(source: str | Path | mujoco.MjSpec) -> mujoco.MjSpec:
    """An editable :class:`mujoco.MjSpec` from an MJCF path, an XML string, a spec, or a
    MuJoCo Menagerie robot named ``"menagerie:NAME"`` or ``"menagerie:NAME/ENTRY"`` (for
    example ``"menagerie:franka_emika_panda"``, ``"menagerie:unitree_g1/g1"``; see
    :mod:`mpcbox.core.menagerie`).

    Raises:
        InvalidTypeError: If ``source`` is none of these types.
        ModelNotFoundError: If a path does not exist.
        ModelLoadError: If MuJoCo cannot parse the file, or a geom that collides uses a
            mesh whose file is missing. A visual-only geom whose mesh file is missing (as in
            a partial Menagerie copy) is dropped with a
            :class:`~mpcbox.core.menagerie.MissingMeshWarning`.
    """
    if isinstance(source, mujoco.MjSpec):
        return source.copy()
    if not isinstance(source, (str, Path)):
        raise InvalidTypeError(
            "model must be an MJCF path, an XML string, a mujoco.MjSpec, a mujoco.MjModel or "
            f"'menagerie:NAME', got {type(source).__name__}"
        )
    if isinstance(source, str) and source.startswith(menagerie.PREFIX):
        name, _, entry = source[len(menagerie.PREFIX) :].partition("/")
        return menagerie.robot_spec(name, entry or None)
    if isinstance(source, str) and source.lstrip().startswith("<"):
        try:
            return mujoco.MjSpec.from_string(source)
        except Exception as exc:
            raise ModelLoadError(f"model: MuJoCo could not parse the XML string: {exc}") from exc
    path = Path(source)
    if not path.is_file():
        hint = ""
        if isinstance(source, str) and not path.suffix and not source.startswith("/"):
            hint = f"; for a MuJoCo Menagerie robot write {menagerie.PREFIX + source!r}"
        raise ModelNotFoundError(f"model: no MJCF file at {str(path)!r}{hint}")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise ModelLoadError(f"model: MuJoCo could not load {str(path)!r}: {exc}") from exc
    menagerie.drop_missing_visual_meshes(spec)
    return spec


def compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """Compile a spec, turning MuJoCo's exception into :class:`ModelLoadError`."""
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelLoadError(f"model: MuJoCo could not compile the model: {exc}") from exc


def _check_sensor(model: mujoco.MjModel, req: Any) -> None:
    """The sensor of ``req``'s name in a compiled ``model`` must be the one it asks for."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, req.name)
    objtype = int(model.sensor_objtype[sid])
    lookup = int(mujoco.mjtObj.mjOBJ_BODY) if objtype == int(mujoco.mjtObj.mjOBJ_XBODY) else objtype
    objid = int(model.sensor_objid[sid])
    name = mujoco.mj_id2name(model, lookup, objid) if objid >= 0 else ""
    found = (int(model.sensor_type[sid]), objtype, name or "")
    if found != (int(req.type), int(req.objtype), str(req.objname)):
        raise ModelLoadError(
            f"model: its sensor {req.name!r} is not the one the cost needs (type "
            f"{mujoco.mjtSensor(found[0]).name} on {found[2]!r}, the cost asks for "
            f"{mujoco.mjtSensor(int(req.type)).name} on {req.objname!r}); pass an MJCF path, "
            "XML string or MjSpec, or give the cost term another name"
        )


def with_sensors(
    source: mujoco.MjSpec | mujoco.MjModel, requests: Sequence[Any], timestep: float | None = None
) -> mujoco.MjModel:
    """A compiled copy of ``source`` that has the sensors a cost requests.

    Args:
        source: A spec (the sensors are added to a copy of it) or a compiled model (which
            must already have them).
        requests: :class:`~mpcbox.core.cost.SensorRequest` items (name, type, objtype,
            objname).
        timestep: A timestep for the copy (default: the source's).

    Raises:
        ModelLoadError: If a compiled model lacks a requested sensor.
    """
    if isinstance(source, mujoco.MjModel):
        missing = [
            r.name
            for r in requests
            if mujoco.mj_name2id(source, mujoco.mjtObj.mjOBJ_SENSOR, r.name) < 0
        ]
        if missing:
            raise ModelLoadError(
                f"model: the cost needs sensors {missing} that a compiled MjModel cannot "
                "receive; pass an MJCF path, XML string or MjSpec instead"
            )
        for req in requests:
            _check_sensor(source, req)
        model = copy.copy(source)
    else:
        spec = source.copy()
        for req in requests:
            spec.add_sensor(name=req.name, type=req.type, objtype=req.objtype, objname=req.objname)
        if timestep is not None:
            spec.option.timestep = positive("planning_timestep", timestep)
        model = compile_spec(spec)
    if timestep is not None:
        model.opt.timestep = positive("planning_timestep", timestep)
    return model


def build_planning_model(
    model: mujoco.MjModel,
    spec: mujoco.MjSpec | None,
    requests: Sequence[Any],
    source: ModelSource | None = None,
    timestep: float | None = None,
) -> mujoco.MjModel:
    """The model to plan with, next to a simulation model.

    Args:
        model: The simulation model (with the cost's sensors).
        spec: The spec ``model`` was compiled from, if any.
        requests: The cost's :class:`~mpcbox.core.cost.SensorRequest` items.
        source: A separate source for the planning model.
        timestep: A planning timestep.

    Returns:
        ``source`` compiled with the sensors, else a copy of ``model`` with ``timestep``,
        else ``model`` itself.

    Raises:
        ShapeError: If ``source`` has other ``nq``, ``nv``, ``nu`` or ``na`` than ``model``.
    """
    if source is not None:
        planning = with_sensors(
            source if isinstance(source, mujoco.MjModel) else load_spec(source), requests, timestep
        )
        check_model(planning, "planning_model")
    elif timestep is None:
        return model
    elif spec is None:
        planning = copy.copy(model)
        planning.opt.timestep = positive("planning_timestep", timestep)
    else:
        planning = with_sensors(spec, requests, timestep)
    sizes = (model.nq, model.nv, model.nu, model.na)
    if (planning.nq, planning.nv, planning.nu, planning.na) != sizes:
        raise ShapeError(
            "planning_model must have the same nq, nv, nu, na as model: got "
            f"{(planning.nq, planning.nv, planning.nu, planning.na)}, expected {sizes}"
        )
    if planning.nsensordata != model.nsensordata:
        raise ShapeError("planning_model and model must have the same sensors")
    return planning


def check_model(model: mujoco.MjModel, name: str = "model") -> None:
    """Reject a model that mpcbox cannot control or whose numbers are broken.

    Args:
        model: The compiled model.
        name: How the model is called in error messages.

    Raises:
        InvalidArgumentError: If the model has no degree of freedom or no actuator, or,
            naming the field, a timestep that is not positive and finite, non-finite
            gravity, a non-finite or negative body mass or inertia, non-finite actuator
            gains, biases or gears.
    """
    if model.nv == 0:
        raise InvalidArgumentError(
            f"{name} has no degrees of freedom (nv = 0): a Problem needs at least one joint "
            "or free body to predict and control"
        )
    if model.nu == 0:
        joints = ", ".join(repr(j) for j in names(model, "joint")[:10]) or "(unnamed)"
        raise InvalidArgumentError(
            f"{name} has no actuators (nu = 0), only {model.njnt} joint(s) ({joints}) and "
            f"{model.nv} degree(s) of freedom: mpcbox controls a model through its actuators, "
            'so it needs at least one (add an <actuator> element, e.g. <motor joint="..."/>)'
        )
    timestep = float(model.opt.timestep)
    if not (np.isfinite(timestep) and timestep > 0.0):
        raise InvalidArgumentError(
            f"{name}: opt.timestep must be positive and finite, got {timestep}"
        )
    if not np.all(np.isfinite(model.opt.gravity)):
        raise InvalidArgumentError(
            f"{name}: opt.gravity must be finite, got {model.opt.gravity.tolist()}"
        )
    for field in _FINITE_FIELDS:
        values = getattr(model, field)
        bad = np.flatnonzero(~np.isfinite(values).all(axis=tuple(range(1, values.ndim))))
        if bad.size:
            raise InvalidArgumentError(
                f"{name}: {field} must be finite; non-finite at {_ids(model, field, bad)}"
            )
    for field in ("body_mass", "body_inertia"):
        values = getattr(model, field)
        negative = np.flatnonzero((values < 0.0).reshape(len(values), -1).any(axis=1))
        if negative.size:
            raise InvalidArgumentError(
                f"{name}: {field} must be >= 0; negative at {_ids(model, field, negative)}"
            )


def check_mjmodel(model: object, name: str = "model") -> mujoco.MjModel:
    """Check that ``model`` is a compiled :class:`mujoco.MjModel` and return it.

    Raises:
        InvalidTypeError: Otherwise (a path or spec must be compiled first, e.g. by a Problem).
    """
    if not isinstance(model, mujoco.MjModel):
        raise InvalidTypeError(
            f"{name} must be a compiled mujoco.MjModel, got {type(model).__name__}"
        )
    return model


def _ids(model: mujoco.MjModel, field: str, ids: np.ndarray) -> str:
    """``"body 1 ('torso'), body 3"``: the objects of ``field`` at ``ids``, with their names."""
    kind = "body" if field.startswith("body") else "actuator"
    shown = []
    for i in ids:
        label = mujoco.mj_id2name(model, _OBJ_KINDS[kind], int(i))
        shown.append(f"{kind} {i}" + (f" ({label!r})" if label else ""))
    return ", ".join(shown)


def plannable(model: mujoco.MjModel, owner: str, keep_rk4: bool = False) -> mujoco.MjModel:
    """``model``, or a copy using :data:`PLANNING_INTEGRATOR` when it uses RK4.

    MuJoCo's ``mjd_transitionFD`` cannot differentiate an RK4 step; planning on a copy with
    another integrator keeps linearization-based controllers working. The replacement is
    announced with a :class:`~mpcbox.errors.PlanningModelWarning`. With ``keep_rk4`` the
    model is planned as it is, and linearized by finite differences of ``mj_step``
    (:func:`~mpcbox.core.step_fd.step_jacobians`: exact for the simulated step, and
    ``2 (2 nv + na + nu)`` RK4 steps per linearization).

    Args:
        model: A planning model.
        owner: Who plans with it, for the warning (e.g. ``"Problem"``).
        keep_rk4: Keep RK4 (no copy, no warning).
    """
    if keep_rk4 or model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
        return model
    warnings.warn(
        PlanningModelWarning(
            f"{owner}: the model uses the RK4 integrator, which mujoco.mjd_transitionFD "
            "cannot differentiate; planning uses a copy with the implicitfast integrator "
            "(the simulation model keeps RK4)"
        ),
        stacklevel=3,
    )
    model = copy.copy(model)
    model.opt.integrator = PLANNING_INTEGRATOR
    return model


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


def object_id(
    model: mujoco.MjModel, kind: str, name: str | int, argument: str | None = None
) -> int:
    """The id of a named object; an integer is checked and returned.

    Args:
        model: The model.
        kind: Object kind (``"body"``, ``"site"``, ...).
        name: Its name, or an id.
        argument: The argument that gave ``name``, for error messages (default: ``kind``).

    Raises:
        InvalidTypeError: If ``name`` is neither a string nor an integer.
        UnknownNameError: If no object of that kind has that name (lists the valid names).
    """
    argument = argument or kind
    if kind not in _OBJ_KINDS:
        raise InvalidArgumentError(f"kind must be one of {sorted(_OBJ_KINDS)}, got {kind!r}")
    count = getattr(model, _COUNTS[kind])
    if isinstance(name, bool) or not isinstance(name, (str, int, np.integer)):
        # mj_name2id crashes the interpreter on None.
        raise InvalidTypeError(
            f"{argument} must be a {kind} name or id, got {type(name).__name__} {name!r}"
        )
    if isinstance(name, (int, np.integer)):
        name = int(name)
        if not 0 <= name < count:
            raise InvalidArgumentError(f"{argument}: {kind} id must be in [0, {count}), got {name}")
        return name
    idx = mujoco.mj_name2id(model, _OBJ_KINDS[kind], name)
    if idx < 0:
        raise UnknownNameError(
            kind, name, names(model, kind), argument if argument != kind else None
        )
    return idx


def frame_object(model: mujoco.MjModel, name: str, argument: str = "frame") -> tuple[str, int]:
    """Resolve a point-like frame: a site if one has this name, else a body.

    Args:
        model: The model.
        name: Site or body name.
        argument: The argument that gave ``name``, for error messages.

    Returns:
        ``("site", id)`` or ``("body", id)``.
    """
    if not isinstance(name, str):  # mj_name2id crashes the interpreter on None
        raise InvalidTypeError(f"{argument} must be a site or body name, got {type(name).__name__}")
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return "site", sid
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid >= 0:
        return "body", bid
    raise UnknownNameError(
        "site or body", name, names(model, "site") + names(model, "body"), argument
    )


def frame_position(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """World position ``(3,)`` of a site or body frame (see :func:`frame_object`), a copy.

    ``data`` must hold kinematics (after ``mj_kinematics``, ``mj_forward`` or a step).
    """
    kind, idx = frame_object(model, name)
    return (data.site_xpos[idx] if kind == "site" else data.xpos[idx]).copy()


def free_body(model: mujoco.MjModel) -> int | None:
    """The body of the model's first free joint (a floating root), or ``None``."""
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and model.jnt_bodyid[j] != 0:
            return int(model.jnt_bodyid[j])
    return None


def dof_weights(
    model: mujoco.MjModel,
    joints: float | np.ndarray,
    free: Sequence[float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
) -> np.ndarray:
    """Per-dof weights ``(nv,)``: ``joints`` everywhere except on free joints.

    Args:
        model: The model.
        joints: Weight of every dof, a scalar or ``(nv,)``.
        free: The six weights of each free joint's dofs (linear x, y, z in the world frame,
            then angular); zero by default, so a floating root is left to other terms.
    """
    weights = np.array(np.broadcast_to(np.asarray(joints, dtype=float), (model.nv,)))
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            adr = model.jnt_dofadr[j]
            weights[adr : adr + 6] = free
    return weights
