"""iLQR-MPC about an equilibrium: the reference linearization through joint dry friction, and
replans that do not inherit a raised regularization."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.core.cost import ControlCost, Cost, StateCost
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks import scene_path

# A two-link arm hanging under gravity, held by position servos at zero: the reference is an
# equilibrium. ``frictionloss`` gives each hinge MuJoCo's dry friction (stick or slip).
ARM = """
<mujoco>
  <option timestep="0.01"/>
  <default><joint axis="0 1 0" frictionloss="{friction}" armature="0.01"/></default>
  <worldbody>
    <body name="upper">
      <joint name="shoulder"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="1"/>
      <body name="lower" pos="0 0 -0.3">
        <joint name="elbow"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position joint="shoulder" kp="20" ctrlrange="-3 3"/>
    <position joint="elbow" kp="10" ctrlrange="-3 3"/>
  </actuator>
</mujoco>
"""
X0 = np.array([0.1, -0.05, 0.0, 0.0])


def gain_errors(friction: float, linearization: str, dry_friction: str = "drop") -> np.ndarray:
    """Relative distance ``(T,)`` of each knot's iLQR gain from the LQR gain, one iteration
    from ``X0`` with the LQR value as terminal cost."""
    problem = mpcbox.Problem(ARM.format(friction=friction), dry_friction=dry_friction, threads=1)
    lqr = mpcbox.LQR(problem)
    ilqr = ILQR(
        problem,
        horizon=30,
        terminal_value="lqr",
        linearization=linearization,
        regularization=0.0,
    )
    res = ilqr.solve(X0, max_iterations=1)
    assert np.all(res.ctrls > -3) and np.all(res.ctrls < 3)  # no clamped gains
    return np.linalg.norm(res.K + lqr.K, axis=(1, 2)) / np.linalg.norm(lqr.K)


def test_reference_linearization_keeps_the_lqr_gain_through_dry_friction():
    # Without friction the arm's dynamics are smooth: Jacobians along the trajectory stay
    # within 1 % of the reference's, and so do the gains.
    assert gain_errors(0.0, "trajectory").max() < 0.02
    # Differenced with it (dry_friction="keep"), each hinge sticks or slips and the
    # trajectory's Jacobians belong to another mode than the reference's: the gains differ
    # from the LQR gain by as much as the gain.
    assert gain_errors(0.3, "trajectory", "keep").max() > 0.5
    # Left out of the derivatives (dry_friction="drop"), it no longer splits the modes.
    assert gain_errors(0.3, "trajectory").max() < 0.02
    # Linearized at the reference, the LQR value is the exact cost-to-go of the backward
    # pass's model, so every knot's gain is the LQR gain, friction or not.
    for friction in (0.0, 0.3):
        for mode in ("drop", "keep"):
            assert gain_errors(friction, "reference", mode).max() < 1e-9


def test_reference_linearization_is_checked():
    problem = mpcbox.Problem(ARM.format(friction=0.0), threads=1)
    with pytest.raises(InvalidArgumentError, match="linearization"):
        ILQR(problem, horizon=5, linearization="knots")


def point_mass() -> mpcbox.Problem:
    """A point mass on two sliders: linear dynamics, quadratic cost, so every backward pass
    at the configured regularization gives the same gains wherever the trajectory is."""
    return mpcbox.Problem(
        """
        <mujoco>
          <option timestep="0.05" gravity="0 0 0"/>
          <worldbody><body>
            <joint name="x" type="slide" axis="1 0 0"/>
            <joint name="y" type="slide" axis="0 1 0"/>
            <geom type="sphere" size="0.1" mass="2" contype="0" conaffinity="0"/>
          </body></worldbody>
          <actuator><motor joint="x"/><motor joint="y"/></actuator>
        </mujoco>
        """,
        cost=Cost(
            [StateCost(np.zeros(2), weight_qpos=1.0, weight_qvel=0.1), ControlCost(weight=0.05)]
        ),
        threads=1,
    )


def test_a_stalled_replan_keeps_riccati_gains_and_the_next_starts_afresh():
    problem = point_mass()

    class Stalling(ILQR):
        stall = True

        def _forward(self, *args):
            out = super()._forward(*args)
            return (out[0] * np.nan, out[1], np.inf) if self.stall else out

    options = dict(horizon=20, replan_period=0.2, max_retries=25)
    ctrl = Stalling(problem, **options)
    x0 = np.array([1.0, -0.5, 0.0, 0.0])
    ctrl(x0, 0.0)  # every line search fails and the regularization grows 4^26-fold
    first = ctrl.last_result
    assert first.stop_reason.stalled and first.regularization > 1e9
    # Its gains are still the Riccati gains at the configured regularization (those of the
    # backward pass at 1e9 would be near zero, and applied until the next replan).
    gains = ILQR(problem, **options).solve(x0, max_iterations=1).K
    assert np.linalg.norm(gains[0]) > 0.1
    np.testing.assert_allclose(first.K, gains, rtol=1e-6, atol=1e-9)
    assert ctrl.stats["fallbacks"] == 1
    assert ctrl.stats["regularization"] == ctrl.config.regularization
    ctrl.stall = False
    x1 = np.array([0.9, -0.4, -0.5, 0.5])
    ctrl(x1, 0.2)  # the next replan, steps accepted again
    second = ctrl.last_result
    assert not second.stop_reason.stalled and ctrl.stats["fallbacks"] == 1
    # Carried over, the raised regularization would have started the second replan there.
    assert second.regularization <= ctrl.config.regularization
    np.testing.assert_allclose(second.K, gains, rtol=1e-6, atol=1e-9)


def test_a_replan_that_improves_and_then_stalls_is_a_stall_not_a_fallback():
    # The first iteration's line search succeeds; every later one fails: the replan
    # returns the improved plan with a stall reason. Counted as a fallback it had read
    # as a degraded run of a controller that kept replanning.
    class SecondStalls(ILQR):
        searches = 0

        def _forward(self, x0, states, ctrls, k, K, alpha):
            out = super()._forward(x0, states, ctrls, k, K, alpha)
            if alpha == max(self.config.step_sizes):
                SecondStalls.searches += 1
            return out if SecondStalls.searches <= 1 else (out[0], out[1], np.inf)

    options = dict(horizon=20, replan_period=0.2, mpc_iterations=2, first_iterations=2)
    ctrl = SecondStalls(point_mass(), max_retries=2, warm_start_feedback=True, **options)
    x0 = np.array([1.0, -0.5, 0.0, 0.0])
    ctrl(x0, 0.0)
    result = ctrl.last_result
    assert result.stop_reason.stalled and len(result.costs) == 2
    assert result.costs[1] < result.costs[0]
    # The plan is the first iteration's, not the initial guess rolled out.
    fresh = ILQR(point_mass(), **options).solve(x0, max_iterations=1)
    np.testing.assert_allclose(result.ctrls, fresh.ctrls, rtol=1e-9, atol=1e-12)
    assert ctrl.stats["stalled"] == 1 and ctrl.stats["fallbacks"] == 0
    assert result.start == "guess"  # the first solve: the controls, open loop
    # A replan whose every search fails keeps the previous plan's feedback law rolled out
    # from the measured state: a stall. From its controls rolled out open loop
    # (warm_start_feedback=False) it is a fallback too.
    ctrl(x0 + 0.1, 0.2)
    assert len(ctrl.last_result.costs) == 1 and ctrl.last_result.start == "policy"
    assert ctrl.stats["stalled"] == 2 and ctrl.stats["fallbacks"] == 0
    SecondStalls.searches = 0
    ctrl = SecondStalls(point_mass(), max_retries=2, warm_start_feedback=False, **options)
    ctrl(x0, 0.0)
    ctrl(x0 + 0.1, 0.2)
    assert len(ctrl.last_result.costs) == 1
    assert ctrl.stats["stalled"] == 2 and ctrl.stats["fallbacks"] == 1
    assert ctrl.last_result.start == "guess"
    # A law whose rollout diverges (here its plan's states are NaN) leaves the solver to
    # start from the controls open loop: a stall from there is a fallback again.
    SecondStalls.searches = 0

    class LawDiverges(SecondStalls):
        def _shifted_policy(self, time):
            ctrls, (states, gains) = super()._shifted_policy(time)
            return ctrls, (states * np.nan, gains)

    ctrl = LawDiverges(point_mass(), max_retries=2, warm_start_feedback=True, **options)
    ctrl(x0, 0.0)
    ctrl(x0 + 0.1, 0.2)
    assert ctrl.last_result.start == "guess" and ctrl.last_result.divergences >= 1
    assert ctrl.stats["stalled"] == 2 and ctrl.stats["fallbacks"] == 1


def test_replans_after_the_first_stop_at_mpc_max_retries():
    # Every rollout diverges, so every line search fails at all six step sizes and each
    # failure raises the regularization once more until the cap: the cold first solve may
    # retry max_retries times, every later replan only mpc_max_retries times.
    class Failing(ILQR):
        rollouts = 0

        def _forward(self, *args):
            Failing.rollouts += 1
            out = super()._forward(*args)
            return out[0] * np.nan, out[1], np.inf

    # (Open-loop warm starts: each stall before a step is then a fallback too.)
    ctrl = Failing(
        point_mass(),
        horizon=10,
        replan_period=0.1,
        max_retries=6,
        mpc_max_retries=2,
        warm_start_feedback=False,
    )
    steps = len(ctrl.config.step_sizes)
    ctrl(np.array([1.0, -0.5, 0.0, 0.0]), 0.0)
    assert ctrl.last_result.stop_reason.stalled
    assert Failing.rollouts == steps * (6 + 1)
    Failing.rollouts = 0
    ctrl(np.array([0.9, -0.4, -0.5, 0.5]), 0.1)
    assert ctrl.last_result.stop_reason.stalled
    assert Failing.rollouts == steps * (2 + 1)
    assert ctrl.stats["fallbacks"] == 2
    # With 0 a replan stops at its first failed line search.
    ctrl = Failing(point_mass(), horizon=10, replan_period=0.1, max_retries=6, mpc_max_retries=0)
    ctrl(np.array([1.0, -0.5, 0.0, 0.0]), 0.0)
    Failing.rollouts = 0
    ctrl(np.array([0.9, -0.4, -0.5, 0.5]), 0.1)
    assert ctrl.last_result.stop_reason.stalled and Failing.rollouts == steps
    # Without mpc_max_retries the replans keep max_retries.
    assert ILQR(point_mass(), horizon=10, max_retries=6).config.effective_mpc_max_retries == 6


def test_mpc_max_retries_is_checked():
    with pytest.raises(InvalidArgumentError, match="mpc_max_retries"):
        ILQR(point_mass(), horizon=5, mpc_max_retries=-1)


def test_replans_roll_the_warm_start_out_under_the_previous_feedback_law():
    """``warm_start_feedback``: a replan starts from the previous plan's feedback law rolled
    out from the measured state, as the world executes it between replans, not from its
    controls open loop, which leave an unstable plant's trajectory within the horizon."""
    # The project's pendulum balanced upright (2 N m motor, unsaturated here): open loop, a
    # deviation grows by e^(4.4 t) over the 0.8 s horizon.
    problem = mpcbox.Problem(
        scene_path("pendulum.xml"),
        keyframe="up",
        cost=Cost(
            [
                StateCost(np.array([np.pi]), weight_qpos=10.0, weight_qvel=0.1),
                ControlCost(np.zeros(1), weight=1.0),
            ]
        ),
        threads=1,
    )
    x0, dt = np.array([np.pi + 0.05, 0.0]), 0.02
    starts = {}
    for feedback in (True, False):
        mpc = ILQR(
            problem,
            horizon=80,
            terminal_value="lqr",
            linearization="reference",
            regularization=0.0,
            replan_period=dt,
            first_iterations=20,
            warm_start_feedback=feedback,
        )
        mpc(x0, 0.0)
        plan = mpc.last_result
        # The measured state is off the plan's prediction, as after a disturbance.
        x1 = plan.states[2] + np.array([0.02, -0.1])
        if feedback:
            warm, (states, gains) = mpc._shifted_policy(dt)
            np.testing.assert_array_equal(warm[:-2], plan.ctrls[2:])
            np.testing.assert_array_equal(states[:-2], plan.states[2:])
            np.testing.assert_array_equal(gains[-3:], np.repeat(plan.K[-1:], 3, axis=0))
        mpc(x1, dt)
        replan = mpc.last_result
        assert replan.states[0] == pytest.approx(x1)
        starts[feedback] = replan.costs[0]
    # Near an equilibrium the previous plan's law (LQR's gains with the LQR terminal value)
    # is already the optimal plan from the new state; its controls open loop are not.
    best = mpc.solve(x1, max_iterations=50).cost
    assert best <= starts[True] < best * (1 + 1e-3)
    assert starts[False] > 1.5 * best
    with pytest.raises(InvalidArgumentError, match="warm_start_feedback"):
        ILQR(problem, warm_start_feedback="yes")


def test_a_guess_that_diverges_is_replaced_by_ctrl_ref_and_said_so():
    class GuessDiverges(ILQR):
        calls = 0

        def _initial_rollout(self, x0, ctrls):
            GuessDiverges.calls += 1
            states, cost = super()._initial_rollout(x0, ctrls)
            return (states, np.inf) if GuessDiverges.calls == 1 else (states, cost)

    x0 = np.array([1.0, -0.5, 0.0, 0.0])
    result = GuessDiverges(point_mass(), horizon=10).solve(x0)
    assert result.start == "ctrl_ref" and result.divergences == 1 and result.converged
    plain = ILQR(point_mass(), horizon=10).solve(x0)  # its guess is ctrl_ref too
    assert plain.start == "guess" and plain.divergences == 0
    np.testing.assert_allclose(result.ctrls, plain.ctrls, atol=1e-9)
