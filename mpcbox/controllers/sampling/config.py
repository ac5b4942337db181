"""Keyword-only configuration of the sampling controllers and of domain randomization.

Each config checks its own options with ``validate``; the checks that depend on the Problem
take its number of controls ``nu`` and its planning timestep ``dt``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from mpcbox.controllers.sampling.backends import BACKENDS
from mpcbox.controllers.sampling.splines import INTERPOLATIONS, Interpolation
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import (
    as_array,
    boolean,
    checked_options,
    finite_array,
    in_range,
    instance,
    integer,
    non_negative,
    one_of,
    positive,
    positive_int,
    string,
)
from mpcbox.validation import seed as check_seed

Backend = Literal["cpu", "warp"]
Risk = Literal["mean", "worst", "cvar"]
Integrator = Literal["euler", "implicitfast", "implicit", "rk4"]
RISKS: tuple[str, ...] = ("mean", "worst", "cvar")
NoiseSchedule = Literal["constant", "linear", "ramp"]
NOISE_SCHEDULES: tuple[str, ...] = ("constant", "linear", "ramp")
ShiftMode = Literal["resample", "least_squares"]
SHIFT_MODES: tuple[str, ...] = ("resample", "least_squares")
TerminalValue = Literal["lqr"]
TERMINAL_VALUES: tuple[str, ...] = ("lqr",)
Catch = Literal["lqr"]
CATCHES: tuple[str, ...] = ("lqr",)
TemperatureMode = Literal["normalized", "absolute"]
TEMPERATURE_MODES: tuple[str, ...] = ("normalized", "absolute")
#: MuJoCo integrator names (``mjtIntegrator``) accepted by ``planning_integrator``.
INTEGRATORS: dict[str, int] = {"euler": 0, "rk4": 1, "implicit": 2, "implicitfast": 3}


def disable_bits(names: Sequence[str]) -> int:
    """``mjtDisableBit`` flags from names such as ``"constraint"`` (the error lists them).

    Raises:
        InvalidArgumentError: For a plain string or an unknown name.
    """
    valid = {
        n[len("mjDSBL_") :].lower(): int(getattr(mujoco.mjtDisableBit, n))
        for n in dir(mujoco.mjtDisableBit)
        if n.startswith("mjDSBL_")
    }
    if isinstance(names, str):
        raise InvalidArgumentError(
            f"planning_disable must be a sequence of names, got the string {names!r}"
        )
    if not isinstance(names, Sequence):
        raise InvalidTypeError(
            f"planning_disable must be a sequence of names, got {type(names).__name__}"
        )
    bits = 0
    for name in names:
        name = string("planning_disable", name)
        bits |= valid[one_of("planning_disable", name.lower(), sorted(valid))]
    return bits


@checked_options
@dataclass(frozen=True, kw_only=True)
class Randomization:
    """Per-world model perturbations for robust planning.

    Every candidate is rolled out on ``num_models`` planning models whose body masses (and
    inertias, scaled alike) and geom friction coefficients are scaled by factors drawn
    uniformly from the given ranges; the first model is always the nominal one. The costs
    of one candidate across the models are aggregated with the controller's ``risk``.

    Attributes:
        num_models: Number of models ``M`` (>= 1), including the nominal one.
        mass_scale: Range ``(low, high)`` of the per-body mass factors.
        friction_scale: Range ``(low, high)`` of the per-geom friction factors.
        seed: Seed of the draw.
    """

    num_models: int = 4
    mass_scale: tuple[float, float] = (0.9, 1.1)
    friction_scale: tuple[float, float] = (0.7, 1.3)
    seed: int = 0

    def validate(self) -> None:
        """Check ``num_models >= 1`` and ``0 < low <= high`` for both ranges.

        Raises:
            InvalidArgumentError: Naming the offending field.
        """
        positive_int("randomization.num_models", self.num_models)
        integer("randomization.seed", self.seed)
        for label in ("mass_scale", "friction_scale"):
            lo, hi = finite_array(f"randomization.{label}", getattr(self, label), (2,))
            if not 0.0 < lo <= hi:
                raise InvalidArgumentError(
                    f"randomization.{label} must satisfy 0 < low <= high, got {(lo, hi)}"
                )


@checked_options
@dataclass(frozen=True, kw_only=True)
class SamplingConfig:
    r"""Options shared by all sampling controllers.

    Attributes:
        num_samples: Candidates ``N`` per iteration (>= 1).
        horizon: Planning horizon ``H`` in seconds (at least one planning timestep).
        num_knots: Spline knots ``K`` over the horizon.
        interpolation: ``"zero"``, ``"linear"``, ``"cubic"`` (C1 Hermite) or ``"cubic_c2"``
            (natural cubic spline, C2) (see :mod:`.splines`).
        noise_scale: Standard deviation of the knot noise, in control units; a scalar or one
            value per actuator ``(nu,)``.
        noise_schedule: Multiplier :math:`g_k` of the noise standard deviation on knot ``k``,
            so knot ``k`` of actuator ``j`` gets :math:`g_k \sigma_j`: ``"constant"``
            (:math:`g_k = 1`, the default), ``"linear"`` (:math:`g_k = (k + 1) / K`, little
            noise on the first knot, which the robot executes next, the full noise on the
            last), ``"ramp"`` (:math:`g_k = k / (K - 1)`, ``K >= 2``: none on the first knot,
            whose control then comes from the shifted plan alone) or one non-negative value
            per knot ``(K,)``.
        iterations: Sample/update rounds per control tick.
        guess_candidate: Replace the last candidate of each tick's first iteration by the
            task's guess from the measured state (:meth:`mpcbox.Problem.initial_ctrls` read
            at the knot times, the cold start's nominal): a plan that holds the equilibrium
            for a balancing task, the goal's set-points for a reach. Near a goal the random
            candidates differ little in cost, and their weighted average (MPPI) or the
            luckiest one (predictive sampling) walks away from it; a planner that always
            scores the guess keeps it when nothing beats it.
        terminal_value: ``"lqr"`` adds the infinite-horizon LQR value function of the planning
            model at the reference to the terminal cost
            (:func:`~mpcbox.controllers.lqr.with_lqr_terminal_value`), so a short horizon
            still sees the cost-to-go; ``None`` (default) keeps the Problem's terminal cost.
            Both backends (on the warp backend one launch per tick evaluates the dense form).
            It suits a state that the LQR brings back quickly (the acrobot's upright hold);
            on the humanoid stand, whose LQR leaves slow modes (closed-loop eigenvalues up to
            0.9999 at 0.02 s), the value's largest eigenvalue, along the fall of the centre of
            mass, is 430 times the running cost's largest weight, and in the real-time loop
            MPPI stood 0/10 and CEM 2/10 in the hard scenario against 8/10 and 6/10 without it
            (``benchmarks/results/stand_terminal_value_h100.json``).
        catch: ``"lqr"`` hands the control to the LQR of the planning model at the
            reference (with the task's ``"lqr"`` config when it has one) wherever the state
            is inside its estimated basin of attraction, in every rollout and in the closed
            loop (:class:`~mpcbox.controllers.sampling.catch.LQRCatch`), so the planner sees
            which samples reach a state the LQR holds; ``None`` (default): open-loop
            rollouts. CPU backend only (each rollout step is one
            :func:`mujoco.rollout.rollout` call).
        catch_level: The basin level :math:`c` of ``catch`` (the LQR's value
            :math:`V(x) < c`); ``None``: estimated by simulation when the controller is
            built (:func:`~mpcbox.controllers.sampling.catch.basin_level`).
        shift: Warm start of the nominal spline at a tick: ``"resample"`` (default,
            :meth:`~.splines.Spline.shift`: re-evaluated at the shifted knot times) or
            ``"least_squares"`` (:meth:`~.splines.Spline.refit`: the least-squares fit, over
            the planning steps, to the rest of the old plan). On an unstable plant the
            resampled plan is another plan: on dm_control's acrobot near the upright
            (1 s horizon, 10 cubic knots, RK4) a plan of cost 16.9 shifted by 0.04 s costs
            41.1 resampled and 16.7 refitted (``benchmarks/dm_acrobot_dm_starts.py
            --mppi-hold``).
        planning_timestep: Plan on a copy of the Problem whose planning model takes steps of
            this many seconds (:meth:`~mpcbox.Problem.with_planning_timestep`); default: the
            Problem's planning timestep. A coarser step buys a longer horizon per rollout.
        planning_integrator: The planning model's integrator (``"euler"``,
            ``"implicitfast"``, ``"implicit"`` or ``"rk4"``; default: the model's). With
            joint damping and plain motors Euler (implicit in the damping) predicts like
            implicitfast and skips its velocity derivatives, a cheaper step.
        planning_disable: MuJoCo features the planning model switches off, by the names of
            ``mjtDisableBit`` without the prefix (``"constraint"``, ``"eulerdamp"``,
            ``"limit"``, ``"contact"``, ...): for example a cart-pole planned without its
            rail limits and Euler damping: 5% faster per tick on MJWarp.
        solver_iterations: Warp backend: cap on the constraint solver's iterations in the
            planning model (``opt.iterations``; default: the model's). Every world waits for
            the slowest one to converge, so a low cap (1-3 for Newton) makes contact-rich
            rollouts markedly faster at a small cost in accuracy: on the humanoid with one
            iteration and Euler, rollout costs 1.2% (median) and 4.3% (max) from the full
            model's. The CPU backend ignores it: each CPU rollout
            stops when it converges anyway, and MuJoCo's CPU Newton solver diverges with
            one iteration where MJWarp's does not (16 of 20 humanoid rollouts,
            ``tests/test_problem.py``).
        solver_tolerance: The planning model's solver tolerance (``opt.tolerance``; MJWarp
            uses at least 1e-6).
        servo_armature: :math:`c`: in the planning model, raise the armature of each hinge
            or slide driven by a position servo (any actuator whose force depends on its
            length) to at least :math:`c\,k\,\Delta t^2`, with :math:`k = -b_1 g^2` the
            servo's stiffness on the joint (bias ``biasprm[1]``, gear :math:`g`) and
            :math:`\Delta t` the planning timestep
            (:func:`~mpcbox.controllers.sampling.planning.servo_armature`). A servo's spring
            is integrated explicitly, and a step is stable only while
            :math:`k \Delta t^2 / I < 4`; the added inertia lets stiff servos be planned
            at a coarse step. On Menagerie's G1 (kp 500) lying on the floor, rollouts of
            random set-points all diverge at 0.02 s without it and none with
            :math:`c = 0.5`, and their costs rank as in the simulated world (meshes,
            0.002 s) with a rank correlation of 0.75, as the 0.01 s plan without it does
            (0.82 planning at 0.002 s, 0.70 with :math:`c = 1`;
            ``benchmarks/planning_fidelity.py --tasks g1_getup``). ``None`` (default): the
            model's armature.
        period: Seconds between controller calls (``None``: every simulation step); without
            ``replan_period`` every call replans and the control is held in between.
        replan_period: Seconds between replans when the controller is called more often
            (typically with ``period=None``): calls in between return the nominal spline at
            the time elapsed since the last replan instead of holding its first value.
        backend: ``"cpu"`` (:func:`mujoco.rollout`) or ``"warp"`` (MuJoCo Warp).
        device: Warp device (``"cuda"``, ``"cuda:0"``, ``"cpu"``); default: CUDA if present.
        seed: Seed of the numpy Generator that draws the noise.
        randomization: Optional domain randomization of the planning model.
        risk: How costs over randomized models are combined: ``"mean"``, ``"worst"``
            (maximum) or ``"cvar"`` (mean of the worst ``cvar_alpha`` fraction).
        cvar_alpha: Tail fraction for ``risk="cvar"``, in ``(0, 1]``.
        headroom: Warp backend: contact and constraint capacity as a multiple of the largest
            counts seen in the calibration rollouts.
        use_graph: Warp backend: capture each tick as one CUDA graph (CUDA only).
    """

    num_samples: int = 128
    horizon: float = 1.0
    num_knots: int = 4
    interpolation: Interpolation = "cubic"
    noise_scale: float | Sequence[float] = 0.3
    noise_schedule: NoiseSchedule | Sequence[float] = "constant"
    iterations: int = 1
    guess_candidate: bool = False
    shift: ShiftMode = "resample"
    terminal_value: TerminalValue | None = None
    catch: Catch | None = None
    catch_level: float | None = None
    planning_timestep: float | None = None
    planning_integrator: Integrator | None = None
    planning_disable: Sequence[str] = ()
    solver_iterations: int | None = None
    solver_tolerance: float | None = None
    servo_armature: float | None = None
    period: float | None = None
    replan_period: float | None = None
    backend: Backend = "cpu"
    device: str | None = None
    seed: int = 0
    randomization: Randomization | None = None
    risk: Risk = "mean"
    cvar_alpha: float = 0.25
    headroom: float = 2.0
    use_graph: bool = True

    def validate(self, nu: int, dt: float) -> None:
        """Check every option for a Problem with ``nu`` controls and planning timestep ``dt``.

        Args:
            nu: Number of controls of the Problem.
            dt: The Problem's planning timestep (s); ``planning_timestep`` replaces it.

        Raises:
            InvalidArgumentError: Naming the offending option (and listing the valid choices
                of a choice).
        """
        if self.planning_timestep is not None:
            dt = positive("planning_timestep", self.planning_timestep)
        disable_bits(self.planning_disable)
        if self.solver_iterations is not None:
            positive_int("solver_iterations", self.solver_iterations)
        if self.planning_integrator is not None:
            one_of("planning_integrator", self.planning_integrator, list(INTEGRATORS))
        if self.solver_tolerance is not None:
            positive("solver_tolerance", self.solver_tolerance)
        if self.servo_armature is not None:
            positive("servo_armature", self.servo_armature)
        positive_int("num_samples", self.num_samples)
        positive_int("iterations", self.iterations)
        one_of("shift", self.shift, SHIFT_MODES)
        if self.terminal_value is not None:
            one_of("terminal_value", self.terminal_value, TERMINAL_VALUES)
        if self.catch is not None:
            one_of("catch", self.catch, CATCHES)
            if self.backend != "cpu":
                raise InvalidArgumentError(
                    f"catch={self.catch!r} needs backend='cpu' (its rollouts step through a "
                    f"state feedback), got backend={self.backend!r}"
                )
        if self.catch_level is not None:
            positive("catch_level", self.catch_level)
        steps = self.horizon_steps(dt)
        positive_int("num_knots", self.num_knots)
        if self.num_knots > steps + 1:
            raise InvalidArgumentError(
                f"num_knots must be at most the horizon's planning steps + 1 ({steps + 1}: "
                f"{self.horizon:g} s of {dt:g} s), got {self.num_knots}"
            )
        one_of("interpolation", self.interpolation, INTERPOLATIONS)
        self.noise_scales(nu)
        self.noise_multipliers()
        if self.period is not None:
            positive("period", self.period)
        if self.replan_period is not None:
            positive("replan_period", self.replan_period)
            if self.period is not None and self.replan_period < self.period:
                raise InvalidArgumentError(
                    f"replan_period ({self.replan_period:g} s) below period ({self.period:g} s) "
                    "has no effect (every call replans): leave it None or make it longer"
                )
        one_of("risk", self.risk, RISKS)
        in_range("cvar_alpha", self.cvar_alpha, 0.0, 1.0, low_open=True, high_open=False)
        positive("headroom", self.headroom)
        one_of("backend", self.backend, BACKENDS)
        if self.device is not None:
            string("device", self.device)
        check_seed("seed", self.seed)
        boolean("use_graph", self.use_graph)
        boolean("guess_candidate", self.guess_candidate)
        if self.randomization is not None:
            instance("randomization", self.randomization, Randomization)
            self.randomization.validate()

    def horizon_steps(self, dt: float) -> int:
        """Planning steps ``T = round(horizon / dt)`` of a rollout (at least one).

        Raises:
            InvalidArgumentError: If the horizon is shorter than one planning timestep.
        """
        horizon = positive("horizon", self.horizon)
        steps = round(horizon / dt)
        if horizon < dt * (1 - 1e-9) or steps < 1:
            raise InvalidArgumentError(
                f"horizon must be at least one planning timestep ({dt} s), got {horizon}"
            )
        return steps

    def noise_scales(self, nu: int) -> np.ndarray:
        """``noise_scale`` as one non-negative standard deviation per control ``(nu,)``.

        Raises:
            InvalidArgumentError: For a wrong shape, a negative or a non-finite value.
        """
        scale = as_array(
            "noise_scale", self.noise_scale, (None,) * min(1, np.ndim(self.noise_scale))
        )
        if scale.ndim == 0:
            scale = np.full(nu, float(scale))
        if scale.shape != (nu,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise InvalidArgumentError(
                f"noise_scale must be a non-negative scalar or ({nu},) array, "
                f"got {self.noise_scale!r}"
            )
        return scale

    def noise_multipliers(self) -> np.ndarray:
        """``noise_schedule`` as one multiplier per knot ``(K,)``.

        Raises:
            InvalidArgumentError: For an unknown name, a wrong length, a negative or a
                non-finite value.
        """
        k = positive_int("num_knots", self.num_knots)
        schedule = self.noise_schedule
        if isinstance(schedule, str):
            name = one_of("noise_schedule", schedule, NOISE_SCHEDULES)
            if name == "ramp":
                if k < 2:
                    raise InvalidArgumentError(
                        "noise_schedule='ramp' leaves the first knot without noise and needs "
                        f"num_knots >= 2, got {k}"
                    )
                return np.arange(k) / (k - 1)
            return np.ones(k) if name == "constant" else np.arange(1, k + 1) / k
        gains = as_array("noise_schedule", schedule, (None,))
        if gains.shape != (k,) or not np.all(np.isfinite(gains)) or np.any(gains < 0):
            raise InvalidArgumentError(
                f"noise_schedule must be 'constant', 'linear', 'ramp' or {k} non-negative values "
                f"(one per knot), got {schedule!r}"
            )
        return gains

    def knot_noise(self, nu: int) -> np.ndarray:
        """Noise standard deviation per knot and control ``(K, nu)``: schedule x scale."""
        return self.noise_multipliers()[:, None] * self.noise_scales(nu)[None, :]


@checked_options
@dataclass(frozen=True, kw_only=True)
class PredictiveSamplingConfig(SamplingConfig):
    """Predictive sampling: keep the best of the nominal and ``N - 1`` perturbations."""


@checked_options
@dataclass(frozen=True, kw_only=True)
class MPPIConfig(SamplingConfig):
    r"""MPPI options.

    Attributes:
        temperature: Softmax temperature :math:`\lambda`.
        temperature_mode: ``"normalized"`` (default): :math:`\lambda` is in units of the
            standard deviation :math:`s_J` of the valid costs of one iteration,
            :math:`w_n \propto \exp(-(J_n - J^*) / (\lambda s_J))` (scale-free, so one
            value suits many tasks); ``"absolute"``: :math:`\lambda` is in cost units,
            :math:`w_n \propto \exp(-J_n / \lambda)`, the textbook MPPI weights (the
            sharpness then follows the cost's scale, as in judo and MJPC).
    """

    temperature: float = 0.1
    temperature_mode: TemperatureMode = "normalized"

    def validate(self, nu: int, dt: float) -> None:
        """The shared checks (:meth:`SamplingConfig.validate`), ``temperature > 0`` and the
        temperature mode."""
        super().validate(nu, dt)
        positive("temperature", self.temperature)
        one_of("temperature_mode", self.temperature_mode, TEMPERATURE_MODES)


@checked_options
@dataclass(frozen=True, kw_only=True)
class CEMConfig(SamplingConfig):
    """Cross-entropy method options.

    The sampling distribution is a diagonal Gaussian over knots whose mean and standard
    deviation are refitted to the elites. The initial standard deviation is ``std_init``
    (default ``noise_scale``) and the refit is capped at ``max(std_init, noise_scale)``;
    both are multiplied by ``noise_schedule`` per knot.

    Attributes:
        std_init: Initial standard deviation, a scalar or one value per actuator ``(nu,)``;
            ``None``: ``noise_scale``.
        num_elites: Number of lowest-cost candidates the distribution is refitted to.
        std_min: Floor of the standard deviation (keeps exploring).
        smoothing: Weight of the old distribution in the refit, in ``[0, 1)``.
    """

    num_elites: int = 16
    std_min: float = 0.05
    smoothing: float = 0.0
    std_init: float | Sequence[float] | None = None

    def validate(self, nu: int, dt: float) -> None:
        """The shared checks (:meth:`SamplingConfig.validate`) and the elite/std options."""
        super().validate(nu, dt)
        if not 1 <= integer("num_elites", self.num_elites) <= self.num_samples:
            raise InvalidArgumentError(
                f"num_elites must be in [1, num_samples={self.num_samples}], got {self.num_elites}"
            )
        non_negative("std_min", self.std_min)
        in_range("smoothing", self.smoothing, 0.0, 1.0, low_open=False, high_open=True)
        cap = float(np.max(np.maximum(self.initial_std(nu), self.knot_noise(nu))))
        if self.std_min > cap:
            raise InvalidArgumentError(
                f"std_min must not exceed the largest standard deviation the refit allows, "
                f"max(std_init, noise_scale) = {cap:g}, got {self.std_min!r}"
            )

    def initial_std(self, nu: int) -> np.ndarray:
        """``std_init`` (or ``noise_scale``) per knot and control ``(K, nu)``, scheduled.

        Raises:
            InvalidArgumentError: For a wrong shape, a negative or a non-finite value.
        """
        if self.std_init is None:
            return self.knot_noise(nu)
        std = as_array("std_init", self.std_init, (None,) * min(1, np.ndim(self.std_init)))
        if std.ndim == 0:
            std = np.full(nu, float(std))
        if std.shape != (nu,) or not np.all(np.isfinite(std)) or np.any(std < 0):
            raise InvalidArgumentError(
                f"std_init must be None, a non-negative scalar or ({nu},) array, "
                f"got {self.std_init!r}"
            )
        return self.noise_multipliers()[:, None] * std[None, :]
