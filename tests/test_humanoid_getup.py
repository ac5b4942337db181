"""The humanoid get-up task (mpcbox.tasks.humanoid.getup) on the CPU."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.registry import task_class
from mpcbox.tasks.humanoid.getup import HumanoidGetup


@pytest.fixture(scope="module")
def problem():
    return task_class("humanoid_getup")()


def test_registered_by_name(problem):
    assert isinstance(problem, HumanoidGetup)
    assert problem.name == "humanoid_getup"


def test_starts_lying_on_its_back_at_rest(problem):
    x = problem.initial_state()
    data = mujoco.MjData(problem.model)
    data.qpos[:] = x[: problem.nq]
    mujoco.mj_kinematics(problem.model, data)
    torso = data.xmat[problem.torso_id].reshape(3, 3)
    # Lying: the torso is low and its long (z) axis is horizontal; its chest (x) faces up.
    assert data.xpos[problem.torso_id, 2] < 0.3
    assert abs(torso[2, 2]) < 0.3
    assert torso[2, 0] > 0.7
    # At rest after settling: a passive step barely moves it.
    data.qvel[:] = 0.0
    mujoco.mj_step(problem.model, data)
    assert np.abs(data.qvel).max() < 0.5
    # The stand keyframe's torso height is the target, well above the threshold.
    assert problem.torso_height > problem.stand_height


def test_success_needs_the_torso_up_for_the_last_hold_seconds(problem):
    lying, standing = problem.initial_state(), problem.reference_state()
    t = np.round(np.arange(0.0, 2.01, 0.1), 10)
    up_late = np.array([standing if ti >= 1.2 else lying for ti in t])
    assert problem.goal_failure(t, up_late) is None
    assert problem.getup_time(t, up_late) == pytest.approx(1.2)
    up_too_late = np.array([standing if ti >= 1.7 else lying for ti in t])
    assert "not standing" in problem.goal_failure(t, up_too_late)
    fell_again = up_late.copy()
    fell_again[-1] = lying
    assert "not standing" in problem.goal_failure(t, fell_again)
    assert np.isnan(problem.getup_time(t, fell_again))
    assert problem.failure(problem.model, mujoco.MjData(problem.model)) is None


def test_cost_prefers_standing_to_lying(problem):
    lying, standing = problem.initial_state(), problem.reference_state()
    ctrls = np.zeros((3, problem.nu))
    cost_lying = problem.rollout_cost(problem.rollout(lying, ctrls))
    cost_standing = problem.rollout_cost(problem.rollout(standing, ctrls))
    assert float(np.ravel(cost_standing)[0]) < float(np.ravel(cost_lying)[0])


def test_bad_options_are_rejected():
    with pytest.raises(mpcbox.InvalidArgumentError, match="stand_height"):
        HumanoidGetup(stand_height=0.0)
    with pytest.raises(mpcbox.InvalidArgumentError, match="hold"):
        HumanoidGetup(hold=-1.0)
