"""Two-feet standing balance of the humanoid (keyframe ``stand``)."""

from __future__ import annotations

from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.core.model import ModelSource
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.balance import HumanoidBalance
from mpcbox.tasks.humanoid.base import HumanoidProblem, balance_dofs, joint_weights
from mpcbox.tasks.legged.balance import FEET_CENTER, QP_OSQP_SETTINGS
from mpcbox.validation import finite, non_negative

__all__ = ["FEET_CENTER", "HumanoidTwoFeet"]


class HumanoidTwoFeet(HumanoidProblem):
    """Stand on both feet, the center of mass above the middle of the feet: a preset of
    :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    A world-fixed site ``feet_center`` is added to the model at the midpoint of the sites
    ``foot_left`` and ``foot_right`` in keyframe ``stand``; the root height is adjusted and
    the holding control found by inverse dynamics (:func:`~mpcbox.find_equilibrium`).

    The cost mirrors :class:`~mpcbox.tasks.humanoid.balance.HumanoidBalance`: the horizontal
    distance of the center of mass from ``feet_center`` (``balance_cost``), joint deviations
    (``balance_joint_cost`` on the abdomen and leg joints without a ``z`` in their names,
    ``other_joint_cost`` elsewhere, none on the root) and control effort (``ctrl_cost``).

    Args:
        model: MJCF with the humanoid's names (default: ``mpcbox/tasks/scenes/humanoid.xml``).
        balance_cost: Weight of the COM-over-feet residual.
        balance_joint_cost: Weight of balance-joint deviations.
        other_joint_cost: Weight of the other joint deviations.
        velocity_cost: Weight of joint velocities.
        ctrl_cost: Weight of control deviations.
        fall_height: The run fails when the torso is lower than this (m).
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance` and
            :class:`~mpcbox.Problem`.
    """

    name = "humanoid_two_feet"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "lqr": LQRConfig(),
        "qp": QPMPCConfig(
            contacts=("body:foot_left", "body:foot_right"),
            period=0.02,
            stance_weight=1e5,
            lifted_force_law="cancel",  # the published push limits (QPMPCConfig docs)
            # The legged presets' OSQP settings (rho 0.3, no duality-gap test): on one idle
            # Xeon core the tick under the noise recipe is 10.7 ms median, 14.6 ms p99 (29.4 /
            # 49.1 ms with OSQP_DEFAULTS' rho 3, 84 % of ticks over the 20 ms period); push
            # grid forward 100 N (same), backward 85 N (90), sideways 110 N (90)
            # (results/qp_tick_humanoid.json, results/qp_two_feet_legged_osqp.json).
            osqp_settings=QP_OSQP_SETTINGS,
        ),
        # iLQR-MPC: the one-leg task's config (0.35 s on a 0.015 s planning model, one
        # iteration per 50 Hz replan). With the controller's defaults (50 knots at 5 ms) a
        # replan took 130-150 ms and the humanoid fell in the real-time loop (0/5 seeds);
        # with this one it stood 3/3 there, ticks 25-28 ms median, and 3/3 with 25 knots of
        # three 5 ms steps instead (control_steps=3, 29-42 ms; results/
        # realtime_feedback_law_two_feet.json, realtime_feedback_law_two_feet_tuned.json).
        "ilqr": HumanoidBalance.controller_configs["ilqr"],
    }
    #: Contact bodies for contact-aware controllers.
    contacts: ClassVar[tuple[str, ...]] = ("body:foot_left", "body:foot_right")

    def __init__(
        self,
        *,
        model: ModelSource | None = None,
        balance_cost: float = 1000.0,
        balance_joint_cost: float = 3.0,
        other_joint_cost: float = 0.3,
        velocity_cost: float = 0.0,
        ctrl_cost: float = 1.0,
        fall_height: float = 0.8,
        **kwargs: Any,
    ) -> None:
        self.balance_joint_cost = non_negative("balance_joint_cost", balance_joint_cost)
        if kwargs.get("keyframe") is None:
            kwargs["keyframe"] = "stand"
        super().__init__(
            scene_path("humanoid.xml") if model is None else model,
            feet=("foot_left", "foot_right"),
            root="torso",
            fall_height=finite("fall_height", fall_height),
            fall_tilt=None,
            support="center",
            contacts=self.contacts,
            balance_cost=balance_cost,
            joint_cost=non_negative("other_joint_cost", other_joint_cost),
            velocity_cost=velocity_cost,
            ctrl_cost=non_negative("ctrl_cost", ctrl_cost),
            ctrl_units="control",
            recovery_tilt=None,
            **kwargs,
        )
        self.weights["balance_joint"] = self.balance_joint_cost

    def joint_weights(self, model: mujoco.MjModel) -> np.ndarray:
        """``balance_joint_cost`` on the abdomen and both legs' joints without a ``z``,
        ``other_joint_cost`` elsewhere, none on the root."""
        dofs = balance_dofs(model, ("left", "right"))
        return joint_weights(model, dofs, self.balance_joint_cost, self.weights["joint"])
