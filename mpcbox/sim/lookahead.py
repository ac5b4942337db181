r"""Latency compensation for the real-time loop: plan from where the robot will be.

A planner tick that starts from the state :math:`x(t_s)` and takes :math:`\ell` wall
seconds publishes a plan whose first :math:`a = \ell \cdot \text{speed}` simulated seconds
are already in the past: the world executed the previous plan meanwhile, and the new plan
starts from a state :math:`a` seconds old. With a *lookahead* :math:`L` the planner first
predicts

.. math::

    \hat x(t_s + L) = \Phi_L\big(x(t_s);\ u_{\text{prev}}(\cdot)\big),

stepping the task's model (:attr:`Problem.model <mpcbox.Problem.model>`, at its own
timestep; the disturbances and any model mismatch are unknown to the planner) under the
control the world will apply meanwhile, the previous plan's (its spline, feedback law or
catch, exactly as :meth:`~mpcbox.sim.planner_thread.PlannerThread.control` evaluates it),
and plans from :math:`(\hat x, t_s + L)`. The world keeps executing the previous plan until
:math:`t_s + L` and the new one from then on, so the prediction is consistent with what
runs. This is the usual delay compensation of MPC on hardware; the prediction error (noise,
pushes, contact changes within :math:`L`) is what remains.

``lookahead="auto"`` takes :math:`L` as ``speed`` times the median wall time of the last
:data:`AUTO_WINDOW` ticks (the controller's ``period`` before the first tick was timed), so
a plan starts about when it is published. A plan takes effect at the first world step at or
after its start, so :math:`L` is rounded up to whole model steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from mpcbox.core.dynamics import write_state
from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.divergence import DivergenceMonitor
from mpcbox.validation import non_negative

#: Ticks whose median wall time sets ``lookahead="auto"``.
AUTO_WINDOW = 10

#: The values ``lookahead`` accepts besides a number of seconds.
LOOKAHEAD_CHOICES = ("auto",)


def whole_steps(seconds: float, dt: float) -> int:
    """Simulation steps of ``dt`` until ``seconds`` have passed, rounded up (a plan takes
    effect at the first world step at or after its start): ``ceil(seconds / dt)``, to within
    1e-6 of a step, and at least 0."""
    return max(0, math.ceil(seconds / dt - 1e-6))


def check_lookahead(value: object) -> float | str | None:
    """Check a ``lookahead`` argument: ``None`` (off), ``"auto"``, or seconds ``>= 0``.

    Raises:
        InvalidArgumentError: For another string or a negative or non-finite number.
        InvalidTypeError: For another type.
    """
    if value is None:
        return None
    if isinstance(value, str):
        if value not in LOOKAHEAD_CHOICES:
            raise InvalidArgumentError(
                f"lookahead must be None, 'auto' or seconds >= 0, got {value!r}"
            )
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidTypeError(
            f"lookahead must be None, 'auto' or seconds >= 0, got {type(value).__name__}"
        )
    return non_negative("lookahead", value) + 0.0  # -0.0 as 0.0


class Lookahead:
    """Predicts the state a tick's plan will start from (see the module docstring).

    Args:
        problem: The task; its ``model`` is stepped, in an ``MjData`` of this object's own
            (use one :class:`Lookahead` per thread).
        lookahead: ``"auto"`` or seconds ``>= 0`` of simulated time.
        period: The controller's period (s): the ``"auto"`` guess before any tick was timed.
        speed: Simulated seconds per wall-clock second of the run.
        limit: The longest lookahead (s; the run's duration): ``"auto"``'s estimate is
            capped there, so a slow tick cannot ask for an endless prediction.
    """

    def __init__(
        self,
        problem: Problem,
        lookahead: float | str,
        *,
        period: float,
        speed: float,
        limit: float = np.inf,
    ) -> None:
        self.problem = problem
        self.lookahead = check_lookahead(lookahead)
        self.period = float(period)
        self.speed = float(speed)
        self.limit = float(limit)
        self.model = problem.model
        self.data = mujoco.MjData(self.model)
        self.dt = float(self.model.opt.timestep)

    def seconds(self, latencies: Sequence[float]) -> float:
        """The lookahead of the next tick (s of simulated time), given the wall times (s)
        of the ticks so far."""
        if self.lookahead != "auto":
            return min(float(self.lookahead), self.limit)  # type: ignore[arg-type]
        if not latencies:
            return min(self.period, self.limit)
        return min(self.speed * float(np.median(latencies[-AUTO_WINDOW:])), self.limit)

    def steps(self, seconds: float) -> int:
        """Model steps of a lookahead of ``seconds``, rounded up (:func:`whole_steps`)."""
        return whole_steps(seconds, self.dt)

    def predict(
        self,
        state: np.ndarray,
        time: float,
        steps: int,
        control: Callable[[float, np.ndarray], np.ndarray],
    ) -> tuple[np.ndarray, float]:
        """Step the model ``steps`` times from ``state`` ``(nstate,)`` at ``time`` under the
        feedback ``control(time, state) -> ctrl (nu,)``.

        Returns:
            The predicted state ``(nstate,)`` and its time ``time + steps dt``; ``state``
            and ``time`` unchanged when ``steps = 0`` or when the prediction diverged
            (MuJoCo's warnings or a non-finite state,
            :class:`~mpcbox.sim.divergence.DivergenceMonitor`: the planner then plans from
            what it saw, and the world's own checks report a divergence that happens there).
        """
        if steps <= 0:
            return state, time
        data = self._start(state, time)
        monitor = DivergenceMonitor(data)
        for _ in range(steps):
            data.ctrl[:] = control(float(data.time), self.problem.get_state(data))
            monitor.before_step()
            mujoco.mj_step(self.model, data)
            if monitor.after_step() is not None:
                return state, time
        return self.problem.get_state(data), time + steps * self.dt

    def predict_open_loop(
        self, state: np.ndarray, time: float, ctrls: np.ndarray
    ) -> tuple[np.ndarray, float]:
        """:meth:`predict` under controls known in advance ``(steps, nu)``, in one
        :func:`mujoco.rollout.rollout` call (no Python per step, and the GIL is released
        while it runs, so the world's thread is not held up). Same returns."""
        from mujoco import rollout as mj_rollout

        steps = len(ctrls)
        if steps <= 0:
            return state, time
        data = self._start(state, time)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        init = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, data, init, spec)
        with captured_warnings():
            out, _ = mj_rollout.rollout(self.model, data, init[None], ctrls[None], nstep=steps)
        final = out[0, -1]
        # A reset by MuJoCo (divergence) sets the time back; the full state starts with it.
        if not (np.all(np.isfinite(final)) and final[0] > time + (steps - 0.5) * self.dt):
            return state, time
        mujoco.mj_setState(self.model, data, final, spec)
        return self.problem.get_state(data), time + steps * self.dt

    def _start(self, state: np.ndarray, time: float) -> mujoco.MjData:
        """This object's data at ``state`` and ``time``, without applied forces."""
        data = self.data
        # Unchecked: a state beyond MuJoCo's limit makes it reset, which the prediction
        # detects and answers with the observed state (the world reports the divergence).
        write_state(data, state)
        data.time = time
        data.xfrc_applied[:] = 0.0
        return data
