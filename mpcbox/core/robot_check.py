"""A robot's model checked before any controller runs on it: what mpcbox will do, and why.

Each problem that robots nobody here wrote have shown (see ``docs/results/legged.md`` and
``docs/results/stops.md``) has a check of its own in :mod:`mpcbox.core`; :func:`check_robot`
runs them all on one model at one posture and says, per topic, what it found and what
mpcbox or the user can do about it:

* ``model``: bodies, joints, actuators by kind, keyframes, a floating root;
* ``integrator``: RK4, which linearization cannot differentiate (a planning copy is used);
* ``loading``: visual-only meshes dropped because their files are missing, and what MuJoCo
  said while compiling;
* ``actuators``: none, or an actuator model the equilibrium cannot invert;
* ``joint limits``: driven joints on or past a limit in the posture
  (:func:`~mpcbox.core.joint_limits.clear_of_limits`);
* ``parent contacts``: links touching the static body they hang from
  (:mod:`~mpcbox.core.parent_contacts`);
* ``dry friction``: joints with ``frictionloss``, which stick in a linearization at rest;
* ``servo ringing``: servos that ring at the timestep (:mod:`~mpcbox.core.servo_ringing`);
* ``servo saturation``: servos whose velocity jumps in one step where their force saturates
  under an implicit integrator (:mod:`~mpcbox.core.saturation_jumps`);
* ``equilibrium``: the control that holds the posture through the actuator model, and what
  the actuators cannot supply (:func:`~mpcbox.find_equilibrium`);
* ``open-loop hold``: the model held at that control, without feedback, for ``hold``
  seconds: MuJoCo's instability warnings, and how far the root or joints drift.

The command line runs it as ``mpcbox inspect MODEL``.
"""

from __future__ import annotations

import copy
import textwrap
import warnings
from collections import Counter
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.actuation import actuator_name, motor_actuators, position_servo_actuators
from mpcbox.core.divergence import diverged, unstable_warning
from mpcbox.core.equilibrium import Equilibrium, find_equilibrium
from mpcbox.core.joint_limits import (
    clear_of_limits,
    describe_moves,
    far_outside,
    movable_joints,
)
from mpcbox.core.menagerie import MissingMeshWarning
from mpcbox.core.model import ModelSource, compile_spec, free_body, load_spec, object_id
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.core.parent_contacts import describe, static_parent_contacts
from mpcbox.core.saturation_jumps import saturation_jumps
from mpcbox.core.servo_ringing import ServoRinging, servo_ringing
from mpcbox.errors import MpcboxError
from mpcbox.validation import boolean, non_negative

#: Levels of a :class:`Finding`, mildest first.
LEVELS = ("ok", "note", "warning", "error")


class Finding(NamedTuple):
    """One topic's result.

    Attributes:
        topic: What was checked (see the module docstring).
        level: ``"ok"``, ``"note"`` (mpcbox deals with it), ``"warning"`` (controllers may
            fail: the text says what to change) or ``"error"`` (mpcbox cannot control the
            model as it is).
        text: What was found, and what to do.
    """

    topic: str
    level: str
    text: str


class RobotCheck(NamedTuple):
    """The findings of :func:`check_robot`, in the order they were checked.

    Attributes:
        findings: One :class:`Finding` per topic checked.
        posture: The posture checked ``(nq,)`` (the keyframe's).
        model: The compiled model checked.
    """

    findings: tuple[Finding, ...]
    posture: np.ndarray
    model: mujoco.MjModel

    @property
    def level(self) -> str:
        """The worst level found."""
        return max((f.level for f in self.findings), key=LEVELS.index, default="ok")

    def format(self) -> str:
        """The findings as text, one topic a line (continuations indented)."""
        marks = {"ok": "ok  ", "note": "note", "warning": "WARN", "error": "ERR "}
        width = max((len(f.topic) for f in self.findings), default=0)
        lines = []
        for f in self.findings:
            head = f"{marks[f.level]} {f.topic:<{width}}  "
            lines.append(
                textwrap.fill(
                    f.text,
                    100,
                    initial_indent=head,
                    subsequent_indent=" " * len(head),
                    break_long_words=False,
                    break_on_hyphens=False,
                )
            )
        return "\n".join(lines)


