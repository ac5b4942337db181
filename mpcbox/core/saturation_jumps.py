r"""Where a servo's force saturates, MuJoCo's implicit step jumps: by how much, per actuator.

MuJoCo's ``implicit`` and ``implicitfast`` integrators step the velocity as

.. math:: v^+ = v + h\,(M - h D)^{-1} f, \qquad D = \partial f / \partial v,

where :math:`D` holds the joints' damping and each actuator's velocity gain (a position
servo's ``kv``: :math:`-k_v m_i^T m_i` with the actuator's moment row :math:`m_i`), but an
actuator's term only while its force is inside ``forcerange``: a clamped force does not
depend on the velocity. Across the boundary the force is continuous and :math:`D` is not, so
the velocity after one step jumps. Along the actuator, for a force at its limit :math:`F_i`,

.. math:: \Delta v_i = h F_i\, m_i^T \big[(M_d - h k_{v,i} m_i^T m_i)^{-1} - M_d^{-1}\big]\, m_i,
   \qquad M_d = M + h \big(\mathrm{diag}(d) + \textstyle\sum_j k_{v,j} m_j^T m_j\big),

with every other servo's damping in :math:`M_d` (as MuJoCo has it while they are
unsaturated). The jump is a property of the discretization, not of the robot (the
continuous dynamics have no jump), and it shrinks with the timestep.

A gradient-based planner sees it as a jagged cost: on Menagerie's Panda (wrist servos of
kv 200 on about 0.1 kg m^2, limited to 12 N m, 0.12-0.17 rad/s per jump at 2 ms) about half
of iLQR-MPC's line searches found no step size that lowers the cost, and the jumps vanished
on a copy without the force limits (``benchmarks/ilqr_servo_saturation.py``). Sampling
planners do not differentiate and are unaffected; the Euler and RK4 integrators treat the
velocity gain explicitly throughout and have no such jump (their stability limit instead is
:math:`k_v h / I < 2` and about 2.8).
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.actuation import actuator_moment, actuator_name, velocity_gain
from mpcbox.core.model import check_mjmodel
from mpcbox.validation import as_array

#: Integrators whose step treats the actuators' velocity gains implicitly.
IMPLICIT = (mujoco.mjtIntegrator.mjINT_IMPLICIT, mujoco.mjtIntegrator.mjINT_IMPLICITFAST)


class SaturationJumps(NamedTuple):
    """The one-step velocity jump of each actuator at its force limit (:func:`saturation_jumps`).

    Attributes:
        names: Every actuator's name ``(nu,)``.
        velocity_jump: How much faster the actuator's length moves after one step from rest
            when its force is clamped at the limit than just inside it ``(nu,)`` (rad/s or
            m/s of the actuator length); 0 for an actuator without a force limit or a
            velocity gain, and for every actuator under an explicit integrator.
        fraction: That jump over the clamped step's own velocity change ``(nu,)``: near 1,
            the velocity gain dominates the inertia it drives (:math:`h k_v \\gg I`).
        timestep: The timestep (s).
        implicit: Whether the integrator is ``implicit`` or ``implicitfast`` (else no jumps).
    """

    names: tuple[str, ...]
    velocity_jump: np.ndarray
    fraction: np.ndarray
    timestep: float
    implicit: bool

    def large(self, min_fraction: float = 0.5) -> np.ndarray:
        """Actuators whose jump is at least ``min_fraction`` of their clamped step ``(nu,)``."""
        return (self.fraction >= min_fraction) & (self.velocity_jump > 0.0)

    def message(self, min_fraction: float = 0.5) -> str:
        """The largest jumps and what they mean for planners; ``""`` when none is large."""
        big = np.flatnonzero(self.large(min_fraction))
        if big.size == 0:
            return ""
        worst = big[np.argmax(self.velocity_jump[big])]
        return (
            f"{big.size} force-limited servo(s) jump in velocity where their force saturates "
            f"(up to {self.velocity_jump[worst]:.3g} rad/s or m/s in one step, "
            f"{self.names[worst]!r}; "
            f"{100 * self.fraction[big].min():.0f}-{100 * self.fraction[big].max():.0f}% of a "
            f"saturated step's change at {1e3 * self.timestep:g} ms): MuJoCo's implicit step "
            "drops a servo's kv once its force is clamped, so gradient planners meet a jagged "
            "cost (ArmReach's iLQR-MPC replans give up after one retry; sampling planners are "
            "unaffected); the jump scales with the timestep"
        )


def saturation_jumps(model: mujoco.MjModel, qpos: np.ndarray | None = None) -> SaturationJumps:
    """Each actuator's one-step velocity jump at its force limit, at a posture at rest.

    Args:
        model: The compiled model (not changed).
        qpos: Posture ``(nq,)``; default the first keyframe, else ``qpos0``.

    Returns:
        A :class:`SaturationJumps` (the module docstring gives the formula).

    Raises:
        InvalidTypeError: If ``model`` is not an ``MjModel``.
        ShapeError: If ``qpos`` has the wrong shape.
    """
    model = check_mjmodel(model)
    if qpos is None:
        qpos = model.key_qpos[0] if model.nkey else model.qpos0
    qpos = as_array("qpos", qpos, (model.nq,))
    h = float(model.opt.timestep)
    names = tuple(actuator_name(model, i) for i in range(model.nu))
    jump, fraction = np.zeros(model.nu), np.zeros(model.nu)
    implicit = model.opt.integrator in IMPLICIT
    if not implicit or model.nu == 0:
        return SaturationJumps(names, jump, fraction, h, implicit)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    moment = actuator_moment(model, data)[: model.nu]
    kv = np.array([velocity_gain(model, i) for i in range(model.nu)])
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    damped = mass + h * (np.diag(model.dof_damping) + (moment.T * kv) @ moment)
    limit = np.max(np.abs(model.actuator_forcerange), axis=1)
    for i in np.flatnonzero(model.actuator_forcelimited.astype(bool) & (kv > 0.0)):
        m_i = moment[i]
        if not np.any(m_i):
            continue
        inside = float(m_i @ np.linalg.solve(damped, m_i))
        clamped = float(m_i @ np.linalg.solve(damped - h * kv[i] * np.outer(m_i, m_i), m_i))
        jump[i] = h * limit[i] * (clamped - inside)
        fraction[i] = 1.0 - inside / clamped if clamped > 0.0 else 0.0
    return SaturationJumps(names, jump, fraction, h, implicit)


__all__ = ["IMPLICIT", "SaturationJumps", "saturation_jumps"]
