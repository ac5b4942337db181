"""ArmReach on third-party arms: free objects, the goal check, the error measure, iLQR-MPC.

The arm without a marker is mujoco-warp's ALOHA scene (two ViperX arms with position servos
and a free pot with a sliding lid). Tests marked ``menagerie`` use the Franka Panda from an
offline Menagerie copy and skip without one.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.result import StopReason
from mpcbox.errors import InvalidArgumentError
from mpcbox.registry import make_controller
from mpcbox.tasks.reach import ArmReach
from mpcbox.tasks.reach_measures import arrival


def aloha_scene() -> Path:
    mujoco_warp = pytest.importorskip("mujoco_warp")
    return Path(mujoco_warp.__file__).parent / "test_data" / "aloha_pot" / "scene.xml"


@pytest.fixture(scope="module")
def aloha() -> ArmReach:
    return ArmReach(aloha_scene(), frame="left\\gripper", target=[0.0, 0.06, -0.08], relative=True)


def test_arrival_time_and_overshoot_of_a_known_series() -> None:
    time = np.arange(6) * 0.5
    errors = np.array([0.3, 0.02, 0.008, 0.012, 0.004, 0.001])
    hit = arrival(errors, time, 0.01)
    assert hit.time == 1.0 and hit.overshoot == 0.012  # left the ball again at t = 1.5
    assert np.isnan(arrival(errors, time, 1e-4).time)


def test_free_pot_is_refused_by_name_or_welded_out_of_the_state(aloha: ArmReach) -> None:
    with pytest.raises(InvalidArgumentError, match=r"free objects \['partnet_100015/'\]"):
        ArmReach(aloha_scene(), frame="left\\gripper", target=[0, 0, 0], free_objects="error")
    assert aloha.welded == ("partnet_100015/",)
    # 24 positions less the pot's free joint (7) and its lid's slide (1); the arms remain.
    assert (aloha.nq, aloha.nv, aloha.nu) == (16, 16, 14)
    assert aloha.goal.position_error < 1e-3
    lqr = mpcbox.LQR(aloha)  # the Riccati equation has a stabilizing solution without the pot
    assert np.max(np.abs(np.linalg.eigvals(lqr.A - lqr.B @ lqr.K))) < 1.0


@pytest.mark.parametrize(
    "argument, value",
    [("target", [np.nan, 0.0, 0.0]), ("orientation", [1.0, np.nan, 0.0, 0.0])],
)
def test_non_finite_targets_are_refused_by_their_name(argument, value) -> None:
    """A NaN target was reported as ``position must be finite`` (the IK's argument)."""
    kwargs = {"target": [0.0, 0.0, 0.0], argument: value}
    with pytest.raises(InvalidArgumentError, match=f"^{argument} must be finite"):
        ArmReach(aloha_scene(), frame="left\\gripper", relative=True, **kwargs)


def test_a_frame_no_joint_moves_is_refused_by_name() -> None:
    """Such a frame (the world, a table) went to the IK, which called the target out of
    reach."""
    with pytest.raises(InvalidArgumentError, match="frame 'world' is fixed to the world"):
        ArmReach(aloha_scene(), frame="world", target=[0.0, 0.0, 0.0], relative=True)


def test_lqr_reaches_and_the_goal_check_and_measure_agree(aloha: ArmReach) -> None:
    start = aloha.initial_state()
    assert aloha.dry_friction == "drop"  # the ViperX joints' dry friction (2 N m) left out
    assert aloha.reach_error(start) == pytest.approx(0.1, abs=1e-9)
    missed = aloha.goal_failure(np.array([0.0]), start[None])
    assert missed is not None and "10.00 cm from the target" in missed
    result = mpcbox.simulate(aloha, mpcbox.LQR(aloha), 2.0, seed=0)
    final = aloha.reach_error(result.states[-1])
    assert final < aloha.tolerance
    assert aloha.goal_failure(result.time, result.states) is None
    measured = result.metrics.measures
    assert measured["reach_error_final_m"] == pytest.approx(final, abs=2e-3)  # one step apart
    assert measured["reach_error_max_m"] == pytest.approx(0.1, abs=2e-3)
    arrived, settled = measured["reach_error_arrival_s"], measured["reach_error_settle_time_s"]
    assert 0.0 < arrived <= settled < 2.0


@pytest.mark.menagerie
def test_panda_ilqr_mpc_reaches_within_1cm_and_short_offline_plan_says_not_converged() -> None:
    from mpcbox.core import menagerie

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("franka_emika_panda")):
        pytest.skip("no offline Menagerie copy with franka_emika_panda (set MENAGERIE_ROOT)")
    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        home = ArmReach(
            "menagerie:franka_emika_panda", frame="hand", target=[0, 0, 0.0], relative=True
        )
        start = home.start_qpos.copy()
        start[:7] += rng.uniform(-0.1, 0.1, 7)
        offset = np.array([0.0, 0.3, -0.2646]) + rng.uniform(-0.03, 0.03, 3)
        problem = ArmReach(
            "menagerie:franka_emika_panda",
            frame="hand",
            target=offset,
            relative=True,
            start_qpos=start,
        )
    assert problem.reach_error(problem.initial_state()) > 0.35
    # The tuned 0.2 s horizon cannot cover the reach: the solver must not claim convergence.
    offline = ILQR(problem, problem.controller_configs["ilqr"]).solve(
        problem.initial_state(), max_iterations=15
    )
    assert problem.reach_error(offline.states[-1]) > 0.05
    assert not offline.converged, offline.status  # the solver said "converged" here
    result = mpcbox.simulate(problem, make_controller("ilqr", problem), 1.0, seed=0)
    errors = np.array([problem.reach_error(s) for s in result.states])
    hit = arrival(errors, result.time, problem.tolerance)
    assert hit.time < 1.0 and hit.overshoot <= problem.tolerance
    assert problem.goal_failure(result.time, result.states) is None