def _load(source: ModelSource | mujoco.MjModel) -> tuple[mujoco.MjModel, list[str]]:
    """The compiled model, and what loading it said (meshes dropped, MuJoCo's warnings)."""
    if isinstance(source, mujoco.MjModel):
        return source, []
    with warnings.catch_warnings(record=True) as caught, captured_warnings() as said:
        warnings.simplefilter("always", MissingMeshWarning)
        model = compile_spec(load_spec(source))
    notes = [str(w.message) for w in caught if issubclass(w.category, MissingMeshWarning)]
    return model, notes + [f"MuJoCo said while loading: {m.strip()}" for m in said]


def _actuator_kinds(model: mujoco.MjModel) -> Counter:
    kinds: Counter = Counter()
    servo, motor = position_servo_actuators(model), motor_actuators(model)
    for i in range(len(servo)):
        gain, bias = model.actuator_gaintype[i], model.actuator_biastype[i]
        dyn = model.actuator_dyntype[i]
        if gain == mujoco.mjtGain.mjGAIN_MUSCLE:
            kinds["muscle"] += 1
        elif servo[i]:
            kinds["position servo"] += 1
        elif bias == mujoco.mjtBias.mjBIAS_AFFINE and model.actuator_biasprm[i, 2] < 0:
            kinds["velocity servo"] += 1
        elif motor[i]:
            kinds["motor"] += 1
        else:
            kinds["general"] += 1
        if dyn != mujoco.mjtDyn.mjDYN_NONE and gain != mujoco.mjtGain.mjGAIN_MUSCLE:
            kinds[f"with {mujoco.mjtDyn(dyn).name.removeprefix('mjDYN_').lower()} dynamics"] += 1
    return kinds


def _summary(model: mujoco.MjModel) -> Finding:
    kinds = ", ".join(f"{n} {k}" for k, n in _actuator_kinds(model).items()) or "none"
    root = free_body(model)
    keys = [model.key(k).name or f"#{k}" for k in range(model.nkey)]
    text = (
        f"{model.nbody - 1} bodies, {model.njnt} joints (nq={model.nq}, nv={model.nv}), "
        f"actuators: {kinds}; keyframes: {', '.join(keys) or 'none (qpos0 is used)'}; "
        + (
            f"floating root {model.body(root).name or f'body {root}'!r} (a legged task "
            "balances it: BipedStand, QuadrupedStand or LeggedBalance of mpcbox.tasks.legged)"
            if root is not None
            else "fixed base"
        )
    )
    return Finding("model", "ok", text)


def _integrator(model: mujoco.MjModel) -> Finding:
    name = mujoco.mjtIntegrator(model.opt.integrator).name.removeprefix("mjINT_").lower()
    text = f"{name}, timestep {1e3 * model.opt.timestep:g} ms"
    if model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        return Finding(
            "integrator",
            "note",
            text + ": mujoco.mjd_transitionFD cannot differentiate RK4, so a Problem plans on "
            "an implicitfast copy (Problem(plan_rk4=True) differentiates mj_step instead)",
        )
    return Finding("integrator", "ok", text)


def _limits(model: mujoco.MjModel, qpos: np.ndarray) -> Finding:
    far = []  # what clear_of_limits leaves as given: a posture of its own, past the limits
    for j in movable_joints(model):
        q = float(qpos[model.jnt_qposadr[j]])
        if far_outside(model, q, j):
            lo, hi = model.jnt_range[j]
            far.append(f"{model.joint(j).name or f'joint {j}'} {q:.3g} not in [{lo:.3g}, {hi:.3g}]")
    if far:
        return Finding(
            "joint limits",
            "warning",
            f"{len(far)} driven joint(s) far outside their range: {'; '.join(far[:4])}"
            + (" ..." if len(far) > 4 else "")
            + ": the limits push them back, so the posture cannot be held as it is (a range "
            "in degrees where the model's compiler reads radians, or the wrong keyframe?)",
        )
    _, moves = clear_of_limits(model, qpos)
    if not moves:
        return Finding("joint limits", "ok", "no driven joint on or past a limit")
    return Finding(
        "joint limits",
        "note",
        f"{len(moves)} driven joint(s) on or near a limit: {describe_moves(moves)}; a Problem "
        "moves them 0.01 rad inside (a limit is a kink of the dynamics; "
        "limit_clearance=0 keeps the posture)",
    )


def _parents(model: mujoco.MjModel, qpos: np.ndarray) -> Finding:
    found = static_parent_contacts(model, [model.qpos0, qpos])
    if not found:
        return Finding("parent contacts", "ok", "no link touches the static body it hangs from")
    return Finding(
        "parent contacts",
        "note",
        f"{describe(found)}: MuJoCo filters parent-child contacts only when the parent moves; "
        "a Problem excludes these pairs (parent_contacts='exclude', the default)",
    )


