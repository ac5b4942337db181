r"""Repeated inverse kinematics of one arm inside a larger model, with mink.

:class:`ArmIK` keeps one mink configuration and its tasks, so a controller can solve many
small IK problems (waypoints of a pick-and-place) cheaply: each :meth:`ArmIK.solve` starts
from a given posture and takes Gauss-Newton-like steps of differential IK

.. math::
    \min_{\dot q}\; \|J_p \dot q - k\,e_p\|^2_{W_p} + \|J_R \dot q - k\,e_R\|^2_{W_R}
    + w_q \|\dot q - k (q^\circ - q)\|^2 \quad\text{s.t. joint limits},\;
    \dot q_j = 0 \text{ for every joint not of the arm,}

until the frame is within ``tolerance`` of the target. Every joint that is not the arm's
(free objects, fingers, another arm) is frozen by an equality constraint
(:class:`mink.DofFreezingTask`).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import check_mjmodel, frame_object, object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import finite_array, positive, positive_int


class IKSolution(NamedTuple):
    """Result of :meth:`ArmIK.solve`.

    Attributes:
        qpos: The arm's joint angles ``(n,)`` (rad), in the order of ``joints``.
        position_error: Distance of the frame from the target (m).
        orientation_error: Angle to the target orientation (rad; 0 without one).
        iterations: IK steps taken.
    """

    qpos: np.ndarray
    position_error: float
    orientation_error: float
    iterations: int


def _narrowed(
    model: mujoco.MjModel,
    joints: Sequence[str],
    ranges: Sequence[tuple[float, float] | None],
) -> mujoco.MjModel:
    """A copy of ``model`` whose ``joints`` are limited to ``ranges`` (``None``: unchanged)."""
    if len(ranges) != len(joints):
        raise InvalidArgumentError(
            f"ranges must have one entry per joint ({len(joints)}), got {len(ranges)}"
        )
    model = copy.copy(model)
    for joint, bounds in zip(joints, ranges, strict=True):
        if bounds is None:
            continue
        low, high = (float(v) for v in bounds)
        if not low < high:
            raise InvalidArgumentError(f"ranges: joint {joint!r} needs low < high, got {bounds}")
        j = object_id(model, "joint", joint, "joints")
        model.jnt_range[j] = [low, high]
        model.jnt_limited[j] = 1
    return model


class ArmIK:
    """Inverse kinematics of the joints ``joints`` of ``model`` for the site or body ``frame``.

    Args:
        model: The model (the whole scene; other joints are frozen).
        frame: Site or body name of the end effector.
        joints: Names of the arm's joints (hinge or slide).
        posture: Rest angles ``(n,)`` of the joints that a light posture task pulls toward.
        iterations: Maximum IK steps per solve.
        tolerance: Stop when the position error is below this (m) and the orientation
            error below ``10 * tolerance`` rad.
        posture_cost: Weight :math:`w_q` of the posture task.
        orientation_cost: Weight of the orientation task relative to position.
        gain: Share of the remaining error each step removes, in ``(0, 1]`` (1: Gauss-Newton
            steps, which may jump to another branch of the IK from far away).
        ranges: Joint ranges ``(low, high)`` (rad) the IK keeps to instead of the model's,
            one per joint or ``None`` to keep the model's; they keep the IK on one branch
            (an arm whose forearm can roll half a turn reaches a pose two ways).
        solver: QP solver name for :func:`mink.solve_ik`.

    Raises:
        UnknownNameError: For a frame or joint that does not exist.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        frame: str,
        joints: Sequence[str],
        posture: np.ndarray,
        iterations: int = 40,
        tolerance: float = 1e-3,
        posture_cost: float = 1e-3,
        orientation_cost: float = 0.5,
        gain: float = 0.5,
        ranges: Sequence[tuple[float, float] | None] | None = None,
        solver: str = "daqp",
    ) -> None:
        import mink

        model = check_mjmodel(model)
        if ranges is not None:
            model = _narrowed(model, joints, ranges)
        self.model = model
        self.kind = frame_object(model, frame, "frame")[0]
        self.frame = frame
        ids = [object_id(model, "joint", j, "joints") for j in joints]
        self.qadr = np.array([model.jnt_qposadr[j] for j in ids])
        arm_dofs = {int(model.jnt_dofadr[j]) for j in ids}
        frozen = [i for i in range(model.nv) if i not in arm_dofs]
        self.iterations = positive_int("iterations", iterations)
        self.tolerance = positive("tolerance", tolerance)
        self.solver = solver
        self.config = mink.Configuration(model)
        self.task = mink.FrameTask(
            frame, self.kind, position_cost=1.0, orientation_cost=orientation_cost, gain=gain
        )
        self.posture = mink.PostureTask(model, cost=posture_cost)
        rest = self.config.q.copy()
        rest[self.qadr] = finite_array("posture", posture, (len(ids),))
        self.posture.set_target(rest)
        self.constraints = [mink.DofFreezingTask(model, dof_indices=frozen)] if frozen else []
        self.limits = [mink.ConfigurationLimit(model)]
        # Limited hinge and slide joints, the arm's and the frozen others': a posture a hair
        # outside any limit makes the limit QP infeasible, so solves start clamped inside.
        hinge_slide = (model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE) | (
            model.jnt_type == mujoco.mjtJoint.mjJNT_SLIDE
        )
        clamped = np.flatnonzero(hinge_slide & model.jnt_limited.astype(bool))
        margin = 1e-4
        self._clamp_adr = model.jnt_qposadr[clamped]
        self._low = model.jnt_range[clamped, 0] + margin
        self._high = model.jnt_range[clamped, 1] - margin
        self._mink = mink

    def solve(
        self, qpos: np.ndarray, position: np.ndarray, quat: np.ndarray | None = None
    ) -> IKSolution:
        """Joint angles that put the frame at ``position`` (and ``quat``).

        Args:
            qpos: The whole model's positions ``(nq,)`` to start from (the other joints stay).
            position: Target position ``(3,)`` in the world frame (m).
            quat: Target orientation ``[w, x, y, z]``, or ``None`` to keep the frame's
                orientation at ``qpos``.
        """
        mink = self._mink
        config = self.config
        start = np.asarray(qpos, dtype=float).copy()
        start[self._clamp_adr] = np.clip(start[self._clamp_adr], self._low, self._high)
        config.update(start)
        pose = config.get_transform_frame_to_world(self.frame, self.kind)
        rotation = pose.rotation() if quat is None else mink.SO3(wxyz=np.asarray(quat, float))
        target = mink.SE3.from_rotation_and_translation(rotation, np.asarray(position, float))
        self.task.set_target(target)

        def errors() -> tuple[float, float]:
            now = config.get_transform_frame_to_world(self.frame, self.kind)
            pos = float(np.linalg.norm(now.translation() - target.translation()))
            return pos, float(np.linalg.norm((rotation.inverse() @ now.rotation()).log()))

        pos_err, rot_err = errors()
        used = 0
        dt = 1.0
        while used < self.iterations and not (
            pos_err < self.tolerance and rot_err < 10 * self.tolerance
        ):
            used += 1
            try:
                vel = mink.solve_ik(
                    config,
                    [self.task, self.posture],
                    dt,
                    self.solver,
                    damping=1e-4,
                    limits=self.limits,
                    constraints=self.constraints,
                )
            except mink.NoSolutionFound:
                break  # keep the last posture; its errors say how far it is
            config.integrate_inplace(vel, dt)
            pos_err, rot_err = errors()
        return IKSolution(config.q[self.qadr].copy(), pos_err, rot_err, used)
