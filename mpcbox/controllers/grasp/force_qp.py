r"""The grasp-force QP: finger forces in friction cones that hold an object.

Each finger touches the object at one point :math:`p_i` with inward unit normal :math:`n_i`
(from the finger into the object). Its force is written in the contact frame
:math:`R_i = [t_{1,i}\ t_{2,i}\ n_i]` (:func:`contact_frames`) as
:math:`c_i = (f_{t1}, f_{t2}, f_n)`, plus a moment :math:`\tau_i` about :math:`n_i`
(torsional friction of a soft finger). With the object's centre :math:`o` and the force and
moment :math:`(f^\star, m^\star)` the fingers must apply to it, the QP over
:math:`z = (c_1, \tau_1, \dots, c_k, \tau_k, e)` ``(4 k + 3,)`` is

.. math::

    \min_z \; \sum_i \big(w_n f_{n,i}^2 + w_t \lVert f_{t,i} \rVert^2 + w_\tau \tau_i^2\big)
        + w_m \lVert e \rVert^2

    \text{s.t.}\quad \sum_i R_i c_i = f^\star, \qquad
        \sum_i \big((p_i - o) \times R_i c_i + n_i \tau_i\big) - e = m^\star,

    G(\mu) c_i \le -\delta, \qquad |\tau_i| \le \mu_\tau f_{n,i}, \qquad
        f_{\min} \le f_{n,i} \le f_{\max},

with the friction pyramid :math:`G(\mu)` of :func:`~mpcbox.core.contact.friction_pyramid`
and a margin :math:`\delta \ge 0` (N) on every facet. The force balance is exact, the moment
balance soft (:math:`e` is its residual). Minimizing the normal forces puts them on the
cones: for two opposing fingers holding a weight :math:`m g` with the pyramid's first facet
along gravity, :math:`f_n = (m g / 2 + \delta) / \mu` each.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from mpcbox.controllers.qp_mpc.solvers import QPData, make_backend
from mpcbox.core.contact import friction_pyramid
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, non_negative, positive, positive_int

#: Weights of the objective: normal forces, tangential forces, torsional moments, and the
#: residual of the moment balance.
_W_NORMAL, _W_TANGENT, _W_TORSION, _W_MOMENT = 1.0, 1e-3, 1e-3, 1e4


class GraspForces(NamedTuple):
    """A solution of the grasp-force QP.

    Attributes:
        forces: World forces on the object, one per finger, ``(k, 3)`` (N).
        moments: Torsional moments about each normal ``(k,)`` (N m).
        local: The forces in their contact frames ``(k, 3)``: two tangential, then normal.
        frames: Contact frames ``(k, 3, 3)``, columns :math:`t_1, t_2, n`.
        moment_residual: :math:`e` ``(3,)``, the moment the forces leave unbalanced (N m).
        status: ``"solved"``, or the solver's status when it failed (forces then zero).
        iterations: Solver iterations.
    """

    forces: np.ndarray
    moments: np.ndarray
    local: np.ndarray
    frames: np.ndarray
    moment_residual: np.ndarray
    status: str
    iterations: int

    @property
    def normal(self) -> np.ndarray:
        """Normal force of each finger ``(k,)`` (N)."""
        return self.local[:, 2]

    @property
    def solved(self) -> bool:
        """Whether the QP was solved."""
        return self.status == "solved"


def contact_frames(normals: np.ndarray, up: np.ndarray | None = None) -> np.ndarray:
    r"""Contact frames ``(k, 3, 3)`` with columns :math:`t_1, t_2, n`.

    :math:`t_1` is ``up`` (default world ``z``) projected onto the tangent plane (world
    ``x`` when the normal is along ``up``), :math:`t_2 = n \times t_1`.

    Args:
        normals: Unit normals ``(k, 3)``.
        up: Direction ``(3,)`` that :math:`t_1` follows.
    """
    normals = as_array("normals", normals, (None, 3))
    norms = np.linalg.norm(normals, axis=1)
    if np.any(norms < 1e-9):
        raise InvalidArgumentError("normals must be non-zero vectors")
    normals = normals / norms[:, None]
    up = np.array([0.0, 0.0, 1.0]) if up is None else as_array("up", up, (3,))
    frames = np.zeros((len(normals), 3, 3))
    for i, n in enumerate(normals):
        t1 = up - (up @ n) * n
        if np.linalg.norm(t1) < 1e-6:
            t1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
        t1 /= np.linalg.norm(t1)
        frames[i] = np.column_stack([t1, np.cross(n, t1), n])
    return frames


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class GraspQP:
    """The grasp-force QP for ``fingers`` contacts, solved tick after tick on one backend.

    Args:
        fingers: Number of contacts ``k`` (one per finger).
        facets: Facets of the friction pyramid (even, >= 4).
        solver: QP backend name (``"osqp"`` or a ``qpsolvers`` backend).
    """

    def __init__(self, fingers: int, *, facets: int = 4, solver: str = "osqp") -> None:
        self.k = positive_int("fingers", fingers)
        friction_pyramid(1.0, facets)  # checks facets
        self.facets = int(facets)
        self.n = 4 * self.k + 3
        self.backend = make_backend(solver, {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iter": 4000})
        self._warm: tuple[np.ndarray, np.ndarray] | None = None
        rows = 6 + self.k * (self.facets + 3)
        self.m = rows
        # Every entry that any tick may fill, so that the sparsity pattern never changes.
        mask = np.zeros((rows, self.n), dtype=bool)
        mask[:6, : 4 * self.k] = True
        mask[3:6, 4 * self.k :] = np.eye(3, dtype=bool)
        r = 6
        for i in range(self.k):
            c = 4 * i
            mask[r : r + self.facets, c : c + 3] = True
            mask[r + self.facets : r + self.facets + 2, [c + 2, c + 3]] = True
            mask[r + self.facets + 2, c + 2] = True
            r += self.facets + 3
        cols, rws = np.nonzero(mask.T)
        self._rows, self._cols = rws, cols
        indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=0))])
        self._indices, self._indptr = rws.astype(np.int32), indptr.astype(np.int32)
        diag = np.tile([_W_TANGENT, _W_TANGENT, _W_NORMAL, _W_TORSION], self.k)
        self._P = sp.csc_matrix(2.0 * sp.diags(np.concatenate([diag, np.full(3, _W_MOMENT)])))

    def reset(self) -> None:
        """Forget the warm start."""
        self._warm = None

    def solve(
        self,
        positions: np.ndarray,
        normals: np.ndarray,
        center: np.ndarray,
        force: np.ndarray,
        moment: np.ndarray,
        *,
        friction: float,
        torsion: float,
        margin: float = 0.0,
        f_min: float = 0.0,
        f_max: float = np.inf,
    ) -> GraspForces:
        r"""Solve for the finger forces (see the module docstring).

        Args:
            positions: Contact points :math:`p_i` ``(k, 3)`` (m).
            normals: Inward normals :math:`n_i` ``(k, 3)``.
            center: The object's centre :math:`o` ``(3,)``: where ``moment`` is taken.
            force: :math:`f^\star` ``(3,)`` (N): what the fingers must push on the object
                with, e.g. :math:`m (a - g)` for acceleration :math:`a`.
            moment: :math:`m^\star` ``(3,)`` (N m) about ``center``.
            friction: :math:`\mu` of the pyramid (> 0).
            torsion: :math:`\mu_\tau` (m, >= 0).
            margin: :math:`\delta` (N, >= 0).
            f_min: Least normal force (N, >= 0).
            f_max: Largest normal force (N, > ``f_min``).

        Returns:
            The :class:`GraspForces`.

        Raises:
            InvalidArgumentError: On shapes or values outside those ranges.
        """
        k = self.k
        positions = as_array("positions", positions, (k, 3))
        frames = contact_frames(as_array("normals", normals, (k, 3)))
        center = as_array("center", center, (3,))
        force = as_array("force", force, (3,))
        moment = as_array("moment", moment, (3,))
        g = friction_pyramid(positive("friction", friction), self.facets)
        torsion = non_negative("torsion", torsion)
        margin = non_negative("margin", margin)
        f_min = non_negative("f_min", f_min)
        if not f_max > f_min:
            raise InvalidArgumentError(f"f_max must exceed f_min = {f_min}, got {f_max!r}")
        dense = np.zeros((self.m, self.n))
        low = np.full(self.m, -np.inf)
        up = np.zeros(self.m)
        low[:3], up[:3] = force, force
        low[3:6], up[3:6] = moment, moment
        dense[3:6, 4 * k :] = -np.eye(3)
        r = 6
        for i in range(k):
            c = 4 * i
            frame = frames[i]
            dense[:3, c : c + 3] = frame
            dense[3:6, c : c + 3] = _skew(positions[i] - center) @ frame
            dense[3:6, c + 3] = frame[:, 2]
            dense[r : r + self.facets, c : c + 3] = g
            up[r : r + self.facets] = -margin
            dense[r + self.facets, [c + 2, c + 3]] = (-torsion, 1.0)
            dense[r + self.facets + 1, [c + 2, c + 3]] = (-torsion, -1.0)
            dense[r + self.facets + 2, c + 2] = 1.0
            low[r + self.facets + 2], up[r + self.facets + 2] = f_min, f_max
            r += self.facets + 3
        A = sp.csc_matrix(
            (dense[self._rows, self._cols], self._indices, self._indptr), shape=dense.shape
        )
        qp = QPData(self._P, np.zeros(self.n), A, low, up)
        sol = self.backend.solve(qp, True, self._warm)
        if sol.x is None:
            self._warm = None
            zeros = np.zeros((k, 3))
            return GraspForces(zeros, np.zeros(k), zeros, frames, np.zeros(3), sol.status, 0)
        if sol.y is not None:
            self._warm = (sol.x, sol.y)
        z = sol.x
        local = z[: 4 * k].reshape(k, 4)
        forces = np.einsum("kij,kj->ki", frames, local[:, :3])
        return GraspForces(
            forces,
            local[:, 3].copy(),
            local[:, :3].copy(),
            frames,
            z[4 * k :].copy(),
            "solved",
            sol.iterations,
        )
