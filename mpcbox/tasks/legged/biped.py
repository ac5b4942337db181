"""Bipeds standing on two feet or on one: LeggedBalance with the feet of known Menagerie robots."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from types import MappingProxyType
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.core.model import ModelSource
from mpcbox.core.posture import StancePosture, stance_posture
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.legged.balance import LeggedBalance
from mpcbox.tasks.legged.feet import find_feet
from mpcbox.tasks.legged.ground_feet import ground_feet
from mpcbox.validation import one_of, positive

#: The (left, right) feet of Menagerie bipeds, by robot name (``"menagerie:NAME"``). The
#: G1's sites ``left_foot``/``right_foot`` sit at the ankle, 3.5 cm above the sole; its
#: ankle-roll bodies stand on four small spheres each, so the bodies are the feet (their
#: soles are the middle of the spheres' bottoms, and QP-MPC gets the eight spheres).
MENAGERIE_BIPED_FEET: MappingProxyType[str, tuple[str, str]] = MappingProxyType(
    {
        "unitree_g1": ("body:left_ankle_roll_link", "body:right_ankle_roll_link"),
    }
)

#: iLQR-MPC options of Menagerie bipeds on two feet that differ from :class:`BipedStand`'s,
#: by robot name, each chosen by measurement. The G1 plans on Jacobians without its dry
#: friction (``ILQRConfig.dry_friction="drop"``): after a hop its feet rock back onto their
#: heels, where the friction-aware Jacobians' replans stall and it falls backwards; without
#: the friction it lands flat again. A 250 N push under noise with a simulated 14 ms
#: latency, new seeds 400-409: 10/10 against 7/10 (4/10 with ``lookahead="auto"``, 10/10
#: with it dropped); on the wall clock of 2 CPU cores 10/10 (7-9/10 in stop 48's runs); the
#: largest forward push with the pelvis at rest 4 s later 271.9 N against 240.6 N. Not for
#: every biped: PAL's Talos falls with it (0/3 under noise, both actuator versions), the
#: Booster T1 and Apptronik Apollo recover 5-8 % smaller pushes, and robots without dry
#: friction are unchanged (``benchmarks/results/ilqr_dry_friction_bipeds.json``;
#: ``docs/results/stops.md``, stop 49).
MENAGERIE_BIPED_ILQR: MappingProxyType[str, MappingProxyType[str, Any]] = MappingProxyType(
    {"unitree_g1": MappingProxyType({"dry_friction": "drop"})}
)

#: Stances of :class:`BipedStand`.
STANCES: tuple[str, ...] = ("two", "left", "right")


def menagerie_robot(model: ModelSource) -> str | None:
    """The robot name of a ``"menagerie:NAME[/entry]"`` source, else None."""
    if isinstance(model, str) and model.startswith("menagerie:"):
        return model.removeprefix("menagerie:").partition("/")[0]
    return None


def menagerie_biped_feet(model: ModelSource) -> tuple[str, str] | None:
    """The feet of a ``"menagerie:NAME"`` biped in :data:`MENAGERIE_BIPED_FEET`, else None."""
    robot = menagerie_robot(model)
    return None if robot is None else MENAGERIE_BIPED_FEET.get(robot)


class BipedStand(LeggedBalance):
    """A biped standing on both feet or on one; by default Unitree's G1 from MuJoCo Menagerie.

    :class:`~mpcbox.tasks.legged.balance.LeggedBalance` with its robot-independent defaults
    (cost weights in fractions of each actuator's range, the noise recipe of 5 % of each
    range, the fall height from the keyframe) and the feet of a known Menagerie robot
    (:data:`MENAGERIE_BIPED_FEET`) filled in. On any other biped the feet are found
    (:func:`~mpcbox.tasks.legged.ground_feet.ground_feet`) or named.

    On one foot (``stance="left"`` or ``"right"``) the reference posture comes from
    inverse kinematics (:func:`~mpcbox.core.posture.stance_posture`): from the keyframe, the
    center of mass over the stance foot's sole, the other foot lifted by ``lift``, the root
    kept upright. A posture in self-collision is rejected
    (:class:`~mpcbox.errors.SolverError` naming the touching geoms), since its holding
    torques would be meaningless. The equilibrium then comes through the actuator model as
    for two feet.

    Args:
        model: The robot (default ``"menagerie:unitree_g1"``).
        stance: ``"two"``, or the stance foot ``"left"`` or ``"right"``.
        feet: Its (left, right) feet: site, body or geom names (default: from
            :data:`MENAGERIE_BIPED_FEET`, else the lowest bodies of its two legs in the
            keyframe, :func:`~mpcbox.tasks.legged.ground_feet.ground_feet`).
        lift: Height the swing foot is lifted on one foot (m).
        **kwargs: Passed to :class:`~mpcbox.tasks.legged.balance.LeggedBalance`.

    Raises:
        InvalidArgumentError: If ``feet`` does not name two feet, or is omitted and the
            bodies touching the ground do not form two legs (the message lists them).
        SolverError: On one foot, if inverse kinematics cannot put the center of mass over
            the stance foot or ends in self-collision.
    """

    name = "biped_stand"
    #: LeggedBalance's LQR and QP-MPC (friction cones at every collision geom of the stance
    #: feet); iLQR-MPC on the simulation's own step (0.1 s horizon of 50 knots, 50 Hz
    #: replanning with one iteration and the plan's feedback in between, the LQR value as
    #: terminal cost) with the dynamics linearized once, at the standing reference
    #: (``linearization="reference"``, the LQR's model). On the G1 a coarser planning model
    #: does not hold: at 0.015 s (the humanoid preset's) and 0.01 s the contacts diverge (QACC
    #: warnings within 0.2 s), and at 0.005 s with the LQR terminal value it falls within 2.5 s
    #: without noise. Linearized along its trajectories (every fifth knot) it stood 0 of 5
    #: seeds of 10 s under the noise recipe (tilt 14 deg RMS, results/g1_balance.json): the
    #: G1's joints have dry friction (``frictionloss`` 0.3 N m), each sticks or slips, and the
    #: Jacobians along 0.1 s of drift from the reference differ from the reference's by
    #: 33-62 % (under 1.2 % with the friction removed), so the gains of the backward pass
    #: follow stick-slip modes that do not last (results/g1_ilqr_linearization.json). With the
    #: reference's Jacobians it stands 5 of 5 seeds of 10 s (tilt 0.49 deg RMS, 0.6 % of
    #: replans stalled, 23 ms median tick) and a 162.9 N forward push, 0.94 of LQR's
    #: (results/g1_balance_ilqr.json). With the iLQR of stop 41 (the code of stop 31 fell
    #: after 200 and 250 N pushes on the same G1) it recovers from larger pushes by hopping
    #: forward on both feet: 255.5 N, 1.48 of LQR's, with the pelvis back at rest 4 s after
    #: the push; a 2 s window had counted a G1 still hopping as recovered (485.5 N;
    #: results/g1_balance_ilqr_settled_push.json,
    #: results/g1_push_recovery_ilqr.json). Stop 42 plans it with the cost's Hessians at the
    #: reference too (``cost_hessian="reference"``; the push grid recovers and falls at the
    #: same forces, results/g1_push_recovery_ilqr_reference_hessians.json), so that every
    #: backward pass repeats the last one's matrices (the solver's Riccati cache: 7.4 ->
    #: 1.3 ms a pass), and caps a replan's regularization retries at one
    #: (``mpc_max_retries=1``): ticks 10-11 ms median with the cost stages (were 22-24 ms;
    #: results/ilqr_tick_g1_stop42.json), 252.3 N (1.46x LQR's), 5/5 under noise
    #: (results/g1_balance_ilqr_riccati_cache.json). In the real-time loop on 2 cores a
    #: 250 N push under noise, seeds 100-109: 8, 5, 5, 8 and 8 of 10 in five runs, against
    #: 0/10 with stop 41's config; lock-step 8/10 with either
    #: (results/realtime_g1_ilqr_push250_{riccati_cache,stop42,seeds100}.json). The cache
    #: without the retry cap fell 0/3 in real time, the cap without the cache 3/10
    #: (..._reference_hessians.json, ..._retries1_seeds100.json). The QP-MPC's largest
    #: forward push on two feet (169 N) and LQR's (172.5 N) are both within 4 % of the
    #: capture-point bound of the ankle strategy (175.6 N: the G1's center of mass is 0.117 m
    #: behind its toes), and no single change of the QP options (period, step, horizon,
    #: terminal, relinearization, friction, slack weight) passed 172.5 N
    #: (``benchmarks/g1_push_limit.py``, results/g1_push_limit.json). QP-MPC's OSQP solve
    #: has a 15 ms budget (``time_limit``, 75 % of the 20 ms period): without it the G1's
    #: tick took 11.0 ms median but 37.1 ms p99 and up to 233 ms on one idle Xeon core (a
    #: few solves need 75-400 iterations where most need 25-30; 5.3 % of ticks overran the
    #: period); with it 16.9 ms p99, 17.7 ms at most, 10 of 1500 solves truncated, and the
    #: same 20/20 under noise and 169.3 N push (results/qp_tick_one_core.json,
    #: results/g1_balance_qp_budget.json). Stop 46: each replan starts from the last
    #: plan's feedback law rolled out from the measured state (``warm_start_feedback``)
    #: instead of its controls open loop, and the balance term of
    #: :class:`~mpcbox.tasks.legged.balance.LeggedBalance` is zero at the equilibrium. Most
    #: replans then find no better step than that law (a stall, not a fallback), so a
    #: replan tries three step sizes and no retry (``step_sizes=(1.0, 0.5, 0.25)``,
    #: ``mpc_max_retries=0``): the Go2's median replan 10 ms instead of 29-37 ms with the
    #: six sizes and a retry, at the same pushes within 3 % on six of seven quadrupeds
    #: (the ANYmal C 9 % less, 1.05x LQR's still; results/ilqr_feedback_warm_start.json).
    controller_configs: ClassVar[dict[str, Any]] = {
        **LeggedBalance.controller_configs,
        "qp": dataclasses.replace(LeggedBalance.controller_configs["qp"], time_limit=0.015),
        "ilqr": ILQRConfig(
            horizon=50,
            replan_period=0.02,
            mpc_iterations=1,
            first_iterations=5,
            regularization=1e-3,
            terminal_value="lqr",
            linearization="reference",
            cost_hessian="reference",
            mpc_max_retries=0,
            step_sizes=(1.0, 0.5, 0.25),
            warm_start_feedback=True,
        ),
    }
    posture: StancePosture | None = None

    def __init__(
        self,
        model: ModelSource = "menagerie:unitree_g1",
        *,
        stance: str = "two",
        feet: Sequence[str] | None = None,
        lift: float = 0.1,
        **kwargs: Any,
    ) -> None:
        self.stance = one_of("stance", stance, STANCES)
        self.lift = positive("lift", lift)
        if feet is None:
            feet = menagerie_biped_feet(model)
        super().__init__(model, feet=feet, **kwargs)
        ilqr = MENAGERIE_BIPED_ILQR.get(menagerie_robot(model) or "")
        if ilqr and self.stance == "two":  # measured options (the class's stay shared)
            configs = dict(type(self).controller_configs)
            configs["ilqr"] = dataclasses.replace(configs["ilqr"], **ilqr)
            self.controller_configs = MappingProxyType(configs)

    def standing_feet(
        self, model: mujoco.MjModel, qpos: np.ndarray, feet: Sequence[str] | str | None
    ) -> Sequence[str]:
        """Both feet, as given or found (:func:`ground_feet`), kept in :attr:`both_feet`;
        returns those the stance stands on."""
        if feet is None:
            feet = ground_feet(model, qpos, 2, root=self.root_id)
        if isinstance(feet, str) or len(feet) != 2:
            raise InvalidArgumentError(f"feet must name the (left, right) feet, got {feet!r}")
        self.both_feet = tuple(feet)
        if self.stance == "two":
            return self.both_feet
        return (feet[0],) if self.stance == "left" else (feet[1],)

    def prepare(self, model: mujoco.MjModel) -> None:
        """On one foot, the inverse-kinematics stance (the swing foot's body is lifted);
        then the equilibrium through the actuator model."""
        if self.stance != "two":
            swing = self.both_feet[1] if self.stance == "left" else self.both_feet[0]
            (foot,) = find_feet(model, (swing,), self.qpos_ref)
            self.posture = stance_posture(
                model,
                self.qpos_ref,
                stance=self.foot_frames[0],
                swing=mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, foot.body),
                lift=self.lift,
                com_body=self.root,
                upright_body=self.root,
                on_collision="raise",
            )
            self.qpos_ref = self.posture.qpos
        super().prepare(model)
