r"""Where each block of variables and constraint rows sits in the QP.

The variables are, stage by stage within each block,

.. math:: z = (\delta x_1 \dots \delta x_N,\ \delta u_0 \dots \delta u_{N-1},\
    f_0 \dots f_{N-1},\ s_0 \dots s_{N-1})

(states ``nx``, controls ``nu``, forces ``nf = 3 k`` in body weights, stance slacks ``ns``
when the stance rows are soft), and the rows are the dynamics (``nx`` per stage), the stance
rows (``ns``), the friction pyramids (``k F``), the normal forces (``k``), the controls
(``nu``) and the joint limits (``nl``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class QPLayout(NamedTuple):
    """Sizes of the QP's blocks, and the offsets derived from them.

    Attributes:
        horizon: Number of stages ``N``.
        nx: State tangent size.
        nu: Number of controls.
        nv: Number of degrees of freedom.
        points: Number of contact points ``k``.
        facets: Facets ``F`` of each friction pyramid.
        ns: Stance rows per stage.
        slacks: Whether the stance rows have slack variables (``ns`` per stage).
        nl: Joint-limit rows per stage.
    """

    horizon: int
    nx: int
    nu: int
    nv: int
    points: int
    facets: int
    ns: int
    slacks: bool
    nl: int

    @property
    def nf(self) -> int:
        """Force variables per stage, ``3 k``."""
        return 3 * self.points

    @property
    def nsl(self) -> int:
        """Number of slack variables, ``N ns`` or 0."""
        return self.horizon * self.ns if self.slacks else 0

    # Columns.
    @property
    def ox(self) -> int:
        """Column of ``x_1``."""
        return 0

    @property
    def ou(self) -> int:
        """Column of ``u_0``."""
        return self.horizon * self.nx

    @property
    def of(self) -> int:
        """Column of ``f_0``."""
        return self.horizon * (self.nx + self.nu)

    @property
    def osl(self) -> int:
        """Column of ``s_0``."""
        return self.horizon * (self.nx + self.nu + self.nf)

    @property
    def nvar(self) -> int:
        """Number of variables."""
        return self.osl + self.nsl

    def x(self, i: int) -> int:
        """Column of ``x_{i+1}``."""
        return self.ox + i * self.nx

    def u(self, i: int) -> int:
        """Column of ``u_i``."""
        return self.ou + i * self.nu

    def f(self, i: int) -> int:
        """Column of ``f_i``."""
        return self.of + i * self.nf

    def s(self, i: int) -> int:
        """Column of ``s_i``."""
        return self.osl + i * self.ns

    # Rows.
    @property
    def r_dyn(self) -> int:
        """First dynamics row."""
        return 0

    @property
    def r_st(self) -> int:
        """First stance row."""
        return self.r_dyn + self.horizon * self.nx

    @property
    def r_fr(self) -> int:
        """First friction-pyramid row."""
        return self.r_st + self.horizon * self.ns

    @property
    def r_fn(self) -> int:
        """First normal-force row."""
        return self.r_fr + self.horizon * self.points * self.facets

    @property
    def r_u(self) -> int:
        """First control row."""
        return self.r_fn + self.horizon * self.points

    @property
    def r_lim(self) -> int:
        """First joint-limit row."""
        return self.r_u + self.horizon * self.nu

    @property
    def ncon(self) -> int:
        """Number of rows."""
        return self.r_lim + self.horizon * self.nl

    @property
    def variable_blocks(self) -> list[tuple[int, int]]:
        """``(offset, size per stage)`` of each variable block."""
        return [
            (self.ox, self.nx),
            (self.ou, self.nu),
            (self.of, self.nf),
            (self.osl, self.ns if self.slacks else 0),
        ]

    @property
    def first_stage_rows(self) -> np.ndarray:
        """Rows of the first stage (its dynamics, stance, friction, normal-force, control
        and joint-limit rows): those that bind the control applied now."""
        return np.concatenate([np.arange(o, o + n) for o, n in self.row_blocks])

    @property
    def row_blocks(self) -> list[tuple[int, int]]:
        """``(offset, size per stage)`` of each row block."""
        return [
            (self.r_dyn, self.nx),
            (self.r_st, self.ns),
            (self.r_fr, self.points * self.facets),
            (self.r_fn, self.points),
            (self.r_u, self.nu),
            (self.r_lim, self.nl),
        ]


def block_pattern(r0: int, c0: int, nr: int, nc: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of a dense ``(nr, nc)`` block at ``(r0, c0)``, row-major."""
    rr, cc = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
    return (r0 + rr).ravel(), (c0 + cc).ravel()


def diag_pattern(r0: int, c0: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of a diagonal of ``size`` entries starting at ``(r0, c0)``."""
    return r0 + np.arange(size), c0 + np.arange(size)
