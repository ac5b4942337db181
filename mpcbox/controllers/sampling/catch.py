r"""An LQR that catches the state inside its basin, in every rollout and in the loop.

Sampling MPC plans open-loop control splines. On a plant that is unstable at its goal (an
acrobot or a cart-pole upright) an open-loop rollout leaves the goal at the unstable
eigenvalues' rate, so a long horizon almost never shows a plan that stays there, and the
planner cannot tell a state from which the goal can be held from one it merely passes
through. With a catch, the controls of a rollout are

.. math::
    u_t = \begin{cases} u_0 - K (x_t \ominus x_0) & \text{if } V(x_t) < c \\
    u^n_t & \text{otherwise} \end{cases},
    \qquad V(x) = (x \ominus x_0)^T P (x \ominus x_0),

with the infinite-horizon LQR :math:`K, P` of the planning model at the Problem's reference
:math:`(x_0, u_0)` (hinges without a range wrapped to the nearest whole turn; the weights of
the task's ``"lqr"`` config when it has one, as :func:`mpcbox.make_controller` would build
it, else its cost's) and the level
:math:`c` of an estimated basin of attraction; the closed loop applies the same rule to the
measured state at every controller call (with the LQR designed for that call period). A
sample that reaches the basin is then held for the rest of its horizon and scored so.

The level, when not given, is estimated by simulation (:func:`basin_level`): for levels
:math:`c_i = 4^i c_{\mathrm{lin}}` from the largest level set on which the LQR's controls
stay inside the control range, :math:`c_{\mathrm{lin}} = \min_j r_j^2 / (K_j P^{-1} K_j^T)`
(:math:`r_j` the half-width of control ``j``'s range about :math:`u_{0,j}`), it draws states
uniformly inside :math:`V < c_i` and simulates the saturated LQR on the planning model; the
largest level from which every draw converges (:math:`V` below :math:`10^{-3} c_i`) is kept,
refined by three geometric bisections toward the first level that failed.
A sampled estimate, not a certificate.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mpcbox.controllers.lqr import LQR, LQRConfig, hold_steps, nearest_psd
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, NotStabilizableError

#: Levels tried by :func:`basin_level`: ``c_lin`` times ``4 ** i`` for these ``i``.
LEVEL_POWERS = range(0, 13)
#: Geometric bisections between the last level passed and the first failed.
BISECTIONS = 3


class LQRCatch:
    """The reference's LQR as a catch for a sampling controller's rollouts and loop.

    Args:
        problem: The sampling controller's planning Problem (its planning timestep is the
            rollouts' step).
        period: Seconds between the closed loop's controller calls: the loop's LQR holds its
            control that long (a multiple of the planning step, or a copy of the Problem at
            that step is used).
        level: The basin level :math:`c` (``None``: :func:`basin_level`).
        lqr: The LQR's options (its weights, operating point); ``wrap`` is always on and
            ``period`` is set here. Default: :class:`~mpcbox.controllers.lqr.LQRConfig`'s,
            the Gauss-Newton Hessian of the Problem's cost at the reference.
        samples: States drawn per level by :func:`basin_level`.
        seed: Seed of those draws.

    Attributes:
        rollout_lqr: The LQR at the planning step (its :math:`P` defines :math:`V`).
        loop_lqr: The LQR at the loop's call period.
        level: The basin level :math:`c`.
    """

    def __init__(
        self,
        problem: Problem,
        period: float,
        level: float | None = None,
        *,
        lqr: LQRConfig | None = None,
        samples: int = 256,
        seed: int = 0,
    ) -> None:
        self.problem = problem
        base = replace(lqr or LQRConfig(), wrap=True, period=None)
        self.rollout_lqr = LQR(problem, base)
        self.P = nearest_psd(self.rollout_lqr.P)
        self.loop_lqr = _loop_lqr(problem, period, base)
        self.level = (
            basin_level(problem, self.rollout_lqr, samples=samples, seed=seed)
            if level is None
            else float(level)
        )

    def deviation(self, states: np.ndarray) -> np.ndarray:
        """Tangent deviations ``(..., nx)`` of states ``(..., nstate)`` from the reference,
        unlimited hinges wrapped to ``[-pi, pi)`` (:meth:`LQR.deviation
        <mpcbox.controllers.lqr.LQR.deviation>`)."""
        return self.rollout_lqr.deviation(states)

    def value(self, states: np.ndarray) -> np.ndarray:
        """:math:`V` of states ``(..., nstate)``: shape ``(...)``, NaN for NaN states."""
        return _value(self.rollout_lqr, self.P, states)

    def engaged(self, states: np.ndarray) -> np.ndarray:
        """Whether each state ``(..., nstate)`` is inside the basin, :math:`V < c`."""
        with np.errstate(invalid="ignore"):
            return self.value(states) < self.level

    def policy(self, states: np.ndarray, ctrls: np.ndarray) -> np.ndarray:
        """Rollout controls ``(B, nu)``: the LQR's where engaged, ``ctrls`` elsewhere."""
        out = np.array(ctrls, dtype=np.float64)
        inside = self.engaged(states)
        if inside.any():
            lqr = self.rollout_lqr
            dx = self.deviation(states[inside])
            out[inside] = self.problem.clip_ctrl(lqr.ctrl0 - dx @ lqr.K.T)
        return out

    def control(self, state: np.ndarray) -> np.ndarray | None:
        """The loop LQR's control ``(nu,)`` for a measured state inside the basin, else
        ``None``."""
        if not self.engaged(state):
            return None
        lqr = self.loop_lqr
        return self.problem.clip_ctrl(lqr.ctrl0 - lqr.K @ self.deviation(state))


