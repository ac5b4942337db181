"""Reference postures from inverse kinematics with mink."""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import frame_object
from mpcbox.errors import SolverError
from mpcbox.validation import as_array, positive, positive_int


class StancePosture(NamedTuple):
    """Result of :func:`stance_posture`.

    Attributes:
        qpos: The posture ``(nq,)``.
        com_error: Horizontal distance of the COM from the stance point (m).
        swing_height: Height gained by the swing frame (m).
        iterations: IK iterations used.
    """

    qpos: np.ndarray
    com_error: float
    swing_height: float
    iterations: int


def _mink_frame(model: mujoco.MjModel, name: str) -> tuple[str, str]:
    kind, _ = frame_object(model, name)
    return name, kind


def stance_posture(
    model: mujoco.MjModel,
    qpos_init: np.ndarray,
    *,
    stance: str,
    swing: str,
    lift: float = 0.1,
    com_body: int = 1,
    upright_body: str | None = "torso",
    iterations: int = 300,
    tolerance: float = 1e-4,
    solver: str = "daqp",
) -> StancePosture:
    """A one-leg stance: the center of mass over ``stance``, ``swing`` lifted by ``lift``.

    Solves differential inverse kinematics with mink (frame tasks on both feet, a center-of-mass
    task on the horizontal plane, posture regularization, joint limits) from ``qpos_init``.

    Args:
        model: The model.
        qpos_init: Start posture ``(nq,)``, both feet on the floor.
        stance: Site or body name of the stance foot (kept where it is).
        swing: Site or body name of the swing foot (lifted).
        lift: Height to lift the swing foot (m).
        com_body: Body whose subtree COM is placed (default: the root body).
        upright_body: Body whose orientation is kept as in ``qpos_init`` (``None``: free).
        iterations: Maximum IK iterations.
        tolerance: Stop when the COM is this close to the stance point and the swing foot
            this close to its target (m).
        solver: A QP solver name that qpsolvers knows.

    Raises:
        SolverError: If the COM stays farther than 1 cm from the stance point.
    """
    import mink

    qpos_init = as_array("qpos_init", qpos_init, (model.nq,))
    positive("lift", lift)
    positive_int("iterations", iterations)
    config = mink.Configuration(model, q=qpos_init.copy())
    data = config.data
    stance_name, stance_kind = _mink_frame(model, stance)
    swing_name, swing_kind = _mink_frame(model, swing)
    stance_task = mink.FrameTask(
        stance_name, stance_kind, position_cost=100.0, orientation_cost=10.0
    )
    swing_task = mink.FrameTask(swing_name, swing_kind, position_cost=10.0, orientation_cost=1.0)
    com_task = mink.ComTask(cost=np.array([20.0, 20.0, 0.0]))
    posture_task = mink.PostureTask(model, cost=0.05)
    stance_pose = config.get_transform_frame_to_world(stance_name, stance_kind)
    swing_pose = config.get_transform_frame_to_world(swing_name, swing_kind)
    stance_task.set_target(stance_pose)
    swing_target = mink.SE3.from_rotation_and_translation(
        swing_pose.rotation(), swing_pose.translation() + np.array([0.0, 0.0, lift])
    )
    swing_task.set_target(swing_target)
    posture_task.set_target(qpos_init)
    com_target = np.array(data.subtree_com[com_body])
    com_target[:2] = stance_pose.translation()[:2]
    com_task.set_target(com_target)
    tasks = [stance_task, swing_task, com_task, posture_task]
    if upright_body is not None:
        upright = mink.FrameTask(upright_body, "body", position_cost=0.0, orientation_cost=5.0)
        upright.set_target(config.get_transform_frame_to_world(upright_body, "body"))
        tasks.append(upright)
    limits = [mink.ConfigurationLimit(model)]
    dt = 0.02
    used = iterations
    for it in range(iterations):
        vel = mink.solve_ik(config, tasks, dt, solver, damping=1e-3, limits=limits)
        config.integrate_inplace(vel, dt)
        com_err = np.linalg.norm(data.subtree_com[com_body][:2] - com_target[:2])
        swing_err = np.linalg.norm(
            config.get_transform_frame_to_world(swing_name, swing_kind).translation()
            - swing_target.translation()
        )
        if com_err < tolerance and swing_err < tolerance:
            used = it + 1
            break
    mujoco.mj_forward(model, data)
    com_err = float(np.linalg.norm(data.subtree_com[com_body][:2] - com_target[:2]))
    if com_err > 0.01:
        raise SolverError(f"stance_posture: the COM stayed {com_err:.3f} m from the stance foot")
    height = config.get_transform_frame_to_world(swing_name, swing_kind).translation()[2]
    return StancePosture(
        config.q.copy(), com_err, float(height - swing_pose.translation()[2]), used
    )
