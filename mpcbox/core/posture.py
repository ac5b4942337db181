"""Reference postures from inverse kinematics with mink."""

from __future__ import annotations

import warnings
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.contact import collision_geoms
from mpcbox.core.model import check_mjmodel, frame_object, free_body, object_id
from mpcbox.errors import InvalidArgumentError, PostureWarning, SolverError
from mpcbox.validation import (
    as_array,
    boolean,
    checked_keywords,
    finite_array,
    one_of,
    positive,
    positive_int,
)

#: What :func:`stance_posture` does when its posture is in self-collision.
ON_COLLISION: tuple[str, ...] = ("warn", "raise", "ignore")


class StancePosture(NamedTuple):
    """Result of :func:`stance_posture`.

    Attributes:
        qpos: The posture ``(nq,)``.
        com_error: Horizontal distance of the COM from the stance point (m).
        swing_height: Height gained by the swing frame (m).
        iterations: IK iterations used.
        collisions: Geom pairs of different moving bodies that touch at the posture
            (:func:`self_collisions`; empty when free).
    """

    qpos: np.ndarray
    com_error: float
    swing_height: float
    iterations: int
    collisions: tuple[tuple[str, str], ...] = ()


#: Joint speed limit (rad/s or m/s; 0.01 per 0.02 s step) of the collision-avoiding retry of
#: :func:`stance_posture`.
RETRY_SPEED = 0.5

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)


def _mink_frame(model: mujoco.MjModel, name: str, argument: str) -> tuple[str, str]:
    kind, _ = frame_object(model, name, argument)
    return name, kind


@checked_keywords
def stance_posture(
    model: mujoco.MjModel,
    qpos_init: np.ndarray,
    *,
    stance: str,
    swing: str,
    lift: float = 0.1,
    com_body: int | str | None = None,
    upright_body: str | None = None,
    keep_upright: bool = True,
    iterations: int = 300,
    tolerance: float = 1e-4,
    solver: str = "daqp",
    on_collision: str = "warn",
) -> StancePosture:
    """A one-leg stance: the center of mass over ``stance``, ``swing`` lifted by ``lift``.

    Solves differential inverse kinematics with mink (frame tasks on both feet, a center-of-mass
    task on the horizontal plane, posture regularization, joint limits) from ``qpos_init``.
    The result is checked for self-collision (:func:`self_collisions`): a posture with a hand
    inside a hip would make the holding torques meaningless. A posture in self-collision is
    solved again with mink's collision-avoidance limit between the robot's own collision
    geoms (from 5 cm) and joints moving at most :data:`RETRY_SPEED` (the limit holds each
    step to first order only; full steps took Booster's T1's hand through its hip between
    two iterations), and that posture is kept when it reaches the goal collision-free
    (without it the T1 put its right hand 1.3 cm into its right hip).

    Args:
        model: The model.
        qpos_init: Start posture ``(nq,)``, both feet on the floor.
        stance: Site or body name of the stance foot (kept where it is).
        swing: Site or body name of the swing foot (lifted).
        lift: Height to lift the swing foot (m).
        com_body: Body (name or id) whose subtree COM is placed (default: the body of the
            free joint, else body 1).
        upright_body: Body whose orientation is kept as in ``qpos_init`` (default: the body
            of the free joint).
        keep_upright: Keep ``upright_body``'s orientation (``False``: free).
        iterations: Maximum IK iterations.
        tolerance: Stop when the COM is this close to the stance point and the swing foot
            this close to its target (m).
        solver: A QP solver name that qpsolvers knows.
        on_collision: What a posture in self-collision does: ``"warn"`` (a
            :class:`~mpcbox.errors.PostureWarning` naming the pairs), ``"raise"``
            (:class:`~mpcbox.errors.SolverError` naming them) or ``"ignore"``; the pairs are
            in :attr:`StancePosture.collisions` either way.

    Raises:
        SolverError: If the COM stays farther than 1 cm from the stance point, or, with
            ``on_collision="raise"``, if the posture is in self-collision.
        UnknownNameError: If a frame or body does not exist (lists those that do).
    """
    import mink
    import qpsolvers

    model = check_mjmodel(model)
    qpos_init = finite_array("qpos_init", qpos_init, (model.nq,))
    lift = positive("lift", lift)
    positive_int("iterations", iterations)
    tolerance = positive("tolerance", tolerance)
    one_of("on_collision", on_collision, ON_COLLISION)
    root = free_body(model)
    if com_body is None:
        com_body = 1 if root is None else root
    com_body = object_id(model, "body", com_body, "com_body")
    if not boolean("keep_upright", keep_upright):
        upright_body = None
    elif upright_body is None and root is not None:
        upright_body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, root)
    elif upright_body is not None:
        object_id(model, "body", upright_body, "upright_body")
    one_of("solver", solver, qpsolvers.available_solvers)
    config = mink.Configuration(model, q=qpos_init.copy())
    data = config.data
    stance_name, stance_kind = _mink_frame(model, stance, "stance")
    swing_name, swing_kind = _mink_frame(model, swing, "swing")
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

    def solve(limits: list) -> tuple[np.ndarray, float, float, int]:
        config.update(qpos_init.copy())
        dt, used = 0.02, iterations
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
        height = config.get_transform_frame_to_world(swing_name, swing_kind).translation()[2]
        return config.q.copy(), com_err, float(height - swing_pose.translation()[2]), used

    bounds = [mink.ConfigurationLimit(model)]
    qpos, com_err, lifted, used = solve(bounds)
    if com_err > 0.01:
        raise SolverError(f"stance_posture: the COM stayed {com_err:.3f} m from the stance foot")
    collisions = self_collisions(model, qpos)
    if collisions:
        # Solve again keeping the robot's own collision geoms apart (mink's limit), and keep
        # that posture if it reaches the goal free of collisions.
        moving = collision_geoms(model) & (model.body_weldid[model.geom_bodyid] != 0)
        robot = np.flatnonzero(moving).tolist()
        apart = mink.CollisionAvoidanceLimit(
            model, [(robot, robot)], collision_detection_distance=0.05
        )
        hinges = [
            name
            for j in range(model.njnt)
            if model.jnt_type[j] in (_HINGE, _SLIDE) and (name := model.joint(j).name)
        ]
        slow = mink.VelocityLimit(model, {name: RETRY_SPEED for name in hinges})
        try:
            again = solve([*bounds, apart, slow])
        except mink.exceptions.NoSolutionFound:  # e.g. joints locked in the collision
            again = None
        if again is not None and again[1] <= 0.01 and not self_collisions(model, again[0]):
            (qpos, com_err, lifted, used), collisions = again, ()
    if collisions and on_collision != "ignore":
        message = "stance_posture: the posture is in self-collision: " + ", ".join(
            f"{a} with {b}" for a, b in collisions
        )
        if on_collision == "raise":
            raise SolverError(message)
        warnings.warn(PostureWarning(message), stacklevel=2)
    return StancePosture(qpos, com_err, lifted, used, collisions)


