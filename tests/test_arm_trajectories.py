"""Arm trajectories: the quintic's closed form, torque limits, the clearance cost, iLQR moves
around an obstacle, time-varying LQR tracking, its measures, and CSV save/load/replay.

The arm is mpcbox's own three-joint torque-motor arm (``scenes/arm3.xml``); the test marked
``menagerie`` uses the Franka Panda from an offline Menagerie copy.
"""

from __future__ import annotations

import csv
import io
import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.cli.replay import run_replay
from mpcbox.controllers.trajectory import TrajectoryTracker, quintic, tracking_reference
from mpcbox.controllers.trajectory.quintic import PEAK_ACCELERATION_RATIO, PEAK_VELOCITY_RATIO
from mpcbox.core.cost import ActuatorForce, Cost, SphereClearance, StateCost
from mpcbox.core.torque_limits import inverse_dynamics, torque_limits, torque_ratio
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.trajectory import replay, trajectory_from_result
from mpcbox.sim.trajectory_files import load_trajectory, save_trajectory
from mpcbox.tasks import scene_path
from mpcbox.tasks.arm import (
    ArmTrack,
    Overshoot,
    Sphere,
    TargetError,
    TrackingError,
    ilqr_move,
    move_report,
    move_tracker,
    quintic_move,
)

ARM = str(scene_path("arm3.xml"))


@pytest.fixture(scope="module")
def arm() -> ArmTrack:
    return ArmTrack(duration=0.6, hold=0.3, threads=1)


def test_quintic_matches_its_closed_form() -> None:
    rng = np.random.default_rng(3)
    q0, q1 = rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)
    T, dt = 0.8, 1e-3
    traj = quintic(q0, q1, T, dt, hold=0.2)
    assert traj.time.shape == (1001,) and traj.qpos.shape == (1001, 4)
    np.testing.assert_allclose(traj.qpos[0], q0, atol=1e-15)
    np.testing.assert_allclose(traj.qpos[800], q1, atol=1e-12)
    np.testing.assert_allclose(traj.qpos[800:], np.tile(q1, (201, 1)), atol=1e-12)
    for ends in (traj.qvel[[0, 800, -1]], traj.qacc[[0, 800, -1]]):
        np.testing.assert_allclose(ends, 0.0, atol=1e-12)
    delta = q1 - q0
    np.testing.assert_allclose(traj.qvel[400], PEAK_VELOCITY_RATIO * delta / T, rtol=1e-12)
    assert np.all(np.abs(traj.qvel) <= np.abs(traj.qvel[400]) + 1e-12)
    t_acc = T * (0.5 - np.sqrt(3) / 6)
    s = quintic(q0, q1, T, t_acc / 1000)  # a sample exactly at the acceleration peak
    np.testing.assert_allclose(s.qacc[1000], PEAK_ACCELERATION_RATIO * delta / T**2, rtol=1e-9)
    # Velocity and acceleration are the derivatives of the samples (central differences).
    np.testing.assert_allclose(
        np.gradient(traj.qpos, dt, axis=0)[1:799], traj.qvel[1:799], atol=1e-4
    )
    np.testing.assert_allclose(
        np.gradient(traj.qvel, dt, axis=0)[1:799], traj.qacc[1:799], atol=1e-3
    )


@pytest.mark.parametrize(
    ("duration", "dt", "hold"), [(0.0, 0.01, 0.0), (1.0, 2.0, 0.0), (1.0, 0.01, -1.0)]
)
def test_quintic_rejects_bad_times(duration: float, dt: float, hold: float) -> None:
    with pytest.raises(InvalidArgumentError):
        quintic(np.zeros(2), np.ones(2), duration, dt, hold=hold)


def test_torque_limits_and_inverse_dynamics_of_the_motor_arm() -> None:
    model = mujoco.MjModel.from_xml_path(ARM)
    limits = torque_limits(model)
    np.testing.assert_array_equal(limits.upper, [6.0, 15.0, 6.0])
    np.testing.assert_array_equal(limits.lower, [-6.0, -15.0, -6.0])
    # At rest the torque is gravity's (the bias force), and it is within the limits.
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0]
    mujoco.mj_forward(model, data)
    tau = inverse_dynamics(model, data.qpos[None], np.zeros((1, 3)), np.zeros((1, 3)))
    np.testing.assert_allclose(tau[0], data.qfrc_bias, atol=1e-10)
    # A quintic needs acceleration torques growing as 1/T^2: too fast a move exceeds them.
    q0, q1 = model.key_qpos[0], model.key_qpos[1]
    ratios = []
    for T in (2.0, 0.15):
        tr = quintic(q0, q1, T, 0.005)
        ratios.append(torque_ratio(inverse_dynamics(model, tr.qpos, tr.qvel, tr.qacc), limits))
    assert ratios[0] < 1.0 < ratios[1]


