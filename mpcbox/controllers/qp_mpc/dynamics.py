r"""The contact-free prediction that both stance models start from, and the soft-contact
model next to it.

The prediction starts from the planning model stepped at the QP step ``dt`` **with contacts
disabled**, the ground acting only through explicit forces :math:`f_k` at the contact points.
About a linearization point :math:`(\bar x, \bar u)`, with tangent deviations
:math:`\delta x` (``nx = 2 nv + na``) and :math:`\delta u = u - \bar u`:

.. math::

    \delta x_{k+1} = A\,\delta x_k + B\,\delta u_k + B_c\,f_k + c, \qquad
    B_c = \begin{bmatrix} dt\,V \\ V \\ 0 \end{bmatrix},\quad
    V = dt\,\tilde M^{-1} J_c^T ,

where ``A``, ``B`` are ``substeps`` steps (of the planning model's own timestep
``h = dt / substeps``, control and force held) of :func:`mujoco.mjd_transitionFD` on the
contact-free model composed (:func:`compose`: :math:`A = A_h^n`,
:math:`B = \sum_{i<n} A_h^i B_h`, likewise ``B_c``; ``V`` then uses ``h``),
:math:`c = \mathrm{step}(\bar x, \bar u) \ominus \bar x` is its drift (gravity),
:math:`J_c` ``(3 k, nv)`` the contact Jacobian and :math:`\tilde M = M + dt\,D` the mass
matrix with the implicitly integrated joint damping ``D`` (MuJoCo's Euler and implicitfast
integrators), so that a force enters the velocity update and, through
:math:`q_{k+1} = q_k \oplus dt\,v_{k+1}`, the position update. Forces are in units of the
body weight :math:`m g` (conditioning).

:class:`ContactDynamics` also reports the soft-contact model's forces on the contact points
(:meth:`ContactDynamics.point_forces`) and which points touch the ground.
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.contact import ContactPoints, body_twist_jacobian, contact_jacobian
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError


class Linearization(NamedTuple):
    r"""The prediction model about :math:`(\bar x, \bar u)`; forces in body weights.

    Attributes:
        state: Linearization state :math:`\bar x` ``(nq + nv + na,)``.
        ctrl: Linearization control :math:`\bar u` ``(nu,)``.
        A: State matrix of one QP step ``(nx, nx)``.
        B: Control matrix of one QP step ``(nx, nu)``.
        c: Drift of one QP step ``(nx,)``.
        Bc: Force input rows ``(2 nv, 3 k)`` (positions, velocities) of one QP step.
        Js: Stance Jacobian ``(ns_rigid, nv)``: twists of the stance bodies, or point
            velocities of bodies with fewer than three points.
        Ah: Contact-free state matrix of one substep ``(nx, nx)``.
        Bh: Contact-free control matrix of one substep ``(nx, nu)``.
        fbar: Soft stance: contact forces at the point ``(3 k,)`` (``None`` for rigid).
        Fx: Soft stance: force law's state matrix ``(3 k, nx)`` (``None`` for rigid).
        Fu: Soft stance: force law's control matrix ``(3 k, nu)`` (``None`` for rigid).
    """

    state: np.ndarray
    ctrl: np.ndarray
    A: np.ndarray
    B: np.ndarray
    c: np.ndarray
    Bc: np.ndarray
    Js: np.ndarray
    Ah: np.ndarray
    Bh: np.ndarray
    fbar: np.ndarray | None = None
    Fx: np.ndarray | None = None
    Fu: np.ndarray | None = None


class StanceGroup(NamedTuple):
    """The contact points of one body and its rigid-stance rows.

    Attributes:
        body: Body id.
        points: Indices of its points ``(j,)``.
        rows: Stance rows: 6 (twist) with three or more points, else ``3 j``.
    """

    body: int
    points: np.ndarray
    rows: int


def stance_groups(points: ContactPoints) -> list[StanceGroup]:
    """The points grouped by body, in order of first appearance."""
    out = []
    for idx in points.groups():
        rows = 6 if len(idx) >= 3 else 3 * len(idx)
        out.append(StanceGroup(int(points.body[idx[0]]), idx, rows))
    return out


def compose(Ah: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``A = Ah^n`` and ``S = sum_{i<n} Ah^i``: ``n`` steps of ``x+ = Ah x + b`` with ``b``
    held give ``x_n = A x_0 + S b``."""
    A = np.eye(len(Ah))
    S = np.zeros_like(Ah)
    for _ in range(n):
        S += A
        A = Ah @ A
    return A, S


