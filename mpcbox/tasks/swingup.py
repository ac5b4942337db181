"""Swing-up tasks: a torque-limited pendulum and a force-limited cart-pole.

In both scenes a hinge angle of 0 means hanging down and pi means upright. The pole angle is
penalized through :class:`~mpcbox.core.cost.WrappedAngle`, which is zero at every upright
angle (pi, 3 pi, -pi, ...), so a controller that lets the pole go over the top is not asked to
unwind it.
"""

from __future__ import annotations

from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ipopt_controller import IpoptConfig
from mpcbox.controllers.sampling.config import CEMConfig, MPPIConfig, PredictiveSamplingConfig
from mpcbox.core.cost import ControlCost, Cost, StateCost, WrappedAngle
from mpcbox.core.problem import Problem
from mpcbox.tasks import scene_path


class PendulumSwingup(Problem):
    """Swing a torque-limited pendulum (|u| <= 2 N m < m g l) from hanging to upright.

    Running cost: wrapped angle (weight 1), angular velocity (0.1) and torque (0.01); the
    terminal cost is heavier (100 and 10). Starts at rest hanging down.

    Args:
        **kwargs: Passed to :class:`~mpcbox.Problem` (e.g. ``planning_timestep``).
    """

    name = "pendulum_swingup"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "ilqr": ILQRConfig(
            horizon=100,
            planning_timestep=0.02,
            first_iterations=100,
            mpc_iterations=2,
            replan_period=0.02,
            ctrls_init=np.array([0.5]),
            threads=1,
        ),
        "ipopt": IpoptConfig(
            horizon=150,
            planning_timestep=0.02,
            tolerance=1e-6,
            ctrls_init=np.array([0.5]),
        ),
    }

    def __init__(self, **kwargs: Any) -> None:
        path = scene_path("pendulum.xml")
        kwargs.setdefault("qpos_ref", np.array([np.pi]))
        super().__init__(path, **kwargs)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        return Cost(
            [
                WrappedAngle("hinge", np.pi, weight=1.0),
                StateCost(self.qpos_ref, weight_qpos=0.0, weight_qvel=0.1, name="velocity"),
                ControlCost(weight=0.01),
            ],
            [
                WrappedAngle("hinge", np.pi, weight=100.0, name="terminal_angle"),
                StateCost(
                    self.qpos_ref, weight_qpos=0.0, weight_qvel=10.0, name="terminal_velocity"
                ),
            ],
        )

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.nstate)

    def upright_error(self, state: np.ndarray) -> float:
        """Angle (rad) between the pole and upright, wrapped to [0, pi]."""
        return float(abs(np.angle(np.exp(1j * (state[0] - np.pi)))))


class CartpoleSwingup(Problem):
    """Swing up the pole of a force-limited cart-pole (|F| <= 10 N) and balance it.

    Running cost: cart position (weight 2), wrapped pole angle (10), both velocities (0.5) and
    control (1); heavier terminal cost. Starts at rest hanging down.

    Args:
        **kwargs: Passed to :class:`~mpcbox.Problem`.
    """

    name = "cartpole_swingup"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "ilqr": ILQRConfig(
            horizon=75,
            planning_timestep=0.02,
            first_iterations=50,
            mpc_iterations=1,
            replan_period=0.02,
            ctrls_init=np.array([0.1]),
            threads=1,
        ),
        "ipopt": IpoptConfig(
            horizon=150,
            planning_timestep=0.02,
            tolerance=1e-6,
            ctrls_init=np.array([0.1]),
        ),
        # Sampling MPC (issue #5, mpcbox.controllers.sampling), tuned on the CPU backend; a 0.02 s
        # planning model halves the steps per rollout (50 over the 1 s horizon).
        "ps": PredictiveSamplingConfig(
            num_samples=128,
            horizon=1.0,
            planning_timestep=0.02,
            num_knots=5,
            noise_scale=0.5,
            period=0.01,
        ),
        "mppi": MPPIConfig(
            num_samples=128,
            horizon=1.0,
            planning_timestep=0.02,
            num_knots=5,
            noise_scale=0.3,
            temperature=0.1,
            period=0.01,
        ),
        "cem": CEMConfig(
            num_samples=128,
            horizon=1.0,
            planning_timestep=0.02,
            num_knots=5,
            noise_scale=0.4,
            num_elites=16,
            std_min=0.05,
            period=0.01,
        ),
    }

    def __init__(self, **kwargs: Any) -> None:
        path = scene_path("cartpole.xml")
        kwargs.setdefault("qpos_ref", np.array([0.0, np.pi]))
        super().__init__(path, **kwargs)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        return Cost(
            [
                StateCost(self.qpos_ref, weight_qpos=[2.0, 0.0], weight_qvel=[0.5, 0.5]),
                WrappedAngle("hinge_1", np.pi, weight=10.0),
                ControlCost(weight=1.0),
            ],
            [
                StateCost(
                    self.qpos_ref,
                    weight_qpos=[20.0, 0.0],
                    weight_qvel=[10.0, 10.0],
                    name="terminal_state",
                ),
                WrappedAngle("hinge_1", np.pi, weight=100.0, name="terminal_angle"),
            ],
        )

    def initial_state(self) -> np.ndarray:
        return np.zeros(self.nstate)

    def upright_error(self, state: np.ndarray) -> float:
        """Angle (rad) between the pole and upright, wrapped to [0, pi]."""
        return float(abs(np.angle(np.exp(1j * (state[1] - np.pi)))))
