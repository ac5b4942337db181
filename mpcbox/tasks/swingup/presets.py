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
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks import scene_path
from mpcbox.tasks.swingup.task import Swingup
from mpcbox.tasks.swingup.weights import SwingupWeights


def _own_scene(task: Swingup, scene: str, kwargs: dict[str, Any]) -> Any:
    """The preset's scene; a ``model`` among ``kwargs`` is refused with a named error."""
    if "model" in kwargs:
        raise InvalidArgumentError(
            f"model: {type(task).__name__} swings up its own scene ({scene}); for another "
            "model use mpcbox.tasks.swingup.task.Swingup(model, joints=..., ...)"
        )
    return scene_path(scene)


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
        super().__init__(_own_scene(self, "pendulum.xml", kwargs), **kwargs)


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
        super().__init__(_own_scene(self, "cartpole.xml", kwargs), **kwargs)


#: Knots (0.02 s each) of the acrobot's plan: the swing-up takes about 3 s, then it holds.
ACROBOT_HORIZON = 200


class AcrobotSwingup(Swingup):
    """Swing up mpcbox's acrobot (two 1 kg, 1 m links; elbow torque |u| <= 6 N m) and hold it.

    The shoulder is passive, so the upper link rises only by swinging and the swing-up pumps
    energy; the elbow's 6 N m is a little more than the 4.9 N m that holds the lower link
    horizontal. This is a stronger elbow than dm_control's acrobot (2 N m,
    :class:`~mpcbox.tasks.swingup.dm_control.DmAcrobotSwingup`), whose swing-up mpcbox has
    not yet solved and held (see that class). Upright is ``shoulder = pi`` and ``elbow = 0``;
    the cost weighs both wrapped angles and the tip's height (10 each), velocities (0.1) and
    the torque as a fraction of its limit (0.1); terminal 100, 100 and 10. Upright within 0.2
    rad (the larger joint error) over the last second counts as success.

    The scene integrates at 0.02 s, the planning timestep of the tuned iLQR, so the plan is
    made on the simulated model itself. That iLQR plans 4 s ahead from the control guess
    ``cos(5 t)`` (one elbow swing per 1.26 s; from a constant guess it stops in a local
    minimum with the chain swinging), solves up to 400 iterations before the first control,
    then replans once per 0.02 s. It uses Tassa's regularization schedule
    (:mod:`~mpcbox.controllers.ilqr.regularization`, factor 1.6, from 1): from the hanging
    rest and four starts perturbed by N(0, 0.05) rad it swung up and held 5 of 5 runs of 6 s,
    against 4 of 5 with the default schedule (``benchmarks/acrobot_swingup.py``).

    Args:
        **kwargs: Passed to :class:`~mpcbox.tasks.swingup.task.Swingup`.
    """

    name = "acrobot_swingup"
    #: The preset's weights (:class:`~mpcbox.tasks.swingup.weights.SwingupWeights`).
    WEIGHTS = SwingupWeights(
        angle=10.0,
        site=10.0,
        velocity=0.1,
        ctrl=0.1,
        position=0.0,
        terminal_angle=100.0,
        terminal_site=100.0,
        terminal_velocity=10.0,
        terminal_position=0.0,
    )
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "ilqr": ILQRConfig(
            horizon=ACROBOT_HORIZON,
            planning_timestep=0.02,
            first_iterations=400,
            max_iterations=400,
            tolerance=1e-10,
            regularization_schedule="tassa",
            regularization_factor=1.6,
            regularization_min=1e-6,
            regularization=1.0,
            mpc_iterations=1,
            replan_period=0.02,
            ctrls_init=np.cos(5.0 * 0.02 * np.arange(ACROBOT_HORIZON))[:, None],
            threads=1,
        ),
        #: MPPI over 2 s (10 knots, 128 samples, CPU backend), replanning every 0.02 s, with
        #: the upright's LQR as catch (basin level estimated when built): from hanging and 4
        #: perturbed starts 5/5 upright (3.1-5.2 s) and held to 1e-4 rad; the same options
        #: without the catch 0/5, passing within 0.03-0.06 rad of upright but dropping it
        #: (``benchmarks/sampling_catch.py``, ``benchmarks/results/sampling_catch.json``).
        "mppi": MPPIConfig(
            horizon=2.0,
            num_knots=10,
            planning_timestep=0.02,
            replan_period=0.02,
            catch="lqr",
        ),
    }

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("joints", {"shoulder": np.pi, "elbow": 0.0})
        kwargs.setdefault("sites", {"tip": None})
        kwargs.setdefault("weights", self.WEIGHTS)
        super().__init__(_own_scene(self, "acrobot.xml", kwargs), **kwargs)