def _friction(model: mujoco.MjModel) -> Finding:
    joints = [j for j in range(model.njnt) if model.dof_frictionloss[model.jnt_dofadr[j]] > 0]
    if not joints:
        return Finding("dry friction", "ok", "no joint has frictionloss")
    largest = max(model.dof_frictionloss[model.jnt_dofadr[j]] for j in joints)
    return Finding(
        "dry friction",
        "note",
        f"{len(joints)} joint(s) with frictionloss (up to {largest:g}): it sticks at rest, so "
        "a linearization there sees stiff joints; standing tasks keep it, ArmReach drops it "
        "(Problem(dry_friction='drop') linearizes a copy without it)",
    )


def _ringing(model: mujoco.MjModel, qpos: np.ndarray) -> Finding:
    try:
        report = servo_ringing(model, qpos)
    except MpcboxError as exc:
        return Finding("servo ringing", "note", f"not tested: {exc}")
    if not report.flagged.any():
        return Finding(
            "servo ringing", "ok", f"no actuator rings after a set-point step ({model.nu} tested)"
        )
    return Finding("servo ringing", "warning", report.message() + _finer(model, qpos, report))


def _saturation(model: mujoco.MjModel, qpos: np.ndarray) -> Finding:
    jumps = saturation_jumps(model, qpos)
    if not jumps.implicit:
        return Finding(
            "servo saturation",
            "ok",
            "the integrator treats velocity gains explicitly: no jump where a force saturates",
        )
    message = jumps.message()
    if message:
        return Finding("servo saturation", "note", message)
    limited = int(np.count_nonzero(jumps.velocity_jump))
    return Finding(
        "servo saturation",
        "ok",
        f"no servo's velocity jumps by half a step's change where its force saturates "
        f"({limited} force-limited with a velocity gain)",
    )


def _finer(model: mujoco.MjModel, qpos: np.ndarray, report: ServoRinging) -> str:
    """Whether halving the timestep (twice at most) cures the flagged actuators, in a sentence."""
    finer = copy.copy(model)
    for _ in range(2):
        finer.opt.timestep /= 2
        again = servo_ringing(finer, qpos)
        still = again.flagged & report.flagged
        if not still.any():
            return f" At {1e3 * finer.opt.timestep:g} ms none rings or diverges."
    names = [repr(n) for n, r in zip(report.names, still) if r]
    one = len(names) == 1
    if not (again.diverged & still).any():
        verb = "rings" if one else "ring"
    elif not (again.ringing & still).any():
        verb = "diverges" if one else "diverge"
    else:
        verb = "ring or diverge"
    return (
        f" At {1e3 * finer.opt.timestep:g} ms {', '.join(names)} still {verb}: a shorter "
        "timestep is no cure there."
    )


#: Beyond these the open-loop hold is a note: the root moved (m), a joint drifted (rad or m).
HOLD_ROOT_MOVE = 0.05
HOLD_JOINT_DRIFT = 0.1


def _hold(model: mujoco.MjModel, eq: Equilibrium, seconds: float) -> Finding:
    """Hold the equilibrium control open-loop for ``seconds``: warnings and drift."""
    with captured_warnings():  # read from data.warning below, not printed
        return _held(model, eq, seconds)


def _held(model: mujoco.MjModel, eq: Equilibrium, seconds: float) -> Finding:
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:] = eq.qpos, eq.ctrl
    if model.na:
        data.act[:] = eq.act
    mujoco.mj_forward(model, data)
    start = data.qpos.copy()
    steps = round(seconds / model.opt.timestep)
    for _ in range(steps):
        mujoco.mj_step(model, data)
        if diverged(data, data.qpos):
            problem = unstable_warning(data)
            return Finding(
                "open-loop hold",
                "error",
                f"the simulation diverged after {data.time:.3f} s ({problem or 'non-finite state'}"
                "): shorten the timestep or check the actuators' gains",
            )
    drift = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, drift, 1.0, start, data.qpos)
    root = free_body(model)
    if root is not None:
        adr = model.jnt_qposadr[model.body_jntadr[root]]
        moved = float(np.linalg.norm(data.qpos[adr : adr + 3] - start[adr : adr + 3]))
        text = f"root moved {100 * moved:.1f} cm in {seconds:g} s without feedback"
        away = moved > HOLD_ROOT_MOVE
    else:
        moved = float(np.max(np.abs(drift))) if model.nv else 0.0
        text = f"joints drifted at most {moved:.3g} rad or m in {seconds:g} s without feedback"
        away = moved > HOLD_JOINT_DRIFT
    if away:  # a fall or drift is no instability of the model, but not "ok" either
        return Finding(
            "open-loop hold",
            "note",
            text + ": the posture is not held without feedback (as for a robot that must "
            "balance); its controllers must hold it. No MuJoCo instability warning",
        )
    return Finding("open-loop hold", "ok", text + "; no MuJoCo instability warning")