def test_aloha_ilqr_mpc_reaches_and_a_short_offline_solve_says_it_stopped_short(
    aloha: ArmReach,
) -> None:
    offline = ILQR(aloha, aloha.controller_configs["ilqr"]).solve(
        aloha.initial_state(), max_iterations=2
    )
    assert aloha.reach_error(offline.states[-1]) > aloha.tolerance  # 0.2 s cannot cover 10 cm
    assert not offline.converged and offline.stop_reason is StopReason.ITERATION_LIMIT
    # The tuned config with half the replans, to keep the test fast.
    controller = make_controller("ilqr", aloha, replan_period=0.04)
    result = mpcbox.simulate(aloha, controller, 0.7, seed=0)
    assert aloha.goal_failure(result.time, result.states) is None
    assert result.metrics.measures["reach_error_overshoot_m"] <= aloha.tolerance


TORQUE_ARM = """
<mujoco>
  <option timestep="0.005" integrator="implicitfast"/>
  <default><joint damping="0.5" armature="0.01"/><motor ctrlrange="-20 20"/></default>
  <worldbody>
    <body name="upper" pos="0 0 0.5">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
      <body name="fore" pos="0.3 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.025" mass="0.6"/>
        <site name="tip" pos="0.3 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="shoulder"/><motor joint="elbow"/></actuator>
  <keyframe><key qpos="0.3 0.6"/></keyframe>
</mujoco>
"""


def _guess_costs(problem: ArmReach, x0: np.ndarray, guesses: list[np.ndarray]) -> np.ndarray:
    return problem.rollout_cost(problem.rollout(x0, np.stack(guesses)))


def test_a_torque_arm_starts_from_holding_its_start_posture() -> None:
    """With motors the goal's gravity torques let the arm fall from the start; the default
    guess of iLQR is then the control that holds the start, which also rolls out cheaper."""
    problem = ArmReach(TORQUE_ARM, frame="tip", target=[-0.1, 0.0, 0.2], relative=True)
    x0, horizon = problem.initial_state(), 60
    hold = mpcbox.find_equilibrium(problem.model, x0[: problem.nq]).ctrl
    goal = np.tile(problem.ctrl_ref, (horizon, 1))
    guess = problem.initial_ctrls(x0, horizon)
    np.testing.assert_allclose(guess, np.tile(hold, (horizon, 1)))
    hold_cost, goal_cost = _guess_costs(problem, x0, [guess, goal])
    assert hold_cost < goal_cost
    # iLQR asks the Problem for its guess from each start state, unless given one.
    np.testing.assert_allclose(ILQR(problem, horizon=horizon).default_ctrls(x0), guess)
    given = ILQR(problem, horizon=horizon, ctrls_init=problem.ctrl_ref)
    np.testing.assert_allclose(given.default_ctrls(x0), goal)
    solver = ILQR(problem, horizon=horizon)
    solver.ctrls_init = goal  # an assigned guess (a hand-over's plan) is kept as well
    np.testing.assert_allclose(solver.default_ctrls(x0), goal)


