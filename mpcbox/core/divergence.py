r"""Catching a planning timestep that makes the model diverge, from MuJoCo's warning counters.

MuJoCo flags an unstable step in ``data.warning`` (for example
``mjWARN_BADQACC``: a non-finite or huge acceleration, after which it resets the data) and
prints the first occurrence through its warning handler. :func:`check_planning_step` rolls the
planning model forward a short while from the reference state at the reference control,
with the handler replaced by :func:`captured_warnings` so that nothing reaches stderr, and
reads the counters: a step of :math:`\Delta t` that is too coarse for a stiff servo (explicit
stiffness :math:`k_p` on an inertia :math:`I` grows like :math:`|1 - \omega^2 \Delta t^2|`
per step when :math:`\omega \Delta t > 2`, :math:`\omega = \sqrt{k_p / I}`) shows within a
few dozen steps.
"""

from __future__ import annotations

import math
from typing import Protocol

import mujoco
import numpy as np

from mpcbox.core.dynamics import write_state
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.errors import PlanningDivergenceError


class PlanningProblem(Protocol):
    """What :func:`check_planning_step` reads of a :class:`~mpcbox.Problem`."""

    model: mujoco.MjModel
    planning_model: mujoco.MjModel
    ctrl_ref: np.ndarray

    def reference_state(self) -> np.ndarray: ...

    def clip_ctrl(self, ctrl: np.ndarray) -> np.ndarray: ...


#: Warnings that mean the state left the numbers MuJoCo can integrate.
UNSTABLE = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
)


def unstable_warning(data: mujoco.MjData) -> str | None:
    """The first instability warning counted in ``data.warning``, in MuJoCo's words, or None."""
    for kind in UNSTABLE:
        stat = data.warning[kind]
        if stat.number:
            return mujoco.mju_warningText(kind, stat.lastinfo)
    return None


def diverged(data: mujoco.MjData, *written: np.ndarray) -> bool:
    """Whether a simulation on ``data`` (reset before it) diverged.

    True if MuJoCo counted a bad position, velocity or acceleration (after which it reset
    ``data`` and carried on) or an array the simulation wrote (states, controls, defects,
    velocities) holds a non-finite value.
    """
    return unstable_warning(data) is not None or not all(np.isfinite(a).all() for a in written)


def check_planning_step(
    problem: PlanningProblem, *, duration: float = 0.1, max_steps: int = 200
) -> None:
    """Raise if the planning model diverges from the reference state at the reference control.

    Rolls ``problem.planning_model`` forward ``min(max_steps, max(10, ceil(duration / dt)))``
    steps from :meth:`~mpcbox.Problem.reference_state` under the clipped ``ctrl_ref`` and
    reads MuJoCo's warning counters (not stderr; nothing is printed). A few hundred steps of
    one model: cheap next to building any controller.

    Args:
        problem: The Problem whose planning model is checked.
        duration: Seconds to roll forward.
        max_steps: Cap on the number of steps.

    Raises:
        PlanningDivergenceError: Naming ``planning_timestep`` and suggesting a smaller one,
            if MuJoCo reports a bad acceleration, velocity or position, or the state turns
            non-finite.
    """
    model = problem.planning_model
    dt = float(model.opt.timestep)
    data = mujoco.MjData(model)
    write_state(data, problem.reference_state())
    ctrl = problem.clip_ctrl(problem.ctrl_ref)
    steps = min(max_steps, max(10, math.ceil(duration / dt)))
    warning, taken = None, 0
    with captured_warnings(), np.errstate(all="ignore"):
        while warning is None and taken < steps:
            data.ctrl[:] = ctrl
            mujoco.mj_step(model, data)
            taken += 1
            warning = unstable_warning(data)
            if warning is None and not np.all(np.isfinite(data.qvel)):
                warning = "non-finite velocities"
    if warning is None:
        return
    sim_dt = float(problem.model.opt.timestep)
    raise PlanningDivergenceError(
        f"the planning model diverges at planning_timestep={dt:g} s: MuJoCo reported "
        f"'{warning}' after {taken} step(s) from the reference state at the reference "
        f"control; use a smaller planning_timestep (the simulation timestep is {sim_dt:g} s)"
    )


__all__ = [
    "UNSTABLE",
    "PlanningProblem",
    "captured_warnings",
    "check_planning_step",
    "unstable_warning",
]
