"""Arms for the manipulation scenes: where their MJCF comes from and how to drive them.

Two arms are known, both driven by position servos (the control of an arm joint is its
target angle):

* ``"aloha"``: one 6-DoF ViperX 300s arm of the ALOHA rig in mujoco-warp's test data
  (``test_data/aloha_pot/scene.xml``, installed with ``mujoco-warp``; works offline). Its
  parallel gripper is a position servo on the finger slide, ``0.002`` (closed) to ``0.037``
  m (open: 58 mm between the finger pads).
* ``"panda"``: the Franka Emika Panda with its hand from MuJoCo Menagerie
  (``menagerie:franka_emika_panda``); the gripper actuator takes ``0`` (closed) to ``255``
  (open: 80 mm).

Every arm gets a tool-centre-point site ``tcp`` between the finger pads whose frame has its
``z`` axis along the approach direction (wrist to fingertips) and its ``x`` axis along the
closing direction of the fingers, so a top-down grasp at yaw :math:`\\psi` is the rotation
:math:`R_z(\\psi) R_x(\\pi)` for every arm.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.errors import BackendUnavailableError, ModelNotFoundError, UnknownNameError

#: Arms that :func:`arm_spec` knows.
ARMS: tuple[str, ...] = ("aloha", "panda")


class ArmSpec(NamedTuple):
    """How to build and drive one arm.

    Attributes:
        name: Arm name (one of :data:`ARMS`).
        spec: The arm's MJCF as a spec (the whole file it comes from).
        base: Name of the arm's root body in ``spec`` (attached to the scene).
        joints: The arm's joint names in ``spec`` (driven by the IK), base to wrist.
        actuators: Position-servo actuator of each joint, same order.
        gripper: The gripper's actuator.
        gripper_open: Gripper control that opens the fingers fully.
        gripper_closed: Gripper control that closes them (squeezing an object).
        home: Start angles of ``joints`` (rad).
        finger_joints: Slide joints of the fingers (start at the open width).
        finger_open: Position of the finger joints when fully open (m).
        tcp_body: Body that carries the tool centre point.
        tcp_pos: Tool centre point in ``tcp_body`` (m).
        tcp_quat: Orientation of the ``tcp`` site in ``tcp_body`` ``[w, x, y, z]``.
        mount: Position of the arm's base in the scene (m), relative to the table centre.
        mount_yaw: Yaw of the base (rad).
        reach: Range ``(near, far)`` of horizontal distances from the base at which the
            arm grasps top-down comfortably (m); random cube layouts are drawn in it.
        ik_ranges: Joint ranges for the IK (one ``(low, high)`` or ``None`` per joint) that
            keep it on the branch of top-down grasps.
    """

    name: str
    spec: mujoco.MjSpec
    base: str
    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    gripper: str
    gripper_open: float
    gripper_closed: float
    home: tuple[float, ...]
    finger_joints: tuple[str, ...]
    finger_open: float
    tcp_body: str
    tcp_pos: tuple[float, float, float]
    tcp_quat: tuple[float, float, float, float]
    mount: tuple[float, float, float]
    mount_yaw: float
    reach: tuple[float, float]
    ik_ranges: tuple[tuple[float, float] | None, ...] | None = None

    def prefixed(self, prefix: str) -> ArmSpec:
        """The same arm with ``prefix`` in front of every name (as after attaching it)."""
        names = ("base", "gripper", "tcp_body")
        tuples = ("joints", "actuators", "finger_joints")
        return self._replace(
            **{n: prefix + getattr(self, n) for n in names},
            **{n: tuple(prefix + v for v in getattr(self, n)) for n in tuples},
        )


def aloha_scene_path() -> Path:
    """Path of mujoco-warp's ``test_data/aloha_pot/scene.xml`` (two ALOHA arms and a pot).

    Raises:
        BackendUnavailableError: If ``mujoco-warp`` is not installed.
        ModelNotFoundError: If the installed mujoco-warp has no such file.
    """
    import importlib.util

    found = importlib.util.find_spec("mujoco_warp")
    if found is None or found.origin is None:
        raise BackendUnavailableError(
            "the ALOHA arm comes with mujoco-warp's test data: pip install mujoco-warp "
            "(or the mpcbox gpu extra)"
        )
    path = Path(os.path.dirname(found.origin)) / "test_data" / "aloha_pot" / "scene.xml"
    if not path.is_file():
        raise ModelNotFoundError(f"the installed mujoco-warp has no {path}")
    return path


def _rotation_quat(columns: np.ndarray) -> tuple[float, float, float, float]:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.asarray(columns, dtype=float).reshape(9))
    return tuple(float(v) for v in quat)  # type: ignore[return-value]


def _aloha(side: str = "left") -> ArmSpec:
    spec = mujoco.MjSpec.from_file(str(aloha_scene_path()))
    p = side + "\\"
    names = ("waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate")
    # gripper_link: x points from the wrist to the fingertips, y is the closing axis. The
    # finger pads span x in [0.047, 0.146] m; the TCP sits 18 mm short of the tips, so a
    # 44 mm cube grasped at its centre leaves the tips 4 mm above the table.
    # The site's axes as columns: x = link y, y = link z, z = link x.
    tcp_axes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return ArmSpec(
        name="aloha",
        spec=spec,
        base=p + "base_link",
        joints=tuple(p + n for n in names),
        actuators=tuple(p + n for n in names),
        gripper=p + "gripper",
        gripper_open=0.037,
        gripper_closed=0.002,
        home=(0.0, -0.96, 1.16, 0.0, -0.3, 0.0),
        finger_joints=(p + "left_finger", p + "right_finger"),
        finger_open=0.037,
        tcp_body=p + "gripper_link",
        tcp_pos=(0.128, 0.0, 0.0),
        tcp_quat=_rotation_quat(tcp_axes),
        mount=(-0.30, 0.0, 0.02),
        mount_yaw=0.0,
        reach=(0.26, 0.42),
        # The forearm can roll half a turn and reach the same pose with the wrist flipped;
        # that branch runs the wrist's rotation into its limit when the cube turns.
        ik_ranges=(None, None, None, (-1.2, 1.2), None, None),
    )


def _panda() -> ArmSpec:
    from mpcbox.core.menagerie import robot_xml

    spec = mujoco.MjSpec.from_file(str(robot_xml("franka_emika_panda", "panda")))
    # hand: z is the approach axis, the fingers slide along y; the pads' centre is 0.1034 m
    # down the hand. The site's axes as columns: x = hand y, y = -hand x, z = hand z.
    tcp_axes = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return ArmSpec(
        name="panda",
        spec=spec,
        base="link0",
        joints=tuple(f"joint{i}" for i in range(1, 8)),
        actuators=tuple(f"actuator{i}" for i in range(1, 8)),
        gripper="actuator8",
        gripper_open=255.0,
        gripper_closed=0.0,
        home=(0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853),
        finger_joints=("finger_joint1", "finger_joint2"),
        finger_open=0.04,
        tcp_body="hand",
        tcp_pos=(0.0, 0.0, 0.1034),
        tcp_quat=_rotation_quat(tcp_axes),
        mount=(-0.40, 0.0, 0.0),
        mount_yaw=0.0,
        reach=(0.40, 0.62),
    )


def arm_spec(name: str) -> ArmSpec:
    """The :class:`ArmSpec` of a known arm.

    Args:
        name: One of :data:`ARMS`.

    Raises:
        UnknownNameError: For another name (lists the known arms).
        BackendUnavailableError: If the arm's source (mujoco-warp, Menagerie) is missing.
    """
    if name == "aloha":
        return _aloha()
    if name == "panda":
        return _panda()
    raise UnknownNameError("arm", name, ARMS)
