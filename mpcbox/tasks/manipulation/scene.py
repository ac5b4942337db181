"""The cube-stacking scene, written with :class:`mujoco.MjSpec`: a table, a red and a blue
cube, and an arm attached to the table through a frame (:meth:`mujoco.MjsFrame.attach_body`).

The table top is the plane :math:`z = 0`; each cube is a free body whose frame is its
centre, so its position is the first three entries of its free joint's ``qpos``.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.tasks.manipulation.arms import ArmSpec, arm_spec
from mpcbox.validation import positive

#: Edge of the cubes of the issue (m).
CUBE_SIZE = 0.044
#: Names of the cube bodies (and of their free joints, with ``"_joint"``).
CUBES: tuple[str, ...] = ("red_cube", "blue_cube")
#: Prefix of the arm's names in the scene.
ARM_PREFIX = "arm/"
#: Name of the tool-centre-point site every arm gets (see :mod:`.arms`).
TCP_SITE = "tcp"


class CubeLayout(NamedTuple):
    """Start poses of the cubes on the table.

    Attributes:
        red: Red cube centre ``(x, y)`` (m).
        blue: Blue cube centre ``(x, y)`` (m).
        red_yaw: Red cube yaw (rad).
        blue_yaw: Blue cube yaw (rad).
    """

    red: tuple[float, float]
    blue: tuple[float, float]
    red_yaw: float = 0.0
    blue_yaw: float = 0.0


def _yaw_quat(yaw: float) -> list[float]:
    return [float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2))]


def stacking_scene(
    arm: str | ArmSpec = "aloha",
    *,
    cube_size: float = CUBE_SIZE,
    cube_mass: float = 0.05,
    friction: float = 1.0,
    timestep: float = 0.002,
) -> mujoco.MjSpec:
    """The stacking scene as a spec, with a ``"home"`` keyframe (arm at home, gripper open,
    cubes at the default :class:`CubeLayout` of :func:`default_layout`).

    Both cubes have edge ``cube_size`` and mass ``cube_mass``. The physics options follow
    the ALOHA model (elliptic friction cones, ``impratio = 10``, ``implicitfast``), which
    makes grasps hold without slip.

    Args:
        arm: An arm name of :data:`~mpcbox.tasks.manipulation.arms.ARMS` or an
            :class:`~mpcbox.tasks.manipulation.arms.ArmSpec`.
        cube_size: Cube edge (m).
        cube_mass: Mass of each cube (kg).
        friction: Sliding friction of the cubes and the table.
        timestep: Simulation timestep (s).

    Returns:
        The spec (compile it with ``spec.compile()``).
    """
    arm = arm_spec(arm) if isinstance(arm, str) else arm
    half = positive("cube_size", cube_size) / 2
    positive("cube_mass", cube_mass)
    positive("friction", friction)
    spec = mujoco.MjSpec()
    spec.modelname = f"stacking_{arm.name}"
    spec.option.timestep = positive("timestep", timestep)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    spec.compiler.autolimits = True
    _copy_compiler(spec, arm.spec)
    world = spec.worldbody
    world.add_light(name="top", pos=[0.0, 0.0, 2.0], dir=[0.0, 0.0, -1.0])
    world.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.05], pos=[0, 0, -0.75]
    )
    table = world.add_body(name="table")
    table.add_geom(
        name="table_top",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.6, 0.45, 0.02],
        pos=[0.0, 0.0, -0.02],
        rgba=[0.55, 0.45, 0.35, 1.0],
        friction=[friction, 0.005, 0.0001],
    )
    layout = default_layout(arm)
    for name, xy, rgba in (
        ("red_cube", layout.red, [0.85, 0.1, 0.1, 1.0]),
        ("blue_cube", layout.blue, [0.1, 0.2, 0.85, 1.0]),
    ):
        body = world.add_body(name=name, pos=[xy[0], xy[1], half])
        body.add_freejoint(name=name + "_joint")
        body.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[half, half, half],
            mass=cube_mass,
            rgba=rgba,
            condim=4,
            friction=[friction, 0.01, 0.0001],
        )
    frame = world.add_frame(pos=list(arm.mount), quat=_yaw_quat(arm.mount_yaw))
    frame.attach_body(arm.spec.body(arm.base), ARM_PREFIX, "")
    arm = arm.prefixed(ARM_PREFIX)
    base = spec.body(arm.base)
    base.pos, base.quat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]  # placed by the frame
    for key in list(spec.keys):  # the arm file's keyframes do not fit this scene
        spec.delete(key)
    spec.body(arm.tcp_body).add_site(
        name=ARM_PREFIX + TCP_SITE,
        pos=list(arm.tcp_pos),
        quat=list(arm.tcp_quat),
        size=[0.005, 0, 0],
    )
    spec.add_exclude(bodyname1="table", bodyname2=arm.base)
    model = spec.compile()
    spec.add_key(name="home", qpos=home_qpos(model, arm, layout), ctrl=home_ctrl(model, arm))
    return spec


def _copy_compiler(spec: mujoco.MjSpec, source: mujoco.MjSpec) -> None:
    """Take over the arm file's mesh folder and angle unit, so its meshes load."""
    spec.meshdir = source.meshdir
    spec.compiler.degree = source.compiler.degree


def default_layout(arm: ArmSpec) -> CubeLayout:
    """The cubes' default start: red 35 cm in front of the base and 8 cm to its left, blue
    35 cm in front and 8 cm to its right."""
    x = arm.mount[0] + 0.35
    return CubeLayout(red=(x, arm.mount[1] + 0.08), blue=(x, arm.mount[1] - 0.08))


def home_qpos(
    model: mujoco.MjModel, arm: ArmSpec, layout: CubeLayout, cube_size: float | None = None
) -> np.ndarray:
    """Positions ``(nq,)``: the arm at home with open fingers, the cubes resting at
    ``layout`` (their size read from the model when ``cube_size`` is not given)."""
    qpos = model.qpos0.copy()
    for name, angle in zip(arm.joints, arm.home, strict=True):
        qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    for name in arm.finger_joints:
        qpos[model.jnt_qposadr[model.joint(name).id]] = arm.finger_open
    half = model.geom("red_cube").size[0] if cube_size is None else cube_size / 2
    for name, xy, yaw in (
        ("red_cube", layout.red, layout.red_yaw),
        ("blue_cube", layout.blue, layout.blue_yaw),
    ):
        adr = model.jnt_qposadr[model.joint(name + "_joint").id]
        qpos[adr : adr + 7] = [xy[0], xy[1], half, *_yaw_quat(yaw)]
    return qpos


def home_ctrl(model: mujoco.MjModel, arm: ArmSpec) -> np.ndarray:
    """Controls ``(nu,)`` that hold the arm at home with the gripper open."""
    ctrl = np.zeros(model.nu)
    for name, angle in zip(arm.actuators, arm.home, strict=True):
        ctrl[model.actuator(name).id] = angle
    ctrl[model.actuator(arm.gripper).id] = arm.gripper_open
    return ctrl


def stacking_model(arm: str | ArmSpec = "aloha", **kwargs: float) -> mujoco.MjModel:
    """:func:`stacking_scene` compiled (keyword arguments passed on)."""
    return stacking_scene(arm, **kwargs).compile()
