"""Contacts between a link and the static body it hangs from.

MuJoCo never lets a body collide with its parent (the ``filterparent`` flag), except when the
parent is welded to the world: then the pair is checked like any other. An arm whose base is
a body of its own without a joint (Kinova's Gen3: ``base_link``, with ``shoulder_link`` on
``joint_1`` below it) then collides with its own base wherever the two collision meshes
overlap, as they do where the real parts nest. On the Gen3 the meshes overlap by 12 mm at
every angle of ``joint_1``: the contact's friction and normal force held the joint against its
saturated 105 N m servo, so it crept at 0.17 rad/s and every controller missed a 40 cm reach.

:func:`static_parent_contacts` finds such pairs in a model's standard postures, and
:func:`exclude_contacts` adds the ``<exclude>`` that MuJoCo's own filter would imply had the
parent been free to move. :class:`~mpcbox.Problem` does both by default
(``parent_contacts="exclude"``) and says so in a :class:`~mpcbox.errors.ModelWarning`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import ModelSource, compile_spec, load_spec
from mpcbox.errors import ModelWarning
from mpcbox.validation import one_of


class ParentContact(NamedTuple):
    """A body touching the static body it hangs from.

    Attributes:
        parent: The parent body's name (welded to the world, not the world body itself).
        child: The moving child body's name.
        depth: Largest penetration (m) over the postures checked (>= 0).
    """

    parent: str
    child: str
    depth: float


def standard_postures(model: mujoco.MjModel) -> list[np.ndarray]:
    """``qpos0`` and every keyframe's positions, each ``(nq,)``."""
    return [model.qpos0.copy(), *(model.key_qpos[k].copy() for k in range(model.nkey))]


def static_parent_contacts(
    model: mujoco.MjModel, postures: Iterable[np.ndarray] | None = None
) -> tuple[ParentContact, ...]:
    """Contacts, in any of ``postures``, between a moving body and its static parent.

    A pair counts when the child's parent body is welded to the world
    (``body_weldid == 0``) but is not the world body, the child moves, and MuJoCo's parent
    filter is on (``mjDSBL_FILTERPARENT`` not set): the pairs MuJoCo would filter out if
    the parent could move. Nothing is reported when the parent filter is disabled, since
    the model then asks for parent-child contacts.

    Args:
        model: The model.
        postures: Positions ``(nq,)`` to check; default: :func:`standard_postures`.

    Returns:
        One :class:`ParentContact` per pair, in order of the first contact found.
    """
    if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        return ()
    parent = model.body_parentid
    static = model.body_weldid == 0
    data = mujoco.MjData(model)
    found: dict[tuple[int, int], float] = {}
    for qpos in standard_postures(model) if postures is None else postures:
        data.qpos[:] = qpos
        mujoco.mj_fwdPosition(model, data)
        for i in range(data.ncon):
            con = data.contact[i]
            b1, b2 = model.geom_bodyid[con.geom1], model.geom_bodyid[con.geom2]
            for p, c in ((b1, b2), (b2, b1)):
                if p != 0 and static[p] and not static[c] and parent[c] == p:
                    key = (int(p), int(c))
                    found[key] = max(found.get(key, 0.0), max(-float(con.dist), 0.0))
    return tuple(
        ParentContact(model.body(p).name, model.body(c).name, depth)
        for (p, c), depth in found.items()
    )


def exclude_contacts(spec: mujoco.MjSpec, contacts: Iterable[ParentContact]) -> None:
    """Add ``<contact><exclude body1=parent body2=child/>`` to ``spec`` for each pair."""
    for c in contacts:
        spec.add_exclude(bodyname1=c.parent, bodyname2=c.child)


def describe(contacts: Iterable[ParentContact]) -> str:
    """``"'base_link' with 'shoulder_link' (12.0 mm deep)"``, comma-separated."""
    return ", ".join(
        f"{c.parent!r} with {c.child!r} ({1e3 * c.depth:.1f} mm deep)" for c in contacts
    )


#: Valid values of ``Problem(parent_contacts=...)``.
PARENT_CONTACTS = ("exclude", "keep")


def load_model(
    source: ModelSource, mode: str = "exclude"
) -> tuple[mujoco.MjSpec | None, mujoco.MjModel, tuple[ParentContact, ...]]:
    """Load ``source`` and deal with its :func:`static_parent_contacts` as ``mode`` says.

    Args:
        source: An MJCF path, XML string, spec, compiled model or ``"menagerie:NAME"``.
        mode: ``"exclude"``: exclude the pairs (:func:`exclude_contacts`) and say so in a
            :class:`~mpcbox.errors.ModelWarning`; ``"keep"``: keep them and warn. A compiled
            model cannot be given exclusions, so its pairs are kept with a warning that names
            the fix.

    Returns:
        The spec (``None`` for a compiled ``source``), the compiled model, and the pairs
        excluded.
    """
    one_of("parent_contacts", mode, PARENT_CONTACTS)
    spec = None if isinstance(source, mujoco.MjModel) else load_spec(source)
    model = source if spec is None else compile_spec(spec)
    found = static_parent_contacts(model)
    named = tuple(c for c in found if c.parent and c.child)  # <exclude> takes body names
    excluded: tuple[ParentContact, ...] = ()
    if mode == "exclude" and spec is not None and named:
        exclude_contacts(spec, named)
        warnings.warn(
            "model: excluded the contacts of links with the static body they hang from, which "
            f"MuJoCo's parent filter leaves on when the parent is welded to the world: "
            f"{describe(named)}; they would resist the links' joints (parent_contacts='keep' "
            "simulates them)",
            ModelWarning,
            stacklevel=4,
        )
        model, excluded = compile_spec(spec), named
    found = tuple(c for c in found if c not in excluded)
    if found:
        fix = (
            "pass the MJCF (path, XML or spec) with parent_contacts='exclude'"
            if spec is None and mode == "exclude"
            else "add <contact><exclude body1=... body2=.../> to the MJCF (naming the bodies)"
        )
        warnings.warn(
            "model: links collide with the static body they hang from (MuJoCo's parent filter "
            f"leaves such pairs on when the parent is welded to the world): {describe(found)}; "
            f"the contacts resist the links' joints: {fix}",
            ModelWarning,
            stacklevel=4,
        )
    return spec, model, excluded
