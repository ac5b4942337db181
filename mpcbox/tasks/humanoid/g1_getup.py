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
from mpcbox.validation import one_of, positive

#: Sampling options of the G1 get-up besides the noise. The planning model steps 0.01 s
#: with implicitfast: with its stiff position servos (kp 500, unlimited force) the G1 lying
#: on the floor under knot noise of 10 % of each range diverges at 0.02 s (Euler and
#: implicitfast, 6 of 6 rollouts) and at 0.01 s with Euler (1 of 6), not at 0.01 s with
#: implicitfast (0 of 6); a 0.6 s horizon is 60 steps per rollout. A starting point, not a
#: tuned config: on an H100 in the real-time loop it got up in 0 of 10 seeds within 5 s
#: (torso at most 0.38-0.66 m of the 0.67 m needed), with ticks (p50) of 145-196 ms against the
#: 20 ms period (benchmarks/results/g1_getup_final_h100.json); 256 samples over 0.5 s
#: also 0/10 (g1_getup_fast_h100.json).
G1_SAMPLING: dict[str, Any] = dict(
    num_samples=512,
    horizon=0.6,
    num_knots=6,
    planning_timestep=0.01,
    planning_integrator="implicitfast",
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
    On an H100 no config tried gets it up within 5 s in the real-time loop (0/10, see
    :data:`G1_SAMPLING`): MJWarp's steps of the G1 (mesh collision geoms) make each tick
    100-200 ms. That was measured with the earlier cost (torso height above the floor, no
    velocity term of the centre of mass); with the two terms that got the classic humanoid
    up (now inherited) MPPI still gets up 0/5 in real time, 1/3 in lock-step. Planning on
    fitted capsules (``planning_geoms="capsules"``) makes a tick 3x shorter (p50 50-64 ms
    against 145-187 ms) and the torso rises higher (0.59-0.89 m against 0.27-0.49 m), still
    0/5 within 5 s (benchmarks/results/g1_getup_capsules_h100.json).
    The same task is ``HumanoidGetup(model="menagerie:unitree_g1", torso="torso_link",
    root="pelvis", feet=("left_foot", "right_foot"), stand_height=None,
    release_height=None)`` with the classic humanoid's controller configs.

    Args:
        model: The robot (default ``"menagerie:unitree_g1"``; needs ``MENAGERIE_ROOT`` or
            the ``robot_descriptions`` package).
        torso: See :class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup`.
        root: Ditto.
        feet: Ditto.
        stand_height: Ditto (default: derived from the keyframe).
        release_height: Ditto (default: derived).
        noise_fraction: Sampling noise as a fraction of each control range.
        planning_geoms: What the planning model's collision meshes touch (the simulated
            world keeps every contact): ``"meshes"`` (the default) the floor and the feet's
            spheres, not each other (:func:`floor_only_meshes`); ``"capsules"`` the same,
            each mesh replaced by the capsule fitted to it; ``"all"`` everything, as in the
            world.
        **kwargs: Passed to :class:`~mpcbox.tasks.humanoid.getup.HumanoidGetup`.
    """

    name = "g1_getup"
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
        stand_height: float | None = None,
        release_height: float | None = None,
        noise_fraction: float = 0.1,
        planning_geoms: str = "meshes",
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
            stand_height=stand_height,
            release_height=release_height,
            **kwargs,
        )
        noise = range_noise(self.model.actuator_ctrlrange, noise_fraction)
        self.noise_fraction = noise_fraction
        self.controller_configs = {
            name: replace(config, noise_scale=noise)
            for name, config in type(self).controller_configs.items()
        }

    def stand_problem(self, **kwargs: Any) -> HumanoidGetup:
        """Not available: the standing stage is tuned for the classic humanoid only.

        Raises:
            InvalidArgumentError: Always (use the get-up controller alone).
        """
        raise InvalidArgumentError(
            "G1Getup has no standing stage for handover_controller: HumanoidStand is tuned "
            "for the classic humanoid; use make_controller with the get-up controller alone"
        )
