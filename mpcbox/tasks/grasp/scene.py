r"""A parallel-jaw gripper over a table with one object, built with :class:`mujoco.MjSpec`.

The gripper hangs above the object: a palm on a vertical slide joint ``lift`` (a position
servo, the wrist), and two fingers on horizontal slide joints ``left`` and ``right`` that
close towards each other along ``x`` (each a position servo with gain ``finger_kp``, damping
``finger_kv`` and force range ``finger_force_max``; joint value 0 is open, positive closes).
Each finger ends in a box pad ``left_pad`` / ``right_pad`` at the height of the object's
centre. The gripper is gravity-compensated and collides only with the object, through
explicit contact pairs (pad, object geom) that carry the object's friction (condim 6) and
contact stiffness. The object (body ``object``, free joint) rests on the table between the
open fingers.

Contact stiffness :math:`K` (N/m) becomes MuJoCo's direct ``solref = (-k, -b)`` with a
constant impedance :math:`d` (``solimp = (d, d, ...)``). A body resting on such a contact
under a load :math:`m a_0` settles at the penetration :math:`r = (1 - d)\, a_0 / k`
(MuJoCo's soft-constraint law; ``tests/test_grasp.py`` measures it), so

.. math:: k = K (1 - d) / m, \qquad b = 2 \zeta \sqrt{k / d}

makes that penetration :math:`m a_0 / K` (:func:`contact_solref`); for the pad contacts
:math:`m` is the reduced mass of the object and one finger, so :math:`K` is the spring
between them. The scene uses elliptic friction cones, whose friction rows have their own
reference (``solreffriction``). A soft friction constraint creeps at a speed near
:math:`(1 - d)\, a_0 / b` under a steady load; with the contact's own damping that is
2-3 mm/s for a 1e5 N/m contact and 2 cm/s at 1e3 N/m (with pyramidal cones, which have no
separate friction reference, it made every grasp of a soft object slide out). The pads'
friction therefore gets the largest damping rate that stays stable, :math:`b = 0.8 / h` for
the step :math:`h` (a creep under 1 mm/s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.tasks.grasp.objects import GraspObject
from mpcbox.validation import checked_options, in_range, positive

#: Names of the finger actuators (and joints), the pads, and the object's body.
FINGERS: tuple[str, str] = ("left", "right")
PADS: tuple[str, str] = ("left_pad", "right_pad")
OBJECT = "object"
LIFT = "lift"
#: Height of the palm above the pads (m).
_PALM_ABOVE_PADS = 0.08


@checked_options
@dataclass(frozen=True, kw_only=True)
class GripperConfig:
    """The gripper's build.

    Attributes:
        opening: Half the gap between the open pads (m); the fingers close by up to this.
        finger_kp: Gain of the finger servos (N/m).
        finger_kv: Damping of the finger servos (N s/m).
        finger_force_max: Force range of each finger servo (N).
        finger_mass: Mass of each finger (kg).
        lift_kp: Gain of the wrist servo (N/m); its damping is critical for the gripper
            plus 1 kg.
        timestep: Simulation step (s).
        impedance: MuJoCo's constant contact impedance :math:`d` of the pad contacts.
    """

    opening: float = 0.045
    finger_kp: float = 500.0
    finger_kv: float = 20.0
    finger_force_max: float = 60.0
    finger_mass: float = 0.05
    lift_kp: float = 4000.0
    timestep: float = 0.0005
    impedance: float = 0.9

    def __post_init__(self) -> None:
        for name in (
            "opening",
            "finger_kp",
            "finger_kv",
            "finger_force_max",
            "finger_mass",
            "lift_kp",
            "timestep",
        ):
            positive(name, getattr(self, name))
        in_range("impedance", self.impedance, 0.0, 1.0, low_open=True, high_open=True)


class GraspScene(NamedTuple):
    """A compiled gripper scene.

    Attributes:
        model: The model.
        object: The object it holds.
        config: The gripper's build.
        center_height: Height of the object's geometric centre, and of the pads (m).
    """

    model: mujoco.MjModel
    object: GraspObject
    config: GripperConfig
    center_height: float


def contact_solref(
    stiffness: float,
    mass: float,
    damping_ratio: float,
    impedance: float,
    timestep: float | None = None,
) -> np.ndarray:
    r"""MuJoCo's direct ``solref = (-k, -b)`` for a contact stiffness (see the module docstring).

    Args:
        stiffness: :math:`K` (N/m).
        mass: The object's mass :math:`m` (kg).
        damping_ratio: :math:`\zeta`.
        impedance: The constant impedance :math:`d` of ``solimp``.
        timestep: The simulation step :math:`h`, or ``None``; when given, :math:`b` is capped
            at :math:`1/h` (a larger damping rate makes MuJoCo's step unstable: a 0.1 kg
            sphere at 1e6 N/m and critical damping flies off at :math:`h` = 1 ms).

    Returns:
        ``(2,)`` array ``(-k, -b)``.
    """
    stiffness = positive("stiffness", stiffness)
    mass = positive("mass", mass)
    d = in_range("impedance", impedance, 0.0, 1.0, low_open=True, high_open=True)
    k = stiffness * (1.0 - d) / mass
    b = 2.0 * positive("damping_ratio", damping_ratio) * np.sqrt(k / d)
    if timestep is not None:
        b = min(b, 1.0 / positive("timestep", timestep))
    return np.array([-k, -b])


def _object_geoms(body: mujoco.MjsBody, obj: GraspObject) -> None:
    """Add the object's geoms (total mass ``obj.mass``) to ``body``, centred at its origin."""
    g = mujoco.mjtGeom
    hx, hy, hz = (float(v) for v in obj.size)
    if obj.shape == "box":
        body.add_geom(type=g.mjGEOM_BOX, size=[hx, hy, hz], mass=obj.mass)
    elif obj.shape == "cylinder":
        body.add_geom(type=g.mjGEOM_CYLINDER, size=[hx, hz, 0], mass=obj.mass)
    elif obj.shape == "sphere":
        body.add_geom(type=g.mjGEOM_SPHERE, size=[hx, 0, 0], mass=obj.mass)
    elif obj.shape == "ellipsoid":
        body.add_geom(type=g.mjGEOM_ELLIPSOID, size=[hx, hy, hz], mass=obj.mass)
    else:  # three capsules: across the fingers, an upright post off to one side, a foot
        r = 0.012
        share = obj.mass / 3.0
        body.add_geom(
            type=g.mjGEOM_CAPSULE, fromto=[-hx + r, 0, 0, hx - r, 0, 0], size=[r, 0, 0], mass=share
        )
        body.add_geom(
            type=g.mjGEOM_CAPSULE,
            fromto=[0, hy - r, -hz + r, 0, hy - r, hz - r],
            size=[r, 0, 0],
            mass=share,
        )
        body.add_geom(
            type=g.mjGEOM_CAPSULE,
            fromto=[0, -hy + r, -hz + r, 0, hy - r, -hz + r],
            size=[r, 0, 0],
            mass=share,
        )


