"""What the humanoid presets share: the classic humanoid's names and its noise recipe."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import mujoco
import numpy as np

from mpcbox.core.model import dof_weights
from mpcbox.sim.disturbances import ActuatorNoise
from mpcbox.tasks.humanoid.noise import balance_noise
from mpcbox.tasks.legged.balance import LeggedBalance


class HumanoidProblem(LeggedBalance):
    """Base of the humanoid presets of :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    The presets pass the classic MuJoCo humanoid's names (root ``torso``, feet the sites
    ``foot_left`` and ``foot_right``, or the bodies of those names when there are no such
    sites, contacts at the foot bodies' capsules), explicit fall
    heights and control weights in control units. Two things stay humanoid-specific: the
    posture weights of the balance joints (:func:`balance_dofs`, found by joint name) and
    the published noise recipe (:func:`~mpcbox.tasks.humanoid.noise.balance_noise`) instead
    of the robot-independent one.
    """

    #: Stance leg whose joints get the low noise of the published recipe.
    noise_stance: str = "left"
    #: The presets' QP-MPC keeps its measured 50 Hz on the torque-driven humanoid.
    torque_qp_period: ClassVar[float | None] = None

    def add_sole_sites(self, spec: mujoco.MjSpec, base: mujoco.MjModel) -> tuple[str, ...]:
        """No sites added: a foot is the site ``foot_<leg>``, or the body of that name in
        models without the site (the classic humanoid of mujoco-warp's test data)."""
        return tuple(foot.name for foot in self.feet)

    def noise(self, scale: float = 1.0) -> ActuatorNoise:
        """The published actuator-noise recipe (low noise on the ``noise_stance`` leg)."""
        return balance_noise(self.model, stance=self.noise_stance, scale=scale)


def balance_dofs(model: mujoco.MjModel, legs: Sequence[str]) -> np.ndarray:
    """Dofs of the abdomen and the ``legs``' hip, knee and ankle joints without a ``z``."""
    dofs = []
    for j in range(model.njnt):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or ""
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE or "z" in name:
            continue
        leg = any(side in name for side in legs) and any(
            k in name for k in ("hip", "knee", "ankle")
        )
        if "abdomen" in name or leg:
            dofs.append(int(model.jnt_dofadr[j]))
    return np.array(dofs, dtype=int)


def joint_weights(
    model: mujoco.MjModel, dofs: np.ndarray, balance_joint: float, other_joint: float
) -> np.ndarray:
    """Per-dof position weights ``(nv,)``: ``balance_joint`` on ``dofs``, ``other_joint``
    elsewhere, zero on free joints (the root)."""
    wq = dof_weights(model, float(other_joint))
    wq[dofs] = balance_joint
    return wq
