r"""Control splines: a few knots over the horizon, interpolated to every planning step.

A sampling controller searches over ``K`` knots :math:`u_0, \dots, u_{K-1}` (each of size
``nu``) placed uniformly over the horizon, :math:`t_k = k h` with :math:`h = H / (K - 1)`.
The control at time :math:`t \in [0, H]` is a fixed linear combination of the knots, so for
a set of query times the whole map is one weight matrix :math:`W` of shape ``(T, K)``:

.. math:: u(t_j) = \sum_k W_{jk} u_k .

Four schemes (with :math:`s = (t - t_i) / h \in [0, 1)` inside interval ``i``):

* ``"zero"`` (zero-order hold): :math:`u(t) = u_i`.
* ``"linear"``: :math:`u(t) = (1 - s) u_i + s u_{i+1}`.
* ``"cubic"`` (cubic Hermite with finite-difference slopes):
  :math:`u(t) = h_{00}(s) u_i + h_{10}(s) h m_i + h_{01}(s) u_{i+1} + h_{11}(s) h m_{i+1}`,
  with :math:`h_{00} = 2s^3 - 3s^2 + 1`, :math:`h_{10} = s^3 - 2s^2 + s`,
  :math:`h_{01} = -2s^3 + 3s^2`, :math:`h_{11} = s^3 - s^2`, and slopes
  :math:`m_i = (u_{i+1} - u_{i-1}) / 2h` inside, :math:`m_0 = (-3u_0 + 4u_1 - u_2) / 2h` and
  :math:`m_{K-1} = (3u_{K-1} - 4u_{K-2} + u_{K-3}) / 2h` at the ends. The slopes are exact for
  quadratics, so the spline reproduces any quadratic exactly; with two knots it is linear.
  It is C1 (continuous slope) but its second derivative jumps at the knots.
* ``"cubic_c2"`` (natural cubic spline, C2): with the second derivatives :math:`M_k` at the
  knots solving :math:`M_{i-1} + 4 M_i + M_{i+1} = 6 (u_{i-1} - 2 u_i + u_{i+1}) / h^2` for
  :math:`0 < i < K - 1` and :math:`M_0 = M_{K-1} = 0`,
  :math:`u(t) = (1 - s) u_i + s u_{i+1} + \tfrac{h^2}{6} \big(((1 - s)^3 - (1 - s)) M_i
  + (s^3 - s) M_{i+1}\big)`. Value, slope and curvature are continuous at every knot; every
  knot moves the whole curve a little (the weight matrix is dense). With two knots it is
  linear.

Times outside ``[0, H]`` are clamped (the first/last knot is held).

A warm start moves the spline ``e`` seconds on. :meth:`Spline.shift` re-evaluates it at the
shifted knot times, :math:`\tilde u_k = u(t_k + e)`: exact for a zero-order hold only when
``e`` is a multiple of :math:`h` (otherwise every switch comes ``e`` late), and for the other
schemes a new interpolant of those samples, not the old curve. :meth:`Spline.refit` instead
fits the old curve by least squares over query times :math:`\tau_j` (the planning steps),

.. math:: U' = \tilde U + W(\tau)^+ \big( W(\tau + e)\, U - W(\tau)\, \tilde U \big),

the spline closest to the rest of the old plan on the steps a rollout applies (:math:`^+`:
the pseudo-inverse); of several such fits (a knot no step uses, such as a zero-order hold's
last), the one closest to the resampled knots :math:`\tilde U`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from mpcbox.validation import one_of, positive, positive_int

Interpolation = Literal["zero", "linear", "cubic", "cubic_c2"]
INTERPOLATIONS: tuple[str, ...] = ("zero", "linear", "cubic", "cubic_c2")


class Spline:
    """Uniform knots over ``[0, duration]`` with one interpolation scheme.

    Args:
        num_knots: Number of knots ``K`` (>= 1; one knot is a constant control).
        duration: Horizon ``H`` in seconds.
        kind: ``"zero"``, ``"linear"``, ``"cubic"`` or ``"cubic_c2"``.
    """

    def __init__(self, num_knots: int, duration: float, kind: Interpolation = "cubic") -> None:
        self.num_knots = positive_int("num_knots", num_knots)
        self.duration = positive("horizon", duration)
        self.kind = one_of("interpolation", kind, INTERPOLATIONS)
        k = self.num_knots
        self.spacing = self.duration / (k - 1) if k > 1 else self.duration
        #: Knot times ``(K,)``.
        self.knot_times = np.linspace(0.0, self.duration, k) if k > 1 else np.zeros(1)

    def weights(self, times: np.ndarray) -> np.ndarray:
        """Interpolation matrix ``W`` of shape ``(len(times), K)``: ``u(times) = W @ knots``."""
        times = np.clip(np.asarray(times, dtype=np.float64).reshape(-1), 0.0, self.duration)
        k = self.num_knots
        out = np.zeros((times.size, k))
        if k == 1:
            out[:, 0] = 1.0
            return out
        h = self.spacing
        x = times / h
        i = np.minimum(np.floor(x).astype(int), k - 2)
        s = x - i
        rows = np.arange(times.size)
        if self.kind == "zero":
            # Hold knot i on [t_i, t_{i+1}); the end time itself takes the last knot.
            idx = np.where(s >= 1.0 - 1e-12, i + 1, i)
            out[rows, idx] = 1.0
            return out
        if self.kind == "linear" or k == 2:
            out[rows, i] += 1.0 - s
            out[rows, i + 1] += s
            return out
        if self.kind == "cubic_c2":
            curv = self._curvature_matrix()  # (K, K): M = curv @ u
            out[rows, i] += 1.0 - s
            out[rows, i + 1] += s
            a = h * h / 6.0 * ((1.0 - s) ** 3 - (1.0 - s))
            b = h * h / 6.0 * (s**3 - s)
            out += a[:, None] * curv[i] + b[:, None] * curv[i + 1]
            return out
        h00 = 2 * s**3 - 3 * s**2 + 1
        h10 = s**3 - 2 * s**2 + s
        h01 = -2 * s**3 + 3 * s**2
        h11 = s**3 - s**2
        slope = self._slope_matrix()  # (K, K): h * m = slope @ u
        out[rows, i] += h00
        out[rows, i + 1] += h01
        out += h10[:, None] * slope[i] + h11[:, None] * slope[i + 1]
        return out

    def _curvature_matrix(self) -> np.ndarray:
        """``C`` with ``M_i = sum_j C_ij u_j``: the natural spline's knot second derivatives."""
        k, h = self.num_knots, self.spacing
        system = np.eye(k)
        rhs = np.zeros((k, k))
        for j in range(1, k - 1):
            system[j, j - 1 : j + 2] = [1.0, 4.0, 1.0]
            rhs[j, j - 1 : j + 2] = np.array([1.0, -2.0, 1.0]) * 6.0 / (h * h)
        return np.linalg.solve(system, rhs)

    def _slope_matrix(self) -> np.ndarray:
        """``S`` with ``h m_i = sum_j S_ij u_j`` (finite-difference slopes times spacing)."""
        k = self.num_knots
        slope = np.zeros((k, k))
        slope[0, :3] = [-1.5, 2.0, -0.5]
        slope[-1, -3:] = [0.5, -2.0, 1.5]
        for j in range(1, k - 1):
            slope[j, j - 1] = -0.5
            slope[j, j + 1] = 0.5
        return slope

    def evaluate(self, knots: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Controls at ``times``.

        Args:
            knots: Knot values ``(..., K, nu)``.
            times: Query times ``(T,)`` in seconds from the start of the horizon.

        Returns:
            Controls ``(..., T, nu)``.
        """
        return np.einsum("tk,...kj->...tj", self.weights(times), knots)

    def shift(self, knots: np.ndarray, elapsed: float) -> np.ndarray:
        """Warm start: the knots of this spline re-evaluated ``elapsed`` seconds later.

        Args:
            knots: Knot values ``(..., K, nu)``.
            elapsed: Seconds since ``knots`` were planned.

        Returns:
            Knots ``(..., K, nu)`` at times ``t_k + elapsed`` (the last knot is held beyond ``H``).
        """
        return self.evaluate(knots, self.knot_times + float(elapsed))

    def refit(self, knots: np.ndarray, elapsed: float, times: np.ndarray) -> np.ndarray:
        """Warm start by least squares: knots whose spline at ``times`` best matches the old
        spline at ``times + elapsed`` (see the module docstring).

        Args:
            knots: Knot values ``(..., K, nu)``.
            elapsed: Seconds since ``knots`` were planned.
            times: Query times ``(T,)`` the fit is made on, typically the planning steps
                ``t dt``. Knots the times do not determine keep their resampled values.

        Returns:
            Knots ``(..., K, nu)``.
        """
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        resampled = self.shift(knots, elapsed)
        now = self.weights(times)
        residual = np.einsum("tk,...kj->...tj", self.weights(times + float(elapsed)), knots)
        residual -= np.einsum("tk,...kj->...tj", now, resampled)
        return resampled + np.einsum("kt,...tj->...kj", np.linalg.pinv(now), residual)
