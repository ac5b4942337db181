"""A four-feet standing Problem for Menagerie quadrupeds, for the QP-MPC benchmarks only.

Stand-in until a generic legged-balance task lands in ``mpcbox.tasks``: the root height is
adjusted and the holding control found through the actuator model
(:func:`~mpcbox.find_equilibrium`); the cost is the state deviation (root pose included) plus
control effort in torque units; the run fails when the root body drops below half its
reference height. The noise is ``torque`` newton metres through each actuator's gain.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost import ControlCost, Cost, StateCost
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.model import load_spec
from mpcbox.core.problem import Problem
from mpcbox.sim.disturbances import ActuatorNoise

#: Menagerie robot -> (root body, foot geoms or bodies, standing joint angles or keyframe).
ROBOTS: dict[str, dict[str, Any]] = {
    "unitree_go1": dict(
        root="trunk", feet=("geom:FR", "geom:FL", "geom:RR", "geom:RL"), keyframe="home"
    ),
    "unitree_a1": dict(
        root="trunk",
        feet=("body:FR_calf", "body:FL_calf", "body:RR_calf", "body:RL_calf"),
        keyframe="home",
    ),
    "anybotics_anymal_c": dict(
        root="base",
        feet=("body:LF_SHANK", "body:RF_SHANK", "body:LH_SHANK", "body:RH_SHANK"),
        # No keyframe: a crouched stance (HAA, HFE, KFE per leg LF, RF, LH, RH).
        joints=[0.0, 0.6, -1.0, 0.0, 0.6, -1.0, 0.0, -0.6, 1.0, 0.0, -0.6, 1.0],
    ),
}


def actuator_gain(model: mujoco.MjModel) -> np.ndarray:
    """Generalized force per unit of control ``(nu,)``: ``gainprm[0] * gear[0]``."""
    return np.abs(model.actuator_gainprm[:, 0] * model.actuator_gear[:, 0])


def torque_noise(model: mujoco.MjModel, torque: float = 1.0) -> ActuatorNoise:
    """Actuator noise of ``torque`` N m standard deviation through each actuator's gain."""
    return ActuatorNoise(std=torque / actuator_gain(model))


class QuadrupedStand(Problem):
    """Stand on four feet (benchmark helper; see the module docstring).

    Args:
        robot: A key of :data:`ROBOTS`.
        **kwargs: Passed to :class:`~mpcbox.Problem`.
    """

    name = "quadruped_stand"

    def __init__(self, robot: str, **kwargs: Any) -> None:
        info = ROBOTS[robot]
        self.robot = robot
        self.root = info["root"]
        self.contacts = tuple(info["feet"])
        self.name = robot
        spec = load_spec(f"menagerie:{robot}")
        if "keyframe" in info:
            kwargs.setdefault("keyframe", info["keyframe"])
        else:
            base = spec.compile()
            qpos = base.qpos0.copy()
            qpos[7:] = info["joints"]
            kwargs.setdefault("qpos_ref", qpos)
        super().__init__(spec, **kwargs)

    def prepare(self, model: mujoco.MjModel) -> None:
        self.equilibrium = find_equilibrium(model, self.qpos_ref)
        self.qpos_ref = self.equilibrium.qpos
        self.ctrl_ref = self.equilibrium.ctrl
        self._root = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.root)
        data = mujoco.MjData(model)
        data.qpos[:] = self.qpos_ref
        mujoco.mj_kinematics(model, data)
        self.fall_height = 0.5 * float(data.xpos[self._root, 2])
        self._gain = actuator_gain(model)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        wq = np.full(model.nv, 1.0)
        wq[:6] = [10.0, 10.0, 30.0, 30.0, 30.0, 10.0]
        # Control cost in torque units: (gain * du)^2 with weight 1e-3 per (N m)^2.
        gain = actuator_gain(model)
        return Cost(
            [
                StateCost(self.qpos_ref, weight_qpos=wq, weight_qvel=0.1),
                ControlCost(self.ctrl_ref, weight=1e-3 * gain**2),
            ]
        )

    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        reason = super().failure(model, data)
        if reason is None and data.xpos[self._root, 2] < self.fall_height:
            reason = f"fell: {self.root} below {self.fall_height:.3f} m"
        return reason

    def noise(self, scale: float = 1.0) -> ActuatorNoise:
        """1 N m of torque noise through each actuator's gain, times ``scale``."""
        noise = torque_noise(self.model)
        return ActuatorNoise(std=noise.std, scale=scale)
