"""Robustness measures: the push grid and its agreement with the bisection."""

from __future__ import annotations

import numpy as np
import pytest

from mpcbox import LQR, InvalidArgumentError
from mpcbox.comparison.push_limits import largest_push, push_grid, summarize_push_grid
from mpcbox.comparison.scenario import PushTest
from mpcbox.tasks.humanoid.two_feet import HumanoidTwoFeet


@pytest.mark.parametrize(
    ("survived", "limit", "largest", "monotone"),
    [
        ([True, True, False, False], 20.0, 20.0, True),
        ([True, False, True, False], 10.0, 30.0, False),
        ([False, True, True, True], 0.0, 40.0, False),
        ([False, False, False, False], 0.0, 0.0, True),
        ([True, True, True, True], 40.0, 40.0, True),
    ],
)
def test_push_grid_summary(survived, limit, largest, monotone):
    grid = summarize_push_grid(np.array([10.0, 20.0, 30.0, 40.0]), np.array(survived))
    assert grid.limit == limit
    assert grid.largest_survived == largest
    assert grid.monotone is monotone
    assert np.all(np.isnan(grid.time_to_fall))


def test_push_grid_summary_rejects_bad_grids():
    with pytest.raises(InvalidArgumentError, match="strictly increasing"):
        summarize_push_grid(np.array([20.0, 10.0]), np.array([True, True]))
    with pytest.raises(InvalidArgumentError, match="one length"):
        summarize_push_grid(np.array([10.0, 20.0]), np.array([True]))


@pytest.fixture(scope="module")
def two_feet() -> HumanoidTwoFeet:
    return HumanoidTwoFeet(threads=1)


def test_push_grid_brackets_the_bisection(two_feet):
    """LQR on two feet survives no push and a moderate one and falls at ten times that; the
    bisection's limit lies between the grid's last survived and first failed force."""
    lqr = LQR(two_feet)
    kw = dict(settle=1.5, direction=(1.0, 0.0, 0.0))
    grid = push_grid(two_feet, lqr, [400.0, 0.0, 40.0], PushTest(**kw))
    np.testing.assert_array_equal(grid.forces, [0.0, 40.0, 400.0])
    np.testing.assert_array_equal(grid.survived, [True, True, False])
    assert grid.monotone and grid.limit == 40.0
    assert grid.time_to_fall[0] == pytest.approx(2.6) and grid.time_to_fall[2] < 2.6
    limit = largest_push(two_feet, lqr, PushTest(max_force=400.0, tolerance=25.0, **kw))
    assert 40.0 <= limit.force < limit.smallest_failed <= 400.0


def test_push_grid_argument_errors(two_feet):
    lqr = LQR(two_feet)
    with pytest.raises(InvalidArgumentError, match="forces"):
        push_grid(two_feet, lqr, [])
    with pytest.raises(InvalidArgumentError, match="forces"):
        push_grid(two_feet, lqr, [-1.0, 10.0])
    with pytest.raises(InvalidArgumentError, match="direction"):
        push_grid(two_feet, lqr, [10.0], PushTest(direction=(0.0, 0.0, 0.0)))
    with pytest.raises(InvalidArgumentError, match="settle"):
        push_grid(two_feet, lqr, [10.0], PushTest(settle=0.0))


def test_bisection_below_float_resolution_ends(monkeypatch) -> None:
    """A tolerance the floats cannot resolve ends at the resolution instead of looping."""
    from types import SimpleNamespace

    from mpcbox.comparison import robustness

    limit = 37.3
    calls = []

    def fake_trial(problem, controller, test, seed):
        def trial(force: float):
            calls.append(force)
            return SimpleNamespace(metrics=SimpleNamespace(success=force <= limit))

        return trial

    monkeypatch.setattr(robustness, "_push_trial", fake_trial)
    monkeypatch.setattr(robustness, "travel", lambda *args: 0.0)  # the fake has no states
    result = robustness.largest_push(None, None, PushTest(max_force=400.0, tolerance=1e-300))
    assert result.force <= limit < result.smallest_failed
    assert result.smallest_failed - result.force <= 2 * np.spacing(limit)
    assert len(calls) < 100  # about 60 halvings of 400 N down to the spacing near 37 N


