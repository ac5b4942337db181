"""Two-feet standing balance of the humanoid (keyframe ``stand``)."""

from __future__ import annotations

from typing import Any, ClassVar

import mujoco

from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.core.cost import ComOverSupport, ControlCost, Cost, StateCost
from mpcbox.core.model import ModelSource, compile_spec, load_spec, object_id
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.base import HumanoidProblem, balance_dofs, joint_weights
from mpcbox.validation import finite, non_negative

#: Name of the world site added midway between the feet.
FEET_CENTER = "feet_center"


class HumanoidTwoFeet(HumanoidProblem):
    """Stand on both feet and keep the center of mass above the middle of the feet.

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
        **kwargs: Passed to :class:`~mpcbox.Problem`.
    """

    name = "humanoid_two_feet"
    #: Tuned config of each controller that :func:`mpcbox.make_controller` builds.
    controller_configs: ClassVar[dict[str, Any]] = {
        "lqr": LQRConfig(),
        "qp": QPMPCConfig(
            contacts=("body:foot_left", "body:foot_right"),
            period=0.02,
            stance_weight=1e5,
        ),
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
        self.weights = dict(
            balance=non_negative("balance_cost", balance_cost),
            balance_joint=non_negative("balance_joint_cost", balance_joint_cost),
            other_joint=non_negative("other_joint_cost", other_joint_cost),
            velocity=non_negative("velocity_cost", velocity_cost),
            ctrl=non_negative("ctrl_cost", ctrl_cost),
        )
        self.fall_height = finite("fall_height", fall_height)
        spec = load_spec(scene_path("humanoid.xml") if model is None else model)
        if kwargs.get("keyframe") is None:
            kwargs["keyframe"] = "stand"
        base = compile_spec(spec)
        data = mujoco.MjData(base)
        key = object_id(base, "keyframe", kwargs["keyframe"], "keyframe")
        data.qpos[:] = base.key_qpos[key]
        mujoco.mj_kinematics(base, data)
        feet = [data.site_xpos[object_id(base, "site", f"foot_{leg}")] for leg in ("left", "right")]
        center = 0.5 * (feet[0] + feet[1])
        spec.worldbody.add_site(name=FEET_CENTER, pos=[center[0], center[1], 0.0])
        super().__init__(spec, **kwargs)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        w = self.weights
        dofs = balance_dofs(model, ("left", "right"))
        wq = joint_weights(model, dofs, w["balance_joint"], w["other_joint"])
        return Cost(
            [
                ComOverSupport(FEET_CENTER, weight=w["balance"], root="torso", name="balance"),
                StateCost(self.qpos_ref, weight_qpos=wq, weight_qvel=w["velocity"]),
                ControlCost(self.ctrl_ref, weight=w["ctrl"]),
            ]
        )

    def support_frames(self) -> tuple[str, ...]:
        """The site midway between the feet."""
        return (FEET_CENTER,)
