r"""Prediction models of the QP-MPC: how the ground forces enter the prediction and
what ties them to the motion (:class:`PredictionModel`).

Both start from the contact-free linearization of
:class:`~mpcbox.controllers.qp_mpc.dynamics.ContactDynamics`,
:math:`\delta x_{k+1} = A\,\delta x_k + B\,\delta u_k + B_c\,f_k + c`.

:class:`RigidStance` predicts with that contact-free model and holds the stance bodies still:
every stance body with three or more points keeps its twist at zero,
:math:`J_s v_{k+1} = 0` (``J_s`` ``(6, nv)``), with a drift correction
:math:`J_s v_1 = -\alpha\, e / dt` on the first step (``e``: pose error from the anchor taken
when the body touched down); bodies with fewer points keep the points still. The forces get
the regularization :math:`\tfrac{w_f}{2}\|f/(m g) - \bar\phi\|^2` toward an even share of
the weight.

:class:`SoftStance` (the default). MuJoCo's contacts are soft, and a foot held rigidly still
mispredicts them (an LQR designed on that rigid model falls where one designed on the soft
model holds). The soft stance therefore predicts with the soft-contact model,
:math:`\delta x_{k+1} = A_s \delta x_k + B_s \delta u_k + B_c s_k + c_s`, and keeps the forces
explicit through the linearized contact-force law of the same model,
:math:`f_k = \bar f + F_x \delta x_k + F_u \delta u_k + s_k` (forward differences of the forces
:func:`mujoco.mj_contactForce` reports, each contact given to the nearest point). The slack
:math:`s_k`, weighted by ``stance_weight``, is a force the soft model does not predict; the
friction pyramid and unilateral bounds apply to :math:`f_k`, so they constrain the forces the
simulator will produce.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import mujoco
import numpy as np

from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.controllers.qp_mpc.dynamics import ContactDynamics, Linearization
from mpcbox.controllers.qp_mpc.layout import QPLayout, block_pattern, diag_pattern

Pattern = list[tuple[np.ndarray, np.ndarray]]


class PredictionModel(abc.ABC):
    """Linearizes the prediction and writes the QP rows that tie the forces to the motion.

    Subclasses say how the forces enter the dynamics rows and what the stance rows are
    (their pattern, values and bounds).

    Args:
        dynamics: The models and data of the prediction.
        config: The controller's options.
    """

    name: ClassVar[str]

    def __init__(self, dynamics: ContactDynamics, config: QPMPCConfig) -> None:
        self.dynamics = dynamics
        self.config = config
        self.reset()

    @property
    @abc.abstractmethod
    def ns(self) -> int:
        """Stance rows per stage."""

    @property
    def force_cost(self) -> float:
        """Hessian weight of the force variables (default ``force_weight``)."""
        return self.config.force_weight

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Forget state kept between ticks (the constructor calls it too)."""

    @abc.abstractmethod
    def linearize(self, state: np.ndarray, ctrl: np.ndarray) -> Linearization:
        """The prediction model about ``(state, ctrl)``."""

    # ------------------------------------------------------------------ QP rows
    @abc.abstractmethod
    def contact_pattern(self, layout: QPLayout) -> Pattern:
        """Index blocks of the force input in the dynamics rows, then of the stance rows."""

    @abc.abstractmethod
    def contact_values(self, lin: Linearization, layout: QPLayout) -> np.ndarray:
        """The values of :meth:`contact_pattern`'s blocks, in the same order."""

    @abc.abstractmethod
    def contact_bounds(
        self,
        lin: Linearization,
        x0: np.ndarray,
        kin: mujoco.MjData,
        active: np.ndarray,
        layout: QPLayout,
    ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """Force gradient ``(N 3 k,)`` (``None``: zero) and stance-row bounds ``(N ns,)``.

        Args:
            lin: The linearization.
            x0: Measured state's deviation from ``lin.state`` ``(nx,)``.
            kin: Kinematics at the measured state (``ContactDynamics.activity``).
            active: Points touching the ground ``(k,)``.
            layout: The QP layout.
        """


class RigidStance(PredictionModel):
    """Contact-free prediction, stance bodies held still, forces as free inputs."""

    name = "rigid"

    _anchors: dict[int, tuple[np.ndarray, np.ndarray]]

    @property
    def ns(self) -> int:
        return sum(g.rows for g in self.dynamics.groups)

    def reset(self) -> None:
        """Forget the stance anchors (the poses held since each body touched down)."""
        self._anchors = {}

    def linearize(self, state: np.ndarray, ctrl: np.ndarray) -> Linearization:
        return self.dynamics.contact_free(state, ctrl)

    def contact_pattern(self, layout: QPLayout) -> Pattern:
        N, nv, ns = layout.horizon, layout.nv, layout.ns
        out = [
            block_pattern(layout.r_dyn + i * layout.nx, layout.f(i), 2 * nv, layout.nf)
            for i in range(N)
        ]  # -Bc on the forces
        for i in range(N):
            out.append(block_pattern(layout.r_st + i * ns, layout.x(i) + nv, ns, nv))  # J_s v
            if layout.nsl:
                out.append(diag_pattern(layout.r_st + i * ns, layout.s(i), ns))  # -slack
        return out

    def contact_values(self, lin: Linearization, layout: QPLayout) -> np.ndarray:
        N, ns = layout.horizon, layout.ns
        row = np.concatenate([lin.Js.ravel(), -np.ones(ns)]) if layout.nsl else lin.Js.ravel()
        return np.concatenate([np.tile(-lin.Bc.ravel(), N), np.tile(row, N)])

    def contact_bounds(
        self,
        lin: Linearization,
        x0: np.ndarray,
        kin: mujoco.MjData,
        active: np.ndarray,
        layout: QPLayout,
    ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        p, cfg = self.dynamics.problem, self.config
        N, ns, k = layout.horizon, layout.ns, layout.points
        phi = np.zeros((k, 3))
        phi[active, 2] = 1.0 / max(1, int(active.sum()))
        q_forces = np.tile(-cfg.force_weight * phi.ravel(), N)

        # Stance rows: anchors, drift correction.
        base = -lin.Js @ lin.state[p.nq : p.nq + p.nv]
        lo = np.full(ns, -np.inf)
        hi = np.full(ns, np.inf)
        first_lo = lo.copy()
        first_hi = hi.copy()
        row = 0
        world = self.dynamics.points.world(kin)
        for body, idx, rows in self.dynamics.groups:
            seg = slice(row, row + rows)
            row += rows
            if not np.any(active[idx]):
                self._anchors.pop(body, None)
                continue
            if rows == 6:
                pos, quat = world[idx[0]].copy(), kin.xquat[body].copy()
                if body not in self._anchors:
                    self._anchors[body] = (pos, quat)
                apos, aquat = self._anchors[body]
                rot = np.zeros(3)
                mujoco.mju_subQuat(rot, quat, aquat)
                err = np.concatenate([pos - apos, kin.xmat[body].reshape(3, 3) @ rot])
            else:
                pos = world[idx].ravel()
                if body not in self._anchors:
                    self._anchors[body] = (pos.copy(), np.zeros(4))
                err = pos - self._anchors[body][0]
            lo[seg] = hi[seg] = base[seg]
            first_lo[seg] = first_hi[seg] = base[seg] - cfg.drift_gain * err / cfg.dt
        return (
            q_forces,
            np.concatenate([first_lo, *[lo] * (N - 1)]),
            np.concatenate([first_hi, *[hi] * (N - 1)]),
        )


class SoftStance(PredictionModel):
    """Soft-contact prediction with the forces tied to its linearized contact-force law."""

    name = "soft"

    @property
    def ns(self) -> int:
        return 3 * self.dynamics.points.count

    @property
    def force_cost(self) -> float:
        return 1e-6  # the force law fixes the forces

    def linearize(self, state: np.ndarray, ctrl: np.ndarray) -> Linearization:
        r"""Contact-free linearization with the soft-contact prediction (``A``, ``B``, drift
        ``c``) and its contact-force law.

        The force law :math:`f \approx \bar f + F_x \delta x + F_u \delta u` (per point,
        world frame, in weights) is differentiated forward in the tangent space.
        """
        dyn, p = self.dynamics, self.dynamics.problem
        nx, nu = p.nx, p.nu
        lin = dyn.contact_free(state, ctrl)
        A, B, drift = dyn.soft_step(state, ctrl)
        touching, _ = dyn.activity(state)
        fbar = dyn.point_forces(state, ctrl, touching)
        eps = 1e-6
        Fx = np.zeros((fbar.size, nx))
        Fu = np.zeros((fbar.size, nu))
        for i in range(nx):
            dx = np.zeros(nx)
            dx[i] = eps
            Fx[:, i] = (dyn.point_forces(p.state_add(state, dx), ctrl, touching) - fbar) / eps
        for i in range(nu):
            du = np.zeros(nu)
            du[i] = eps
            Fu[:, i] = (dyn.point_forces(state, ctrl + du, touching) - fbar) / eps
        return lin._replace(A=A, B=B, c=drift, fbar=fbar, Fx=Fx, Fu=Fu)

    def contact_pattern(self, layout: QPLayout) -> Pattern:
        N, nx, nu, ns = layout.horizon, layout.nx, layout.nu, layout.ns
        # -Bc on the force the soft model does not predict (the slack).
        out = [
            block_pattern(layout.r_dyn + i * nx, layout.s(i), 2 * layout.nv, layout.nf)
            for i in range(N)
        ]
        for i in range(N):  # f_i - F_x x_i - F_u u_i - s_i = fbar
            r0 = layout.r_st + i * ns
            out.append(diag_pattern(r0, layout.f(i), layout.nf))
            if i >= 1:
                out.append(block_pattern(r0, layout.x(i - 1), layout.nf, nx))
            out.append(block_pattern(r0, layout.u(i), layout.nf, nu))
            out.append(diag_pattern(r0, layout.s(i), ns))
        return out

    def contact_values(self, lin: Linearization, layout: QPLayout) -> np.ndarray:
        N, ns = layout.horizon, layout.ns
        first = [np.ones(ns), -lin.Fu.ravel(), -np.ones(ns)]
        later = [np.ones(ns), -lin.Fx.ravel(), -lin.Fu.ravel(), -np.ones(ns)]
        return np.concatenate([np.tile(-lin.Bc.ravel(), N), *first, *later * (N - 1)])

    def contact_bounds(
        self,
        lin: Linearization,
        x0: np.ndarray,
        kin: mujoco.MjData,
        active: np.ndarray,
        layout: QPLayout,
    ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        law = np.tile(lin.fbar, layout.horizon)
        law[: layout.ns] += lin.Fx @ x0
        lo, hi = law, law.copy()
        if self.config.lifted_force_law == "drop":  # see QPMPCConfig.lifted_force_law
            lifted = np.tile(np.repeat(~active, 3), layout.horizon)
            lo[lifted], hi[lifted] = -np.inf, np.inf
        return None, lo, hi


#: Prediction model class by ``QPMPCConfig.stance_model``.
PREDICTION_MODELS: dict[str, type[PredictionModel]] = {"soft": SoftStance, "rigid": RigidStance}
