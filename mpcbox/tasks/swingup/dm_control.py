"""dm_control's suite cart-pole and acrobot as swing-up presets.

The suite's models ship with the ``dm_control`` package (``pip install dm_control``); they
are read from its folder without importing it. Both integrate with RK4, so the Problem plans
on an ``implicitfast`` copy (:class:`~mpcbox.errors.PlanningModelWarning`) and simulates in
RK4. In both, angle 0 is upright: the poles are modelled pointing up.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.sampling.config import MPPIConfig
from mpcbox.errors import ModelNotFoundError
from mpcbox.tasks.swingup.task import Swingup
from mpcbox.tasks.swingup.weights import SwingupWeights


def suite_path(name: str) -> Path:
    """Path of ``NAME.xml`` in dm_control's suite (its ``./common`` includes resolve from there).

    Raises:
        ModelNotFoundError: If dm_control is not installed or has no such model.
    """
    spec = importlib.util.find_spec("dm_control")
    if spec is None or not spec.submodule_search_locations:
        raise ModelNotFoundError(
            f"dm_control's suite model {name!r} needs the dm_control package: "
            "pip install dm_control"
        )
    suite = Path(next(iter(spec.submodule_search_locations))) / "suite"
    path = suite / f"{name}.xml"
    if not path.is_file():
        found = sorted(p.stem for p in suite.glob("*.xml"))
        raise ModelNotFoundError(
            f"dm_control's suite has no model {name!r}; it has: {', '.join(found)}"
        )
    return path


class DmCartpoleSwingup(Swingup):
    """dm_control's cart-pole (``suite/cartpole.xml``): swing the pole up from hanging.

    The pole is upright at ``hinge_1 = 0`` and starts hanging at ``pi``; the cart's rail ends
    at +-1.8 m (a joint limit). Default :class:`~mpcbox.tasks.swingup.weights.SwingupWeights`;
    upright within 0.2 rad over the final second counts as success. The same task as a
    one-liner::

        Swingup(suite_path("cartpole"), joints={"hinge_1": 0.0})

    Args:
        **kwargs: Passed to :class:`~mpcbox.tasks.swingup.task.Swingup`.
    """

    name = "dm_cartpole_swingup"
    #: Tuned configs: iLQR over 1.5 s at a 0.02 s planning step, replanning every 0.02 s
    #: from a small push; MPPI over 1 s with 128 samples on the CPU backend.
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
        "mppi": MPPIConfig(
            num_samples=128,
            horizon=1.0,
            planning_timestep=0.02,
            num_knots=5,
            noise_scale=0.3,
            temperature=0.1,
            period=0.01,
        ),
    }

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("joints", {"hinge_1": 0.0})
        super().__init__(suite_path("cartpole"), **kwargs)


class DmAcrobotSwingup(Swingup):
    """dm_control's acrobot (``suite/acrobot.xml``): swing both links up with the elbow alone.

    Upright is the tip (site ``tip``) at the suite's target, 4 m high above the shoulder at 2
    m; the chain starts hanging (``shoulder = pi``). Success: the tip within 0.2 m of the
    target over the final second. "Up" is the tip, not the joint angles: under a cost on
    the two wrapped angles the hanging rest is a local minimum (leaving it bends the elbow
    away from its upright angle 0), while under the tip's distance it is a saddle.

    Not yet solved: the tuned iLQR-MPC and MPPI pump energy but settle into a local minimum
    of this cost, one link up and the other down, and do not reach the target within 5 s
    (``benchmarks/swingup_dm_control.py``). A state guess does not help either: offline iLQR
    by multiple shooting (``states_init``, FDDP style) from a straight line hanging -> upright
    over 4 s converges to cost 42409 with the tip 1.96 m from the target, the same optimum
    that IPOPT finds from the same guess (42409, 1.96 m); over 3, 5 and 8 s, with arrival at
    60-100 % of the horizon, with an LQR terminal value, or from a growing-swing state guess
    or sinusoidal control guesses, the tip ends 1.2-2.7 m away. An energy-pumping feedback
    rollout (``u = clip(a sign(v1) cos(q2) + b v2 + c q2)``, whose tip comes within 0.68 m of
    the target after 5.8 s) as state and control guess over 6-7 s ends 0.6-2.1 m away after
    iLQR stops on short steps. The closest so far: the time reverse of an energy-draining
    fall from upright (``u = -clip(c v_elbow)`` on an undamped copy) as the state guess of
    multiple shooting, with running tip weight 1 and terminal weights 1000 (tip) and 100
    (velocity): the tip ends 0.05 m from the target after 7.5 s, but passing through, not
    held (``benchmarks/acrobot_swingup.py``); iLQR-MPC over that whole plan, one iteration
    per 0.02 s replan, in the RK4 simulation ended 2.6 m away after 10.5 s. mpcbox's
    acrobot with a 6 N m elbow, :class:`~mpcbox.tasks.swingup.presets.AcrobotSwingup`, is
    swung up and held.

    Args:
        **kwargs: Passed to :class:`~mpcbox.tasks.swingup.task.Swingup`.
    """

    name = "dm_acrobot_swingup"
    #: Tip distance, velocity and control weights in the proportions of MuJoCo MPC's acrobot.
    WEIGHTS = SwingupWeights(
        site=50.0,
        velocity=1.0,
        ctrl=0.05,
        position=0.0,
        angle=0.0,
        terminal_site=50.0,
        terminal_velocity=1.0,
        terminal_position=0.0,
        terminal_angle=0.0,
    )
    controller_configs: ClassVar[dict[str, Any]] = {
        "ilqr": ILQRConfig(
            horizon=100,
            planning_timestep=0.02,
            first_iterations=50,
            mpc_iterations=1,
            replan_period=0.02,
            ctrls_init=np.array([0.5]),
            threads=1,
        ),
        "mppi": MPPIConfig(
            num_samples=128,
            horizon=2.0,
            planning_timestep=0.02,
            num_knots=10,
            noise_scale=0.3,
            temperature=0.1,
            period=0.01,
        ),
    }

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault("sites", {"tip": np.array([0.0, 0.0, 4.0])})
        kwargs.setdefault("weights", self.WEIGHTS)
        kwargs.setdefault("tolerance", 0.2)
        super().__init__(suite_path("acrobot"), **kwargs)