class ReachPosture(NamedTuple):
    """Result of :func:`reach_posture`.

    Attributes:
        qpos: The posture ``(nq,)``.
        position_error: Distance of the frame from the target position (m).
        orientation_error: Angle between the frame and the target orientation (rad; 0 when no
            orientation was asked for).
        iterations: IK iterations used.
        collisions: Names of the geom pairs of different moving bodies in contact at the
            posture (empty when free). From :func:`reach_posture` only pairs that touch at
            ``qpos_init`` already, such as a gripper's closed fingers; any other is refused.
    """

    qpos: np.ndarray
    position_error: float
    orientation_error: float
    iterations: int
    collisions: tuple[tuple[str, str], ...]


def _geom_label(model: mujoco.MjModel, geom: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[geom])
    return name or f"geom {geom} of body {body or model.geom_bodyid[geom]}"


def _watched_pairs(
    colliding: list[int], touching: list[tuple[int, int]]
) -> list[tuple[list[int], list[int]]]:
    """The geom pairs mink's collision-avoidance limit keeps apart: every colliding pair,
    less the ``touching`` ones, between moving bodies that already touch at the start (a
    gripper's closed fingers): such a pair cannot be kept 5 mm apart from the first step,
    and mink's QP then has no solution."""
    start = {tuple(sorted(p)) for p in touching}
    if not start:
        return [(colliding, colliding)]
    return [
        ([a], [b])
        for i, a in enumerate(colliding)
        for b in colliding[i + 1 :]
        if (min(a, b), max(a, b)) not in start
    ]


#: Penetration (m) of the static world that makes a reach posture fail.
_DEPTH = 1e-3


def _touching(
    model: mujoco.MjModel, qpos: np.ndarray, margin: float, static: bool
) -> tuple[tuple[str, str], ...]:
    """Geom pairs closer than ``-margin`` at ``qpos``: between moving bodies, or (``static``)
    between a moving body and the world or a body welded to it."""
    return tuple(
        (_geom_label(model, g1), _geom_label(model, g2))
        for g1, g2 in _touching_ids(model, qpos, margin, static)
    )


