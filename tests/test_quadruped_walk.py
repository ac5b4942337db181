"""QuadrupedWalk: a quadruped's root walked to a target (dm_control's quadruped; the Go1)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.errors import InvalidArgumentError
from mpcbox.registry import task_class
from mpcbox.tasks.legged.walk import QuadrupedWalk

pytest.importorskip("dm_control")


@pytest.fixture(scope="module")
def walk() -> QuadrupedWalk:
    return QuadrupedWalk(threads=1)


def with_root(walk: QuadrupedWalk, xy, yaw: float = 0.0) -> np.ndarray:
    """The reference state with the root moved to ``xy`` and turned by ``yaw`` (rad)."""
    state = walk.reference_state()
    state[:2] = xy
    turn = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    mujoco.mju_mulQuat(state[3:7], turn, walk.qpos_ref[3:7].copy())
    return state


def test_builds_dm_control_quadruped_with_target_ahead(walk) -> None:
    assert task_class("quadruped_walk") is QuadrupedWalk
    assert walk.root == "torso" and walk.root_qpos == 0
    assert walk.nu == 12 and walk.na == 12  # filter-dynamics actuators
    np.testing.assert_allclose(walk.target, walk.start[:2] + np.array([1.0, 0.0]), atol=1e-12)
    assert set(walk.controller_configs) == {"ps", "mppi", "cem"}
    # Every cost term has the GPU row form, so the warp backend plans with the same cost.
    for term in walk.cost.terms:
        assert term.rows()


def test_cost_falls_as_the_root_nears_the_target(walk) -> None:
    u = walk.ctrl_ref
    costs = [walk.running_cost(with_root(walk, [x, 0.0]), u) for x in np.linspace(0, 1, 6)]
    assert np.all(np.isfinite(costs))
    assert np.all(np.diff(costs) < 0)
    # Only the distance term changes: 1/2 w_d d^2, minimal on the target.
    w = walk.walk_weights["distance"]
    d = 1.0 - np.linspace(0, 1, 6)
    np.testing.assert_allclose(np.subtract(costs, costs[-1]), 0.5 * w * d**2, rtol=1e-9)
    # Past the target it rises again, and sideways offsets cost the same as ahead.
    beyond = walk.running_cost(with_root(walk, [1.3, 0.0]), u)
    side = walk.running_cost(with_root(walk, [1.0, 0.3]), u)
    assert beyond == pytest.approx(side) and beyond > costs[-1]


def test_a_target_to_the_side_asks_to_face_it() -> None:
    side = QuadrupedWalk(target=[0.0, 1.2], threads=1)
    u = side.ctrl_ref
    facing = side.running_cost(with_root(side, [0.0, 0.0], yaw=np.pi / 2), u)
    ahead = side.running_cost(with_root(side, [0.0, 0.0]), u)
    # Turning by 90 degrees removes 1/2 w_o (pi/2)^2 of orientation cost.
    expected = 0.5 * side.walk_weights["orientation"] * (np.pi / 2) ** 2
    assert ahead - facing == pytest.approx(expected, rel=1e-6)


def test_time_to_target_and_goal_failure_on_synthetic_runs(walk) -> None:
    time = np.linspace(0.0, 3.0, 31)
    x = np.clip(0.5 * time, 0.0, 0.95)  # 0.5 m/s, stops 5 cm short of the target
    states = np.array([with_root(walk, [xi, 0.0]) for xi in x])
    # Within 0.2 m once x >= 0.8, i.e. from t = 1.6 s.
    assert walk.time_to_target(time, states) == pytest.approx(1.6)
    assert walk.goal_failure(time, states) is None
    np.testing.assert_allclose(walk.target_distances(states), 1.0 - x, atol=1e-12)
    short = np.array([with_root(walk, [min(xi, 0.7), 0.0]) for xi in x])
    assert np.isnan(walk.time_to_target(time, short))
    reason = walk.goal_failure(time, short)
    assert reason is not None and "missed the target" in reason and "0.30 m" in reason
    late = QuadrupedWalk(time_limit=1.0, threads=1)
    assert np.isnan(late.time_to_target(time, states))
    assert "by 1 s" in late.goal_failure(time, states)
    assert walk.goal_failure(time[:0], states[:0]) == "no states recorded"


def test_falls_below_the_fraction_of_the_standing_height(walk) -> None:
    assert walk.fall_height == pytest.approx(0.6 * walk.root_height)
    data = mujoco.MjData(walk.model)
    walk.set_state(data, walk.reference_state())
    mujoco.mj_forward(walk.model, data)
    assert walk.failure(walk.model, data) is None
    low = walk.reference_state()
    low[2] = 0.5 * walk.root_height
    walk.set_state(data, low)
    mujoco.mj_forward(walk.model, data)
    assert walk.failure(walk.model, data).startswith("fell: torso below")


def test_bad_options_name_the_argument() -> None:
    with pytest.raises(InvalidArgumentError, match="target"):
        QuadrupedWalk(target=[0.1, 0.0], threads=1)
    with pytest.raises(InvalidArgumentError, match="radius"):
        QuadrupedWalk(radius=-0.1, threads=1)
    with pytest.raises(InvalidArgumentError, match="target"):
        QuadrupedWalk(target=[1.0, 0.0, 0.0], threads=1)


def test_predictive_sampling_walks_toward_the_target(walk) -> None:
    ctrl = mpcbox.make_controller("ps", walk, num_samples=32, seed=1)
    res = mpcbox.simulate(walk, ctrl, 1.5, seed=1)
    assert res.survived, res.failure
    distances = walk.target_distances(res.states)
    assert distances[0] == pytest.approx(1.0, abs=1e-6)
    assert distances[-1] < 0.5, distances[-1]  # 0.02-0.16 m on seeds 1-6
    assert "target_distance_final_m" in res.metrics.measures


def test_warp_backend_scores_candidates_like_the_cpu_backend(walk, warp_device) -> None:
    from mpcbox.controllers.sampling import PredictiveSampling

    opts = dict(num_samples=8, horizon=0.2, num_knots=3, planning_timestep=0.02)
    cpu = PredictiveSampling(walk, **opts)
    warp = PredictiveSampling(walk, backend="warp", device=warp_device, **opts)
    rng = np.random.default_rng(0)
    cand = walk.clip_ctrl(walk.ctrl_ref + rng.normal(0, 0.3, (8, 3, walk.nu)))
    state = walk.initial_state()
    a, b = cpu.backend.evaluate(state, cand), warp.backend.evaluate(state, cand)
    assert not b.overflow.any() and not b.nonfinite.any()
    np.testing.assert_allclose(b.costs, a.costs, rtol=1e-4)
    assert np.ptp(a.costs) > 1e-3 * np.abs(a.costs).max()  # candidates differ


@pytest.mark.menagerie
def test_go1_preset_finds_its_feet_and_target() -> None:
    go1 = QuadrupedWalk("menagerie:unitree_go1", distance=1.2, threads=1)
    assert go1.root == "trunk" and len(go1.feet) == 4
    np.testing.assert_allclose(go1.target, go1.start[:2] + np.array([1.2, 0.0]), atol=1e-9)
    assert 0.2 < go1.root_height < 0.4
    near = go1.reference_state()
    near[:2] = go1.target
    assert go1.running_cost(near, go1.ctrl_ref) < go1.running_cost(
        go1.reference_state(), go1.ctrl_ref
    )
