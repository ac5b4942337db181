r"""A reference posture kept off its joints' limits.

MuJoCo turns a joint's limit on when the joint reaches it (its distance to the limit falls
below the limit's ``margin``). A reference posture with a joint exactly on a limit, as a
keyframe with straight knees or elbows often has, is a kink of the dynamics: a
finite-difference step on one side engages the limit and on the other does not, so the
one-step Jacobian gets the limit's stiffness on one side only (on Menagerie's Adam Lite,
elbows at their upper limit 0 gave a 2 ms step with eigenvalues of 48 and 81, and a
0.02 s composition of such steps entries of 1e16). A posture on the far side of a limit
(Talos' arm joints) is held by the limit's force, which the actuators then do not supply.

:func:`clear_of_limits` moves each such hinge or slide joint inside its range by a small
clearance, so that every linearization is taken where the dynamics are smooth.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.errors import PostureWarning

#: Distance (rad for hinges, m for slides) kept between a reference joint and its limit,
#: at most :data:`RANGE_FRACTION` of the joint's range. Far above a finite-difference step
#: (1e-6) and well below a posture change that matters.
LIMIT_CLEARANCE = 1e-2

#: Largest clearance as a fraction of the joint's range (a 4 cm finger slide moves 2 mm).
RANGE_FRACTION = 0.05


_LIMITED_TYPES = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class LimitMove(NamedTuple):
    """One joint moved off its limit.

    Attributes:
        joint: Joint name (``"joint <id>"`` when unnamed).
        old: Its position in the given posture.
        new: Its position in the returned posture.
    """

    joint: str
    old: float
    new: float


def far_outside(model: mujoco.MjModel, q: float, joint: int) -> bool:
    """Whether position ``q`` of ``joint`` lies more than :data:`RANGE_FRACTION` of its
    range outside it: a posture of its own, not a rounding onto a limit."""
    lo, hi = model.jnt_range[joint]
    return bool(hi > lo and max(lo - q, q - hi) > RANGE_FRACTION * (hi - lo))


def clear_of_limits(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    clearance: float = LIMIT_CLEARANCE,
    *,
    warn: bool = False,
) -> tuple[np.ndarray, list[LimitMove]]:
    r"""``qpos`` with every limited hinge and slide joint that an actuator drives (and no
    equality couples, :func:`movable_joints`) at least ``clearance`` inside its range (and
    past its limit's ``margin``).

    A joint of range :math:`[l, h]` goes to :math:`\min(\max(q, l + c), h - c)` with
    :math:`c = \min(\text{clearance}, 0.05\,(h - l)) + \text{margin}`. A joint more than
    5 % of its range outside it is left as given (and named in the warning): that is a
    posture of its own, such as a model's ``qpos0`` with every joint at 0, not a rounding.

    Args:
        model: The model.
        qpos: Positions ``(nq,)``.
        clearance: Distance kept from each limit (>= 0).
        warn: Say which joints moved in a :class:`~mpcbox.errors.PostureWarning`.

    Returns:
        The adjusted copy of ``qpos`` and the joints moved (empty when none was on or past
        a limit).
    """
    out = np.array(qpos, dtype=float, copy=True)
    moves: list[LimitMove] = []
    far: list[str] = []
    for j in movable_joints(model):
        lo, hi = model.jnt_range[j]
        if not hi > lo:
            continue
        margin = max(float(model.jnt_margin[j]), 0.0)
        c = min(min(clearance, RANGE_FRACTION * (hi - lo)) + margin, 0.5 * (hi - lo))
        adr = model.jnt_qposadr[j]
        name = model.joint(j).name or f"joint {j}"
        if far_outside(model, out[adr], j):
            far.append(name)
            continue
        new = min(max(out[adr], lo + c), hi - c)
        if new != out[adr]:
            moves.append(LimitMove(name, float(out[adr]), float(new)))
            out[adr] = new
    if warn and (moves or far):
        said = []
        if moves:
            said.append(
                f"{len(moves)} joint(s) on or near a limit moved inside their range "
                f"(limit_clearance={clearance:g}): {describe_moves(moves)}"
            )
        if far:
            more = " ..." if len(far) > 4 else ""
            names = ", ".join(far[:4]) + more
            said.append(f"{len(far)} joint(s) far outside their range left as given: {names}")
        warnings.warn("qpos_ref: " + "; ".join(said), PostureWarning, stacklevel=4)
    return out, moves


def moves_kept(chosen: np.ndarray, cleared: np.ndarray, final: np.ndarray) -> bool:
    """Whether ``final`` kept the joints :func:`clear_of_limits` moved from ``chosen`` to
    ``cleared`` (a Problem's ``prepare`` hook may replace the reference by one of its own,
    such as an IK goal, and the moves then no longer apply)."""
    moved = chosen != cleared
    return np.array_equal(final, cleared) or bool(
        moved.any() and np.array_equal(final[moved], cleared[moved])
    )


def movable_joints(model: mujoco.MjModel) -> list[int]:
    """Limited hinge and slide joints that an actuator drives directly and no equality
    constraint couples: the joints :func:`clear_of_limits` may move.

    A passive joint resting on its limit (a gripper's finger, a coupled linkage) is held
    there by the limit; moved inside, it would hang free, a mode no control reaches.
    """
    driven = driven_joints(model)
    coupled: set[int] = set()
    for e in range(model.neq):
        if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT):
            coupled.update((int(model.eq_obj1id[e]), int(model.eq_obj2id[e])))
    return [
        j
        for j in range(model.njnt)
        if model.jnt_limited[j]
        and int(model.jnt_type[j]) in _LIMITED_TYPES
        and j in driven
        and j not in coupled
    ]


def driven_joints(model: mujoco.MjModel) -> set[int]:
    """Ids of the joints an actuator drives directly (joint transmission)."""
    return {
        int(model.actuator_trnid[a, 0])
        for a in range(model.nu)
        if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
    }


def describe_moves(moves: list[LimitMove], limit: int = 4) -> str:
    """``"knee 0 -> 0.01, ..."`` for the first ``limit`` moves, and how many more."""
    shown = ", ".join(f"{m.joint} {m.old:.4g} -> {m.new:.4g}" for m in moves[:limit])
    more = len(moves) - limit
    return shown + (f" and {more} more" if more > 0 else "")