def test_a_scan_finds_the_first_failure_where_survival_is_not_monotone(monkeypatch):
    """Survived up to 100 N, fallen at 150-250 N, survived again at 300-700 N (as a G1 that
    hops away from some large pushes): the plain bisection lands in the upper band, the scan
    below the first failure."""
    from types import SimpleNamespace

    from mpcbox.comparison import robustness

    def fake_trial(problem, controller, test, seed):
        def trial(force: float):
            success = force <= 100.0 or 300.0 <= force <= 700.0
            return SimpleNamespace(metrics=SimpleNamespace(success=success))

        return trial

    monkeypatch.setattr(robustness, "_push_trial", fake_trial)
    monkeypatch.setattr(robustness, "travel", lambda *args: 0.0)
    plain = robustness.largest_push(None, None, PushTest(max_force=1000.0, tolerance=1.0))
    assert 699.0 <= plain.force <= 700.0
    scanned = PushTest(max_force=1000.0, tolerance=1.0, scan_step=50.0)
    limit = robustness.largest_push(None, None, scanned)
    assert 99.0 <= limit.force <= 100.0 < limit.smallest_failed <= 101.0
    # Survived up to the cap: the cap, as without the scan.
    assert (
        robustness.largest_push(None, None, PushTest(max_force=90.0, scan_step=50.0)).force == 90.0
    )
    with pytest.raises(InvalidArgumentError, match="scan_step"):
        PushTest(scan_step=0.0)


def _lqr(problem):
    """A module-level factory: worker processes rebuild the controller from it."""
    return LQR(problem)


def test_sweeps_on_executors_equal_the_serial_ones(two_feet):
    """The grid's forces, the survival seeds and the bisection run as jobs of worker
    processes (or of the serial executor) give the in-process results exactly."""
    from mpcbox.comparison.executors import ProcessExecutor
    from mpcbox.comparison.push_limits import survival

    lqr = LQR(two_feet)
    test = PushTest(settle=1.5, direction=(1.0, 0.0, 0.0), max_force=400.0, tolerance=150.0)
    task = dict(problem_options={"threads": 1})
    forces = [400.0, 0.0, 40.0]
    here = push_grid(two_feet, lqr, forces, test)
    spread = push_grid("humanoid_two_feet", _lqr, forces, test, executor="processes", **task)
    np.testing.assert_array_equal(spread.survived, here.survived)
    np.testing.assert_array_equal(spread.time_to_fall, here.time_to_fall)
    assert spread.survived.any() and not spread.survived.all()  # both outcomes compared

    limit = largest_push(two_feet, lqr, test)
    remote = largest_push(
        "humanoid_two_feet", _lqr, test, executor=ProcessExecutor(workers=1), **task
    )
    assert tuple(remote) == tuple(limit)

    noise, push = two_feet.noise(1.0), test.push(400.0)
    kw = dict(seeds=[3, 4], duration=test.total_time, noise=noise, pushes=[push])
    serial = survival(two_feet, lqr, **kw)
    by_name = survival("humanoid_two_feet", _lqr, executor="serial", **kw, **task)
    for a, b in zip(serial, by_name):
        np.testing.assert_array_equal(a, b)
    assert serial.rate < 1.0  # the push at 1.0 s felled the robot


def test_sweeps_by_name_check_their_arguments():
    from mpcbox.comparison.push_limits import survival
    from mpcbox.errors import UnknownNameError

    with pytest.raises(UnknownNameError, match="humanoid_two_feet"):
        survival("no_such_task", "lqr", seeds=[0], duration=0.1, executor="serial")
    with pytest.raises(UnknownNameError, match="'ray'"):
        push_grid("pendulum_swingup", "lqr", [0.0], executor="dask")


