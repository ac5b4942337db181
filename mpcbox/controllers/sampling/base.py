r"""The base class of the sampling controllers.

Every control tick, from the measured state :math:`x`:

1. warm start: the previous nominal spline is re-evaluated at its knot times shifted by the
   time elapsed since it was planned (:meth:`Spline.shift`);
2. for each iteration, the algorithm draws candidate knots ``(N, K, nu)`` (:meth:`sample`),
   which are clamped to the control range; the backend interpolates them to ``T`` planning
   steps, rolls them out from :math:`x` (on ``M`` randomized models when asked) and scores
   them with the Problem's cost,

   .. math:: J_n = \sum_{t=0}^{T-1} \ell(x^n_t, u^n_t) + \ell_T(x^n_T);

   samples whose rollout overflowed the backend's contact capacity or produced non-finite
   numbers get :math:`J_n = +\infty` (excluded) and are counted; the algorithm then refits
   the nominal knots (:meth:`update`);
3. the control returned is the nominal spline at the start of the horizon. With
   ``replan_period`` (and the controller called every simulation step, ``period=None``),
   calls between replans return the nominal spline at the elapsed time instead.

The backend may compute asynchronously (``submit``/``collect``, the warp backend): the
noise of the next iteration is then drawn while the device works.

Subclasses implement only :meth:`sample` and :meth:`update`.
"""

from __future__ import annotations

import abc
import dataclasses
import time as _time
import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.controllers.sampling.config import (
    BACKENDS,
    INTEGRATORS,
    RISKS,
    Randomization,
    SamplingConfig,
)
from mpcbox.controllers.sampling.splines import Spline
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError
from mpcbox.validation import one_of, positive, positive_int


class Evaluation(NamedTuple):
    """Backend output for ``N`` candidates on ``M`` models.

    Attributes:
        costs: Total rollout costs ``(N, M)`` (float64).
        overflow: ``(N, M)`` True where the backend ran out of contact/constraint capacity.
        nonfinite: ``(N, M)`` True where the rollout diverged: a NaN or infinite cost or
            state, or a ``qpos``, ``qvel`` or ``qacc`` entry beyond ``1e10`` (MuJoCo's
            ``mjMAXVAL``, where MuJoCo resets and :func:`mujoco.rollout` returns NaN; the
            warp backend checks it after every step).
    """

    costs: np.ndarray
    overflow: np.ndarray
    nonfinite: np.ndarray


class TickInfo(NamedTuple):
    """What the last tick did.

    Attributes:
        time: Simulation time of the tick (s).
        best_cost: Lowest aggregated cost of the last iteration.
        nominal_cost: Aggregated cost of the warm-started nominal (first candidate of the
            first iteration; NaN for algorithms that do not evaluate it).
        valid: Number of valid candidates in the last iteration.
        seconds: Wall time of the tick (s).
    """

    time: float
    best_cost: float
    nominal_cost: float
    valid: int
    seconds: float


def aggregate_risk(costs: np.ndarray, risk: str, alpha: float = 0.25) -> np.ndarray:
    r"""Combine the costs of each candidate across randomized models.

    Args:
        costs: ``(N, M)`` costs (``+inf`` marks an excluded rollout).
        risk: ``"mean"``, ``"worst"`` (:math:`\max_m`) or ``"cvar"``: the mean of the
            :math:`\lceil \alpha M \rceil` largest costs.
        alpha: Tail fraction for ``"cvar"``.

    Returns:
        ``(N,)`` costs.
    """
    costs = np.asarray(costs, dtype=np.float64)
    if costs.ndim != 2:
        raise InvalidArgumentError(f"costs must have shape (N, M), got {costs.shape}")
    if risk == "mean":
        return costs.mean(axis=1)
    if risk == "worst":
        return costs.max(axis=1)
    if risk == "cvar":
        m = costs.shape[1]
        k = max(1, int(np.ceil(alpha * m)))
        return np.sort(costs, axis=1)[:, m - k :].mean(axis=1)
    raise InvalidArgumentError(f"risk must be one of {RISKS}; got {risk!r}")


def _disable_bits(names: Sequence[str]) -> int:
    """``mjtDisableBit`` flags from names such as ``"constraint"`` (the error lists them)."""
    valid = {
        n[len("mjDSBL_") :].lower(): int(getattr(mujoco.mjtDisableBit, n))
        for n in dir(mujoco.mjtDisableBit)
        if n.startswith("mjDSBL_")
    }
    if isinstance(names, str):
        raise InvalidArgumentError(
            f"planning_disable must be a sequence of names, got the string {names!r}"
        )
    bits = 0
    for name in names:
        bits |= valid[one_of("planning_disable", str(name).lower(), sorted(valid))]
    return bits


