r"""The backward pass's matrices, kept for passes whose dynamics and cost Hessians repeat.

With the dynamics linearized once (``linearization="reference"``) the blocks ``A_t``, ``B_t``
are the same in every backward pass of a solver. When the cost Hessians
:math:`\ell_{xx}, \ell_{uu}, \ell_{ux}` repeat too (costs whose residual Jacobians are
constant, or ``cost_hessian="reference"``), so does the whole quadratic part of the Riccati
recursion for a given :math:`\mu`: :math:`V_{xx,t}`, :math:`Q_{uu,t}`, :math:`Q_{ux,t}`, the
inverse of :math:`Q_{uu,t} + \mu I` and the gains :math:`K_t`. Only the gradients change from
pass to pass. A :class:`RiccatiChain` keeps those matrices, and
:func:`~mpcbox.controllers.ilqr.backward_pass.backward_pass` then runs each knot as a few
matrix-vector products, :math:`O(n^2)` instead of the :math:`O(n^3)` matrix products:

.. math::

    q = \begin{pmatrix} \ell_x \\ \ell_u \end{pmatrix} + F_t^T v, \quad
    k_t = -(Q_{uu,t} + \mu I)^{-1} q_u, \quad
    V_{x,t} = q_x + K_t^T (Q_{uu,t} k_t + q_u) + Q_{ux,t}^T k_t,

with :math:`v = V_{x,t+1}` (plus :math:`V_{xx,t+1} f_t` for a multiple-shooting defect).

A chain holds only knots where no control was clamped: at a knot whose unconstrained step
leaves the control box, :math:`K_t` and every earlier :math:`V_{xx}` depend on the clamped
set, so the pass goes on with the full recursion from there (starting from the chain's
:math:`V_{xx,t+1}`, which is exact) and the chain is not extended past it.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from mpcbox.core.problem import Quadratization
from mpcbox.validation import positive_int


class RiccatiChain:
    """The unclamped recursion's matrices of one ``(dynamics blocks, Hessians, mu)``.

    Knots ``lowest .. T - 1`` are filled; ``vxx[T]`` is the terminal Hessian.

    Attributes:
        vxx: :math:`V_{xx}` ``(T + 1, nx, nx)``.
        neg_inv: :math:`-(Q_{uu} + \\mu I)^{-1}` ``(T, nu, nu)``.
        quu: :math:`Q_{uu}` ``(T, nu, nu)``, unregularized.
        qux: :math:`Q_{ux}` ``(T, nu, nx)``.
        K: Gains ``(T, nu, nx)``.
        lowest: The first filled knot (``T``: none).
    """

    def __init__(self, blocks: object, quad: Quadratization, mu: float, nu: int) -> None:
        horizon = len(quad.lxx) - 1
        nx = quad.lxx.shape[1]
        self._key = (blocks, quad.lxx, quad.luu, quad.lux, float(mu))
        self.vxx = np.empty((horizon + 1, nx, nx))
        self.vxx[horizon] = quad.lxx[horizon]
        self.neg_inv = np.empty((horizon, nu, nu))
        self.quu = np.empty((horizon, nu, nu))
        self.qux = np.empty((horizon, nu, nx))
        self.K = np.empty((horizon, nu, nx))
        self.lowest = horizon

    def matches(self, blocks: object, quad: Quadratization, mu: float) -> bool:
        """Whether a pass over ``blocks`` and ``quad`` with ``mu`` repeats this chain's."""
        kb, klxx, kluu, klux, kmu = self._key
        if blocks is not kb or float(mu) != kmu:
            return False
        for mine, theirs in ((klxx, quad.lxx), (kluu, quad.luu), (klux, quad.lux)):
            if mine is not theirs and not np.array_equal(mine, theirs):
                return False
        return True


class RiccatiCache:
    """The chains of a solver, one per recent value of :math:`\\mu` (the schedule revisits a
    few values), the least recently used dropped first.

    Args:
        size: Chains kept.
    """

    def __init__(self, size: int = 4) -> None:
        self.size = positive_int("size", size)
        self._chains: OrderedDict[float, RiccatiChain] = OrderedDict()
        #: Backward passes that found a matching chain, and those that started one.
        self.hits = 0
        self.misses = 0

    def chain(self, blocks: object, quad: Quadratization, mu: float, nu: int) -> RiccatiChain:
        """The chain of ``(blocks, quad's Hessians, mu)``: the kept one if it matches, else a
        new empty one (replacing any kept for ``mu``)."""
        key = float(mu)
        found = self._chains.get(key)
        if found is not None and found.matches(blocks, quad, mu):
            self._chains.move_to_end(key)
            self.hits += 1
            return found
        self.misses += 1
        chain = RiccatiChain(blocks, quad, mu, nu)
        self._chains[key] = chain
        self._chains.move_to_end(key)
        while len(self._chains) > self.size:
            self._chains.popitem(last=False)
        return chain

    def clear(self) -> None:
        """Drop every chain."""
        self._chains.clear()


__all__ = ["RiccatiCache", "RiccatiChain"]