def test_sphere_clearance_residual_and_jacobian_match_finite_differences() -> None:
    model = mujoco.MjModel.from_xml_path(ARM)
    data = mujoco.MjData(model)
    q = np.array([0.3, -0.4, 1.0])
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    ee = data.site_xpos[0].copy()
    term = SphereClearance(["ee", "fore"], ee + np.array([0.03, -0.02, 0.01]), 0.08, weight=2.0)
    problem = mpcbox.Problem(ARM, cost=Cost([term, StateCost(q, weight_qpos=0.0)]), threads=1)

    def residual(qpos: np.ndarray) -> np.ndarray:
        feats = problem.features(np.r_[qpos, np.zeros(3)], np.zeros(3))
        return term.residual(feats)[0]

    r = residual(q)
    assert r[0] == pytest.approx(0.08 - np.linalg.norm([0.03, -0.02, 0.01]), abs=1e-12)
    d = mujoco.MjData(problem.planning_model)
    d.qpos[:] = q
    mujoco.mj_forward(problem.planning_model, d)
    jac = term.jacobian(problem.planning_model, d).dq
    eps = 1e-6
    fd = np.stack(
        [(residual(q + eps * e) - residual(q - eps * e)) / (2 * eps) for e in np.eye(3)], 1
    )
    np.testing.assert_allclose(jac, fd, atol=1e-7)
    # Turned away about the vertical axis, both frames are outside: residual and slope 0.
    away = q + np.array([2.5, 0.0, 0.0])
    np.testing.assert_array_equal(residual(away), 0.0)
    d.qpos[:] = away
    mujoco.mj_forward(problem.planning_model, d)
    np.testing.assert_array_equal(term.jacobian(problem.planning_model, d).dq, 0.0)


SERVO_ARM = """
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <body>
      <joint name="a" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      <body pos="0.3 0 0">
        <joint name="b" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <general name="servo" joint="a" gainprm="50" biastype="affine" biasprm="0 -50 -5"
             forcerange="-3 3" ctrlrange="-2 2" gear="2"/>
    <motor name="motor" joint="b" gear="1.5" ctrlrange="-1 1"/>
  </actuator>
</mujoco>
"""


