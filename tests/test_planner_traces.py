"""Traces of a sampling controller's best rollouts (mpcbox.controllers.sampling.traces)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnknownNameError
from mpcbox.registry import make_controller, task_class

SMALL = {"num_samples": 24, "horizon": 0.3}


@pytest.fixture(scope="module")
def problem():
    return task_class("cartpole_swingup")()


def _state(problem) -> np.ndarray:
    """A state away from rest: the pole at 1 rad, moving."""
    x = problem.initial_state()
    x[: problem.nq] = [0.2, 1.0]
    x[problem.nq : problem.nq + problem.nv] = [0.5, -2.0]
    return x


def _tip(problem, state: np.ndarray) -> np.ndarray:
    model = problem.model
    data = mujoco.MjData(model)
    data.qpos[:] = state[: model.nq]
    mujoco.mj_kinematics(model, data)
    return data.site_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tip")].copy()


@pytest.mark.parametrize("name", ["ps", "mppi", "cem"])
def test_traces_start_at_the_site_and_are_sorted(problem, name) -> None:
    ctrl = make_controller(name, problem, **SMALL)
    ctrl.record_traces(5, site="tip")
    x = _state(problem)
    ctrl(problem.initial_state(), 0.0)
    ctrl(x, 0.01)
    trace = ctrl.traces
    steps = ctrl.horizon_steps
    assert trace.target == "site:tip"
    assert trace.positions.shape == (5, steps + 1, 3) and trace.costs.shape == (5,)
    assert trace.times.shape == (steps + 1,)
    assert trace.times[0] == pytest.approx(0.01)
    assert np.diff(trace.times) == pytest.approx(np.full(steps, ctrl.problem.dt))
    np.testing.assert_allclose(trace.positions[:, 0], np.tile(_tip(problem, x), (5, 1)), atol=1e-9)
    assert np.all(np.diff(trace.costs) >= 0.0)
    assert trace.costs[0] == pytest.approx(ctrl.last.best_cost, rel=1e-12)
    # the paths differ: different candidates move the tip differently
    assert np.ptp(trace.positions[:, -1, 0]) > 1e-6


def test_best_trace_is_the_chosen_plan_stepped_by_mujoco(problem) -> None:
    """Predictive sampling keeps its best candidate: stepping those knots' controls with
    plain mj_step on the planning model must retrace the best trace."""
    ctrl = make_controller("ps", problem, **SMALL)
    ctrl.record_traces(3, body="pole")
    x = _state(problem)
    ctrl(x, 0.0)
    trace = ctrl.traces
    model = ctrl.problem.planning_model
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = x[: model.nq], x[model.nq : model.nq + model.nv]
    pole = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pole")
    mujoco.mj_kinematics(model, data)
    path = [data.xpos[pole].copy()]
    for u in ctrl.problem.clip_ctrl(ctrl.weights @ ctrl.knots):
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
        mujoco.mj_kinematics(model, data)
        path.append(data.xpos[pole].copy())
    assert trace.target == "body:pole"
    np.testing.assert_allclose(trace.positions[0], np.array(path), atol=1e-9)
    # the pole's frame origin sits on the cart, on the rail: only x moves
    assert np.ptp(trace.positions[0, :, 0]) > 1e-4
    np.testing.assert_allclose(trace.positions[0, :, 2], 1.0, atol=1e-9)


def test_traces_off_do_no_work_and_never_change_the_plan(problem) -> None:
    calls = {"n": 0}

    def counting(ctrl):
        inner = ctrl.problem.rollout

        def rollout(*args, **kwargs):
            calls["n"] += 1
            return inner(*args, **kwargs)

        ctrl.problem.rollout = rollout

    off = make_controller("mppi", problem, **SMALL, iterations=2)
    on = make_controller("mppi", problem, **SMALL, iterations=2)
    on.record_traces(4)
    x = _state(problem)
    counting(off)
    off(x, 0.0)
    assert calls["n"] == 2  # one rollout batch per iteration, nothing more
    assert off.trace_recorder is None and off.traces is None
    calls["n"] = 0
    counting(on)
    on(x, 0.0)
    assert calls["n"] == 3 and on.trace_recorder.rollouts == 4
    np.testing.assert_array_equal(on.knots, off.knots)  # recording draws no random numbers
    on.record_traces(0)
    calls["n"] = 0
    on(x, 0.01)
    assert calls["n"] == 2 and on.traces is None and on.trace_recorder is None


def test_trace_arguments_are_checked(problem) -> None:
    ctrl = make_controller("ps", problem, **SMALL)
    with pytest.raises(InvalidArgumentError, match="count"):
        ctrl.record_traces(-1)
    with pytest.raises(InvalidTypeError, match="count"):
        ctrl.record_traces(2.5)
    with pytest.raises(UnknownNameError, match="tip"):
        ctrl.record_traces(2, site="nope")
    with pytest.raises(InvalidArgumentError, match="not both"):
        ctrl.record_traces(2, site="tip", body="pole")
    assert ctrl.trace_recorder is None
    ctrl.record_traces(2)  # default target: the model's last site
    assert ctrl.trace_recorder.target == "site:tip"


def test_warp_traces_re_roll_the_candidates_warp_scored(problem, warp_device) -> None:
    """The warp backend keeps no states: the traces re-roll on the CPU the candidates it
    scored, so the CPU cost of the kept plan (predictive sampling keeps its best) matches
    the warp cost of the best trace up to float32 rounding."""
    ctrl = make_controller("ps", problem, **SMALL, backend="warp", device=warp_device)
    ctrl.record_traces(4, site="tip")
    x = _state(problem)
    ctrl(x, 0.0)
    trace = ctrl.traces
    assert trace.positions.shape == (4, ctrl.horizon_steps + 1, 3)
    np.testing.assert_allclose(trace.positions[:, 0], np.tile(_tip(problem, x), (4, 1)), atol=1e-9)
    assert np.all(np.diff(trace.costs) >= 0.0)
    ctrls = (ctrl.weights @ ctrl.knots)[None]
    cpu_cost = ctrl.problem.rollout_cost(ctrl.problem.rollout(x, ctrls))[0]
    assert trace.costs[0] == pytest.approx(cpu_cost, rel=1e-4)
    ctrl.close()
