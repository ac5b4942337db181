"""How a closed-loop run ends: divergence, controller errors, missed goals, degraded runs.

Each reproducer of issue #14 must end as a recorded failure with its trajectory kept, never
as survival.
"""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.registry import task_class
from mpcbox.sim.disturbances import Push
from mpcbox.sim.simulation import OUTCOMES

# A slide joint of mass 1e-9 driven through a gear of 1e12: any control makes MuJoCo reset.
EXPLODING = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="slider"><joint name="s" type="slide" axis="1 0 0"/>
      <geom type="sphere" size=".1" mass="1e-9"/></body>
  </worldbody>
  <actuator><motor joint="s" gear="1e12"/></actuator>
</mujoco>
"""

PENDULUM = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="pole"><joint name="h" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -.5" size=".02" mass="1"/></body>
  </worldbody>
  <actuator><motor joint="h" ctrlrange="-5 5"/></actuator>
</mujoco>
"""


class Constant(mpcbox.Controller):
    def __init__(self, value: float) -> None:
        self.value = value

    def __call__(self, state, time):
        return np.array([self.value])


class Raising(mpcbox.Controller):
    """Works for ``calls`` calls, then raises a non-mpcbox exception (as OSQP or numpy do)."""

    def __init__(self, calls: int) -> None:
        self.calls = calls
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def __call__(self, state, time):
        self.count += 1
        if self.count > self.calls:
            raise np.linalg.LinAlgError("Singular matrix")
        return np.zeros(1)


class Degrading(mpcbox.Controller):
    """Reports a fallback on a share of its calls, and holds on others."""

    def __init__(self, share: float) -> None:
        self.share = share
        self.calls = 0
        self.fallbacks = 0

    def reset(self) -> None:
        self.calls = self.fallbacks = 0

    def __call__(self, state, time):
        self.calls += 1
        if self.fallbacks < self.share * self.calls:
            self.fallbacks += 1
        self.last_call = "hold" if self.calls % 2 == 0 else "solve"
        return np.zeros(1)

    @property
    def stats(self):
        return {"fallbacks": float(self.fallbacks)}


def test_exploding_model_is_diverged_not_survived():
    problem = mpcbox.Problem(EXPLODING)
    res = mpcbox.simulate(problem, Constant(1.0), 0.1)
    assert not res.survived and not res.metrics.success
    assert res.metrics.outcome == "diverged"
    assert res.failure.startswith("diverged:") and "MuJoCo" in res.failure
    # The record is kept up to the step that diverged.
    assert res.time.shape[0] == res.states.shape[0] >= 1
    assert res.metrics.time_to_fall < 0.1


def test_control_beyond_mujocos_limit_is_reported():
    """MuJoCo zeroes a control beyond 1e10 and warns; the run must not read as survival."""
    problem = mpcbox.Problem(PENDULUM.replace('ctrlrange="-5 5"', 'ctrllimited="false"'))
    res = mpcbox.simulate(problem, Constant(2e10), 0.05)
    assert res.metrics.outcome == "diverged"
    assert "control" in res.failure


def test_a_huge_push_is_diverged():
    problem = mpcbox.Problem(EXPLODING.replace('mass="1e-9"', 'mass="1e-6"'))
    push = Push(body="slider", force=(1e7, 0.0, 0.0), start=0.01, duration=0.01)
    res = mpcbox.simulate(problem, Constant(0.0), 0.05, pushes=[push])
    assert res.metrics.outcome == "diverged"
    assert res.time[-1] == pytest.approx(0.01, abs=0.0021)


@pytest.mark.parametrize("calls", [0, 5])
def test_controller_exception_is_a_recorded_failure(calls):
    problem = mpcbox.Problem(PENDULUM)
    res = mpcbox.simulate(problem, Raising(calls), 0.1)
    assert res.metrics.outcome == "controller error"
    assert "LinAlgError" in res.failure and "Singular matrix" in res.failure
    # The steps before the error are kept.
    assert res.time.shape == (calls + 1,)
    assert res.metrics.time_to_fall == pytest.approx(calls * problem.model.opt.timestep)


class MissesGoal(mpcbox.Problem):
    def goal_failure(self, time, states):
        error = abs(states[-1, 0] - np.pi)
        return None if error < 0.1 else f"not upright at the end: {error:.2f} rad"


def test_goal_failure_makes_a_survived_run_unsuccessful():
    res = mpcbox.simulate(MissesGoal(PENDULUM), Constant(0.0), 0.1)
    assert res.survived and not res.metrics.success
    assert res.metrics.outcome == "goal missed"
    assert res.failure == "not upright at the end: 3.14 rad"
    # Time to fall is the duration: nothing fell.
    assert res.metrics.time_to_fall == pytest.approx(0.1)


