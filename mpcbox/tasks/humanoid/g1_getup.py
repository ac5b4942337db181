"""Get-up of Unitree's G1 from MuJoCo Menagerie: the humanoid get-up by name, with sampling
configs in the units of its position servos."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any, ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.sampling.config import CEMConfig, MPPIConfig, PredictiveSamplingConfig
from mpcbox.core.model import ModelSource, load_spec
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.humanoid.getup import HumanoidGetup
from mpcbox.tasks.legged.biped import BipedStand
from mpcbox.validation import one_of, positive

#: Sampling options of the G1 get-up besides the noise. The planning model steps 0.02 s with
#: implicitfast on fitted capsules (``planning_geoms="capsules"``), each servo-driven joint
#: given the armature ``0.5 kp dt^2`` (``servo_armature=0.5``; 0.1 kg m^2 at kp 500): with
#: its stiff position servos (kp 500, unlimited force) and no added armature the G1 lying on
#: the floor diverges at 0.02 s (every one of 128 rollouts of random set-points), and the
#: planner needed 0.01 s steps, 60 per 0.6 s rollout. With the armature the 30-step rollouts
#: rank candidates as the world (meshes, 0.002 s) does as well as the 0.01 s plan did (rank
#: correlation 0.747 against 0.745; ``benchmarks/planning_fidelity.py --tasks g1_getup``,
#: ``benchmarks/results/planning_fidelity_g1_getup.json``). With the task's noise of 0.05
#: of each control range and height weight of 1000, MPPI gets up within 5 s in the real-time
#: loop on an H200 in 121 of 140 held-out runs (8, 8, 9, 10, 9, 7, 10, 9, 8, 8, 9, 8, 10
#: and 8 of the sets of ten from seed 100 to 199 and 230 to 269; 1.6-2.1 s on average),
#: ticks p50 24-38 ms and p99 27-41 ms against the 20 ms period
#: (``g1_getup_height1000*_h200.json``, ``g1_getup_defaults_150_h200.json``,
#: ``g1_getup_rt_heldout160_h200.json``,
#: ``g1_getup_lookahead_none_{180,190,230,250}_h200.json``). In lock-step
#: (the world waiting for the planner) it got up on all 15 dev seeds 210-224, so the
#: misses in real time come from the planner's latency more than from its cost; a 0.4 s
#: horizon keeps p50 at 17-21 ms but got up in 16 of those 20 held-out runs where these
#: defaults got up in 19 (``g1_getup_rt_dev210_h200.json``). With the classic humanoid's height
#: weight of 100 it got up in 11 of 30 (4, 6 and 1; lock-step 6 of 10 on 110-119, as in
#: real time, so the planner, not its latency, failed), with 300 in 18 of 30
#: (``g1_getup_n05*_h200.json``, ``g1_getup_height300_h200.json``); with noise 0.1 and
#: weight 100 (the defaults of stop 43) 4 of 30 (``g1_getup_defaults*_h200.json``).
G1_SAMPLING: dict[str, Any] = dict(
    num_samples=512,
    horizon=0.6,
    num_knots=6,
    planning_timestep=0.02,
    planning_integrator="implicitfast",
    servo_armature=0.5,
    solver_iterations=2,
    period=0.02,
    headroom=8.0,
)


#: What the G1 get-up's planning model collides with (``planning_geoms``).
PLANNING_GEOMS = ("meshes", "capsules", "all")


def floor_only_meshes(source: ModelSource, *, capsules: bool = False) -> mujoco.MjSpec:
    """A spec of ``source`` whose colliding mesh geoms touch only the others (the floor, the
    feet's spheres) and not each other.

    Each colliding mesh geom gets ``contype=0, conaffinity=1``: MuJoCo's rule
    (``contype_a & conaffinity_b`` or ``contype_b & conaffinity_a``) then keeps a mesh's
    contacts with any geom of ``contype`` 1 and drops mesh-mesh pairs, whose convex
    collision (GJK/EPA) dominates an MJWarp step of the G1.

    Args:
        source: The robot (a ``ModelSource`` that is not a compiled model).
        capsules: Also replace each of those meshes by the capsule MuJoCo's compiler fits to
            it (a primitive geom that names a mesh is sized to it), so that even the
            contacts with the floor need no convex collision.
    """
    spec = load_spec(source)
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH and (geom.contype or geom.conaffinity):
            geom.contype, geom.conaffinity = 0, 1
            if capsules:
                geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
    return spec


def range_noise(ctrlrange: np.ndarray, fraction: float) -> np.ndarray:
    r"""Per-actuator noise standard deviation ``(nu,)``: ``fraction`` of each control range.

    Sampling controllers take ``noise_scale`` in control units (for position servos:
    radians of joint target), so :math:`\sigma_j = f\,(u_{j,max} - u_{j,min})`.

    Args:
        ctrlrange: Control ranges ``(nu, 2)``.
        fraction: :math:`f > 0`.
    """
    return positive("noise_fraction", fraction) * np.diff(np.asarray(ctrlrange), axis=1)[:, 0]


class G1Getup(HumanoidGetup):
    """:class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup` on Unitree's G1 (Menagerie).

    The G1's names: torso ``torso_link`` (its frame sits at the waist joint, 0.83 m high in
    the ``stand`` keyframe), root ``pelvis``, feet the ankle sites ``left_foot`` and
    ``right_foot``; standing counts from ``stand_fraction`` (0.8) of the keyframe's torso
    height (0.67 m) and the hand-over releases below ``release_fraction`` of that. Its 29
    actuators are position servos, so the reference control is the keyframe's joint
    targets and the sampling noise is ``noise_fraction`` of each actuator's range (in
    radians, :func:`range_noise`), not the classic humanoid's 0.4 of a unit torque range.
    It plans on fitted capsules at 0.02 s with added servo armature (:data:`G1_SAMPLING`)
    and, with the torso's height weighted 1000 (``height_cost``), gets up within 5 s in
    the real-time loop in 121 of 140 held-out runs on an H200 (7 to 10 of each 10; of the
    first six misses three ended bent just under the standing mark, one was still rising
    when the 5 s ran out, two lay on the floor); planning from the state predicted one
    median tick ahead (:attr:`realtime_lookahead`) 132 of 140 where the plain loop got 119
    on the same seeds. Planned
    on its meshes at 0.01 s it got up in none (ticks 145-196 ms on an H100); on capsules at
    0.01 s in none either (ticks p50 48-64 ms). :meth:`stand_problem` gives a standing
    stage (:class:`~mpcbox.tasks.legged.biped.BipedStand`) for :meth:`handover_controller`;
    its LQR holds the G1 from a standing state anywhere on the floor, but handed over at
    the task's ``is_up`` (torso tilted up to 0.5 rad) it let the body fall (0 of 3 seeds),
    and with ``handover_tilt=0.2, handover_speed=0.3`` it never took over
    (``benchmarks/results/g1_getup_handover_h200.json``).
    The same task is ``HumanoidGetup(model="menagerie:unitree_g1", torso="torso_link",
    root="pelvis", feet=("left_foot", "right_foot"), stand_height=None,
    release_height=None)`` with the classic humanoid's controller configs.

    Args:
        model: The robot (default ``"menagerie:unitree_g1"``; needs ``MENAGERIE_ROOT`` or
            the ``robot_descriptions`` package).
        torso: See :class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup`.
        root: Ditto.
        feet: Ditto.
        keyframe: The standing keyframe: its posture and control are the references, and
            its torso height sets what counts as up.
        stand_height: Ditto (default: derived from the keyframe).
        release_height: Ditto (default: derived).
        noise_fraction: Sampling noise as a fraction of each control range. 0.05 got up in
            4 of 5 screen seeds (200-204) where 0.03, 0.07 and 0.1 got up in 1, 1 and 0
            (``benchmarks/results/g1_getup_noise_screen_h200.json``,
            ``g1_getup_n05_screen*_h200.json``, ``g1_getup_stage_screen*_h200.json``).
        height_cost: Weight of the torso's height above each foot (the classic humanoid's
            100 by default). 1000 got the G1 up in 10 of 10 dev seeds (200-209, lock-step)
            where 100, 300 and 300 with ``com_velocity_cost=0`` got it up in 3, 8 and 7:
            with 100 the torso rose to a crouch (0.45-0.5 m) within 0.6 s and stayed
            there or sat back down, the posture, balance and center-of-mass velocity terms
            outweighing the rise (``benchmarks/results/g1_getup_screen_*_h200.json``).
        planning_geoms: What the planning model's collision meshes touch (the simulated
            world keeps every contact): ``"meshes"`` the floor and the feet's spheres, not
            each other (:func:`floor_only_meshes`); ``"capsules"`` (the default) the same,
            each mesh replaced by the capsule fitted to it; ``"all"`` everything, as in the
            world.
        **kwargs: Passed to :class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup`.
    """

    name = "g1_getup"
    #: ``--lookahead`` of ``mpcbox compare g1_getup --realtime`` (and of
    #: ``problems/g1_getup.py --realtime``) when none is given: plan from the state predicted
    #: one median tick ahead (:mod:`mpcbox.sim.lookahead`). On an H200, MPPI, task defaults,
    #: 140 paired runs of 5 s in the real-time loop: up in 132 with it against 119 without,
    #: 21 seeds only with it and 8 only without (sign test p = 0.024; the last 60 runs alone,
    #: seeds 280-339: 58 against 50, 10 and 2, p = 0.039), median time up 1.35 s against
    #: 1.57 s (``benchmarks/results/g1_getup_lookahead_{auto,none}_*_h200.json``).
    #: ``--lookahead none`` turns it off. :func:`~mpcbox.sim.realtime.simulate_realtime`
    #: itself plans from the observed state unless told otherwise.
    realtime_lookahead: ClassVar[str | None] = "auto"
    #: The configs' shape; each instance replaces the scalar noise (0.3 rad) by
    #: ``noise_fraction`` of each actuator's range (:func:`range_noise`).
    controller_configs: ClassVar[dict[str, Any]] = {
        "ps": PredictiveSamplingConfig(noise_scale=0.3, **G1_SAMPLING),
        "mppi": MPPIConfig(temperature=0.1, noise_scale=0.3, **G1_SAMPLING),
        "cem": CEMConfig(num_elites=32, std_min=0.02, noise_scale=0.3, **G1_SAMPLING),
    }

    def __init__(
        self,
        model: ModelSource = "menagerie:unitree_g1",
        *,
        torso: str = "torso_link",
        root: str | None = "pelvis",
        feet: Sequence[str] = ("left_foot", "right_foot"),
        keyframe: str = "stand",
        stand_height: float | None = None,
        release_height: float | None = None,
        noise_fraction: float = 0.05,
        height_cost: float = 1000.0,
        planning_geoms: str = "capsules",
        **kwargs: Any,
    ) -> None:
        planning_geoms = one_of("planning_geoms", planning_geoms, PLANNING_GEOMS)
        if planning_geoms != "all" and not isinstance(model, mujoco.MjModel):
            spec = floor_only_meshes(model, capsules=planning_geoms == "capsules")
            kwargs.setdefault("planning_model", spec)
        super().__init__(
            model=model,
            torso=torso,
            root=root,
            feet=feet,
            keyframe=keyframe,
            stand_height=stand_height,
            release_height=release_height,
            height_cost=height_cost,
            **kwargs,
        )
        noise = range_noise(self.model.actuator_ctrlrange, noise_fraction)
        self.noise_fraction = noise_fraction
        self.controller_configs = {
            name: replace(config, noise_scale=noise)
            for name, config in type(self).controller_configs.items()
        }

    def stand_problem(self, **kwargs: Any) -> BipedStand:
        """The standing stage: :class:`~mpcbox.tasks.legged.biped.BipedStand` on both feet
        of this task's model (its equilibrium through the servos, its LQR, QP-MPC and
        iLQR-MPC configs), for :meth:`handover_controller`.

        Args:
            **kwargs: Passed to :class:`~mpcbox.tasks.legged.biped.BipedStand`.

        Raises:
            InvalidArgumentError: If this task was built on a compiled ``MjModel`` (the
                standing task adds sites to the model's spec).
        """
        if isinstance(self._model_source, mujoco.MjModel):
            raise InvalidArgumentError(
                "G1Getup.stand_problem needs the model as a path, XML, spec or Menagerie "
                "name, not a compiled MjModel (BipedStand adds sites to its spec)"
            )
        kwargs.setdefault("stance", "two")
        return BipedStand(self._model_source, **kwargs)
