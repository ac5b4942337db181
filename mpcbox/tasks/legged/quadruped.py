"""Quadrupeds standing on four feet: LeggedBalance with the feet of known Menagerie robots."""

from __future__ import annotations

import importlib.util
import warnings
from collections.abc import Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.core.model import ModelSource
from mpcbox.errors import ModelNotFoundError
from mpcbox.tasks.legged.balance import LeggedBalance
from mpcbox.tasks.legged.biped import BipedStand
from mpcbox.tasks.legged.ground_feet import ground_feet

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
    a known Menagerie robot (:data:`MENAGERIE_FEET`) filled in. On any other quadruped the
    feet are found (:func:`~mpcbox.tasks.legged.ground_feet.ground_feet`) or named. The
    Menagerie robots need ``pip install "mpcbox[menagerie]"`` (or ``MENAGERIE_ROOT``
    pointing at an offline copy).

    Args:
        model: The robot (default ``"menagerie:unitree_go1"``).
        feet: Its feet (default: from :data:`MENAGERIE_FEET`, else the lowest bodies of its
            four legs in the keyframe, :func:`~mpcbox.tasks.legged.ground_feet.ground_feet`).
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    QP-MPC runs with :class:`~mpcbox.tasks.legged.balance.LeggedBalance`'s settings: OSQP
    at ``rho = 0.3`` without the duality-gap test, 50 Hz on robots with position servos
    (Go1, A1, ANYmal C) and 100 Hz with the LQR gain about the plan between ticks on robots
    driven by torque alone (the Go2).

    Raises:
        InvalidArgumentError: If ``feet`` is omitted and the bodies touching the ground do
            not form four legs (the message lists them).
    """

    name = "quadruped_stand"
    #: iLQR-MPC: :class:`~mpcbox.tasks.legged.biped.BipedStand`'s config (dynamics and
    #: cost Hessians at the standing reference, LQR terminal value, one iteration a
    #: replan). Stop 45, with that config's open-loop warm start then: it kept the 20 ms
    #: period where the generic ``ILQRConfig()`` (linearized along each trajectory) does
    #: not: replans 7.2-7.3 ms median on the Go2 and 10.7-11.4 ms on the ANYmal C against
    #: 89 and 143 ms (one thread, 2-core sandbox;
    #: ``benchmarks/ilqr_tick.py --robots go2,anymal_c``, results/ilqr_tick_quadrupeds.json).
    #: Under the noise recipe it stands 34 of 35 runs of 5 s on seven Menagerie quadrupeds
    #: (the Barkour v0 fell once), with 0-4 % of replans falling back on the Go1, Go2,
    #: Spot and Barkour v0, 5-11 % on the ANYmal B and Barkour vB, 12-23 % on the ANYmal C.
    #: Its largest forward push is 1.02-1.04x LQR's on the Go1 and both Barkours but
    #: 0.64x on the ANYmal B, 0.84x on the ANYmal C, 0.90x on the Spot and 0.62x on the
    #: Go2, where the generic config survives 263.7 N against 155.3 N (LQR 249.0 N;
    #: results/quadruped_ilqr_reference.json). A second iteration a replan
    #: (``mpc_iterations=2``) left the tilt and the fallbacks unchanged and took 2.5-5.5x
    #: the tick: its second step stalls on most replans, there being little left to gain
    #: on the reference model. Stop 46 (the config's feedback-law warm start, three step
    #: sizes and no retry; the balance term at rest at the equilibrium): 35 of 35 stand, no
    #: fallback (10-76 % of replans stall and keep the law), pushes 1.00-1.16x LQR's,
    #: replans 10-13 ms median on the Go2 and the ANYmal C
    #: (results/ilqr_feedback_warm_start.json).
    controller_configs: ClassVar[dict[str, Any]] = {
        **LeggedBalance.controller_configs,
        "ilqr": BipedStand.controller_configs["ilqr"],
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
        elif not isinstance(feet, str) and isinstance(feet, Sequence) and len(feet) != 4:
            warnings.warn(
                f"QuadrupedStand: feet names {len(feet)} feet ({list(feet)}); a quadruped "
                "stands on 4, so the others count as off the ground (name all four unless "
                "that is meant)",
                UserWarning,
                stacklevel=2,
            )
        super().__init__(model, feet=feet, **kwargs)

    def standing_feet(
        self, model: mujoco.MjModel, qpos: np.ndarray, feet: Sequence[str] | str | None
    ) -> Sequence[str] | str:
        """The feet as given, else the four found (:func:`ground_feet`)."""
        return ground_feet(model, qpos, 4, root=self.root_id) if feet is None else feet
