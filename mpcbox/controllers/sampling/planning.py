"""The planning models a sampling controller rolls out.

The controller plans on its own copy of the Problem's planning model when its config asks
for another timestep, integrator, solver setting or disabled features, and optionally on
randomized copies of it for robust planning.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from mpcbox.controllers.lqr import with_lqr_terminal_value
from mpcbox.controllers.sampling.config import (
    INTEGRATORS,
    Randomization,
    SamplingConfig,
    disable_bits,
)
from mpcbox.core.problem import Problem


def planning_problem(problem: Problem, config: SamplingConfig) -> Problem:
    """The Problem to plan on: ``problem``, or a copy with its own planning model.

    A copy is made when ``config`` sets ``planning_timestep`` (other than the Problem's),
    ``planning_integrator``, ``planning_disable``, ``solver_tolerance``, ``servo_armature``
    (:func:`servo_armature`), or
    ``solver_iterations`` with the warp backend (the CPU backend ignores the cap, see
    :class:`~mpcbox.controllers.sampling.config.SamplingConfig`); ``terminal_value="lqr"``
    then adds the LQR value of that planning model to its terminal cost. ``problem`` is
    unchanged.

    Args:
        problem: The Problem.
        config: A validated config.
    """
    if config.planning_timestep is not None:
        dt = float(config.planning_timestep)
        if abs(dt - problem.dt) > 1e-12:
            problem = problem.with_planning_timestep(dt)
    disable = disable_bits(config.planning_disable)
    # The solver cap is for MJWarp only (see SamplingConfig.solver_iterations).
    cap = config.solver_iterations if config.backend == "warp" else None
    options = (cap, config.solver_tolerance, config.planning_integrator, config.servo_armature)
    if disable or any(v is not None for v in options):
        problem = problem.with_planning_timestep(problem.dt)  # a private planning model
        opt = problem.planning_model.opt
        if config.planning_integrator is not None:
            opt.integrator = INTEGRATORS[config.planning_integrator]
        opt.disableflags |= disable
        if cap is not None:
            opt.iterations = cap
        if config.solver_tolerance is not None:
            opt.tolerance = float(config.solver_tolerance)
        if config.servo_armature is not None:
            servo_armature(problem.planning_model, float(config.servo_armature))
    if config.terminal_value == "lqr":
        problem = with_lqr_terminal_value(problem)
    return problem


def servo_armature(model: mujoco.MjModel, factor: float) -> np.ndarray:
    r"""Raise the armature of servo-driven joints so that ``model``'s step is stable.

    For each actuator with a joint transmission on a hinge or slide whose force depends on
    its length (an affine bias with ``biasprm[1] < 0``: a position servo, or a general
    actuator with such a bias), the joint's stiffness is :math:`k = -b_1 g^2` (gear
    :math:`g`), and its dof's armature becomes :math:`\max(I_a, c\,k\,\Delta t^2)`
    with :math:`\Delta t` = ``model.opt.timestep``. An explicit step of a spring
    :math:`k` on inertia :math:`I` is stable while :math:`k \Delta t^2 / I < 4`, and the
    armature bounds :math:`I` from below, so :math:`c \ge 1/4` keeps each servo's own
    spring stable at that step (the implicit integrators treat the servo's damping, not
    its spring). The model is changed in place, and its derived constants are recomputed
    (:func:`mujoco.mj_setConst`: MuJoCo keeps the mass of a dof with a constant inertia
    apart).

    Args:
        model: The model (its ``dof_armature`` is changed).
        factor: :math:`c > 0`.

    Returns:
        The dofs whose armature was raised ``(k,)``.
    """
    raised = []
    # int(): a numpy integer is never ``in`` a tuple of MuJoCo's enum values.
    joint_types = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    joint_trns = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    dt2 = float(model.opt.timestep) ** 2
    for a in range(model.nu):
        affine = int(model.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
        if not affine or int(model.actuator_trntype[a]) not in joint_trns:
            continue
        stiffness = -float(model.actuator_biasprm[a, 1]) * float(model.actuator_gear[a, 0]) ** 2
        joint = int(model.actuator_trnid[a, 0])
        if stiffness <= 0 or int(model.jnt_type[joint]) not in joint_types:
            continue
        dof = int(model.jnt_dofadr[joint])
        least = factor * stiffness * dt2
        if model.dof_armature[dof] < least:
            model.dof_armature[dof] = least
            raised.append(dof)
    if raised:
        mujoco.mj_setConst(model, mujoco.MjData(model))
    return np.asarray(raised, dtype=int)


def randomized_models(model: mujoco.MjModel, rand: Randomization) -> list[mujoco.MjModel]:
    r"""``rand.num_models`` copies of ``model`` with scaled masses/inertias and friction.

    The first model is ``model`` unchanged; the others scale body ``b``'s mass and inertia by
    :math:`s_b \sim U(\text{mass\_scale})` (the world body keeps 1) and each geom's friction
    by :math:`f_g \sim U(\text{friction\_scale})`, drawn from ``rand.seed``. Derived
    constants are recomputed with :func:`mujoco.mj_setConst`.
    """
    rng = np.random.default_rng(rand.seed)
    models = [model]
    for _ in range(rand.num_models - 1):
        m = copy.copy(model)
        scale = rng.uniform(*rand.mass_scale, size=m.nbody)
        scale[0] = 1.0
        m.body_mass[:] = model.body_mass * scale
        m.body_inertia[:] = model.body_inertia * scale[:, None]
        m.geom_friction[:] = model.geom_friction * rng.uniform(
            *rand.friction_scale, size=(m.ngeom, 1)
        )
        mujoco.mj_setConst(m, mujoco.MjData(m))
        models.append(m)
    return models


def planning_models(model: mujoco.MjModel, rand: Randomization | None) -> list[mujoco.MjModel]:
    """``[model]``, or its :func:`randomized_models` when ``rand`` is given."""
    return [model] if rand is None else randomized_models(model, rand)