def _touching_ids(
    model: mujoco.MjModel, qpos: np.ndarray, margin: float, static: bool
) -> list[tuple[int, int]]:
    """:func:`_touching` as geom ids (the moving geom first when ``static``)."""
    model = check_mjmodel(model)
    qpos = finite_array("qpos", qpos, (model.nq,))
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    pairs = []
    for i in range(data.ncon):
        con = data.contact[i]
        w1 = model.body_weldid[model.geom_bodyid[con.geom1]]
        w2 = model.body_weldid[model.geom_bodyid[con.geom2]]
        if (w1 == 0 and w2 == 0) or ((w1 == 0 or w2 == 0) != static) or con.dist > -margin:
            continue
        g1, g2 = (con.geom2, con.geom1) if w1 == 0 else (con.geom1, con.geom2)
        pair = (int(g1), int(g2))
        if pair not in pairs:
            pairs.append(pair)
    return pairs


def self_collisions(
    model: mujoco.MjModel, qpos: np.ndarray, *, margin: float = 0.0
) -> tuple[tuple[str, str], ...]:
    """The pairs of geoms of *different moving bodies* that touch or penetrate at ``qpos``.

    Contacts with the world body or a body welded to it (a floor, a table) are not
    self-collisions and are left out (:func:`environment_contacts` lists them); each pair is
    listed once.

    Args:
        model: The model.
        qpos: The posture ``(nq,)``.
        margin: Report pairs closer than this distance (m); 0 reports penetrations only.

    Returns:
        ``(geom_a, geom_b)`` labels, one per touching pair.
    """
    return _touching(model, qpos, margin, static=False)


def environment_contacts(
    model: mujoco.MjModel, qpos: np.ndarray, *, margin: float = 0.0
) -> tuple[tuple[str, str], ...]:
    """The geoms of moving bodies that touch or penetrate the static world at ``qpos``.

    Args:
        model: The model.
        qpos: The posture ``(nq,)``.
        margin: Report pairs closer than this distance (m); 0 reports penetrations only.

    Returns:
        ``(moving geom, static geom)`` labels (a floor, a table), one per touching pair.
    """
    return _touching(model, qpos, margin, static=True)


