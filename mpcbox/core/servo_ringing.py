r"""Servos that ring at the model's timestep: a set-point step test per actuator.

MuJoCo's implicit integrators treat an actuator's velocity gain (a servo's ``kv``)
implicitly only while its force is inside its force range: once the force saturates, the
force no longer depends on the velocity, and the next step is explicit in it. A servo
whose velocity gain is large against the inertia it drives (:math:`k_v \, h / I > 2` for
the timestep :math:`h` and the effective inertia :math:`I`) can then lock into a limit
cycle the continuous dynamics do not have: the force flips between its limits and the
velocity changes sign at every step. A model can look sound to linear tests (the Unitree
Z1's wrist linearizes to a stable eigenvalue of 0.988) and still ring after its first large
set-point step, so every controller driving it fails.

:func:`servo_ringing` finds such actuators by simulation: from a posture at rest, with
gravity and contacts switched off so that only the actuators act, it steps one actuator's
set-point by a fraction of its control range, holds the others, and watches that
actuator's velocity over the second half of the run. An actuator rings when its velocity
still changes sign on most steps there, with an amplitude that is a sizeable fraction of
the step response's peak speed; a physical oscillation, far slower than the timestep,
changes sign on few steps.
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.actuation import (
    actuation_map,
    actuator_moment,
    actuator_name,
    actuator_state,
    control_owner,
    velocity_gain,
)
from mpcbox.core.divergence import diverged
from mpcbox.core.model import check_mjmodel
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, positive

_Disable = mujoco.mjtDisableBit


class ServoRinging(NamedTuple):
    """What the step test saw, per control ``(nu,)`` (see :func:`servo_ringing`).

    Attributes:
        names: The actuator of each control.
        ringing: Whether it rings: its velocity changes sign on at least
            ``min_crossing_rate`` of the late steps, with a late RMS of at least
            ``min_amplitude`` of the peak speed (and the test did not diverge).
        crossing_rate: Fraction of the late steps on which the velocity changes sign.
        amplitude: RMS of the actuator's velocity over the late steps, over its peak speed
            during the whole run.
        velocity_gain_ratio: :math:`k_v h / I`: the actuator's velocity gain (``kv``, from
            its bias or gain) times the timestep over its effective inertia, ``nan`` where
            the actuator has no velocity gain or drives no inertia; the explicit step in
            the velocity is unstable above 2.
        timestep: The timestep tested (s).
        diverged: Whether the step test blew the simulation up (MuJoCo's instability
            warning, which is collected rather than printed, or a non-finite velocity); such
            an actuator's rates cover the steps before it.
    """

    names: tuple[str, ...]
    ringing: np.ndarray
    crossing_rate: np.ndarray
    amplitude: np.ndarray
    velocity_gain_ratio: np.ndarray
    timestep: float
    diverged: np.ndarray

    @property
    def ringing_names(self) -> tuple[str, ...]:
        """The actuators that ring."""
        return tuple(n for n, r in zip(self.names, self.ringing) if r)

    def message(self) -> str:
        """What rings or diverges, the evidence, and what to change; ``""`` if nothing does."""
        rings = np.flatnonzero(self.ringing)
        blown = np.flatnonzero(self.diverged)
        if rings.size == 0 and blown.size == 0:
            return ""
        text = ""
        if blown.size:
            names = ", ".join(repr(self.names[j]) for j in blown)
            text = (
                f"the simulation diverges after a set-point step of {names} at the "
                f"{1e3 * self.timestep:g} ms timestep"
            )
        if rings.size == 0:
            return text + ": shorten the timestep or check those actuators' gains."
        return (f"{text}; " if text else "") + self._ringing_message(rings)

    @property
    def flagged(self) -> np.ndarray:
        """Actuators that ring or whose step test diverged ``(nu,)``."""
        return self.ringing | self.diverged

    def _ringing_message(self, rings: np.ndarray) -> str:
        """The sentence on the ringing actuators ``rings`` (indices)."""

        def span(values: np.ndarray, scale: float = 1.0, fmt: str = ".0f") -> str:
            lo, hi = scale * float(np.min(values)), scale * float(np.max(values))
            return f"{lo:{fmt}}" if f"{lo:{fmt}}" == f"{hi:{fmt}}" else f"{lo:{fmt}}-{hi:{fmt}}"

        names = ", ".join(repr(self.names[j]) for j in rings)
        text = (
            f"{'actuator' if rings.size == 1 else 'actuators'} {names} "
            f"{'rings' if rings.size == 1 else 'ring'} after a set-point step at the "
            f"{1e3 * self.timestep:g} ms timestep: the velocity changes sign on "
            f"{span(self.crossing_rate[rings], 100)}% of the late steps, at "
            f"{span(self.amplitude[rings], 100)}% of the peak speed"
        )
        ratio = self.velocity_gain_ratio[rings]
        if np.any(np.isfinite(ratio) & (ratio > 2.0)):
            text += (
                f"; kv h / I = {span(ratio[np.isfinite(ratio)], fmt='.3g')} (above 2 the "
                "velocity gain is unstable whenever the force saturates)"
            )
        return text + (
            ". Controllers cannot hold such a joint: lower the servo's kv or force limit, add "
            "joint armature, or shorten the timestep, and test again (mpcbox.servo_ringing)."
        )


def _effective_inertia(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """``1 / (m M^-1 m^T)`` per actuator output at the posture in ``data`` (``(nout,)``)."""
    moment = actuator_moment(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    mobility = np.einsum("ij,ij->i", moment, np.linalg.solve(mass, moment.T).T)
    with np.errstate(divide="ignore"):
        return np.where(mobility > 0.0, 1.0 / mobility, np.inf)


def _step_size(model: mujoco.MjModel, i: int, step: float) -> tuple[float, float]:
    """The range a step of actuator ``i``'s variable is a fraction of: ctrlrange, or the
    activation range of an integrator, or ``(-1, 1)`` when unlimited."""
    if model.actuator_dyntype[i] == mujoco.mjtDyn.mjDYN_INTEGRATOR:
        if model.actuator_actlimited[i]:
            return tuple(model.actuator_actrange[i])
    elif model.actuator_ctrllimited[i]:
        return tuple(model.actuator_ctrlrange[i])
    return (-1.0, 1.0)


def servo_ringing(
    model: mujoco.MjModel,
    qpos: np.ndarray | None = None,
    *,
    step: float = 0.25,
    duration: float = 0.5,
    min_crossing_rate: float = 0.5,
    min_amplitude: float = 0.05,
) -> ServoRinging:
    r"""Step each actuator's set-point and report the ones that ring (module docstring).

    A copy of ``model`` without gravity and contacts starts at rest at ``qpos``, every
    actuator resting at zero force (:func:`~mpcbox.core.actuation.actuation_map`). For each
    control in turn its variable (the control, or the activation of an integrator) steps by
    ``step`` times the width of its range, towards the farther end, for ``duration``
    seconds at the model's timestep; the last half of the run is the late window. This
    costs ``nu * duration / h`` steps (0.4 s for a 29-actuator humanoid at 2 ms).

    Args:
        model: The model (not changed).
        qpos: Posture ``(nq,)`` to test at; default the first keyframe, else ``qpos0``.
        step: The step as a fraction of the range, in (0, 1].
        duration: Seconds simulated per actuator.
        min_crossing_rate: Smallest fraction of late steps with a sign change that counts.
        min_amplitude: Smallest late RMS speed, over the peak speed, that counts.

    Returns:
        A :class:`ServoRinging`.

    Raises:
        InvalidArgumentError: For a bad argument.
        UnsupportedModelError: For an actuator whose resting state cannot be set
            (:func:`~mpcbox.core.actuation.control_owner`).
    """
    model = check_mjmodel(model)
    for name, value in (("step", step), ("min_crossing_rate", min_crossing_rate)):
        if not 0.0 < float(value) <= 1.0:
            raise InvalidArgumentError(f"{name} must be in (0, 1], got {value!r}")
    duration = positive("duration", duration)
    min_amplitude = positive("min_amplitude", min_amplitude)
    if qpos is None:
        qpos = model.key_qpos[0] if model.nkey else model.qpos0
    qpos = as_array("qpos", qpos, (model.nq,))
    if not np.all(np.isfinite(qpos)):
        raise InvalidArgumentError("qpos must be finite")
    owner = control_owner(model)
    test = copy.copy(model)
    test.opt.disableflags |= _Disable.mjDSBL_GRAVITY | _Disable.mjDSBL_CONTACT
    data = mujoco.MjData(test)
    data.qpos[:] = qpos
    mujoco.mj_forward(test, data)
    amap = actuation_map(test, data)
    nu, h = model.nu, float(model.opt.timestep)
    rest = np.zeros(nu)
    for j, i in enumerate(owner):
        slope = amap.force_matrix[i, j]
        rest[j] = -amap.force_offset[i] / slope if slope != 0.0 else 0.0
    rest = np.clip(rest, amap.lower, amap.upper)
    inertia = _effective_inertia(test, data)
    steps = max(round(duration / h), 4)
    late = slice(steps // 2, steps)
    crossing, amplitude, ratio = np.zeros(nu), np.zeros(nu), np.full(nu, np.nan)
    blown = np.zeros(nu, dtype=bool)
    velocity = np.zeros(steps)
    for j, i in enumerate(owner):
        lo, hi = _step_size(test, i, step)
        x = rest.copy()
        width = step * (hi - lo)
        x[j] = rest[j] + width if hi - rest[j] >= rest[j] - lo else rest[j] - width
        mujoco.mj_resetData(test, data)
        data.qpos[:] = qpos
        data.ctrl[:], data.act[:] = actuator_state(test, x)
        velocity[:] = 0.0
        with captured_warnings():
            for k in range(steps):
                mujoco.mj_step(test, data)
                velocity[k] = data.actuator_velocity[i]
                if diverged(data, velocity[k : k + 1]):
                    blown[j] = True
                    velocity[k] = 0.0
                    break
        tail = velocity[late]
        peak = float(np.max(np.abs(velocity)))
        signs = np.sign(tail)
        crossing[j] = float(np.mean(signs[1:] * signs[:-1] < 0.0))
        amplitude[j] = float(np.sqrt(np.mean(tail**2)) / peak) if peak > 0.0 else 0.0
        kv = velocity_gain(test, i, x[j])
        if kv > 0.0 and np.isfinite(inertia[i]):
            ratio[j] = kv * h / inertia[i]
    ringing = (crossing >= min_crossing_rate) & (amplitude >= min_amplitude) & ~blown
    return ServoRinging(
        names=tuple(actuator_name(model, int(i)) for i in owner),
        ringing=ringing,
        crossing_rate=crossing,
        amplitude=amplitude,
        velocity_gain_ratio=ratio,
        timestep=h,
        diverged=blown,
    )