def test_a_servo_arm_starts_from_the_goal_set_points(aloha: ArmReach) -> None:
    """With position servos the goal's set-points drive the arm there: the cheaper guess under
    the tuned iLQR's cost (its horizon, the LQR value as terminal cost)."""
    solver = ILQR(aloha, aloha.controller_configs["ilqr"])
    planned, x0 = solver.problem, aloha.initial_state()
    goal = np.tile(aloha.clip_ctrl(aloha.ctrl_ref), (solver.horizon, 1))
    np.testing.assert_allclose(solver.default_ctrls(x0), goal)
    hold = aloha.clip_ctrl(mpcbox.find_equilibrium(aloha.model, x0[: aloha.nq]).ctrl)
    steps = solver.config.control_steps  # each knot's control is held this many steps
    guesses = [np.repeat(g, steps, axis=0) for g in (goal, np.tile(hold, (solver.horizon, 1)))]
    goal_cost, hold_cost = _guess_costs(planned, x0, guesses)
    assert goal_cost < hold_cost


def test_every_planner_cold_starts_from_the_task_guess() -> None:
    """The sampling controllers' first nominal and IPOPT's first iterate come from
    ``Problem.initial_ctrls`` too: on the torque arm, holding the start rather than the
    goal's gravity torques."""
    problem = ArmReach(TORQUE_ARM, frame="tip", target=[-0.1, 0.0, 0.2], relative=True)
    x0 = problem.initial_state()
    hold = mpcbox.find_equilibrium(problem.model, x0[: problem.nq]).ctrl
    mppi = make_controller("mppi", problem, backend="cpu", num_samples=8, seed=0)
    knots = mppi.nominal_knots(x0)
    np.testing.assert_allclose(knots, np.tile(hold, (mppi.spline.num_knots, 1)))
    assert not np.allclose(knots, mppi.nominal_knots())  # without a state: ctrl_ref
    mppi(x0, 0.0)  # the first tick scores that nominal as candidate 0
    steps = mppi.horizon_steps
    expected = mppi.problem.rollout_cost(mppi.problem.rollout(x0, np.tile(hold, (steps, 1))))
    np.testing.assert_allclose(mppi.last.nominal_cost, expected[0], rtol=1e-9)
    calls: list[tuple[np.ndarray, int]] = []
    original = problem.initial_ctrls

    def recorded(state: np.ndarray, horizon: int) -> np.ndarray:
        calls.append((np.array(state), horizon))
        return original(state, horizon)

    problem.initial_ctrls = recorded  # type: ignore[method-assign]
    pytest.importorskip("casadi")
    from mpcbox.controllers.ipopt import solve_ipopt

    solve_ipopt(problem, x0, 5, max_iterations=1)
    assert len(calls) == 1 and calls[0][1] == 5
    np.testing.assert_allclose(calls[0][0], x0)


def test_a_mixed_arm_gets_set_points_for_its_servos_and_holding_torques_for_its_motors() -> None:
    xml = TORQUE_ARM.replace(
        '<motor joint="shoulder"/>', '<position joint="shoulder" kp="200" ctrlrange="-3 3"/>'
    )
    problem = ArmReach(xml, frame="tip", target=[-0.1, 0.0, 0.2], relative=True)
    x0 = problem.initial_state()
    guess = problem.initial_ctrls(x0, 4)
    hold = mpcbox.find_equilibrium(problem.model, x0[: problem.nq]).ctrl
    np.testing.assert_allclose(guess[:, 0], problem.ctrl_ref[0])  # the goal's set-point
    np.testing.assert_allclose(guess[:, 1], hold[1])  # the elbow motor holds the start
    assert not np.isclose(hold[1], problem.ctrl_ref[1])


@pytest.mark.parametrize("timestep, steps, knots", [(0.002, 4, 25), (0.001, 8, 25), (0.005, 2, 20)])
def test_ilqr_knots_last_8ms_over_a_02s_plan_on_any_timestep(timestep, steps, knots) -> None:
    """The Z1 runs at 1 ms: with the 2 ms arms' four steps a knot, its plan covered 0.1 s."""
    problem = ArmReach(
        TORQUE_ARM, frame="tip", target=[-0.1, 0.0, 0.2], relative=True, planning_timestep=timestep
    )
    config = problem.controller_configs["ilqr"]
    assert (config.control_steps, config.horizon) == (steps, knots)
    solver = make_controller("ilqr", problem)
    assert solver.knot_dt == pytest.approx(steps * timestep)
    assert solver.horizon * solver.knot_dt == pytest.approx(0.2, abs=0.5 * solver.knot_dt)
    assert ArmReach.controller_configs["ilqr"].control_steps == 4  # the class's is untouched