def randomized_models(model: mujoco.MjModel, rand: Randomization) -> list[mujoco.MjModel]:
    """``rand.num_models`` copies of ``model`` with scaled masses/inertias and friction.

    The first model is ``model`` unchanged; derived constants are recomputed with
    :func:`mujoco.mj_setConst`.
    """
    import copy

    rng = np.random.default_rng(rand.seed)
    models = [model]
    for _ in range(rand.num_models - 1):
        m = copy.copy(model)
        scale = rng.uniform(*rand.mass_scale, size=m.nbody)
        scale[0] = 1.0
        m.body_mass[:] = model.body_mass * scale
        m.body_inertia[:] = model.body_inertia * scale[:, None]
        m.geom_friction[:] = model.geom_friction * rng.uniform(
            *rand.friction_scale, size=(m.ngeom, 1)
        )
        mujoco.mj_setConst(m, mujoco.MjData(m))
        models.append(m)
    return models


class SamplingController(Controller):
    """Spline-parameterized sampling MPC on the Problem's planning model.

    Args:
        problem: The Problem (model, cost, control limits).
        config: Options; a default config of the subclass's type when omitted.
        **options: Fields of the config that replace those of ``config`` (this is how
            :func:`mpcbox.make_controller` passes a task's ``controller_options``).

    Attributes:
        knots: Nominal knots ``(K, nu)`` (``None`` before the first tick).
        horizon_steps: Planning steps ``T`` per rollout.
        last: :class:`TickInfo` of the last tick.
    """

    name = "sampling"
    config_class: type[SamplingConfig] = SamplingConfig

    def __init__(
        self, problem: Problem, config: SamplingConfig | None = None, **options: Any
    ) -> None:
        if not isinstance(problem, Problem):
            raise InvalidArgumentError(
                f"problem must be an mpcbox.Problem, got {type(problem).__name__}"
            )
        config = self.config_class() if config is None else config
        if not isinstance(config, SamplingConfig):
            raise InvalidArgumentError(
                f"config must be a {self.config_class.__name__}, got {type(config).__name__}"
            )
        valid = {f.name for f in dataclasses.fields(config)}
        unknown = sorted(set(options) - valid)
        if unknown:
            raise InvalidArgumentError(
                f"unknown option(s) {unknown} for {type(self).__name__}; valid: {sorted(valid)}"
            )
        self.config = config = dataclasses.replace(config, **options)
        if config.planning_timestep is not None:
            dt = positive("planning_timestep", config.planning_timestep)
            if abs(dt - problem.dt) > 1e-12:
                problem = problem.with_planning_timestep(dt)
        disable = _disable_bits(config.planning_disable)
        # The solver cap is for MJWarp only (see SamplingConfig.solver_iterations).
        cap = config.solver_iterations if config.backend == "warp" else None
        if config.solver_iterations is not None:
            positive_int("solver_iterations", config.solver_iterations)
        planning_opts = (cap, config.solver_tolerance, config.planning_integrator)
        if disable or any(v is not None for v in planning_opts):
            problem = problem.with_planning_timestep(problem.dt)  # a private planning model
            opt = problem.planning_model.opt
            if config.planning_integrator is not None:
                name = one_of("planning_integrator", config.planning_integrator, list(INTEGRATORS))
                opt.integrator = INTEGRATORS[name]
            opt.disableflags |= disable
            if cap is not None:
                opt.iterations = cap
            if config.solver_tolerance is not None:
                opt.tolerance = positive("solver_tolerance", config.solver_tolerance)
        self.problem = problem
        self.num_samples = positive_int("num_samples", config.num_samples)
        self.iterations = positive_int("iterations", config.iterations)
        horizon = positive("horizon", config.horizon)
        steps = round(horizon / problem.dt)
        if horizon < problem.dt * (1 - 1e-9) or steps < 1:
            raise InvalidArgumentError(
                f"horizon must be at least one planning timestep ({problem.dt} s), got {horizon}"
            )
        self.horizon_steps = steps
        self.spline = Spline(config.num_knots, steps * problem.dt, config.interpolation)
        #: Interpolation matrix ``(T, K)`` from knots to the planning steps.
        self.weights = self.spline.weights(np.arange(steps) * problem.dt)
        scale = np.asarray(config.noise_scale, dtype=np.float64)
        if scale.ndim == 0:
            scale = np.full(problem.nu, float(scale))
        if scale.shape != (problem.nu,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise InvalidArgumentError(
                f"noise_scale must be a non-negative scalar or ({problem.nu},) array, "
                f"got {config.noise_scale!r}"
            )
        self.noise_scale = scale
        self.period = None if config.period is None else positive("period", config.period)
        replan = config.replan_period
        self.replan_period = None if replan is None else positive("replan_period", replan)
        one_of("risk", config.risk, RISKS)
        if not 0.0 < config.cvar_alpha <= 1.0:
            raise InvalidArgumentError(f"cvar_alpha must be in (0, 1], got {config.cvar_alpha}")
        positive("headroom", config.headroom)
        one_of("backend", config.backend, BACKENDS)
        rand = config.randomization
        if rand is not None:
            positive_int("randomization.num_models", rand.num_models)
            for label, (lo, hi) in (
                ("mass_scale", rand.mass_scale),
                ("friction_scale", rand.friction_scale),
            ):
                if not 0.0 < lo <= hi:
                    raise InvalidArgumentError(
                        f"randomization.{label} must satisfy 0 < low <= high, got {(lo, hi)}"
                    )
        self.models = (
            [problem.planning_model]
            if rand is None
            else randomized_models(problem.planning_model, rand)
        )
        self.backend = self._make_backend()
        self.check_config()
        self.reset()

    # ------------------------------------------------------------------ hooks
    def check_config(self) -> None:
        """Validate algorithm-specific options (called once in ``__init__``)."""

    def reset_algorithm(self) -> None:
        """Reset algorithm state other than the nominal knots."""

    @abc.abstractmethod
    def sample(self) -> np.ndarray:
        """Draw candidate knots ``(N, K, nu)`` around the current distribution/nominal."""

    @abc.abstractmethod
    def update(self, candidates: np.ndarray, costs: np.ndarray) -> None:
        """Refit :attr:`knots` (and any distribution) from scored candidates.

        Args:
            candidates: ``(N, K, nu)`` clamped candidate knots.
            costs: ``(N,)`` aggregated costs; ``+inf`` for excluded candidates (at least one
                is finite).
        """

    # ------------------------------------------------------------------ helpers
    def noise(self, count: int) -> np.ndarray:
        """Gaussian knot noise ``(count, K, nu)`` scaled by ``noise_scale``."""
        return self.standard_normal(count) * self.noise_scale

    def standard_normal(self, count: int) -> np.ndarray:
        """Standard normal draws ``(count, K, nu)`` from :attr:`rng`.

        While the backend computes asynchronously, :meth:`plan` draws the next iteration's
        block ahead of time; the sequence of draws is the same as without the prefetch.
        """
        shape = (count, self.spline.num_knots, self.problem.nu)
        buf, self._prefetched = self._prefetched, None
        if buf is not None and buf.shape == shape:
            return buf
        if buf is not None:  # pragma: no cover - a subclass drew another shape
            raise RuntimeError("prefetched noise of another shape was not consumed")
        return self.rng.standard_normal(shape)

    def _prefetch(self) -> None:
        if self._prefetched is None and self.num_samples > 1:
            shape = (self.num_samples - 1, self.spline.num_knots, self.problem.nu)
            self._prefetched = self.rng.standard_normal(shape)

    def _make_backend(self):
        cfg = self.config
        if cfg.backend == "cpu":
            if cfg.device not in (None, "cpu"):
                raise InvalidArgumentError(
                    f"device={cfg.device!r} needs backend='warp'; the cpu backend has no device"
                )
            from mpcbox.controllers.sampling.backends.cpu import CpuBackend

            return CpuBackend(self.problem, self.weights, self.models)
        from mpcbox.controllers.sampling.backends.warp import WarpBackend, resolve_device

        device = resolve_device(cfg.device)
        return WarpBackend(
            self.problem,
            self.weights,
            self.models,
            device=device,
            headroom=cfg.headroom,
            use_graph=cfg.use_graph,
        )

    # ------------------------------------------------------------------ controller API
    def reset(self) -> None:
        """Forget the nominal plan and statistics; re-seed the noise generator."""
        self.rng = np.random.default_rng(self.config.seed)
        self._prefetched: np.ndarray | None = None
        self.knots: np.ndarray | None = None
        self._plan_time: float | None = None
        self.last: TickInfo | None = None
        self._stats = {
            "ticks": 0,
            "rollouts": 0,
            "excluded_samples": 0,
            "overflow_samples": 0,
            "nonfinite_samples": 0,
            "failed_iterations": 0,
            "tick_seconds_total": 0.0,
            "tick_seconds_max": 0.0,
        }
        self.reset_algorithm()

    def nominal_knots(self) -> np.ndarray:
        """The reference control on every knot ``(K, nu)`` (the cold start)."""
        ref = self.problem.clip_ctrl(self.problem.ctrl_ref)
        return np.tile(ref, (self.spline.num_knots, 1))

    def evaluate(
        self, state: np.ndarray, candidates: np.ndarray, *, prefetch: bool = False
    ) -> np.ndarray:
        """Aggregated costs ``(N,)`` of candidate knots from ``state`` (+inf if excluded).

        Args:
            state: Start state ``(nstate,)``.
            candidates: Knots ``(N, K, nu)`` (clamped to the control range here).
            prefetch: Draw the next iteration's noise while the backend computes.
        """
        cand = self.problem.clip_ctrl(np.asarray(candidates, dtype=np.float64))
        submit = getattr(self.backend, "submit", None)
        if submit is not None:
            submit(state, cand)
            if prefetch:
                self._prefetch()
            ev = self.backend.collect()
        else:
            ev = self.backend.evaluate(state, cand)
        bad = ev.overflow | ev.nonfinite | ~np.isfinite(ev.costs)
        costs = np.where(bad, np.inf, ev.costs)
        agg = aggregate_risk(costs, self.config.risk, self.config.cvar_alpha)
        agg[bad.any(axis=1)] = np.inf
        s = self._stats
        s["rollouts"] += ev.costs.size
        s["excluded_samples"] += int(bad.any(axis=1).sum())
        s["overflow_samples"] += int(ev.overflow.any(axis=1).sum())
        s["nonfinite_samples"] += int((ev.nonfinite | ~np.isfinite(ev.costs)).any(axis=1).sum())
        return agg

    def plan(self, state: np.ndarray, time: float) -> np.ndarray:
        """Run one tick from ``state`` at ``time`` and return the new nominal knots."""
        start = _time.perf_counter()
        state = self.problem.check_state(state)
        if self.knots is None or self._plan_time is None:
            self.knots = self.nominal_knots()
        else:
            self.knots = self.problem.clip_ctrl(
                self.spline.shift(self.knots, time - self._plan_time)
            )
            self.shift(time - self._plan_time)
        self._plan_time = float(time)
        best, nominal, valid = np.nan, np.nan, 0
        for it in range(self.iterations):
            cand = self.problem.clip_ctrl(self.sample())
            costs = self.evaluate(state, cand, prefetch=True)
            finite = np.isfinite(costs)
            valid = int(finite.sum())
            if it == 0 and self.evaluates_nominal:
                nominal = float(costs[0])
            if valid == 0:
                self._stats["failed_iterations"] += 1
                continue
            best = float(costs[finite].min())
            self.update(cand, costs)
            self.knots = self.problem.clip_ctrl(self.knots)
        seconds = _time.perf_counter() - start
        s = self._stats
        s["ticks"] += 1
        s["tick_seconds_total"] += seconds
        s["tick_seconds_max"] = max(s["tick_seconds_max"], seconds)
        self.last = TickInfo(float(time), best, nominal, valid, seconds)
        return self.knots

    #: Whether candidate 0 is the nominal (reported as ``TickInfo.nominal_cost``).
    evaluates_nominal: bool = True

    def shift(self, elapsed: float) -> None:
        """Warm-start hook for algorithm state besides :attr:`knots` (e.g. CEM's std)."""

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        replan = self.replan_period
        if replan is None or self.knots is None or self._plan_time is None:
            knots = self.plan(state, time)
            return self.problem.clip_ctrl(self.weights[0] @ knots)
        elapsed = float(time) - self._plan_time
        if elapsed < 0.0 or elapsed >= replan - 1e-9:
            knots = self.plan(state, time)
            return self.problem.clip_ctrl(self.weights[0] @ knots)
        return self.action(elapsed)

    def action(self, time_offset: float) -> np.ndarray:
        """The nominal control ``time_offset`` seconds after the last tick."""
        if self.knots is None:
            raise InvalidArgumentError("action() needs a plan: call the controller first")
        return self.problem.clip_ctrl(self.spline.evaluate(self.knots, [time_offset])[0])

    @property
    def stats(self) -> dict[str, float]:
        s = dict(self._stats)
        ticks = max(s["ticks"], 1)
        s["tick_seconds_mean"] = s.pop("tick_seconds_total") / ticks
        s["fallbacks"] = s["failed_iterations"]
        s.update(self.backend.stats)
        return {k: float(v) for k, v in s.items()}

    def close(self) -> None:
        """Release backend resources."""
        self.backend.close()


def warn_cpu_fallback(device: str) -> None:
    """Warn that the warp backend runs on warp's CPU device (slow; for tests)."""
    warnings.warn(
        f"backend='warp' without CUDA: running MuJoCo Warp on warp's {device!r} device, which "
        "is much slower than backend='cpu'",
        RuntimeWarning,
        stacklevel=3,
    )


__all__ = [
    "BackendUnavailableError",
    "Evaluation",
    "SamplingController",
    "TickInfo",
    "aggregate_risk",
    "randomized_models",
]
