"""Cube stacking: the scene, the success check, the waypoint controller, the MJWarp batch."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.waypoints import ArmDrive, Phase, Waypoint, WaypointController
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.tasks.manipulation.arms import arm_spec
from mpcbox.tasks.manipulation.pick_place import (
    PickPlaceTiming,
    arm_drive,
    nearest_quarter,
    stacking_controller,
    top_down,
)
from mpcbox.tasks.manipulation.scene import CUBE_SIZE, CubeLayout, stacking_model
from mpcbox.tasks.manipulation.stacking import StackCubes, random_layout, stack_check

pytest.importorskip("mink")


@pytest.fixture(scope="module")
def aloha() -> StackCubes:
    return StackCubes("aloha", threads=1)


# ---------------------------------------------------------------------- success check
@pytest.mark.parametrize(
    ("offset", "ok"),
    [
        ((0.0, 0.0, 0.044), True),
        ((0.010, 0.010, 0.044), True),  # xy_err 14.1 mm
        ((0.011, 0.011, 0.044), False),  # xy_err 15.6 mm
        ((0.0, 0.0, 0.0349), False),
        ((0.0, 0.0, 0.0351), True),
        ((0.0, 0.0, 0.0549), True),
        ((0.0, 0.0, 0.0551), False),
        ((0.0, 0.0, -0.044), False),  # blue on red
    ],
)
def test_stack_check_thresholds(offset, ok):
    blue = np.array([0.1, -0.2, 0.022])
    check = stack_check(blue + offset, blue)
    assert check.success is ok
    assert check.xy_err == pytest.approx(np.hypot(offset[0], offset[1]))
    assert check.dz == pytest.approx(offset[2])


def _settle(problem: StackCubes, state: np.ndarray, duration: float = 0.4) -> np.ndarray:
    """Hold the arm at home with the gripper open and let the cubes settle."""
    model = problem.model
    data = mujoco.MjData(model)
    problem.set_state(data, state)
    data.ctrl[:] = problem.ctrl_ref
    states = []
    for _ in range(round(duration / model.opt.timestep)):
        mujoco.mj_step(model, data)
        states.append(problem.get_state(data))
    return np.array(states)


def test_hand_placed_stack_passes_and_side_by_side_fails(aloha):
    layout = CubeLayout(red=(0.05, 0.0), blue=(0.05, 0.0))
    state = aloha.layout_state(layout)
    red = aloha._cube_adr["red_cube"]
    state[red + 2] += CUBE_SIZE + 0.002  # red resting on blue after a 2 mm drop
    state[red + 0] += 0.006
    states = _settle(aloha, state)
    time = np.arange(len(states)) * aloha.model.opt.timestep
    check = aloha.check(states[-1])
    assert check.success and check.xy_err == pytest.approx(0.006, abs=1e-3)
    assert aloha.goal_failure(time, states) is None

    apart = _settle(aloha, aloha.layout_state(CubeLayout(red=(0.05, 0.1), blue=(0.05, -0.1))))
    reason = aloha.goal_failure(time, apart)
    assert reason is not None and "never lifted" in reason


# ---------------------------------------------------------------------- scene
def test_scene_has_cubes_table_and_attached_arm():
    model = stacking_model("aloha")
    assert model.geom("red_cube").size == pytest.approx([0.022] * 3)
    assert model.geom("blue_cube").size == pytest.approx([0.022] * 3)
    assert model.nu == 7 and model.nkey == 1
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    arm = arm_spec("aloha")
    assert data.body("arm/" + arm.base).xpos == pytest.approx(arm.mount)
    # Cubes rest on the table top (z = 0) at the start.
    assert data.body("red_cube").xpos[2] == pytest.approx(0.022)
    with pytest.raises(UnknownNameError, match="aloha"):
        stacking_model("so101")


def test_random_layouts_keep_cubes_apart_and_in_reach():
    arm = arm_spec("aloha")
    rng = np.random.default_rng(7)
    base = np.array(arm.mount[:2])
    for _ in range(50):
        lay = random_layout(rng, arm)
        red, blue = np.array(lay.red), np.array(lay.blue)
        assert np.linalg.norm(red - blue) >= 0.1
        for xy in (red, blue):
            assert arm.reach[0] - 1e-9 <= np.linalg.norm(xy - base) <= arm.reach[1] + 1e-9


def test_nearest_quarter_and_top_down():
    assert nearest_quarter(0.1, 1.6) == pytest.approx(0.1 + np.pi / 2)
    assert nearest_quarter(-0.7, 0.0) == pytest.approx(-0.7)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, top_down(0.3))
    mat = mat.reshape(3, 3)
    assert mat[:, 2] == pytest.approx([0.0, 0.0, -1.0])  # approach straight down
    assert mat[:, 0] == pytest.approx([np.cos(0.3), np.sin(0.3), 0.0])


# ---------------------------------------------------------------------- controller
def test_waypoint_controller_reaches_a_waypoint(aloha):
    target = np.array([0.05, 0.05, 0.12])

    def above(m, d, memo):
        return Waypoint(target, top_down(np.pi / 2 + np.arctan2(0.05, 0.35)), None)

    controller = WaypointController(
        aloha, arms=[arm_drive(aloha.arm)], phases=[Phase("reach", above, 0.8, 0.4)]
    )
    sim = mpcbox.simulate(aloha, controller, 1.2)
    data = mujoco.MjData(aloha.model)
    aloha.set_state(data, sim.states[-1])
    mujoco.mj_kinematics(aloha.model, data)
    assert np.linalg.norm(data.site("arm/tcp").xpos - target) < 0.005
    assert controller.phase_name == "reach" and controller.stats["ik_error_max"] < 2e-3


def test_waypoint_controller_rejects_bad_input(aloha):
    drive = arm_drive(aloha.arm)
    with pytest.raises(InvalidArgumentError, match="at least one"):
        WaypointController(aloha, arms=[drive], phases=[])
    bad = ArmDrive(drive.frame, drive.joints, drive.actuators[::-1], drive.posture)
    with pytest.raises(InvalidArgumentError, match="position servo"):
        phase = Phase("x", lambda m, d, memo: Waypoint(), 1.0)
        WaypointController(aloha, arms=[bad], phases=[phase])


@pytest.mark.parametrize("seed", [1, 2])
def test_closed_loop_stacking_on_aloha(aloha, seed):
    controller = stacking_controller(aloha)
    sim = mpcbox.simulate(
        aloha, controller, PickPlaceTiming().total, initial_state=aloha.trial_state(seed)
    )
    assert sim.metrics.outcome == "success", sim.failure
    check = aloha.check(sim.states[-1])
    assert check.xy_err < 0.015 and 0.035 <= check.dz <= 0.055


def test_closed_loop_follows_a_pushed_cube(aloha):
    from mpcbox.sim.disturbances import Push

    state = aloha.trial_state(0)
    red, blue = aloha.cube_position(state, "red_cube"), aloha.cube_position(state, "blue_cube")
    away = (red - blue) * [1.0, 1.0, 0.0]
    # Shove the red cube away from the blue one while the arm approaches it.
    push = Push(force=0.65 * away / np.linalg.norm(away), start=0.3, duration=0.15, body="red_cube")
    controller = stacking_controller(aloha)
    sim = mpcbox.simulate(
        aloha, controller, PickPlaceTiming().total, initial_state=state, pushes=[push]
    )
    before_grasp = sim.states[np.searchsorted(sim.time, 1.2)]
    # Farther than the fingers' 7 mm clearance per side: a grasp planned at the start misses.
    assert np.linalg.norm(aloha.cube_position(before_grasp, "red_cube") - red) > 0.03
    assert sim.metrics.outcome == "success", sim.failure


# ---------------------------------------------------------------------- MJWarp batch
def test_warp_batch_matches_cpu_closed_loop(aloha):
    pytest.importorskip("mujoco_warp")
    from mpcbox.sim.batch_warp import simulate_batch_warp

    seeds = (0, 1)
    duration = 0.3
    states0 = np.stack([aloha.trial_state(s) for s in seeds])
    template = stacking_controller(aloha)
    controllers = [template.fork() for _ in seeds]
    out = simulate_batch_warp(aloha, controllers, states0, duration, device="cpu")
    assert not out.overflow.any() and not out.diverged.any() and out.errors == ["", ""]
    assert out.nconmax >= 2 * out.calibration[0] and out.calibration[0] > 0
    for i, seed in enumerate(seeds):
        cpu = mpcbox.simulate(
            aloha, stacking_controller(aloha), duration, initial_state=aloha.trial_state(seed)
        )
        # Same controller, same period: the arm follows the same set-points (float32 vs 64).
        moved = np.abs(cpu.states[-1, 14:20] - cpu.states[0, 14:20]).max()
        assert moved > 0.01
        assert np.abs(out.states[-1, i, 14:20] - cpu.states[-1, 14:20]).max() < 1e-3


# ---------------------------------------------------------------------- Panda
@pytest.mark.menagerie
def test_panda_scene_and_top_down_reach():
    problem = StackCubes("panda", threads=1)
    assert problem.nu == 8
    target = np.array([0.05, 0.0, 0.15])
    controller = WaypointController(
        problem,
        arms=[arm_drive(problem.arm)],
        phases=[Phase("reach", lambda m, d, memo: Waypoint(target, top_down(np.pi / 2)), 1.0, 0.5)],
    )
    sim = mpcbox.simulate(problem, controller, 1.5)
    data = mujoco.MjData(problem.model)
    problem.set_state(data, sim.states[-1])
    mujoco.mj_kinematics(problem.model, data)
    assert np.linalg.norm(data.site("arm/tcp").xpos - target) < 0.005


# ---------------------------------------------------------------------- pot lift
def test_bimanual_pot_lift_on_aloha():
    from mpcbox.tasks.manipulation.pot_lift import PotLift, PotLiftTiming, pot_lift_controller

    problem = PotLift(threads=1)
    controller = pot_lift_controller(problem)
    start = problem.trial_state(3)
    sim = mpcbox.simulate(problem, controller, PotLiftTiming().total, initial_state=start)
    assert sim.metrics.outcome == "success", sim.failure
    assert problem.pot_height(sim.states[-1]) - problem.pot_height(start) >= 0.05
    # Held, not tossed: the pot stays up over the last half second of the hold.
    steps = round(0.5 / problem.model.opt.timestep)
    heights = [problem.pot_height(s) for s in sim.states[-steps:]]
    assert max(heights) - min(heights) < 0.005
    # Without closing the grippers the pot stays on the table.
    open_timing = PotLiftTiming()
    open_controller = pot_lift_controller(problem, timing=open_timing)
    close = next(p for p in open_controller.phases if p.name == "close")
    phases = [
        p if p.name != "close" else close._replace(target=_keep) for p in open_controller.phases
    ]
    open_controller.phases = tuple(phases)
    missed = mpcbox.simulate(problem, open_controller, open_timing.total, initial_state=start)
    assert missed.metrics.outcome == "goal missed"


def _keep(m, d, memo):
    return [Waypoint(), Waypoint()]
