"""The planner side of the real-time loop (:mod:`mpcbox.sim.realtime`): a controller ticking
in a thread of its own on the latest observed state, publishing plans the world reads.

All exchange between the world and the planner goes through one lock: the world writes the
latest state (:meth:`PlannerThread.observe`) and reads the control of the latest plan
(:meth:`PlannerThread.control`); the planner copies the state, solves without the lock and
publishes an immutable plan.
"""

from __future__ import annotations

import copy
import threading
import time as _time
from typing import Any, NamedTuple

import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.core.problem import Problem
from mpcbox.sim.lookahead import Lookahead
from mpcbox.sim.simulation import _error_text


class Plan(NamedTuple):
    """One published plan.

    Attributes:
        time: Simulated time of the state it was planned from (s).
        ctrl: The control the controller returned ``(nu,)``.
        knots: Copy of the controller's spline knots ``(K, nu)``, or ``None`` (hold ``ctrl``).
        spline: The spline that evaluates ``knots`` (the controller's when the plan was
            published: a controller that hands over between planners may change it).
        policy: The controller's feedback law of this plan, ``policy(state, time) -> ctrl``
            (iLQR-MPC's :class:`~mpcbox.controllers.ilqr.policy.FeedbackPolicy`), or
            ``None``.
        visible: Simulated time from which the world may use it (a simulated ``delay``;
            ``-inf``: at once).
    """

    time: float
    ctrl: np.ndarray
    knots: np.ndarray | None
    spline: Any = None
    policy: Any = None
    visible: float = -np.inf