@checked_keywords
def reach_posture(
    model: mujoco.MjModel,
    qpos_init: np.ndarray,
    *,
    frame: str,
    position: np.ndarray,
    orientation: np.ndarray | None = None,
    avoid_collisions: bool = True,
    iterations: int = 500,
    tolerance: float = 1e-4,
    solver: str = "daqp",
    max_error: float | None = None,
) -> ReachPosture:
    """A posture that puts ``frame`` at ``position`` (and ``orientation``), free of collisions.

    Differential inverse kinematics with mink from ``qpos_init``: a frame task, light posture
    regularization toward ``qpos_init``, joint limits and, with ``avoid_collisions``, a
    collision-avoidance limit between every pair of colliding geoms of the model (mink skips
    pairs that cannot collide: welded, parent-child, or excluded by contype/conaffinity).

    Args:
        model: The model (a fixed-base arm; free joints are moved too).
        qpos_init: Start posture ``(nq,)``; also the posture regularization target.
        frame: Site or body name of the end effector.
        position: Target position ``(3,)`` in the world frame (m).
        orientation: Target orientation as a unit quaternion ``(4,)`` ``[w, x, y, z]``, or
            ``None`` to leave the orientation free.
        avoid_collisions: Keep geoms at least 5 mm apart while solving (pairs are watched
            from 5 cm apart, not mink's default 1 cm, which one IK step can jump), and reject
            a posture whose geoms go deeper than 1 mm into the static world (a floor, a
            table) where they did not touch it at ``qpos_init``. mink leaves out a link
            whose parent is welded to the world against the world's geoms, so this check is
            what catches such a link in the floor (a KUKA iiwa's wrist went 7 mm into the
            floor for a target at floor level, and the goal was called reached).
        iterations: Maximum IK iterations.
        tolerance: Stop when the position error is below this (m) and the orientation error
            below ``10 * tolerance`` rad.
        solver: A QP solver name that qpsolvers knows.
        max_error: Largest position error (m) accepted at the end; ``None``: any.

    Raises:
        SolverError: If the frame ends farther than ``max_error`` from the target, or the
            final posture is in self-collision (a pair that did not touch at ``qpos_init``)
            or (``avoid_collisions``) in the environment.
    """
    import mink

    model = check_mjmodel(model)
    qpos_init = finite_array("qpos_init", qpos_init, (model.nq,))
    target_pos = finite_array("position", position, (3,))
    if orientation is not None:
        quat = as_array("orientation", orientation, (4,))
        norm = float(np.linalg.norm(quat))
        if not np.isfinite(norm) or norm < 1e-9:
            raise InvalidArgumentError(f"orientation must be a unit quaternion, got {quat}")
        quat = quat / norm
    positive_int("iterations", iterations)
    positive("tolerance", tolerance)
    if max_error is not None:
        positive("max_error", max_error)
    name, kind = _mink_frame(model, frame, "frame")
    # MuJoCo's joint limits are soft, so a measured start can lie just past one. The IK
    # starts there: clipped into its range, a gripper's finger can land inside the other
    # jaw (tests/test_end_effector.py); a first step that has no solution with the
    # collision limit is taken within the joint limits alone.
    config = mink.Configuration(model, q=np.asarray(qpos_init, dtype=float))
    task = mink.FrameTask(
        name, kind, position_cost=1.0, orientation_cost=0.0 if orientation is None else 0.5
    )
    rotation = (
        config.get_transform_frame_to_world(name, kind).rotation()
        if orientation is None
        else mink.SO3(wxyz=quat)
    )
    task.set_target(mink.SE3.from_rotation_and_translation(rotation, target_pos))
    posture = mink.PostureTask(model, cost=1e-3)
    posture.set_target(qpos_init)
    limits: list = [mink.ConfigurationLimit(model)]
    # Pairs that touch at the start are the model's own (a gripper's closed fingers in its
    # keyframe): not watched by the IK, and reported, not refused, at the end.
    start_pairs = _touching_ids(model, qpos_init, 0.0, static=False)
    if avoid_collisions:
        colliding = np.flatnonzero(collision_geoms(model)).tolist()
        if colliding:
            limits.append(
                mink.CollisionAvoidanceLimit(
                    model,
                    _watched_pairs(colliding, start_pairs),
                    collision_detection_distance=0.05,
                )
            )

    def errors() -> tuple[float, float]:
        pose = config.get_transform_frame_to_world(name, kind)
        pos_err = float(np.linalg.norm(pose.translation() - target_pos))
        if orientation is None:
            return pos_err, 0.0
        delta = (rotation.inverse() @ pose.rotation()).log()
        return pos_err, float(np.linalg.norm(delta))

    dt = 0.02
    used = iterations
    for it in range(iterations):
        try:
            vel = mink.solve_ik(config, [task, posture], dt, solver, damping=1e-3, limits=limits)
        except mink.NoSolutionFound:
            # Two geoms closer than the limit's 5 mm that no joint can part (a gripper's
            # jaws at its joint limit) make the step's QP infeasible. That step is taken
            # within the joint limits alone; the final posture is still checked below.
            try:
                vel = mink.solve_ik(
                    config, [task, posture], dt, solver, damping=1e-3, limits=limits[:1]
                )
            except mink.NoSolutionFound as exc:
                raise SolverError(
                    f"reach_posture: mink's IK step for {frame!r} has no solution within "
                    f"the joint limits at iteration {it}"
                ) from exc
        config.integrate_inplace(vel, dt)
        pos_err, rot_err = errors()
        if pos_err < tolerance and rot_err < 10 * tolerance:
            used = it + 1
            break
    qpos = config.q.copy()  # pos_err and rot_err hold its errors (iterations >= 1)
    if max_error is not None and pos_err > max_error:
        how = "collision-free " if avoid_collisions else ""
        raise SolverError(
            f"reach_posture: {frame!r} cannot reach {np.round(target_pos, 4).tolist()}: the "
            f"closest {how}posture found in {used} IK iterations leaves it {pos_err:.3g} m "
            f"away (max_error {max_error:g} m); the target may be out of reach or inside an "
            "obstacle"
        )
    if avoid_collisions:
        before = set(environment_contacts(model, qpos_init, margin=_DEPTH))
        touching = [p for p in environment_contacts(model, qpos, margin=_DEPTH) if p not in before]
        if touching:
            raise SolverError(
                f"reach_posture: the posture for {frame!r} at "
                f"{np.round(target_pos, 4).tolist()} goes into the environment: "
                + ", ".join(f"{a} into {b}" for a, b in touching)
                + "; the target may lie inside or below an obstacle (a floor, a table)"
            )
    collisions = self_collisions(model, qpos)
    start = {(_geom_label(model, a), _geom_label(model, b)) for a, b in start_pairs}
    new = [pair for pair in collisions if pair not in start]
    if new:
        raise SolverError(
            f"reach_posture: the posture for {frame!r} is in self-collision: "
            + ", ".join(f"{a} with {b}" for a, b in new)
        )
    return ReachPosture(qpos, pos_err, rot_err, used, collisions)
