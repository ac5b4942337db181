"""iLQR's step-by-step rollouts score MuJoCo's own reset as a divergence, as Problem.rollout does.

The model: a 1 kg pendulum whose motor has a gear of 1e12, so a control of 1 asks for an
acceleration of about 1e13 rad/s^2. MuJoCo's limit is 1e10 (``mjMAXVAL``): it counts a bad
acceleration (``mjWARN_BADQACC``), resets the data to the model's reference pose and carries
on. The states after the reset are finite, so a finiteness check alone scored the rollout
as a cheap trajectory that stays at rest.
"""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.forward_pass import ClosedLoopRollout
from mpcbox.controllers.ilqr.multiple_shooting import GappedRollout

HUGE_GEAR = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05" mass="1"/>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" gear="1e12" ctrlrange="-1 1"/></actuator>
</mujoco>
"""
T = 20
KICK = 5  # the knot whose control triggers the reset


@pytest.fixture(scope="module")
def problem() -> mpcbox.Problem:
    return mpcbox.Problem(HUGE_GEAR)


def _plan(problem: mpcbox.Problem, kick: float):
    x0 = problem.reference_state()
    states = np.tile(x0, (T + 1, 1))
    ctrls = np.zeros((T, problem.nu))
    ctrls[KICK] = kick
    gains = np.zeros((T, problem.nu, problem.nx))
    return x0, states, ctrls, np.zeros((T, problem.nu)), gains


def test_closed_loop_rollout_scores_a_reset_as_divergence(problem, capfd) -> None:
    rollout = ClosedLoopRollout(problem, problem.ctrl_low, problem.ctrl_high)
    x0, states, ctrls, k, K = _plan(problem, 1.0)
    # Problem.rollout marks the steps from the reset on non-finite ...
    assert np.isnan(problem.rollout(x0, ctrls).states[0, KICK + 1 :]).all()
    # ... and the closed-loop rollout of the same controls is a divergence, not a cost.
    new_states, _, cost = rollout(x0, states, ctrls, k, K, 1.0)
    assert cost == np.inf
    assert np.all(np.isfinite(new_states))  # what a finiteness check alone would have seen
    # The same rollout with a harmless control is scored.
    x0, states, ctrls, k, K = _plan(problem, 1e-9)
    assert np.isfinite(rollout(x0, states, ctrls, k, K, 1.0)[2])
    capfd.readouterr()


def test_gapped_rollout_and_defects_score_a_reset_as_divergence(problem) -> None:
    rollout = GappedRollout(problem, problem.ctrl_low, problem.ctrl_high)
    x0, states, ctrls, k, K = _plan(problem, 1.0)
    gaps, cost = rollout.defects(states, ctrls)
    assert cost == np.inf
    assert rollout.gapped(x0, states, ctrls, np.zeros((T, problem.nx)), k, K, 0.5)[2] == np.inf
    x0, states, ctrls, k, K = _plan(problem, 1e-9)
    gaps, cost = rollout.defects(states, ctrls)
    assert np.isfinite(cost)
    assert np.isfinite(rollout.gapped(x0, states, ctrls, gaps, k, K, 0.5)[2])


def test_the_rollout_follows_its_update_law_on_quaternion_and_plain_models() -> None:
    """The closed-loop rollout's controls are ``clip(u + alpha k + K (x - xbar))``, with the
    tangent difference on a free body and a plain one on hinges (same numbers as
    Problem.state_difference)."""
    rng = np.random.default_rng(3)
    for xml in (HUGE_GEAR.replace('gear="1e12"', 'gear="1"'), _FREE_BODY):
        problem = mpcbox.Problem(xml)
        x0 = problem.reference_state()
        ctrls = rng.uniform(-0.5, 0.5, (T, problem.nu))
        nominal = problem.rollout(x0, ctrls).states[0]
        k = rng.normal(size=(T, problem.nu))
        K = 0.3 * rng.normal(size=(T, problem.nu, problem.nx))
        rollout = ClosedLoopRollout(problem, problem.ctrl_low, problem.ctrl_high)
        states, applied, cost = rollout(x0, nominal, ctrls, k, K, 0.5)
        assert np.isfinite(cost)
        dx = problem.state_difference(states[:-1], nominal[:-1])
        law = ctrls + 0.5 * k + np.einsum("tij,tj->ti", K, dx)
        expected = np.clip(law, problem.ctrl_low, problem.ctrl_high)
        assert np.allclose(applied, expected, rtol=0, atol=1e-12)
        replay = problem.rollout(x0, applied).states[0]
        assert np.allclose(replay, states, rtol=0, atol=1e-12)


_FREE_BODY = """
<mujoco>
  <option timestep="0.01" gravity="0 0 0"/>
  <worldbody>
    <body pos="0 0 1">
      <freejoint/>
      <geom type="box" size="0.1 0.2 0.3" mass="1"/>
      <body pos="0 0 0.3">
        <joint name="hinge" type="hinge" axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03" mass="0.2"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""