def test_sweeps_raise_when_a_run_could_not_start():
    """A controller that cannot be built measured nothing: the sweep says so with the
    original error instead of counting a fall at 0 s (or a NaN push limit)."""
    from mpcbox.comparison.push_limits import survival
    from mpcbox.errors import RunError

    bad = dict(executor="serial", controller_options={"bogus": 1})
    test = PushTest(settle=0.2, max_force=100.0, tolerance=50.0)
    with pytest.raises(RunError, match=r"2 of 2 runs of the push grid.*UnknownOptionError.*Q, R"):
        push_grid("humanoid_two_feet", "lqr", [0.0, 10.0], test, **bad)
    with pytest.raises(RunError, match=r"1 of 1 runs of the survival.*'bogus'"):
        survival("humanoid_two_feet", "lqr", seeds=[0], duration=0.1, **bad)
    with pytest.raises(RunError, match=r"largest push.*error in push search.*'bogus'") as info:
        largest_push("humanoid_two_feet", "lqr", test, **bad)
    assert isinstance(info.value, RuntimeError)


def test_a_trial_still_moving_at_its_end_is_not_recovered_with_rest_speed(two_feet):
    """With ``rest_speed`` a push trial counts only when the pushed body has come to rest:
    LQR on two feet still sways 0.05 s after a 40 N push, and is at rest 3 s after it."""
    import mujoco

    from mpcbox.comparison.robustness import end_speed, recovered
    from mpcbox.sim.simulation import simulate

    lqr = LQR(two_feet)
    short = PushTest(settle=0.05, rest_speed=0.01)
    result = simulate(two_feet, lqr, short.total_time, pushes=[short.push(40.0)])
    assert result.metrics.success
    # The body's speed at the end is its centre of mass's last step (MuJoCo integrates the
    # positions with the new velocities).
    model, data = two_feet.model, mujoco.MjData(two_feet.model)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, short.body)
    positions = []
    for state in result.states[-2:]:
        two_feet.set_state(data, state)
        mujoco.mj_kinematics(model, data)
        positions.append(data.xipos[body].copy())
    speed = end_speed(two_feet, result, short.body)
    step = result.time[-1] - result.time[-2]
    assert speed == pytest.approx(np.linalg.norm(positions[1] - positions[0]) / step, rel=1e-3)
    assert speed > short.rest_speed
    assert not recovered(two_feet, short, result)
    assert recovered(two_feet, PushTest(settle=0.05), result)  # staying up was enough
    settled = PushTest(settle=3.0, rest_speed=0.01)
    result = simulate(two_feet, lqr, settled.total_time, pushes=[settled.push(40.0)])
    assert recovered(two_feet, settled, result)
    # The bisection asks for rest too: no force passes a 0.05 s settle at rest.
    assert (
        largest_push(two_feet, lqr, PushTest(settle=0.05, rest_speed=1e-4, tolerance=50.0)).force
        == 0.0
    )
    with pytest.raises(InvalidArgumentError, match="rest_speed"):
        PushTest(rest_speed=-1.0)
    with pytest.raises(InvalidArgumentError, match="rest_speed needs"):
        push_grid("humanoid_two_feet", "lqr", [10.0], PushTest(rest_speed=0.1))


PUCK = """
<mujoco>
  <option timestep="0.001" gravity="0 0 0"/>
  <worldbody>
    <body name="puck" pos="0 0 1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <geom type="box" size=".1 .1 .1" mass="2" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator><motor joint="y" ctrlrange="-1 1"/></actuator>
</mujoco>
"""


def test_a_push_limit_reports_how_far_the_body_travelled():
    """A free 2 kg puck without gravity or friction, pushed along x with F for d seconds,
    travels F d^2 / (2 m) + (F d / m) * settle from the push's start to the trial's end."""
    import mpcbox

    class Zero(mpcbox.Controller):
        def __call__(self, state, time):
            return np.zeros(1)

    problem = mpcbox.Problem(PUCK)
    test = PushTest(body="puck", start=0.2, duration=0.1, settle=0.5, max_force=10.0)
    limit = largest_push(problem, Zero(), test)
    assert limit.force == 10.0 and limit.smallest_failed == np.inf
    a = 10.0 / 2.0
    want = 0.5 * a * 0.1**2 + a * 0.1 * 0.5
    assert limit.travel == pytest.approx(want, rel=0.03)
