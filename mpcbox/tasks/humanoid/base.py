"""What the humanoid tasks share: equilibrium reference, falls, measures and noise recipe."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.core.equilibrium import Equilibrium, find_equilibrium
from mpcbox.core.model import object_id
from mpcbox.core.problem import Problem
from mpcbox.sim.disturbances import ActuatorNoise
from mpcbox.sim.measures import Measure
from mpcbox.tasks.humanoid.measures import balance_measures
from mpcbox.tasks.humanoid.noise import balance_noise


class HumanoidProblem(Problem):
    """Base of the humanoid tasks (bodies named like the classic MuJoCo humanoid's).

    :meth:`prepare` moves the reference posture's root until the contacts carry the weight
    and takes the holding control from inverse dynamics (:func:`~mpcbox.find_equilibrium`);
    a run fails when the ``torso`` body drops below ``fall_height``. The measures reported
    are the whole-body center of mass over the :meth:`support_frames` and the torso tilt
    (:func:`~mpcbox.tasks.humanoid.measures.balance_measures`); the noise model is the
    published recipe (:func:`~mpcbox.tasks.humanoid.noise.balance_noise`). Subclasses set
    ``fall_height`` before calling ``Problem.__init__`` and define :meth:`support_frames`.
    """

    fall_height: float = 0.8
    #: Stance leg whose joints get the low noise of the published recipe.
    noise_stance: str = "left"
    equilibrium: Equilibrium | None = None

    def prepare(self, model: mujoco.MjModel) -> None:
        self.equilibrium = find_equilibrium(model, self.qpos_ref)
        self.qpos_ref = self.equilibrium.qpos
        self.ctrl_ref = self.equilibrium.ctrl
        self._torso = object_id(model, "body", "torso")

    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        reason = super().failure(model, data)
        if reason is None and data.xpos[self._torso, 2] < self.fall_height:
            reason = f"fell: torso below {self.fall_height} m"
        return reason

    def support_frames(self) -> tuple[str, ...]:
        """Sites or bodies whose mean horizontal position the center of mass should be above."""
        raise NotImplementedError(f"{type(self).__name__} must define support_frames()")

    def measures(self) -> tuple[Measure, ...]:
        """COM deviation from the support point (m) and torso tilt (deg)."""
        return balance_measures(self.support_frames(), body="torso")

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
    wq = np.full(model.nv, float(other_joint))
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            adr = model.jnt_dofadr[j]
            wq[adr : adr + 6] = 0.0
    wq[dofs] = balance_joint
    return wq