def test_actuator_force_jacobian_matches_finite_differences() -> None:
    term = ActuatorForce(np.array([0.5, -0.2]), weight=1.0)
    problem = mpcbox.Problem(SERVO_ARM, cost=Cost([term]), threads=1)
    model = problem.planning_model

    def residual(state: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        return term.residual(problem.features(state, ctrl))[0]

    data = mujoco.MjData(model)
    for state, ctrl, saturated in (
        (np.array([0.3, -0.2, 0.4, 0.1]), np.array([0.7, 0.5]), False),
        (np.array([0.3, -0.2, 0.4, 0.1]), np.array([1.5, 0.5]), True),  # servo at 3 N
    ):
        data.qpos[:], data.qvel[:], data.ctrl[:] = state[:2], state[2:], ctrl
        mujoco.mj_forward(model, data)
        jac = term.jacobian(model, data)
        eps = 1e-6
        fd_x = np.stack(
            [
                (residual(state + d, ctrl) - residual(state - d, ctrl)) / (2 * eps)
                for d in eps * np.eye(4)
            ],
            1,
        )
        fd_u = np.stack(
            [
                (residual(state, ctrl + d) - residual(state, ctrl - d)) / (2 * eps)
                for d in eps * np.eye(2)
            ],
            1,
        )
        np.testing.assert_allclose(np.hstack([jac.dq, jac.dv]), fd_x, atol=1e-6)
        np.testing.assert_allclose(jac.du, fd_u, atol=1e-6)
        assert (jac.du[0, 0] == 0.0) == saturated
    # The servo's force is its torque over the gear, not its set-point.
    assert residual(np.r_[0.3, 0.0, 0.0, 0.0], np.array([0.62, 0.0]))[0] == pytest.approx(
        50 * (0.62 - 2 * 0.3) - 0.5
    )


@pytest.mark.parametrize("offset", [[0.0, 0.0, 0.015], [0.0, -0.02, 0.0]])
def test_ilqr_move_goes_around_the_obstacle_within_the_torque_limits(offset) -> None:
    plain = ArmTrack(duration=0.6, hold=0.0, threads=1)
    path = plain.frame_path(quintic_move(plain).states)
    # An obstacle just off the quintic's path at mid-move: the quintic goes through it.
    obstacle = Sphere(path[len(path) // 2] + offset, 0.05)
    problem = ArmTrack(duration=0.6, hold=0.0, obstacle=obstacle, threads=1)
    q = quintic_move(problem)
    m = ilqr_move(problem, max_iterations=40)
    rq, rm = move_report(problem, q), move_report(problem, m)
    assert rq.clearance < -0.02 and rq.final_error < 1e-9
    assert rm.clearance > 0.0, rm
    assert rm.cost < rq.cost
    assert rm.final_error < 0.01
    assert rm.torque_ratio <= 1.0 + 1e-2
    assert np.all(m.ctrls >= problem.ctrl_low) and np.all(m.ctrls <= problem.ctrl_high)


def test_too_fast_a_quintic_exceeds_the_torque_limits_where_the_ilqr_move_does_not() -> None:
    fast = ArmTrack(duration=0.3, hold=0.3, threads=1)
    q, m = quintic_move(fast), ilqr_move(fast, max_iterations=40)
    rq, rm = move_report(fast, q), move_report(fast, m)
    assert rq.torque_ratio > 1.5 and rm.torque_ratio <= 1.0 + 1e-2
    assert rm.final_error < 0.01
    rmse = {}
    for plan in (q, m):
        sim = mpcbox.simulate(fast, move_tracker(fast, plan), fast.duration + fast.hold)
        rmse[plan.method] = sim.metrics.measures["tracking_error_rms_m"]
    assert rmse["ilqr"] < 0.005 < 0.02 < rmse["quintic"]


def test_tracking_with_time_varying_lqr_beats_feedforward_under_model_mismatch(arm) -> None:
    move = quintic_move(arm)
    mismatch = mpcbox.ModelMismatch(mass_scale=1.3)
    rows = {}
    for feedback in (False, True):
        tracker = move_tracker(arm, move, feedback=feedback)
        sim = mpcbox.simulate(arm, tracker, arm.duration + arm.hold, mismatch=mismatch)
        rows[feedback] = sim.metrics.measures
    tuned = rows[True]
    assert tuned["tracking_error_rms_m"] < 0.005
    assert tuned["tracking_error_rms_m"] < 0.5 * rows[False]["tracking_error_rms_m"]
    assert tuned["target_error_final_m"] < arm.tolerance
    assert np.isfinite(tuned["target_error_settling_s"]) and tuned["overshoot_max_pct"] < 3.0


def test_tracking_reference_reproduces_the_quintic_without_mismatch(arm) -> None:
    traj = arm.joint_reference()
    ref = tracking_reference(arm, traj)
    assert ref.residual < 1e-3
    start = ref.states[0].copy()
    start[1] += 0.05  # a perturbed start: the gains pull it back on the reference
    sim = mpcbox.simulate(arm, TrajectoryTracker(arm, ref), 0.9, initial_state=start)
    assert np.max(np.abs(sim.states[-1] - ref.states[-1])) < 1e-4


def test_measures_of_known_motions() -> None:
    time = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    over = Overshoot(frame="ee", start=(0.0, 0.0, 0.0), target=(0.5, 0.0, 0.0))
    assert over.summarize(np.array([-100.0, -20.0, 6.0, 1.0, 0.0]), time) == {
        "overshoot_max_pct": 6.0
    }
    assert over.summarize(np.array([-100.0, -1.0]), time[:2])["overshoot_max_pct"] == 0.0
    err = TargetError(frame="ee", target=(0.5, 0.0, 0.0), tolerance=0.01, end_time=1.0)
    out = err.summarize(np.array([0.5, 0.2, 0.02, 0.008, 0.001]), time)
    assert out["target_error_settle_time_s"] == 1.5 and out["target_error_settling_s"] == 0.5
    track = TrackingError(frame="ee", time=np.array([0.0, 1.0]), positions=np.eye(3)[:2])
    np.testing.assert_allclose(track.reference(0.25), [0.75, 0.25, 0.0])
    np.testing.assert_allclose(track.reference(5.0), [0.0, 1.0, 0.0])


def test_arm_track_arguments() -> None:
    with pytest.raises(InvalidArgumentError, match="not both"):
        ArmTrack(goal_qpos=np.zeros(3), target=np.zeros(3))
    with pytest.raises(InvalidArgumentError, match="does not move"):
        ArmTrack(goal_qpos=np.array([0.0, -0.6, 1.2]))


def test_trajectory_csv_save_load_and_replay(arm, tmp_path) -> None:
    tracker = move_tracker(arm, quintic_move(arm))
    sim = mpcbox.simulate(arm, tracker, 0.3)
    meta = {"task": "arm_track", "task_options": arm.task_options()}
    traj = trajectory_from_result(sim, arm, metadata=meta)
    csv_path, _ = save_trajectory(traj, tmp_path / "move")
    with open(csv_path) as fh:
        header = next(csv.reader(fh))
    assert header[0] == "time" and {"site_ee_x", "site_ee_y", "site_ee_z"} <= set(header)
    assert {"qpos_0", "qvel_2", "ctrl_2"} <= set(header)
    loaded = load_trajectory(csv_path)
    np.testing.assert_array_equal(loaded.states, traj.states)
    np.testing.assert_allclose(loaded.sites["ee"], arm.frame_path(traj.states), atol=1e-12)
    again = replay(loaded, arm)
    assert again.final_error == 0.0
    np.testing.assert_array_equal(again.states, traj.states)
    out = io.StringIO()
    assert run_replay([str(csv_path)], stream=out) == 0, out.getvalue()


@pytest.mark.menagerie
def test_panda_tracks_a_quintic_within_five_millimetres() -> None:
    from mpcbox.core.menagerie import MissingMeshWarning
    from mpcbox.errors import EquilibriumWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MissingMeshWarning)
        warnings.simplefilter("ignore", EquilibriumWarning)
        goal = np.r_[0.4, 0.3, 0.2, -1.9, 0.1, 1.9, -0.5, 0.04, 0.04]
        panda = ArmTrack(
            "menagerie:franka_emika_panda",
            frame="hand",
            site_offset=[0.0, 0.0, 0.1034],
            goal_qpos=goal,
            duration=0.5,
            hold=0.1,
        )
        tracker = move_tracker(panda, quintic_move(panda))
        sim = mpcbox.simulate(panda, tracker, 0.6, mismatch=mpcbox.ModelMismatch(mass_scale=1.2))
    assert "ee" in mujoco.mj_id2name(panda.model, mujoco.mjtObj.mjOBJ_SITE, panda.model.nsite - 1)
    assert sim.metrics.measures["tracking_error_rms_m"] < 0.005


OFFSET_ARM = """
<mujoco>
  <worldbody>
    <body name="a"><joint name="low" range="-1 2"/><geom size=".05"/>
      <body name="b" pos="0 0 .2"><joint name="narrow" range="-.1 .1"/><geom size=".05"/>
        <body name="c" pos="0 0 .2"><joint name="free_turn"/><geom size=".05"/>
          <body name="d" pos="0 0 .2"><joint name="slide" type="slide"/><geom size=".05"/>
            <body name="e" pos="0 0 .2"><joint name="idle" range="-1 1"/><geom size=".05"/>
            </body></body></body></body></body>
  </worldbody>
  <actuator>
    <position joint="low" kp="10"/><motor joint="narrow"/><motor joint="free_turn"/>
    <position joint="slide" kp="10"/>
  </actuator>
</mujoco>
"""


def test_arm_trajectory_defaults_turn_each_driven_hinge_towards_its_middle(problem_script):
    script = problem_script("arm_trajectory")
    model = mujoco.MjModel.from_xml_string(OFFSET_ARM)
    start = np.array([-1.0, 0.05, 0.0, 0.0, 0.0])
    offsets = script.default_offsets(model, start)
    # +0.3 from the low end; -0.05 to the middle of a 0.2 rad range (nearer than 0.3); +0.3
    # unlimited; the slide and the undriven hinge stay.
    np.testing.assert_allclose(offsets, [0.3, -0.05, 0.3, 0.0, 0.0], atol=1e-12)
    assert script.DEFAULT_OFFSET == 0.3


def test_panda_reach_scales_its_default_target_by_the_arms_length(problem_script):
    script = problem_script("panda_reach")
    model = mujoco.MjModel.from_xml_string(OFFSET_ARM)
    # Five joints 0.2 m apart in a column and the frame at the last one: 0.8 m.
    assert script.arm_length(model, "e", model.qpos0) == pytest.approx(0.8, abs=1e-12)
    qpos = model.qpos0.copy()
    qpos[0] = np.pi / 2  # folding the chain at its base does not change its length
    assert script.arm_length(model, "e", qpos) == pytest.approx(0.8, abs=1e-12)
    offset = script.default_offset(OFFSET_ARM, "e")
    assert np.linalg.norm(offset) == pytest.approx(script.ARM_FRACTION * 0.8, abs=1e-12)
    np.testing.assert_allclose(offset / np.linalg.norm(offset), [0.0, 0.75, -0.6615], atol=1e-3)


def test_the_arm_scripts_print_a_bad_arguments_named_error_and_return_2(capsys, problem_script):
    script = problem_script("arm_trajectory")
    assert script.main(["--model", "arm3", "--duration", "0"]) == 2
    assert "error: --duration must be > 0, got 0.0" in capsys.readouterr().err
    assert script.main(["--model", "arm3", "--offsets", "1", "1", "1", "1"]) == 2
    assert "--offsets: 4 given, the model has 3 qpos" in capsys.readouterr().err
