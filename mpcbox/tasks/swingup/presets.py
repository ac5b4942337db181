"""The shipped swing-up scenes as presets of :class:`~mpcbox.tasks.swingup.task.Swingup`.

In both scenes a hinge angle of 0 means hanging down and pi means upright. The pole angle is
penalized through :class:`~mpcbox.core.cost.WrappedAngle`, which is zero at every upright
angle (pi, 3 pi, -pi, ...), so a controller that lets the pole go over the top is not asked to
unwind it.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ipopt_controller import IpoptConfig
from mpcbox.controllers.sampling.config import CEMConfig, MPPIConfig, PredictiveSamplingConfig
from mpcbox.tasks import scene_path
from mpcbox.tasks.swingup.task import Swingup
from mpcbox.tasks.swingup.weights import SwingupWeights


class PendulumSwingup(Swingup):
    """Swing a torque-limited pendulum (|u| <= 2 N m < m g l) from hanging to upright.

    Running cost: wrapped angle (weight 1), angular velocity (0.1) and torque (0.01 per
    (N m)^2, i.e. 0.04 on the torque as a fraction of its 2 N m limit); the terminal cost is
    heavier (100 and 10). Starts at rest hanging down; upright within 0.2 rad over the last
    second counts as success.

    Args:
        **kwargs: Passed to :class:`~mpcbox.tasks.swingup.task.Swingup` (e.g.
            ``planning_timestep``, ``tolerance``).
    """

    name = "pendulum_swingup"
    #: The preset's weights (:class:`~mpcbox.tasks.swingup.weights.SwingupWeights`).
    WEIGHTS = SwingupWeights(
        angle=1.0,
        velocity=0.1,
        ctrl=0.04,
        position=0.0,
        site=0.0,
        terminal_angle=100.0,
        terminal_velocity=10.0,
        terminal_position=0.0,
        terminal_site=0.0,
    )
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
        kwargs.setdefault("joints", {"hinge": np.pi})
        kwargs.setdefault("weights", self.WEIGHTS)
        super().__init__(scene_path("pendulum.xml"), **kwargs)


class CartpoleSwingup(Swingup):
    """Swing up the pole of a force-limited cart-pole (|F| <= 10 N) and balance it.

    Running cost: cart position (weight 2), wrapped pole angle (10), both velocities (0.5) and
    control (1, the control being the force as a fraction of 10 N); heavier terminal cost.
    Starts at rest hanging down; upright within 0.2 rad over the last second counts as success.

    Args:
        **kwargs: Passed to :class:`~mpcbox.tasks.swingup.task.Swingup`.
    """

    name = "cartpole_swingup"
    #: The preset's weights (:class:`~mpcbox.tasks.swingup.weights.SwingupWeights`).
    WEIGHTS = SwingupWeights(
        angle=10.0,
        position=2.0,
        velocity=0.5,
        ctrl=1.0,
        site=0.0,
        terminal_angle=100.0,
        terminal_position=20.0,
        terminal_velocity=10.0,
        terminal_site=0.0,
    )
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
        kwargs.setdefault("joints", {"hinge_1": np.pi})
        kwargs.setdefault("weights", self.WEIGHTS)
        super().__init__(scene_path("cartpole.xml"), **kwargs)