@pytest.mark.parametrize(("share", "outcome"), [(0.2, "success"), (0.9, "degraded")])
def test_runs_that_mostly_fell_back_are_degraded(share, outcome):
    res = mpcbox.simulate(mpcbox.Problem(PENDULUM), Degrading(share), 0.1)
    assert res.metrics.outcome == outcome
    calls = res.metrics.solve_ticks + res.metrics.held_ticks
    assert calls == 50
    assert res.metrics.degraded_ticks == res.metrics.fallbacks == pytest.approx(share * 50, abs=1)
    # Held calls are counted but not timed as ticks.
    assert res.metrics.held_ticks == 25 and res.compute_times.shape == (25,)


def test_fallbacks_are_counted_per_run_not_cumulated():
    controller, problem = Degrading(0.9), mpcbox.Problem(PENDULUM)
    first = mpcbox.simulate(problem, controller, 0.1)
    controller.reset = lambda: None  # a controller that never clears its counters
    second = mpcbox.simulate(problem, controller, 0.1)
    assert second.metrics.fallbacks == first.metrics.fallbacks


def test_offline_and_held_calls_are_not_ticks():
    problem = task_class("pendulum_swingup")()
    ilqr = mpcbox.make_controller("ilqr", problem, horizon=20, first_iterations=5)
    res = mpcbox.simulate(problem, ilqr, 0.1)
    m = res.metrics
    assert m.offline_ms > 0  # the warm-up solve
    assert m.solve_ticks + m.held_ticks + 1 == 0.1 / problem.model.opt.timestep
    assert m.solve_ticks == res.compute_times.size
    # A solve's budget is the replanning period, not the step at which held calls come.
    assert ilqr.replan_period > problem.model.opt.timestep
    assert m.period_s == pytest.approx(ilqr.replan_period)


def test_outcomes_are_documented_and_bad_arguments_named():
    assert set(OUTCOMES) == {
        "success",
        "failed",
        "diverged",
        "controller error",
        "goal missed",
        "degraded",
    }
    problem = mpcbox.Problem(PENDULUM)
    with pytest.raises(mpcbox.errors.InvalidArgumentError, match="degraded_limit"):
        mpcbox.simulate(problem, Constant(0.0), 0.1, degraded_limit=2.0)
    with pytest.raises(mpcbox.errors.InvalidArgumentError, match="seed"):
        mpcbox.simulate(problem, Constant(0.0), 0.1, seed=-1)


def test_rollout_that_diverges_on_its_first_step_is_marked_non_finite():
    """MuJoCo's reset on the first step of a rollout leaves time at one step, as if nothing
    happened; the rollout must still come back NaN from there, never as the reset pose."""
    problem = mpcbox.Problem(EXPLODING)
    rollout = problem.rollout(problem.reference_state(), np.ones((2, 3, 1)))
    assert np.all(rollout.states[:, 0] == 0.0)
    assert np.all(np.isnan(rollout.states[:, 1:]))
    calm = problem.rollout(problem.reference_state(), np.zeros((1, 3, 1)))
    assert np.all(np.isfinite(calm.states))


class Stalling(Degrading):
    """Reports a stall (a solve that kept its warm start) on every solve."""

    def __init__(self) -> None:
        super().__init__(0.0)
        self.stalled = 0

    def reset(self) -> None:
        super().reset()
        self.stalled = 0

    def __call__(self, state, time):
        ctrl = super().__call__(state, time)
        if self.last_call == "solve":
            self.stalled += 1
        return ctrl

    @property
    def stats(self):
        return {"fallbacks": 0.0, "stalled": float(self.stalled)}


def test_stalls_are_counted_per_run_and_are_not_failures():
    controller, problem = Stalling(), mpcbox.Problem(PENDULUM)
    first = mpcbox.simulate(problem, controller, 0.1)
    # 25 solves (every other call), each a stall; held calls cannot stall.
    assert first.metrics.stalls == first.metrics.solve_ticks == 25
    assert first.metrics.outcome == "success"
    assert first.metrics.fallbacks == 0
    controller.reset = lambda: None  # counters that are never cleared
    second = mpcbox.simulate(problem, controller, 0.1)
    assert second.metrics.stalls == first.metrics.stalls
    assert mpcbox.simulate(problem, Degrading(0.0), 0.1).metrics.stalls == 0
