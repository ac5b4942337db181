"""Test conditions of a comparison: closed-loop :class:`Scenario` and :class:`PushTest`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.disturbances import MAX_FORCE, ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.lookahead import check_lookahead
from mpcbox.sim.realtime import simulate_realtime
from mpcbox.sim.simulation import SimulationResult, simulate
from mpcbox.validation import (
    boolean,
    checked_options,
    finite_array,
    instance,
    non_negative,
    positive,
    string,
)


def _check_noise_scale(value: float) -> None:
    non_negative("noise_scale", value)


def task_noise(problem: Problem, scale: float) -> ActuatorNoise | None:
    """The problem's noise model at ``scale`` (:meth:`~mpcbox.Problem.noise`); ``None`` at 0.

    Raises:
        InvalidArgumentError: When ``scale > 0`` and the task has no noise model.
    """
    return None if scale == 0 else problem.noise(scale)


def has_noise_model(problem: Problem | type[Problem]) -> bool:
    """Whether the task overrides :meth:`~mpcbox.Problem.noise` (the base class has none)."""
    cls = problem if isinstance(problem, type) else type(problem)
    return cls.noise is not Problem.noise


@checked_options
@dataclass(frozen=True, kw_only=True)
class Scenario:
    """One closed-loop test condition, run once per seed.

    The actuator noise is ``noise`` scaled by ``noise_scale`` when ``noise`` is given, and
    otherwise the task's own model ``problem.noise(noise_scale)``
    (:meth:`~mpcbox.Problem.noise`, e.g. the humanoid recipe); asking a task without a noise
    model for noise is an error. ``noise_scale = 0`` always means no noise.

    Attributes:
        name: Label in tables and file names (default: built from the settings).
        duration: Simulated time per run (s).
        noise_scale: Multiplier on the noise standard deviation.
        noise: Explicit actuator noise (overrides the task's noise model).
        pushes: Pushes applied in every run.
        mismatch: Model mismatch of the simulated plant.
        realtime: Run in the asynchronous real-time loop
            (:func:`~mpcbox.sim.realtime.simulate_realtime`): the world does not wait for the
            planner, and the table reports whether each planner kept up. Latency depends on
            the machine's load: run real-time comparisons serially (``workers=1``).
        speed: Simulated seconds per wall-clock second of a real-time run.
        lookahead: Latency compensation of a real-time run (:mod:`mpcbox.sim.lookahead`):
            ``None`` plans from the observed state, ``"auto"`` or seconds from the state
            predicted that far ahead. Only with :attr:`realtime`.
        delay: A simulated latency (s) for a real-time run instead of the wall clock
            (``simulate_realtime``'s ``delay``: reproducible on any machine). Only with
            :attr:`realtime`.
    """

    name: str = ""
    duration: float = 10.0
    noise_scale: float = 1.0
    noise: ActuatorNoise | None = None
    pushes: tuple[Push, ...] = ()
    mismatch: ModelMismatch | None = None
    realtime: bool = False
    speed: float = 1.0
    lookahead: float | str | None = None
    delay: float | None = None

    def __post_init__(self) -> None:
        string("name", self.name)
        boolean("realtime", self.realtime)
        # Plain floats (-0.0 as 0.0), so that scenarios hash and print alike.
        object.__setattr__(self, "speed", positive("speed", self.speed))
        if self.speed != 1.0 and not self.realtime:
            raise InvalidArgumentError("speed needs realtime=True (a lock-step run has no clock)")
        object.__setattr__(self, "lookahead", check_lookahead(self.lookahead))
        if self.lookahead is not None and not self.realtime:
            raise InvalidArgumentError(
                "lookahead needs realtime=True (a lock-step run has no latency to compensate)"
            )
        if self.delay is not None:
            if not self.realtime:
                raise InvalidArgumentError("delay needs realtime=True")
            object.__setattr__(self, "delay", non_negative("delay", self.delay) + 0.0)
            if self.speed != 1.0:
                raise InvalidArgumentError(
                    "speed has no effect with delay (the world waits for each tick): "
                    "leave it at 1.0"
                )
        positive("duration", self.duration)
        _check_noise_scale(self.noise_scale)
        if isinstance(self.pushes, (str, bytes)) or not isinstance(self.pushes, Sequence):
            raise InvalidTypeError(
                f"pushes must be a sequence of mpcbox.Push, got {type(self.pushes).__name__}"
            )
        object.__setattr__(self, "pushes", tuple(self.pushes))
        for push in self.pushes:
            instance("pushes", push, Push, "an mpcbox.Push (one per item)")
        if self.noise is not None:
            instance("noise", self.noise, ActuatorNoise, "an mpcbox.ActuatorNoise")
        if self.mismatch is not None:
            instance("mismatch", self.mismatch, ModelMismatch, "an mpcbox.ModelMismatch")

    @property
    def label(self) -> str:
        """``name``, or a short description such as ``"noise x1 push 30N mass x1.1"``."""
        if self.name:
            return self.name
        parts = [f"noise x{self.noise_scale:g}"]
        for push in self.pushes:
            parts.append(f"push {np.linalg.norm(push.force):g}N@{push.start:g}s")
        if self.mismatch is not None:
            m = self.mismatch
            if m.mass_scale != 1.0:
                parts.append(f"mass x{m.mass_scale:g}")
            if m.friction_scale != 1.0:
                parts.append(f"friction x{m.friction_scale:g}")
            for body, value in (m.body_mass_scale or {}).items():
                parts.append(f"{body} mass x{value:g}")
        if self.realtime:
            parts.append("real time" + ("" if self.speed == 1.0 else f" x{self.speed:g}"))
            if self.delay is not None:
                parts.append(f"delay {self.delay:g} s")
            if self.lookahead is not None:
                ahead = self.lookahead
                parts.append(f"lookahead {ahead if isinstance(ahead, str) else f'{ahead:g} s'}")
        return " ".join(parts)

    @property
    def uses_task_noise(self) -> bool:
        """Whether the noise comes from the task's noise model (none given, scale > 0)."""
        return self.noise is None and self.noise_scale > 0

    def resolve_noise(self, problem: Problem) -> ActuatorNoise | None:
        """The actuator noise of this scenario for ``problem`` (``None`` for none).

        Raises:
            InvalidArgumentError: When the scenario asks for the task's noise and the task
                has none.
        """
        if self.noise_scale == 0:
            return None
        if self.noise is not None:
            return replace(self.noise, scale=self.noise.scale * self.noise_scale)
        return task_noise(problem, self.noise_scale)

    def run(
        self, problem: Problem, controller: Controller, seed: int, **options: Any
    ) -> SimulationResult:
        """Simulate ``controller`` on ``problem`` under this scenario's disturbances.

        Lock-step (:func:`~mpcbox.sim.simulation.simulate`), or with :attr:`realtime` the
        asynchronous loop (:func:`~mpcbox.sim.realtime.simulate_realtime`) at :attr:`speed`.

        Args:
            problem: The task.
            controller: The controller.
            seed: Seed of the noise.
            **options: Passed to the loop (e.g. ``viewer``).
        """
        loop, extra = simulate, {}
        if self.realtime:
            loop = simulate_realtime
            extra = {"speed": self.speed, "lookahead": self.lookahead, "delay": self.delay}
        return loop(
            problem,
            controller,
            self.duration,
            noise=self.resolve_noise(problem),
            pushes=self.pushes,
            mismatch=self.mismatch,
            seed=seed,
            **extra,
            **options,
        )

    @classmethod
    def noise_sweep(cls, scales: Sequence[float], **kwargs: Any) -> list[Scenario]:
        """One scenario per noise scale, the other settings shared (``kwargs``)."""
        return [cls(noise_scale=float(s), **kwargs) for s in scales]


@checked_options
@dataclass(frozen=True, kw_only=True)
class PushTest:
    """A push-recovery test: the push, and the bisection that finds the largest survived one.

    Each trial starts from the initial state, pushes ``body`` with a constant force along
    ``direction`` from ``start`` for ``duration`` seconds, and must stay up ``settle``
    seconds after the push. :func:`~mpcbox.comparison.push_limits.largest_push` bisects the
    force magnitude on ``[0, max_force]`` down to ``tolerance``;
    :func:`~mpcbox.comparison.push_limits.push_grid` tries a grid of forces.
    :func:`~mpcbox.compare` runs a push test once per controller (seed 0 of the noise), not
    once per seed.

    Attributes:
        direction: Push direction ``(3,)`` (normalized for the force); ``(1, 0, 0)`` pushes
            forward (sagittal).
        duration: How long the force acts (s).
        start: Push start (s).
        settle: Time that must be survived after the push (s).
        body: Pushed body.
        max_force: Upper end of the search (N).
        tolerance: Bracket width at which the bisection stops (N).
        noise_scale: Scale of the task's noise model during the trials (0: none).
        name: Column label (default: from the direction, e.g. ``"+x"``).
        scan_step: Before bisecting, try ``scan_step``, ``2 scan_step``, ... (N) up to
            ``max_force`` and bisect between the last force survived and the first failed:
            the largest force below the first failure, as
            :func:`~mpcbox.comparison.push_limits.push_grid` reports it. ``None`` bisects
            ``[0, max_force]`` directly, which assumes that surviving a force means
            surviving every smaller one. A Unitree G1 under iLQR-MPC breaks that assumption:
            it falls after every push from 250 to 650 N on a grid, but after 638.8 N it
            hopped 2.75 m and was still up 2 s later, the figure the plain bisection
            reported (no rest criterion).
        rest_speed: Largest speed (m/s) of ``body``'s centre of mass at the end of a trial to
            count as recovered; ``None``: staying up is enough. A robot that is still hopping
            or drifting when ``settle`` ends has not recovered yet, and may fall later (a
            Unitree G1 under iLQR-MPC hopped on after 300-400 N pushes and fell 2.2-2.7 s
            after them).
    """

    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    duration: float = 0.1
    start: float = 1.0
    settle: float = 3.0
    body: str = "torso"
    max_force: float = 2000.0
    tolerance: float = 1.0
    noise_scale: float = 0.0
    name: str = ""
    rest_speed: float | None = None
    scan_step: float | None = None

    def __post_init__(self) -> None:
        direction = tuple(float(d) for d in finite_array("direction", self.direction, (3,)))
        if not any(direction):
            raise InvalidArgumentError(f"direction must be a non-zero 3-vector, got {direction}")
        object.__setattr__(self, "direction", direction)
        for name in ("duration", "settle", "max_force", "tolerance"):
            positive(name, getattr(self, name))
        if self.max_force > MAX_FORCE:
            raise InvalidArgumentError(
                f"max_force must be at most {MAX_FORCE:g} N (MAX_FORCE), got {self.max_force!r}"
            )
        non_negative("start", self.start)
        string("body", self.body)
        string("name", self.name)
        _check_noise_scale(self.noise_scale)
        if self.rest_speed is not None:
            positive("rest_speed", self.rest_speed)
        if self.scan_step is not None:
            positive("scan_step", self.scan_step)
        if self.tolerance >= self.max_force:
            raise InvalidArgumentError(
                f"tolerance must be below max_force ({self.max_force:g} N), got "
                f"{self.tolerance!r}: the bisection would stop before its first trial"
            )

    @property
    def label(self) -> str:
        """``name``, or the dominant axis with its sign, e.g. ``"+x"`` or ``"-y"``."""
        if self.name:
            return self.name
        axis = int(np.argmax(np.abs(self.direction)))
        sign = "+" if self.direction[axis] > 0 else "-"
        return f"{sign}{'xyz'[axis]}"

    @property
    def total_time(self) -> float:
        """Simulated time of one trial: ``start + duration + settle`` (s)."""
        return self.start + self.duration + self.settle

    @property
    def uses_task_noise(self) -> bool:
        """Whether the trials use the task's noise model (``noise_scale > 0``)."""
        return self.noise_scale > 0

    def push(self, force: float) -> Push:
        """The push of magnitude ``force`` (N) along the normalized ``direction``."""
        direction = np.asarray(self.direction, dtype=np.float64)
        return Push(
            force=force * (direction / np.linalg.norm(direction)),
            start=self.start,
            duration=self.duration,
            body=self.body,
        )


def check_noise_models(
    problem: Problem | type[Problem], conditions: Sequence[Scenario | PushTest]
) -> None:
    """Fail early when a condition asks for the task's noise and the task has no noise model.

    Args:
        problem: The Problem or its class.
        conditions: Scenarios and push tests.

    Raises:
        InvalidArgumentError: Naming the first such condition.
    """
    if has_noise_model(problem):
        return
    for condition in conditions:
        if condition.uses_task_noise:
            raise InvalidArgumentError(
                f"task {problem.name!r} has no noise model, but {type(condition).__name__} "
                f"{condition.label!r} asks for noise x{condition.noise_scale:g}: set "
                "noise_scale=0 (--noise 0) or give an explicit mpcbox.ActuatorNoise"
            )
