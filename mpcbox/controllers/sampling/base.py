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
   calls between replans return the nominal spline at the elapsed time instead. With
   ``catch="lqr"`` (:mod:`mpcbox.controllers.sampling.catch`) the rollouts step through the
   reference's LQR inside its basin, and a call whose state is inside it returns the LQR's
   control (counted in ``stats["catch_calls"]``);
4. only after :meth:`SamplingController.record_traces`: the ``k`` best candidates of the
   last iteration are re-rolled on the CPU into :attr:`SamplingController.traces`
   (:mod:`mpcbox.controllers.sampling.traces`, for viewers).

The backend may compute asynchronously (``submit``/``collect``, the warp backend): the
noise of the next iteration is then drawn while the device works.

Subclasses implement only :meth:`sample` and :meth:`update`.
"""

from __future__ import annotations

import abc
import time as _time
from typing import Any, NamedTuple

import numpy as np

from mpcbox.config import resolve_config
from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.lqr import LQRConfig
from mpcbox.controllers.sampling.backends import RolloutBackend, make_backend
from mpcbox.controllers.sampling.catch import LQRCatch
from mpcbox.controllers.sampling.config import RISKS, SamplingConfig
from mpcbox.controllers.sampling.planning import planning_models, planning_problem
from mpcbox.controllers.sampling.splines import Spline
from mpcbox.controllers.sampling.traces import PlannerTrace, TraceRecorder
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import finite


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


class SamplingController(Controller):
    """Spline-parameterized sampling MPC on the Problem's planning model.

    Args:
        problem: The Problem (model, cost, control limits).
        config: Options; a default config of the subclass's type when omitted.
        **options: Fields of the config that replace those of ``config`` (this is how
            :func:`mpcbox.make_controller` passes a task's ``controller_configs``).

    Attributes:
        knots: Nominal knots ``(K, nu)`` (``None`` before the first tick).
        horizon_steps: Planning steps ``T`` per rollout.
        last: :class:`TickInfo` of the last tick.
        traces: :class:`~mpcbox.controllers.sampling.traces.PlannerTrace` of the last tick
            while :meth:`record_traces` is on, else ``None``.
        trace_recorder: The :class:`~mpcbox.controllers.sampling.traces.TraceRecorder`, or
            ``None`` (the default: no trace work at all).
    """

    name = "sampling"
    config_class: type[SamplingConfig] = SamplingConfig
    #: Whether candidate 0 is the nominal (reported as ``TickInfo.nominal_cost``).
    evaluates_nominal: bool = True

    def __init__(
        self, problem: Problem, config: SamplingConfig | None = None, **options: Any
    ) -> None:
        owner = type(self).__name__
        problem = check_problem(problem, owner)
        self.config = config = resolve_config(self.config_class, config, options, owner)
        config.validate(problem.nu, problem.dt)
        self.problem = problem = planning_problem(problem, config)
        self.num_samples = int(config.num_samples)
        self.iterations = int(config.iterations)
        self.horizon_steps = steps = config.horizon_steps(problem.dt)
        self.spline = Spline(config.num_knots, steps * problem.dt, config.interpolation)
        #: Start times of the planning steps ``(T,)`` (s).
        self.step_times = np.arange(steps) * problem.dt
        #: Interpolation matrix ``(T, K)`` from knots to the planning steps.
        self.weights = self.spline.weights(self.step_times)
        #: Standard deviation of the knot noise per control ``(nu,)``.
        self.noise_scale = config.noise_scales(problem.nu)
        #: Standard deviation of the noise per knot and control ``(K, nu)``
        #: (``noise_schedule`` times ``noise_scale``).
        self.knot_noise = config.knot_noise(problem.nu)
        self.period = None if config.period is None else float(config.period)
        replan = config.replan_period
        self.replan_period = None if replan is None else float(replan)
        #: The ``M`` planning models (the nominal one first).
        self.models = planning_models(problem.planning_model, config.randomization)
        #: The :class:`~mpcbox.controllers.sampling.catch.LQRCatch` (``catch="lqr"``) or
        #: ``None``.
        self.catch: LQRCatch | None = None
        if config.catch is not None:
            self.catch = LQRCatch(
                problem,
                problem.model.opt.timestep if self.period is None else self.period,
                config.catch_level,
                lqr=_task_lqr_config(problem),
                seed=config.seed,
            )
        self.backend: RolloutBackend = make_backend(
            config.backend,
            problem,
            self.weights,
            self.models,
            device=config.device,
            headroom=config.headroom,
            use_graph=config.use_graph,
            policy=None if self.catch is None else self.catch.policy,
        )
        self.trace_recorder: TraceRecorder | None = None
        self.reset()

    # ------------------------------------------------------------------ hooks
    def reset_algorithm(self) -> None:
        """Reset algorithm state other than the nominal knots."""

    def shift(self, elapsed: float) -> None:
        """Warm-start hook for algorithm state besides :attr:`knots` (e.g. CEM's std)."""

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
    def gaussian_candidates(self, std: np.ndarray) -> np.ndarray:
        r"""The nominal and ``N - 1`` Gaussian perturbations of it ``(N, K, nu)``.

        :math:`U^0 = \bar U` and :math:`U^n = \bar U + \sigma \odot \varepsilon^n` with
        :math:`\varepsilon^n \sim \mathcal N(0, I)` drawn by :meth:`standard_normal`.

        Args:
            std: Standard deviation :math:`\sigma`, ``(nu,)`` or ``(K, nu)``.
        """
        assert self.knots is not None
        eps = self.standard_normal(self.num_samples - 1)
        cand = np.empty((self.num_samples, *self.knots.shape))
        cand[0] = self.knots
        cand[1:] = self.knots + std * eps
        return cand

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

    # ------------------------------------------------------------------ controller API
    def reset(self) -> None:
        """Forget the nominal plan and statistics; re-seed the noise generator."""
        self.rng = np.random.default_rng(self.config.seed)
        self._prefetched: np.ndarray | None = None
        self.knots: np.ndarray | None = None
        self._plan_time: float | None = None
        self.last: TickInfo | None = None
        self.traces: PlannerTrace | None = None
        self._stats = {
            "ticks": 0,
            "rollouts": 0,
            "excluded_samples": 0,
            "overflow_samples": 0,
            "nonfinite_samples": 0,
            "failed_iterations": 0,
            "tick_seconds_total": 0.0,
            "tick_seconds_max": 0.0,
            "catch_calls": 0,
        }
        self.reset_algorithm()

    def warm_start(self, knots: np.ndarray | None, time: float) -> None:
        """Replace the nominal plan, e.g. with one handed over by another controller.

        The algorithm state restarts (:meth:`reset_algorithm`); the random stream and the
        statistics go on.

        Args:
            knots: Nominal knots ``(K, nu)`` planned at ``time`` (clamped to the control
                range), or ``None`` for a cold start at the next tick
                (:meth:`nominal_knots` from its state).
            time: Simulated time the knots start at (s).

        Raises:
            InvalidArgumentError: If ``knots`` has another shape.
        """
        if knots is not None:
            knots = np.asarray(knots, dtype=np.float64)
            shape = (self.spline.num_knots, self.problem.nu)
            if knots.shape != shape:
                raise InvalidArgumentError(f"knots must have shape {shape}, got {knots.shape}")
            knots = self.problem.clip_ctrl(knots)
        self.knots = knots
        self._plan_time = None if knots is None else float(time)
        self.reset_algorithm()

    def nominal_knots(self, state: np.ndarray | None = None) -> np.ndarray:
        """The cold start's knots ``(K, nu)``.

        Without a state, the reference control on every knot. From ``state``, the task's
        first guess over the planning horizon (:meth:`mpcbox.Problem.initial_ctrls`,
        ``(T, nu)``: ``ctrl_ref`` unless the task chooses better) read at the knot times,
        the same guess the trajectory optimizers start from.

        Args:
            state: The state ``(nstate,)`` the first tick plans from, or ``None``.
        """
        k = self.spline.num_knots
        if state is None:
            return np.tile(self.problem.clip_ctrl(self.problem.ctrl_ref), (k, 1))
        steps = self.horizon_steps
        guess = np.asarray(self.problem.initial_ctrls(state, steps), dtype=np.float64)
        if guess.shape != (steps, self.problem.nu) or not np.all(np.isfinite(guess)):
            raise InvalidArgumentError(
                f"{type(self.problem).__name__}.initial_ctrls must return finite controls "
                f"of shape {(steps, self.problem.nu)}, got shape {guess.shape}"
            )
        index = np.rint(self.spline.knot_times / self.problem.dt).astype(int)
        return self.problem.clip_ctrl(guess[np.clip(index, 0, steps - 1)])

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
            self.knots = self.nominal_knots(state)
        else:
            elapsed = time - self._plan_time
            if self.config.shift == "least_squares":
                shifted = self.spline.refit(self.knots, elapsed, self.step_times)
            else:
                shifted = self.spline.shift(self.knots, elapsed)
            self.knots = self.problem.clip_ctrl(shifted)
            self.shift(time - self._plan_time)
        self._plan_time = float(time)
        best, nominal, valid = np.nan, np.nan, 0
        scored: tuple[np.ndarray, np.ndarray] | None = None
        guess = self.nominal_knots(state) if self.config.guess_candidate else None
        for it in range(self.iterations):
            cand = self.problem.clip_ctrl(self.sample())
            if it == 0 and guess is not None and len(cand) > 1:
                cand[-1] = guess  # the task's guess is scored at every tick
            costs = self.evaluate(state, cand, prefetch=True)
            finite = np.isfinite(costs)
            valid = int(finite.sum())
            if it == 0 and self.evaluates_nominal:
                nominal = float(costs[0])
            if valid == 0:
                self._stats["failed_iterations"] += 1
                continue
            best = float(costs[finite].min())
            scored = (cand, costs)
            self.update(cand, costs)
            self.knots = self.problem.clip_ctrl(self.knots)
        seconds = _time.perf_counter() - start
        s = self._stats
        s["ticks"] += 1
        s["tick_seconds_total"] += seconds
        s["tick_seconds_max"] = max(s["tick_seconds_max"], seconds)
        self.last = TickInfo(float(time), best, nominal, valid, seconds)
        if self.trace_recorder is not None and scored is not None:
            self.traces = self.trace_recorder.record(time, state, *scored, self.weights)
        return self.knots

    def record_traces(
        self,
        count: int | None,
        *,
        site: str | int | None = None,
        body: str | int | None = None,
    ) -> None:
        """Keep the paths of the ``count`` best candidates of every tick in :attr:`traces`.

        Each tick then re-rolls its ``count`` lowest-cost candidates of the last iteration
        on the CPU (:class:`~mpcbox.controllers.sampling.traces.TraceRecorder`: ``count``
        rollouts of ``T`` steps and ``count (T + 1)`` kinematics passes). That work comes
        after the tick's timing (:attr:`TickInfo.seconds`) but inside the controller call,
        so a closed loop's compute times include it. It draws no random numbers: the plans
        are the same with traces on or off.

        Args:
            count: How many candidates to trace; ``None`` or 0 turns recording off.
            site: The site to trace, by name or id.
            body: The body (frame origin) to trace instead. Without either, the planning
                model's last site, or else its last body.

        Raises:
            InvalidArgumentError: For a negative count, or both ``site`` and ``body``.
            UnknownNameError: For a site or body the model does not have.
        """
        self.traces = None
        if count is None or (type(count) is int and count == 0):
            self.trace_recorder = None
            return
        policy = None if self.catch is None else self.catch.policy
        self.trace_recorder = TraceRecorder(
            self.problem, count, site=site, body=body, policy=policy
        )

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        ctrl = self._planned(state, finite("time", time))
        if self.catch is not None:
            caught = self.catch.control(self.problem.check_state(state))
            if caught is not None:
                self.last_call = "catch"
                self._stats["catch_calls"] += 1
                return caught
        return ctrl

    def _planned(self, state: np.ndarray, time: float) -> np.ndarray:
        """The plan's control at ``time``, replanning when due."""
        replan = self.replan_period
        self.last_call = "solve"
        if replan is None or self.knots is None or self._plan_time is None:
            knots = self.plan(state, time)
            return self.problem.clip_ctrl(self.weights[0] @ knots)
        elapsed = float(time) - self._plan_time
        if elapsed < 0.0 or elapsed >= replan - 1e-9:
            knots = self.plan(state, time)
            return self.problem.clip_ctrl(self.weights[0] @ knots)
        self.last_call = "hold"
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


def _task_lqr_config(problem: Problem) -> LQRConfig | None:
    """The task's ``"lqr"`` config (its tuned weights), if it has one."""
    config = getattr(problem, "controller_configs", {}).get("lqr")
    return config if isinstance(config, LQRConfig) else None


__all__ = [
    "SamplingController",
    "TickInfo",
    "aggregate_risk",
]
