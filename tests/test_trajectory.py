"""Saved trajectories load back exactly and replay open loop to the saved final state."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mpcbox.errors import InvalidArgumentError
from mpcbox.registry import make_controller, task_class
from mpcbox.sim.disturbances import ActuatorNoise, ModelMismatch, Push
from mpcbox.sim.simulation import simulate
from mpcbox.sim.trajectory import replay, trajectory_from_result
from mpcbox.sim.trajectory_files import load_trajectory, save_trajectory
from mpcbox.sim.viewer import Viewer


@pytest.fixture(scope="module")
def pendulum_run():
    problem = task_class("pendulum_swingup")()
    push = Push(force=(3.0, 0.0, 0.0), start=0.2, duration=0.1, body="pole")
    result = simulate(
        problem,
        make_controller("lqr", problem),
        0.8,
        noise=ActuatorNoise(std=0.3, width=0.1),
        pushes=(push,),
        mismatch=ModelMismatch(mass_scale=1.2),
        seed=4,
    )
    return problem, result


def test_round_trip_is_bit_exact(pendulum_run, tmp_path) -> None:
    problem, result = pendulum_run
    traj = trajectory_from_result(result, problem, metadata={"task": "pendulum_swingup"})
    csv_path, json_path = save_trajectory(traj, tmp_path / "run")
    assert csv_path.name == "run.csv" and json_path.name == "run.json"
    back = load_trajectory(csv_path)
    for name in ("time", "states", "ctrls", "initial_state"):
        assert np.array_equal(getattr(back, name), getattr(traj, name)), name
    assert back.sites.keys() == traj.sites.keys()
    for name in traj.sites:
        assert np.array_equal(back.sites[name], traj.sites[name])
    assert back.pushes == traj.pushes and back.mismatch == traj.mismatch
    assert back.noise == result.noise and back.seed == 4
    assert back.metadata["task"] == "pendulum_swingup" and back.metadata["nq"] == 1
    # LQR from hanging never swings the pole up: the task's goal check says so, and the
    # reason survives the round trip.
    assert result.failure is not None and result.failure.startswith("not upright")
    assert (back.problem, back.controller, back.failure) == (
        "pendulum_swingup",
        "lqr",
        result.failure,
    )
    # The same file loads from either name.
    assert np.array_equal(load_trajectory(json_path).states, traj.states)


def test_site_positions_follow_the_pendulum(pendulum_run) -> None:
    problem, result = pendulum_run
    traj = trajectory_from_result(result, problem)
    angle = traj.states[:, 0]
    tip = traj.sites["tip"]  # 0.5 m below the hinge at angle 0, rotating about +y
    expected = np.stack([-0.5 * np.sin(angle), np.zeros_like(angle), -0.5 * np.cos(angle)], 1)
    np.testing.assert_allclose(tip, expected, atol=1e-12)


def test_replay_reaches_the_saved_final_state(pendulum_run, tmp_path) -> None:
    problem, result = pendulum_run
    traj = trajectory_from_result(result, problem)
    back = load_trajectory(save_trajectory(traj, tmp_path / "run")[0])
    out = replay(back, problem)
    assert out.final_error == 0.0
    assert np.array_equal(out.states, result.states)
    # Without the push or the mismatch, the same controls end elsewhere: the replay uses them.
    assert replay(back._replace(pushes=()), problem).final_error > 1e-3
    assert replay(back._replace(mismatch=None), problem).final_error > 1e-3


class _Frames(Viewer):
    """Keeps the time and the pendulum angle of every frame drawn."""

    def open(self, problem, controller) -> None:
        self.seen: list[tuple[float, float]] = []
        self.closed = False

    def draw(self, trace) -> None:
        assert trace is None  # a replay has no planner
        self.seen.append((float(self.data.time), float(self.data.qpos[0])))

    def close(self) -> None:
        self.closed = True


def test_replay_feeds_a_viewer_the_saved_run(pendulum_run) -> None:
    problem, result = pendulum_run
    traj = trajectory_from_result(result, problem)
    view = _Frames(fps=25.0)
    out = replay(traj, problem, viewer=view)
    assert out.final_error == 0.0 and view.closed  # watching changes nothing
    times = np.array([t for t, _ in view.seen])
    np.testing.assert_allclose(times, np.arange(len(times)) * 0.04, atol=1e-9)
    assert times[-1] > traj.time[-1] - 0.04
    for t, angle in view.seen:  # each frame shows the saved state of its time
        k = int(np.argmin(np.abs(traj.time - t)))
        assert angle == pytest.approx(traj.states[k, 0], abs=1e-12)
    with pytest.raises(InvalidArgumentError, match="viewer must be"):
        replay(traj, problem, viewer="video.avi")


def test_humanoid_replay_with_task_noise_push_and_mismatch(tmp_path) -> None:
    problem = task_class("humanoid_balance")()
    result = simulate(
        problem,
        make_controller("lqr", problem),
        0.5,
        noise=problem.noise(1.0),
        pushes=(Push(force=(60.0, 0.0, 0.0), start=0.2, duration=0.1, body="torso"),),
        mismatch=ModelMismatch(mass_scale=1.05, friction_scale=0.8),
        seed=2,
    )
    assert result.failure is None
    traj = trajectory_from_result(result, problem)
    back = load_trajectory(save_trajectory(traj, tmp_path / "h")[0])
    assert replay(back, problem).final_error <= 1e-9
    assert replay(back._replace(pushes=()), problem).final_error > 1e-6


def test_bad_files_and_problems_are_named(pendulum_run, tmp_path) -> None:
    problem, result = pendulum_run
    with pytest.raises(InvalidArgumentError, match="nothere"):
        load_trajectory(tmp_path / "nothere.csv")
    csv_path, json_path = save_trajectory(trajectory_from_result(result, problem), tmp_path / "r")
    meta = json.loads(json_path.read_text())
    json_path.write_text(json.dumps({**meta, "format": "other"}))
    with pytest.raises(InvalidArgumentError, match="not an mpcbox trajectory"):
        load_trajectory(csv_path)
    json_path.write_text(json.dumps({**meta, "nq": 2}))
    with pytest.raises(InvalidArgumentError, match="columns"):
        load_trajectory(csv_path)
    json_path.write_text(json.dumps(meta))
    # A CSV cut short (or only its header) no longer reads as the whole run.
    lines = csv_path.read_text().splitlines(keepends=True)
    csv_path.write_text("".join(lines[:5]))
    with pytest.raises(InvalidArgumentError, match=rf"4 rows; .* and {meta['steps']} rows"):
        load_trajectory(csv_path)
    csv_path.write_text(lines[0])
    with pytest.raises(InvalidArgumentError, match="and 0 rows;"):
        load_trajectory(csv_path)
    csv_path.write_text("".join(lines))
    cartpole = task_class("cartpole_swingup")()
    with pytest.raises(InvalidArgumentError, match="nq"):
        replay(load_trajectory(csv_path), cartpole)
    with pytest.raises(InvalidArgumentError, match="Trajectory"):
        save_trajectory(result, tmp_path / "x")


def test_edited_files_are_refused_naming_the_row(pendulum_run, tmp_path) -> None:
    """Each edit once loaded as a valid run (or gave a NumPy message about NumPy's API)."""
    problem, result = pendulum_run
    traj = trajectory_from_result(result, problem, metadata={"task": "pendulum_swingup"})
    csv_path, json_path = save_trajectory(traj, tmp_path / "r")
    meta = json.loads(json_path.read_text())
    lines = csv_path.read_text().splitlines(keepends=True)

    def edited(csv_lines=None, **changes):
        csv_path.write_text("".join(lines if csv_lines is None else csv_lines))
        json_path.write_text(json.dumps({**meta, **changes}))
        with pytest.raises(InvalidArgumentError) as info:
            load_trajectory(csv_path)
        return str(info.value)

    assert "version 99" in edited(version=99)
    assert "task_options must be a JSON object" in edited(task_options=[1, 2])
    assert "'xx', expected 'qpos_0'" in edited([lines[0].replace("qpos_0", "xx"), *lines[1:]])
    cells = lines[3].split(",")
    cells[1 + problem.nq + problem.nv + problem.na] = "nan"  # the first control
    nan_ctrl = [*lines[:3], ",".join(cells), *lines[4:]]
    assert "data row 3 holds NaN" in edited(nan_ctrl)
    backwards = [lines[0], lines[2], lines[1], *lines[3:]]
    assert "time does not increase at data row 2" in edited(backwards)
    assert "empty" in edited([])
    assert "data row 2 has" in edited([lines[0], lines[1], lines[2][: len(lines[2]) // 2] + "\n"])
    # The untouched files still load.
    csv_path.write_text("".join(lines))
    json_path.write_text(json.dumps(meta))
    assert np.array_equal(load_trajectory(csv_path).states, traj.states)