def prediction_models(
    problem: Problem, dt: float, substeps: int
) -> tuple[mujoco.MjModel, mujoco.MjModel]:
    """Copies of the planning model at timestep ``dt / substeps``: contacts off, and on; both
    without dry friction when the Problem linearizes without it (``dry_friction="drop"``)."""
    free = copy.copy(problem.planning_model)
    free.opt.timestep = dt / substeps
    free.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    soft = copy.copy(problem.planning_model)
    soft.opt.timestep = dt / substeps
    if problem.drops_friction:
        for m in (free, soft):
            m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    return free, soft


class ContactDynamics:
    """The prediction's MuJoCo models and data, and what they compute about a point.

    Args:
        problem: The Problem.
        model: Contact-free prediction model (:func:`prediction_models`).
        soft_model: Soft-contact model at the same timestep.
        points: The contact points.
        substeps: Model steps per QP step.
        state_ref: Reference state; its lowest contact point is the ground height.
        fd_centered: Centered finite differences for :func:`mujoco.mjd_transitionFD`.
        contact_margin: A point higher than this above the ground is lifted (m).

    Attributes:
        body_weight: Total weight :math:`m g` of the model (N); the unit of the forces.
        ground: Height of the lowest contact point at the reference (m).
        groups: The :class:`StanceGroup` of each contact body.
    """

    def __init__(
        self,
        problem: Problem,
        model: mujoco.MjModel,
        soft_model: mujoco.MjModel,
        points: ContactPoints,
        substeps: int,
        state_ref: np.ndarray,
        fd_centered: bool,
        contact_margin: float,
    ) -> None:
        self.problem = problem
        self.model = model
        self.soft_model = soft_model
        self.points = points
        self.substeps = substeps
        self.fd_centered = fd_centered
        self.contact_margin = contact_margin
        self.groups = stance_groups(points)
        self._data = mujoco.MjData(model)  # contact-free steps
        self._kin = mujoco.MjData(model)  # kinematics at the linearization point
        self._activity = mujoco.MjData(model)  # kinematics at the measured state
        self._soft = mujoco.MjData(soft_model)  # soft-contact steps and forces
        self.body_weight = float(np.sum(model.body_mass) * np.linalg.norm(model.opt.gravity))
        if self.body_weight <= 0:
            raise InvalidArgumentError("the model must have mass and gravity for contact forces")
        self._kin.qpos[:] = state_ref[: problem.nq]
        mujoco.mj_kinematics(model, self._kin)
        self.ground = float(np.min(points.world(self._kin)[:, 2]))

    def contact_free(self, state: np.ndarray, ctrl: np.ndarray) -> Linearization:
        """The contact-free linearization (``fbar``, ``Fx``, ``Fu`` left ``None``)."""
        p, m = self.problem, self.model
        nx, nv = p.nx, p.nv
        Ah, Bh, A, S, drift = self._composed_step(m, self._data, state, ctrl)
        B = S @ Bh
        # Kinematics, mass matrix and Jacobians at the linearization point.
        kin = self._kin
        p.set_state(kin, state)
        mujoco.mj_fwdPosition(m, kin)
        M = np.zeros((nv, nv))
        mujoco.mj_fullM(m, kin, M)
        if m.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
            M += m.opt.timestep * np.diag(m.dof_damping)
        Jc = contact_jacobian(m, kin, self.points)
        h = m.opt.timestep
        V = h * np.linalg.solve(M, Jc.T) * self.body_weight  # per weight unit, one substep
        Bc_h = np.vstack([h * V, V, np.zeros((nx - 2 * nv, V.shape[1]))])
        Bc = (S @ Bc_h)[: 2 * nv]
        world = self.points.world(kin)
        Js = np.vstack(
            [
                body_twist_jacobian(m, kin, g.body, world[g.points[0]])
                if g.rows == 6
                else contact_jacobian(
                    m,
                    kin,
                    ContactPoints(self.points.body[g.points], self.points.local[g.points], ()),
                )
                for g in self.groups
            ]
        )
        return Linearization(state.copy(), ctrl.copy(), A, B, drift, Bc, Js, Ah, Bh)

    def _composed_step(
        self, m: mujoco.MjModel, d: mujoco.MjData, state: np.ndarray, ctrl: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One QP step of ``m`` (``substeps`` steps, control held) about ``(state, ctrl)``.

        Returns:
            ``A_h``, ``B_h`` of one substep (``mjd_transitionFD``), the composed ``A`` and
            the input sum ``S`` (:func:`compose`), and the drift ``step(x, u) ⊖ x``.
        """
        p = self.problem
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        Ah = np.zeros((p.nx, p.nx))
        Bh = np.zeros((p.nx, p.nu))
        mujoco.mjd_transitionFD(m, d, p.fd_eps, self.fd_centered, Ah, Bh, None, None)
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        mujoco.mj_step(m, d, self.substeps)
        drift = p.state_difference(p.get_state(d), state)
        A, S = compose(Ah, self.substeps)
        return Ah, Bh, A, S, drift

    def activity(self, state: np.ndarray) -> tuple[np.ndarray, mujoco.MjData]:
        """Which points touch the ground ``(k,)`` at ``state``, and its kinematics."""
        kin = self._activity
        self.problem.set_state(kin, state)
        mujoco.mj_kinematics(self.model, kin)
        z = self.points.world(kin)[:, 2]
        return z < self.ground + self.contact_margin, kin

    def soft_step(
        self, state: np.ndarray, ctrl: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``A`` ``(nx, nx)``, ``B`` ``(nx, nu)`` and drift ``c`` ``(nx,)`` of one QP step of
        the soft-contact model about ``(state, ctrl)``."""
        _, Bh, A, S, drift = self._composed_step(self.soft_model, self._soft, state, ctrl)
        return A, S @ Bh, drift

    def point_forces(
        self, state: np.ndarray, ctrl: np.ndarray, touching: np.ndarray | None = None
    ) -> np.ndarray:
        """Ground forces on the contact points in the soft-contact model, ``(3 k,)`` in body
        weights.

        Each MuJoCo contact on a contact body is given to the nearest point of that body
        that touches the ground (:meth:`activity`), or to its nearest point when none does.
        A lifted point may carry no force in the QP, so a force given to it (a calf capsule
        whose end touches the floor next to the foot sphere, on Menagerie's A1) could only
        be carried by the slack.

        Args:
            state: The state.
            ctrl: The control ``(nu,)``.
            touching: Which points count as touching ``(k,)``; default: those of
                :meth:`activity` at ``state``. Finite differences pass the mask of the
                nominal state, so that a point at the threshold does not flip.
        """
        p, m, d = self.problem, self.soft_model, self._soft
        p.set_state(d, state)
        d.ctrl[:] = ctrl
        mujoco.mj_forward(m, d)
        world = self.points.world(d)
        if touching is None:
            touching = world[:, 2] < self.ground + self.contact_margin
        out = np.zeros((self.points.count, 3))
        f6 = np.zeros(6)
        for c in range(d.ncon):
            con = d.contact[c]
            b1, b2 = m.geom_bodyid[con.geom1], m.geom_bodyid[con.geom2]
            for body, sign in ((b2, 1.0), (b1, -1.0)):
                idx = np.flatnonzero(self.points.body == body)
                if idx.size == 0:
                    continue
                if np.any(touching[idx]):
                    idx = idx[touching[idx]]
                mujoco.mj_contactForce(m, d, c, f6)
                force = sign * (con.frame.reshape(3, 3).T @ f6[:3])
                near = idx[np.argmin(np.linalg.norm(world[idx] - con.pos, axis=1))]
                out[near] += force
                break
        return out.ravel() / self.body_weight
