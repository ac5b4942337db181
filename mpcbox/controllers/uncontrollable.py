r"""Uncontrollable modes on the unit circle, and the projector that takes them out of a cost.

A floating robot standing on a flat floor can be moved sideways or turned about the
vertical as a whole and is again at rest: linearized at rest, those motions are modes of
:math:`A` with eigenvalue exactly 1 that no control reaches (:math:`w^H B = 0` for their
left eigenvectors :math:`w`). A cost that weighs them (the center of mass over a
world-fixed support point, the root's horizontal drift) asks the Riccati equation for
something no gain can do: its solution grows without bound along them (to 1e10 and more),
which leaves the gain alone but ruins every use of the value matrix as a cost (a QP's
terminal cost, a basin estimate).

For a semisimple eigenvalue :math:`\lambda` with right and left eigenvectors
:math:`V, W` (``(n, k)``, :math:`W^H A = \lambda W^H`), the unit left eigenvectors that the
inputs barely reach, :math:`L` (orthonormal, :math:`\|L^H B\| \le` a tolerance, ``B``'s
columns scaled to unit length), give coordinates :math:`\zeta = L^H x` with
:math:`\zeta^+ = \lambda \zeta`: no control moves them. Then

.. math::
    \Pi_u = V X L^H, \qquad L^H V X = I ,

projects a state onto those motions along an :math:`A`-invariant complement that contains
the range of :math:`B`: :math:`\Pi_u A = A \Pi_u = \lambda \Pi_u` and
:math:`\Pi_u B = 0`. The part :math:`(I - \Pi_u) x` is what a controller can act on;
weighing it alone, :math:`Q \mapsto (I - \Pi_u)^T Q (I - \Pi_u)`, keeps the Riccati
solution finite and changes nothing that a control could change.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

#: Eigenvalues closer than this are treated as one (repeated) eigenvalue.
_CLUSTER = 1e-6

#: Input gain :math:`\|w^H B\|` (``w`` of unit length, ``B``'s columns scaled to unit length)
#: below which a mode on the unit circle counts as uncontrollable (and is left out of the
#: LQR's cost). Finite-difference Jacobians put up to 2e-5 of noise on the motions that no
#: input reaches (a standing robot slid or turned as a whole: Unitree's H1, PAL's Talos),
#: where every real motion of the robots measured (H1, Talos, Go2, G1, Cassie) had 1e-3 or
#: more.
INPUT_GAIN_TOL = 1e-4

#: The same off the unit circle, where "uncontrollable" means no stabilizing gain exists
#: (:class:`~mpcbox.errors.NotStabilizableError`): only a gain at rounding level counts. A
#: generic Problem of Unitree's A1 at its keyframe (not an equilibrium) drifts sideways at
#: eigenvalues up to 1.0007 with gains of 7e-5, which the LQR still stabilizes.
UNSTABLE_GAIN_TOL = 1e-8

#: Relative tolerance of the PBH rank test, used for defective eigenvalues.
PBH_TOL = 1e-8

#: Largest condition number of a repeated eigenvalue's eigenvectors (right and left) for
#: which it counts as semisimple; above it it is defective (a Jordan block: a double
#: integrator, such as a joint driven by a motor, gives two parallel eigenvectors), has no
#: projector, and only the PBH test applies.
_MAX_CONDITION = 1e6


def unit_columns(B: np.ndarray) -> np.ndarray:
    """``B`` ``(n, m)`` with each nonzero column scaled to unit length (controllability tests
    do not depend on how each input is scaled, and so should their tolerances not)."""
    norms = np.linalg.norm(B, axis=0)
    return B / np.where(norms > 0.0, norms, 1.0)


def _clusters(values: np.ndarray) -> list[np.ndarray]:
    """Index groups of eigenvalues within :data:`_CLUSTER` of each other."""
    groups: list[list[int]] = []
    for i, lam in enumerate(values):
        for group in groups:
            if abs(values[group[0]] - lam) <= _CLUSTER:
                group.append(i)
                break
        else:
            groups.append([i])
    return [np.array(g) for g in groups]


class UncontrollableMode(NamedTuple):
    r"""Uncontrollable directions of one (possibly repeated) eigenvalue of ``A``.

    Attributes:
        eigenvalue: The eigenvalue.
        projector: :math:`\Pi_u` ``(n, n)`` onto those directions (complex; see the module),
            or ``None`` for a defective eigenvalue found by the PBH rank test whose
            generalized eigenspace inputs partly reach (no projector leaves it out).
    """

    eigenvalue: complex
    projector: np.ndarray | None


def uncontrollable_modes(
    A: np.ndarray,
    B: np.ndarray,
    tol: float = INPUT_GAIN_TOL,
    margin: float = 1e-6,
    unstable_tol: float = UNSTABLE_GAIN_TOL,
) -> list[UncontrollableMode]:
    r"""Uncontrollable modes of ``A`` with :math:`|\lambda| \ge 1 -` ``margin``.

    Eigenvalues within :data:`_CLUSTER` of each other are one repeated eigenvalue. For a
    semisimple one the test is on its left eigenspace :math:`W` (orthonormalized): the
    unit left eigenvectors :math:`w` with :math:`\|w^H B\| \le` ``tol`` (``B``'s columns
    scaled to unit length; ``unstable_tol`` off the unit circle) are uncontrollable. This is
    what the PBH rank test asks, without its blind spot: the smallest singular value of
    :math:`[A - \lambda I,\ B]` is also small when other eigenvalues are near
    :math:`\lambda` (a robot at rest has dozens within 1e-4 of 1), which made well-controlled
    modes look uncontrollable. A defective eigenvalue (a Jordan block) falls back to the PBH
    test, at :data:`PBH_TOL` times :math:`\max(1, \|A\|_2, \|B\|_2)`.

    Args:
        A: State matrix ``(n, n)``.
        B: Input matrix ``(n, m)``.
        tol: Input gain below which a unit left eigenvector on the unit circle is
            uncontrollable.
        margin: Modes with :math:`|\lambda| < 1 -` ``margin`` are not examined; those
            within ``margin`` of the unit circle are on it.
        unstable_tol: The same for modes with :math:`|\lambda| > 1 +` ``margin``.
    """
    B = unit_columns(B)
    values, left, right = scipy.linalg.eig(A, left=True, right=True)
    outside = np.flatnonzero(np.abs(values) >= 1.0 - margin)
    n = A.shape[0]
    scale = max(1.0, float(np.linalg.norm(A, 2)), float(np.linalg.norm(B, 2)))
    modes = []
    for group in _clusters(values[outside]):
        idx = outside[group]
        lam = complex(values[idx[0]])
        V, W = right[:, idx], left[:, idx]
        if max(np.linalg.cond(V), np.linalg.cond(W)) > _MAX_CONDITION:
            pbh = np.hstack([A - lam * np.eye(n), B])
            if np.linalg.svd(pbh, compute_uv=False)[-1] <= PBH_TOL * scale:
                modes.append(UncontrollableMode(lam, _block_projector(A, B, lam, len(idx), tol)))
            continue
        # Left eigenvectors of unit length that the (unit-column) input barely moves.
        Wo = np.linalg.qr(W)[0]
        U, sv, _ = np.linalg.svd(Wo.conj().T @ B, full_matrices=True)
        rank = int(np.sum(sv > (tol if abs(lam) <= 1.0 + margin else unstable_tol)))
        L = Wo @ U[:, rank:]
        if L.shape[1]:
            # The part of the state those coordinates see, in the eigenspace: V X L^H with
            # L^H V X = I.
            modes.append(UncontrollableMode(lam, V @ np.linalg.pinv(L.conj().T @ V) @ L.conj().T))
    return modes


def _block_projector(
    A: np.ndarray, B: np.ndarray, lam: complex, k: int, tol: float
) -> np.ndarray | None:
    r"""The spectral projector onto a defective eigenvalue's generalized eigenspace when no
    input reaches any of it, else ``None``.

    A joint that turns freely with neither stiffness nor damping and no actuator (a body
    spinning about an axis no motor drives) is a Jordan block at :math:`\lambda = 1`: its
    angle and rate. With :math:`R, L` ``(n, k)`` orthonormal bases of the right and left
    generalized eigenspaces (the null spaces of :math:`(A - \lambda I)^k` and of its
    conjugate transpose), the coordinates :math:`L^H x` evolve on their own when
    :math:`\|L^H B\| \le` ``tol``, and :math:`\Pi_u = R (L^H R)^{-1} L^H` projects along
    the invariant complement, which holds the range of :math:`B`.
    """
    n = A.shape[0]
    power = np.linalg.matrix_power(A - lam * np.eye(n), k)
    U, _, Vh = np.linalg.svd(power)
    R, L = Vh[n - k :].conj().T, U[:, n - k :]
    if np.linalg.norm(L.conj().T @ B, 2) > tol:
        return None  # part of the block is reached: only the PBH test's verdict stands
    LR = L.conj().T @ R
    if np.linalg.cond(LR) > _MAX_CONDITION:
        return None
    return R @ np.linalg.solve(LR, L.conj().T)


def marginal_projector(modes: list[UncontrollableMode], margin: float = 1e-6) -> np.ndarray | None:
    r"""The projector :math:`\Pi_u` ``(n, n)`` onto those of ``modes`` (from
    :func:`uncontrollable_modes`) with :math:`\bigl||\lambda| - 1\bigr| \le` ``margin``, or
    ``None`` when there are none (a defective one that inputs partly reach has no projector
    and is left out)."""
    parts = [
        mode.projector
        for mode in modes
        if mode.projector is not None and abs(abs(mode.eigenvalue) - 1.0) <= margin
    ]
    if not parts:
        return None
    return np.sum(parts, axis=0).real


def uncontrollable_marginal_projector(
    A: np.ndarray, B: np.ndarray, tol: float = INPUT_GAIN_TOL, margin: float = 1e-6
) -> np.ndarray | None:
    r"""The projector :math:`\Pi_u` ``(n, n)`` onto the uncontrollable modes of ``(A, B)`` on
    the unit circle (see the module, :func:`uncontrollable_modes` and
    :func:`marginal_projector`), or ``None`` when there are none."""
    return marginal_projector(uncontrollable_modes(A, B, tol, margin), margin)