class PlannerThread:
    """Runs ``controller`` in a thread, one tick per ``period`` of simulated time.

    Args:
        problem: The Problem (control clipping and shapes).
        controller: The controller; a spline plan is used when it has ``spline`` and
            ``knots`` attributes (the sampling controllers), read at every publication, and
            a feedback law when its ``policy()`` returns one (iLQR-MPC).
        period: Simulated seconds between tick starts.
        max_ticks: Bound on the ticks of one run (the loop is bounded).
        lookahead: Latency compensation (:mod:`mpcbox.sim.lookahead`): ``None`` plans from
            the observed state; ``"auto"`` or seconds plan from the state predicted that far
            ahead, and the world keeps the previous plan until the new one's start.
        speed: Simulated seconds per wall-clock second (for ``lookahead="auto"``).
        delay: A simulated latency (s): no thread; the world calls :meth:`tick_inline`
            after each :meth:`observe`, each tick takes ``delay`` simulated seconds (its plan
            becomes visible to the world then) and the next one starts when it is done or
            ``period`` after it started, whichever is later, as one planner thread whose
            ticks take ``delay / speed`` wall seconds would (``lookahead="auto"`` then
            predicts ``delay`` ahead).
        end: The run's last simulated time (s): ``"auto"`` lookaheads are capped at it, and
            with ``delay`` no tick starts whose plan would take effect only at or after it.

    Attributes:
        latencies: Wall time of each tick published in the run, the prediction included (s).
        lookaheads: Simulated time each of those ticks planned ahead of its observed
            state (s; zeros without ``lookahead``).
        kinds: ``Controller.last_call`` of each of those ticks.
        error: ``"controller error: ..."`` once the controller raised or returned an
            invalid control, else ``None``.
    """

    def __init__(
        self,
        problem: Problem,
        controller: Controller,
        *,
        period: float,
        max_ticks: int,
        lookahead: float | str | None = None,
        speed: float = 1.0,
        delay: float | None = None,
        end: float = np.inf,
    ) -> None:
        self.problem = problem
        self.controller = controller
        self.period = float(period)
        self.max_ticks = int(max_ticks)
        self.delay = None if delay is None else float(delay)
        self.end = float(end)
        if lookahead == "auto" and self.delay is not None:
            lookahead = self.delay
        self.lookahead = (
            None
            if lookahead is None
            else Lookahead(problem, lookahead, period=self.period, speed=speed, limit=end)
        )
        self.latencies: list[float] = []
        self.lookaheads: list[float] = []
        self.kinds: list[str] = []
        self.error: str | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._new_state = threading.Event()
        # The latest observed state, its time, the plan in force then and (with a lookahead)
        # a snapshot of that plan's feedback law as the world holds it at that time.
        self._state: tuple[np.ndarray, float, Plan, Any] | None = None
        # Published plans, oldest first: one without a lookahead or delay; with them, also
        # those not yet in force (planned from a predicted state, or not yet visible) and
        # the one in force before them.
        self._plans = [Plan(0.0, problem.clip_ctrl(problem.ctrl_ref.copy()), None)]
        self._thread: threading.Thread | None = None
        self._next_time = -np.inf
        self._last_start = -np.inf  # start time of the latest plan published

    # ------------------------------------------------------------------ world side
    def observe(self, state: np.ndarray, time: float) -> Plan:
        """Record the latest state ``(nstate,)`` at simulated ``time``; returns the plan in
        force at ``time``, for the world's :meth:`control` of that step (so that a tick
        predicting ahead from this state knows which plan the world applies at it, even
        when it publishes a new one in between)."""
        with self._lock:
            plan = self._select(float(time))
            # A law may hold its control within a knot: the prediction continues from the
            # world's copy as it is now, not from one that the world goes on calling.
            law = None
            if self.lookahead is not None and plan.policy is not None:
                law = copy.copy(plan.policy)
            self._state = (state.copy(), float(time), plan, law)
        self._new_state.set()
        return plan

    def control(
        self,
        time: float,
        state: np.ndarray | None = None,
        plan: Plan | None = None,
        own: dict[int, Any] | None = None,
    ) -> np.ndarray:
        """The control at simulated ``time`` ``(nu,)`` of ``plan`` (default: the plan in
        force at ``time``: the latest, or the one before it while the latest, planned from a
        predicted state, has not started).

        For a controller with a catch (a sampling controller's ``catch``, see
        :mod:`mpcbox.controllers.sampling.catch`) and the world's ``state`` ``(nstate,)``,
        the catch's feedback wherever it engages, as in the controller's own calls.
        ``own`` holds a caller's own copies of the plans' feedback laws, by plan (the
        prediction's: a law may hold its control within a knot, so the world's copy must
        not be evaluated at predicted states).
        """
        catch = getattr(self.controller, "catch", None)
        if catch is not None and state is not None:
            caught = catch.control(state)
            if caught is not None:
                return caught
        if plan is None:
            with self._lock:
                plan = self._select(float(time))
        if plan.policy is not None and state is not None:
            policy = plan.policy
            if own is not None:
                if id(plan) not in own:
                    own[id(plan)] = copy.copy(policy)
                policy = own[id(plan)]
            return self.problem.clip_ctrl(policy(state, float(time)))
        if plan.knots is None or plan.spline is None:
            return plan.ctrl
        offset = float(time) - plan.time
        return self.problem.clip_ctrl(plan.spline.evaluate(plan.knots, [offset])[0])

    def _select(self, time: float) -> Plan:
        """The plan in force at ``time``: the latest published one that has started and is
        visible (the oldest kept when none is). Call with the lock held."""
        for plan in reversed(self._plans):
            if plan.time <= time + 1e-12 and plan.visible <= time + 1e-12:
                return plan
        return self._plans[0]

    def prime(self, state: np.ndarray, time: float) -> float:
        """Solve one tick before the clock starts; returns its wall time (s).

        An exception is recorded in :attr:`error` (the run then ends at its first step).
        """
        start = _time.perf_counter()
        try:
            out = self.controller(state.copy(), float(time))
        except Exception as exc:  # recorded; the world ends the run
            self.error = _error_text(exc)
            return _time.perf_counter() - start
        seconds = _time.perf_counter() - start
        if self._publish(out, float(time)):
            self._next_time = float(time) + self.period
        return seconds

    def start(self, state: np.ndarray, time: float) -> None:
        """Start the thread from ``state`` at ``time``."""
        self.observe(state, time)
        self._thread = threading.Thread(target=self._loop, name="mpcbox-planner", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Ask the thread to stop after its current tick and join it."""
        self._stop.set()
        self._new_state.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def tick_inline(self) -> None:
        """With a simulated ``delay``: run a tick now if one is due at the latest observed
        time (the world waits for it), its plan visible ``delay`` later. A fault is recorded
        in :attr:`error`."""
        state, time, seen, law = self._state  # type: ignore[misc]
        if self.error is not None or time < self._next_time - 1e-12:
            return
        if len(self.latencies) >= self.max_ticks:
            return
        delay = float(self.delay or 0.0)
        if time + delay >= self.end - 1e-9:
            return  # its plan would take effect at the run's end or later: never applied
        # One planner, as in the threaded loop: the next tick starts when this one is done
        # or a period after it started, whichever is later.
        self._next_time = time + max(self.period, delay)
        try:
            self._tick(state, time, seen, law, visible=time + delay)
        except Exception as exc:  # recorded; the world ends the run
            self.error = _error_text(exc)

    def calls(self) -> dict[str, list[float]]:
        """Tick durations (s) by ``last_call`` kind (``"solve"``, ``"hold"``, ``"offline"``)."""
        out: dict[str, list[float]] = {"solve": [], "hold": [], "offline": []}
        for kind, seconds in zip(self.kinds, self.latencies):
            out[kind if kind in out else "solve"].append(seconds)
        return out

    # ------------------------------------------------------------------ planner side
    def _loop(self) -> None:
        try:
            self._ticks()
        except Exception as exc:  # a fault of the loop itself (never silent): recorded too
            self.error = _error_text(exc)

    def _ticks(self) -> None:
        for _ in range(self.max_ticks):
            while not self._stop.is_set() and self.error is None:
                self._new_state.clear()
                with self._lock:
                    state, time, seen, law = self._state  # type: ignore[misc]
                if time >= self._next_time - 1e-12:
                    break
                self._new_state.wait(0.05)
            if self._stop.is_set() or self.error is not None:
                return
            self._next_time = time + self.period
            try:
                self._tick(state, time, seen, law)
            except Exception as exc:  # recorded; the world ends the run
                self.error = _error_text(exc)
            if self.error is not None:
                return

    def _tick(
        self, state: np.ndarray, time: float, seen: Plan, law: Any, visible: float = -np.inf
    ) -> None:
        """One tick from ``state`` observed at ``time``: predict (with a lookahead), plan,
        publish; records its wall time. An invalid control is recorded in :attr:`error`."""
        start = _time.perf_counter()
        ahead = 0.0
        if self.lookahead is not None:
            state, predicted = self._predict(state, time, seen, law)
            ahead, time = predicted - time, predicted
        out = self.controller(state, time)
        seconds = _time.perf_counter() - start
        if self._publish(out, time, visible):
            self.latencies.append(seconds)
            self.lookaheads.append(ahead)
            self.kinds.append(str(getattr(self.controller, "last_call", "solve")))

    def _predict(
        self, state: np.ndarray, time: float, seen: Plan, law: Any = None
    ) -> tuple[np.ndarray, float]:
        """The state and time the next plan starts from (:attr:`lookahead`'s prediction
        under the controls the world applies meanwhile: ``seen``, the plan in force when
        ``state`` was observed, at ``time``, then the plans in force). Open-loop plans
        (splines and held controls, no catch) are evaluated in advance and rolled out in
        one call; feedback laws step by step."""
        assert self.lookahead is not None
        want = self.lookahead.seconds(self.latencies)
        # Plans start at least a period apart, as the ticks do: a lookahead that shrank
        # (``"auto"`` after faster ticks) must not hand the controller a time less than a
        # period after its last one (iLQR-MPC would skip the replan as not yet due).
        want = max(want, self._last_start + self.period - time)
        steps = self.lookahead.steps(want)
        if time + self.lookahead.dt * steps < self._last_start + self.period - 1e-9:
            steps += 1  # within whole_steps' 1e-6 of a step, but short of the spacing
        times = time + self.lookahead.dt * np.arange(steps)
        with self._lock:
            plans = [seen] + [self._select(float(t)) for t in times[1:]]
        if getattr(self.controller, "catch", None) is None and all(p.policy is None for p in plans):
            ctrls = np.empty((steps, self.problem.nu))
            for i, plan in enumerate(plans):
                if i and plan is plans[i - 1]:
                    continue
                j = i + 1
                while j < steps and plans[j] is plan:
                    j += 1
                if plan.knots is None or plan.spline is None:
                    ctrls[i:j] = plan.ctrl
                else:
                    ctrls[i:j] = plan.spline.evaluate(plan.knots, times[i:j] - plan.time)
            return self.lookahead.predict_open_loop(state, time, self.problem.clip_ctrl(ctrls))

        # The prediction's own copies of the laws (a law may hold its control within a
        # knot): of ``seen``'s as the world held it at ``time``, and of later plans'.
        own: dict[int, Any] = {} if law is None else {id(seen): law}

        def control(t: float, x: np.ndarray) -> np.ndarray:
            return self.control(t, x, seen if t == time else None, own)

        return self.lookahead.predict(state, time, steps, control)

    def _publish(self, out: object, time: float, visible: float = -np.inf) -> bool:
        """Publish the controller's output; record an error and return False if invalid."""
        ctrl = np.asarray(out, dtype=np.float64)
        if ctrl.shape != (self.problem.nu,) or not np.all(np.isfinite(ctrl)):
            self.error = (
                f"controller error: invalid control (shape {ctrl.shape}, finite="
                f"{bool(np.all(np.isfinite(ctrl)))})"
            )
            return False
        has_knots = hasattr(self.controller, "knots")
        spline = getattr(self.controller, "spline", None) if has_knots else None
        if spline is not None and getattr(self.controller, "last_call", "") == "hold":
            return True  # followed the current plan: keep its knots and plan time
        knots = getattr(self.controller, "knots", None) if spline is not None else None
        if knots is None:
            spline = None
        else:
            knots = np.array(knots, copy=True)
        policy = getattr(self.controller, "policy", None)
        policy = policy() if callable(policy) else None
        if policy is not None:  # the world's own copy (the controller keeps calling its own)
            policy = copy.copy(policy)
        plan = Plan(time, ctrl.copy(), knots, spline, policy, visible)
        self._last_start = time
        with self._lock:
            if self.lookahead is None and self.delay is None:
                self._plans = [plan]
            else:
                # Keep the plan in force at the latest observed time and all later ones.
                seen = self._state[1] if self._state is not None else -np.inf
                self._plans.append(plan)
                in_force = self._select(seen)
                start = next(i for i, p in enumerate(self._plans) if p is in_force)
                del self._plans[:start]
        return True