def _loop_lqr(problem: Problem, period: float, config: LQRConfig) -> LQR:
    """The LQR for controls held ``period`` seconds: on ``problem`` when ``period`` is a
    multiple of its step, else on a copy whose planning step is ``period``."""
    try:
        hold_steps(period, problem.dt)
    except InvalidArgumentError:
        return LQR(problem.with_planning_timestep(period), config)
    return LQR(problem, replace(config, period=period))


def linear_level(lqr: LQR, problem: Problem) -> float:
    r""":math:`c_{\mathrm{lin}}`: the largest :math:`c` with :math:`|K_j dx| \le r_j` on all of
    :math:`dx^T P dx \le c` (:math:`r_j` the distance from :math:`u_{0,j}` to the nearer end
    of control ``j``'s range; controls without a range are left out)."""
    P = nearest_psd(lqr.P)
    Pinv = np.linalg.pinv(P)
    low = np.where(np.isfinite(problem.ctrl_low), lqr.ctrl0 - problem.ctrl_low, np.inf)
    high = np.where(np.isfinite(problem.ctrl_high), problem.ctrl_high - lqr.ctrl0, np.inf)
    room = np.minimum(low, high)
    reach = np.einsum("ji,ik,jk->j", lqr.K, Pinv, lqr.K)
    ratios = [r**2 / g for r, g in zip(room, reach, strict=True) if np.isfinite(r) and g > 0]
    if not ratios:
        return float(np.trace(P))
    return float(max(min(ratios), 1e-12))


def basin_level(
    problem: Problem,
    lqr: LQR,
    *,
    samples: int = 256,
    seed: int = 0,
    seconds: float | None = None,
) -> float:
    """Estimate the LQR's basin level :math:`c` by simulation (see the module docstring).

    Args:
        problem: The Problem whose planning model is simulated.
        lqr: Its LQR at the planning step.
        samples: States drawn per level.
        seed: Seed of the draws.
        seconds: Simulated time per draw (default: ten times the slowest closed-loop time
            constant, within 1-10 s).

    Returns:
        The largest level tried from which every draw converged.

    Raises:
        NotStabilizableError: If draws fail to converge even at :math:`c_{\\mathrm{lin}}`.
    """
    dt = problem.dt
    if seconds is None:
        slowest = float(np.max(np.abs(lqr.closed_loop_eigenvalues)))
        tau = dt / max(-np.log(min(slowest, 1.0 - 1e-9)), 1e-9)
        seconds = float(np.clip(10.0 * tau, 1.0, 10.0))
    steps = max(1, round(seconds / dt))
    P = nearest_psd(lqr.P)
    w, v = np.linalg.eigh(P)
    keep = w > 1e-12 * max(float(w.max()), 1e-300)
    root = v[:, keep] / np.sqrt(w[keep])  # dx = root @ z has dx^T P dx = |z|^2
    rng = np.random.default_rng(seed)
    zeros = np.tile(lqr.ctrl0, (samples, steps, 1))

    def saturated(states: np.ndarray, ctrls: np.ndarray) -> np.ndarray:
        """The LQR everywhere, clipped to the control range."""
        return problem.clip_ctrl(lqr.ctrl0 - lqr.deviation(states) @ lqr.K.T)

    def converges(level: float) -> bool:
        z = rng.standard_normal((samples, root.shape[1]))
        z *= (rng.uniform(size=(samples, 1)) ** (1.0 / z.shape[1])) / np.linalg.norm(
            z, axis=1, keepdims=True
        )
        starts = np.stack([problem.state_add(lqr.state0, root @ (np.sqrt(level) * zi)) for zi in z])
        roll = problem.dynamics.rollout_policy(starts, zeros, saturated)
        return bool(np.all(_value(lqr, P, roll.states[:, -1]) < 1e-3 * level))

    base = linear_level(lqr, problem)
    best, failed = None, None
    for power in LEVEL_POWERS:
        if not converges(base * 4.0**power):
            failed = base * 4.0**power
            break
        best = base * 4.0**power
    if best is not None and failed is not None:
        for _ in range(BISECTIONS):  # geometric bisection between the last pass and fail
            mid = float(np.sqrt(best * failed))
            best, failed = (mid, failed) if converges(mid) else (best, mid)
    if best is None:
        raise NotStabilizableError(
            f"the LQR at the reference does not bring {samples} states from its linear "
            f"region (V < {base:.3g}) back within {seconds:.3g} s: no basin to catch in"
        )
    return best


def _value(lqr: LQR, P: np.ndarray, states: np.ndarray) -> np.ndarray:
    """:math:`V` ``(...)`` of states ``(..., nstate)`` for ``lqr`` with the value matrix
    ``P``."""
    dx = lqr.deviation(states)
    return np.einsum("...i,ij,...j->...", dx, P, dx)


__all__ = ["LQRCatch", "basin_level", "linear_level"]