def build_scene(obj: GraspObject, config: GripperConfig | None = None) -> GraspScene:
    """Build and compile the gripper scene holding ``obj`` (see the module docstring).

    Args:
        obj: The object.
        config: The gripper's build (default :class:`GripperConfig`).

    Returns:
        The :class:`GraspScene`.
    """
    config = config or GripperConfig()
    spec = mujoco.MjSpec()
    spec.option.timestep = config.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    g = mujoco.mjtGeom
    spec.worldbody.add_geom(name="table", type=g.mjGEOM_PLANE, size=[0.5, 0.5, 0.01])
    center = float(obj.size[2])
    body = spec.worldbody.add_body(name=OBJECT, pos=[0, 0, center])
    body.add_freejoint(name=OBJECT)
    _object_geoms(body, obj)

    palm = spec.worldbody.add_body(name="palm", pos=[0, 0, center + _PALM_ABOVE_PADS])
    palm.gravcomp = 1.0
    palm.add_joint(name=LIFT, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], range=[0, 0.3])
    palm.add_geom(type=g.mjGEOM_BOX, size=[0.06, 0.02, 0.01], mass=0.3, contype=0, conaffinity=0)
    for name, pad, side in zip(FINGERS, PADS, (-1.0, 1.0)):
        finger = palm.add_body(name=name, pos=[side * (config.opening + 0.004), 0, 0])
        finger.gravcomp = 1.0
        finger.add_joint(
            name=name,
            type=mujoco.mjtJoint.mjJNT_SLIDE,
            axis=[-side, 0, 0],
            range=[0, config.opening],
            armature=0.001,
        )
        finger.add_geom(
            type=g.mjGEOM_BOX,
            size=[0.004, 0.01, 0.5 * _PALM_ABOVE_PADS],
            pos=[0, 0, -0.5 * _PALM_ABOVE_PADS],
            mass=0.2 * config.finger_mass,
            contype=0,
            conaffinity=0,
        )
        finger.add_geom(
            name=pad,
            type=g.mjGEOM_BOX,
            size=[0.004, 0.015, 0.015],
            pos=[0, 0, -_PALM_ABOVE_PADS],
            mass=0.8 * config.finger_mass,
            contype=0,
            conaffinity=0,
            rgba=[0.8, 0.3, 0.2, 1],
        )
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=config.finger_kp, kv=config.finger_kv)
        act.ctrlrange = [-0.1, 0.3]
        act.forcerange = [-config.finger_force_max, config.finger_force_max]
    lift = spec.add_actuator(name=LIFT, target=LIFT, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    lift_mass = 0.3 + 2 * config.finger_mass + 1.0
    lift.set_to_position(kp=config.lift_kp, kv=2.0 * np.sqrt(config.lift_kp * lift_mass))
    lift.ctrlrange = [0, 0.3]

    reduced = 1.0 / (1.0 / obj.mass + 1.0 / config.finger_mass)
    solref = contact_solref(
        obj.stiffness, reduced, obj.damping_ratio, config.impedance, config.timestep
    )
    solimp = [config.impedance, config.impedance, 0.001, 0.5, 2.0]
    mu, torsion, rolling = (float(v) for v in obj.friction)
    for geom in body.geoms:
        for pad in PADS:
            spec.add_pair(
                geomname1=pad,
                geomname2=geom.name or _name_geom(geom, body),
                condim=6,
                friction=[mu, mu, torsion, rolling, rolling],
                solref=list(solref),
                solreffriction=[solref[0], -0.8 / config.timestep],
                solimp=solimp,
            )
    model = spec.compile()
    return GraspScene(model, obj, config, center)


def _name_geom(geom: mujoco.MjsGeom, body: mujoco.MjsBody) -> str:
    """Give an unnamed object geom a name (pairs refer to geoms by name)."""
    geom.name = f"{body.name}_{list(body.geoms).index(geom)}"
    return geom.name
