"""Quadrupeds standing on four feet: LeggedBalance with the feet of known Menagerie robots."""

from __future__ import annotations

import dataclasses
import importlib.util
from collections.abc import Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.core.model import ModelSource
from mpcbox.errors import InvalidArgumentError, ModelNotFoundError
from mpcbox.tasks.legged.balance import QP_OSQP_SETTINGS, LeggedBalance

#: The four feet of Menagerie quadrupeds, by robot name (``"menagerie:NAME"``). The Go1 has
#: a site and a geom called ``FR``; its sphere geoms are the feet. The A1's and ANYmal C's
#: foot spheres have no names, so their lower-leg bodies stand for them (their soles are the
#: spheres' bottoms).
MENAGERIE_FEET: MappingProxyType[str, tuple[str, ...]] = MappingProxyType(
    {
        "unitree_go1": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
        "unitree_go2": ("geom:FR", "geom:FL", "geom:RR", "geom:RL"),
        "unitree_a1": ("body:FR_calf", "body:FL_calf", "body:RR_calf", "body:RL_calf"),
        "anybotics_anymal_c": (
            "body:LF_SHANK",
            "body:RF_SHANK",
            "body:LH_SHANK",
            "body:RH_SHANK",
        ),
    }
)


#: The toes of dm_control's quadruped (sites at the centers of its foot spheres).
DM_CONTROL_FEET: tuple[str, ...] = (
    "toe_front_left",
    "toe_front_right",
    "toe_back_right",
    "toe_back_left",
)


#: QP-MPC's replanning period (s) on a robot driven by torque alone (see QuadrupedStand).
TORQUE_QP_PERIOD = 0.004


def position_feedback(model: mujoco.MjModel) -> bool:
    """Whether any actuator's force depends on its length (a bias on it, such as a position
    servo's :math:`-k_p`), so that it holds a position between two controller calls."""
    return bool(np.any(model.actuator_biasprm[:, 1] != 0))


def dm_control_quadruped() -> mujoco.MjSpec:
    """dm_control's quadruped (``suite/quadruped.xml``) on a flat floor.

    Left out: the ball that drops on it from 3 m, the (flat) height field under the floor,
    which only costs collision tests, and the suite's sensors (20 range finders cast rays
    at every step; a Problem adds the sensors its cost needs).

    Raises:
        ModelNotFoundError: If dm_control is not installed.
    """
    found = importlib.util.find_spec("dm_control")
    if found is None or found.origin is None:
        raise ModelNotFoundError(
            "model: dm_control's quadruped needs dm_control (pip install dm_control)"
        )
    spec = mujoco.MjSpec.from_file(str(Path(found.origin).parent / "suite" / "quadruped.xml"))
    spec.delete(spec.body("ball"))
    spec.delete(spec.geom("terrain"))
    for sensor in list(spec.sensors):
        spec.delete(sensor)
    return spec


def menagerie_feet(model: ModelSource) -> tuple[str, ...] | None:
    """The feet of a ``"menagerie:NAME"`` robot listed in :data:`MENAGERIE_FEET`, else None."""
    if isinstance(model, str) and model.startswith("menagerie:"):
        return MENAGERIE_FEET.get(model.removeprefix("menagerie:").partition("/")[0])
    return None


class QuadrupedStand(LeggedBalance):
    """A quadruped standing on its four feet; by default Unitree's Go1 from MuJoCo Menagerie.

    :class:`~mpcbox.tasks.legged.balance.LeggedBalance` with its defaults, and the feet of
    a known Menagerie robot (:data:`MENAGERIE_FEET`) filled in. Any other quadruped works
    with its ``feet`` named. The Menagerie robots need ``pip install "mpcbox[menagerie]"``
    (or ``MENAGERIE_ROOT`` pointing at an offline copy).

    Args:
        model: The robot (default ``"menagerie:unitree_go1"``).
        feet: Its feet (default: from :data:`MENAGERIE_FEET`).
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    QP-MPC runs with OSQP at ``rho = 0.3`` and without OSQP 1.x's duality-gap test
    (:data:`QP_OSQP_SETTINGS`). It replans at 50 Hz on robots whose actuators hold a
    position between two ticks (position servos: Go1, A1, ANYmal C) and at 250 Hz
    (:data:`TORQUE_QP_PERIOD`) on robots driven by torque alone (motors: the Go2), which get
    no feedback in between. On the Go2 under the noise recipe, at 50 Hz one of two 3 s runs
    fell (the root height swinging by 8 cm, the knee torques at their limits); at 100 Hz
    over 15 steps 2 of 20 seeds of 10 s fell, over 20, 25 or 30 steps seeds 17 or 19 still
    did; at 250 Hz (two 0.002 s physics steps) over 10 steps none of seeds 0, 17 and 19
    did, at a median 2.7-3.0 ms a tick (``benchmarks/results/go2_stand.json`` for all 20).

    Raises:
        InvalidArgumentError: If ``feet`` is omitted for a robot not in
            :data:`MENAGERIE_FEET`.
    """

    name = "quadruped_stand"
    #: LQR, and QP-MPC with friction cones at the four feet (50 Hz; an instance whose
    #: actuators have no position feedback replans every :data:`TORQUE_QP_PERIOD` s).
    controller_configs: ClassVar[dict[str, Any]] = {
        "lqr": LQRConfig(),
        "qp": QPMPCConfig(period=0.02, stance_weight=1e5, osqp_settings=QP_OSQP_SETTINGS),
    }

    def __init__(
        self,
        model: ModelSource = "menagerie:unitree_go1",
        *,
        feet: Sequence[str] | None = None,
        **kwargs: Any,
    ) -> None:
        if feet is None:
            feet = menagerie_feet(model)
        if feet is None:
            raise InvalidArgumentError(
                "feet: name the four feet (sites, bodies or geoms) of this model; they are "
                "known only for " + ", ".join(f"'menagerie:{n}'" for n in MENAGERIE_FEET)
            )
        super().__init__(model, feet=feet, **kwargs)
        qp = type(self).controller_configs.get("qp")
        if isinstance(qp, QPMPCConfig) and not position_feedback(self.model):
            self.controller_configs = {
                **type(self).controller_configs,
                "qp": dataclasses.replace(qp, period=TORQUE_QP_PERIOD),
            }