def check_robot(
    model: ModelSource | mujoco.MjModel,
    *,
    keyframe: str | int | None = None,
    hold: float = 1.0,
    servo_test: bool = True,
) -> RobotCheck:
    """Check a robot's model at a posture (the module docstring lists the topics).

    Args:
        model: The model (MJCF path, XML, spec, ``"menagerie:NAME"`` or a compiled model).
        keyframe: The posture's keyframe (name or index); default the first, else ``qpos0``.
        hold: Seconds of the open-loop hold (0 skips it).
        servo_test: Run the servo step test (``nu * 0.5`` simulated seconds).

    Returns:
        A :class:`RobotCheck`; ``.level`` is its worst finding, ``.format()`` its text.

    Raises:
        ModelNotFoundError: If the file does not exist (a bare Menagerie name gets a hint).
        ModelLoadError: If MuJoCo cannot load it.
        UnknownNameError: If ``keyframe`` does not exist (the message lists those that do).
    """
    hold = non_negative("hold", hold)
    servo_test = boolean("servo_test", servo_test)
    m, dropped = _load(model)
    if keyframe is not None:
        qpos = m.key_qpos[object_id(m, "keyframe", keyframe)].copy()
    else:
        qpos = (m.key_qpos[0] if m.nkey else m.qpos0).copy()
    findings = [_summary(m), _integrator(m)]
    if dropped:
        findings.append(Finding("loading", "note", "; ".join(dropped)))
    if m.nu == 0:
        findings.append(
            Finding("actuators", "error", "the model has no actuators: nothing to control")
        )
        return RobotCheck(tuple(findings), qpos, m)
    findings += [_limits(m, qpos), _parents(m, qpos), _friction(m)]
    if servo_test:
        findings.append(_ringing(m, qpos))
    findings.append(_saturation(m, qpos))
    qpos, _ = clear_of_limits(m, qpos)
    try:
        eq = find_equilibrium(m, qpos, on_infeasible="ignore")
    except MpcboxError as exc:
        hint = " (choose a standing keyframe)" if free_body(m) is not None else ""
        findings.append(Finding("equilibrium", "warning", f"{type(exc).__name__}: {exc}{hint}"))
        return RobotCheck(tuple(findings), qpos, m)
    findings.append(_equilibrium(m, eq))
    if hold > 0:
        findings.append(_hold(m, eq, hold))
    return RobotCheck(tuple(findings), qpos, m)


def _equilibrium(model: mujoco.MjModel, eq: Equilibrium) -> Finding:
    lo, hi = model.actuator_ctrlrange.T
    limited = model.actuator_ctrllimited.astype(bool)
    at_limit = limited & ((eq.ctrl <= lo + 1e-9) | (eq.ctrl >= hi - 1e-9))
    parts = []
    if free_body(model) is not None:
        parts.append(
            f"root moved {1e3 * eq.height_offset:+.1f} mm vertically so the contacts carry "
            f"the body; root wrench left {np.linalg.norm(eq.residual_wrench):.3g}"
        )
    parts.append(f"actuators supply all but {eq.shortfall:.3g} N or N m on the joints they drive")
    if at_limit.any():
        names = [actuator_name(model, int(i)) for i in np.flatnonzero(at_limit)]
        parts.append(f"controls at their range's end: {', '.join(names[:6])}")
    # A shortfall counts above 1 % of the largest force the actuated dofs need (a 0.01 N m
    # residual is round-off on a 100 kg humanoid, not on a gripper).
    needed = float(np.max(np.abs(eq.qfrc[eq.actuated]), initial=0.0))
    level = "warning" if eq.shortfall > max(1e-3, 0.01 * needed) else "ok"
    if level == "warning":
        parts.append("the posture cannot be held as given: choose another keyframe")
    return Finding("equilibrium", level, "; ".join(parts))
