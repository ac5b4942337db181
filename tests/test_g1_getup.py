"""The get-up by name: HumanoidGetup's names checked, and the G1 preset (Menagerie)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnknownNameError
from mpcbox.registry import make_controller, task_class
from mpcbox.tasks.humanoid.g1_getup import G1Getup, range_noise
from mpcbox.tasks.humanoid.getup import HumanoidGetup


@pytest.mark.parametrize(
    ("options", "listed"),
    [
        ({"torso": "chest"}, "torso"),
        ({"root": "base_link"}, "torso"),
        ({"feet": ("foot_left", "left_sole")}, "foot_right"),
        ({"keyframe": "crouch"}, "stand"),
    ],
)
def test_unknown_names_are_rejected_listing_what_exists(options, listed) -> None:
    bad = (
        next(v for v in options.values() if isinstance(v, str))
        if "feet" not in options
        else "left_sole"
    )
    with pytest.raises(UnknownNameError, match=listed) as info:
        HumanoidGetup(settle=0.0, **options)
    assert bad in str(info.value)


def test_feet_must_name_two_feet() -> None:
    with pytest.raises(InvalidArgumentError, match="feet"):
        HumanoidGetup(settle=0.0, feet=("foot_left",))


def test_stand_height_derived_from_the_keyframe_when_omitted() -> None:
    task = HumanoidGetup(settle=0.0, stand_height=None, stand_fraction=0.5, release_height=None)
    assert task.stand_height == pytest.approx(0.5 * task.torso_height)
    assert task.release_height == pytest.approx(0.8 * task.stand_height)
    assert task.handover_height == task.stand_height


def test_height_above_feet_and_com_velocity_terms() -> None:
    """Zero at the standing keyframe; lifting a foot costs height only above the feet."""
    plain = HumanoidGetup(settle=0.0, height_above_feet=False, com_velocity_cost=0.0)
    task = HumanoidGetup(settle=0.0)  # the defaults: both terms
    names = {t.name for t in task.cost.running}
    assert {"height_left", "height_right", "com_vel"} <= names and "height" not in names
    assert "com_vel" not in {t.name for t in plain.cost.running}
    stand = task.reference_state()
    u = task.ctrl_ref
    for term in task.cost.running:
        if term.name.startswith("height") or term.name == "com_vel":
            assert np.abs(term.residual(task.features(stand, u))).max() < 1e-9, term.name
    # The standing keyframe with the left foot raised 0.2 m (the hip and knee bent).
    data = mujoco.MjData(task.model)
    data.qpos[:] = task.qpos_ref
    mujoco.mj_kinematics(task.model, data)
    foot = task.model.site("foot_left").id
    z0 = data.site_xpos[foot, 2]
    qpos = task.qpos_ref.copy()
    for name, angle in (("hip_y_left", -1.0), ("knee_left", -1.6)):
        qpos[task.model.joint(name).qposadr[0]] = angle
    data.qpos[:] = qpos
    mujoco.mj_kinematics(task.model, data)
    assert data.site_xpos[foot, 2] - z0 > 0.15
    lifted = np.concatenate([qpos, np.zeros(task.nv)])

    def height_cost(problem):
        terms = [t for t in problem.cost.running if t.name.startswith("height")]
        feats = problem.features(lifted, u)
        return sum(0.5 * np.sum(t.weight * t.residual(feats) ** 2) for t in terms)

    assert height_cost(plain) < 1e-9 < 1.0 < height_cost(task)
    with pytest.raises(InvalidTypeError, match="height_above_feet"):
        HumanoidGetup(settle=0.0, height_above_feet="yes")


def test_range_noise_is_a_fraction_of_each_control_range() -> None:
    ranges = np.array([[-1.0, 1.0], [0.0, 0.5]])
    np.testing.assert_allclose(range_noise(ranges, 0.1), [0.2, 0.05])
    with pytest.raises(InvalidArgumentError, match="noise_fraction"):
        range_noise(ranges, 0.0)


LINKS = """
<mujoco>
  <asset>
    <mesh name="rod" vertex="-.02 -.02 -.1  .02 -.02 -.1  .02 .02 -.1  -.02 .02 -.1
                              -.02 -.02 .1  .02 -.02 .1  .02 .02 .1  -.02 .02 .1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="a" pos="0 0 .5"><freejoint/><geom name="a" type="mesh" mesh="rod"/></body>
    <body name="b" pos="0 0 .7"><freejoint/><geom name="b" type="mesh" mesh="rod"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("capsules", [False, True])
def test_planning_meshes_touch_the_floor_only_and_can_become_fitted_capsules(capsules) -> None:
    from mpcbox.tasks.humanoid.g1_getup import floor_only_meshes

    model = floor_only_meshes(LINKS, capsules=capsules).compile()
    a, b, floor = (model.geom(n).id for n in ("a", "b", "floor"))
    want = mujoco.mjtGeom.mjGEOM_CAPSULE if capsules else mujoco.mjtGeom.mjGEOM_MESH
    assert model.geom_type[a] == model.geom_type[b] == want
    if capsules:  # fitted to the 4 x 4 x 20 cm rod, along its long axis
        assert 0.015 < model.geom_size[a, 0] < 0.03 and 0.05 < model.geom_size[a, 1] < 0.1

    # Each link meets the floor, not the other link (contype & conaffinity rule).
    def touches(i: int, j: int) -> bool:
        ct, ca = model.geom_contype, model.geom_conaffinity
        return bool((ct[i] & ca[j]) or (ct[j] & ca[i]))

    assert touches(a, floor) and touches(b, floor) and not touches(a, b)


def test_planning_geoms_is_checked_by_name() -> None:
    with pytest.raises(InvalidArgumentError, match="planning_geoms"):
        G1Getup(model=LINKS, planning_geoms="spheres")


@pytest.fixture(scope="module")
def g1():
    return task_class("g1_getup")(settle=0.5)


def _torso(task, state):
    data = mujoco.MjData(task.model)
    data.qpos[:] = state[: task.nq]
    mujoco.mj_forward(task.model, data)
    return data


@pytest.mark.menagerie
def test_g1_getup_builds_by_name_with_noise_in_radians(g1) -> None:
    assert isinstance(g1, G1Getup) and g1.nu == 29
    width = np.diff(g1.model.actuator_ctrlrange, axis=1)[:, 0]
    ctrl = make_controller("ps", g1, num_samples=8)
    np.testing.assert_allclose(ctrl.noise_scale, g1.noise_fraction * width)
    # Position servos: the reference control is the keyframe's joint targets.
    np.testing.assert_allclose(g1.ctrl_ref, g1.model.key_ctrl[g1.keyframe])
    assert 0.5 < g1.stand_height < g1.torso_height


@pytest.mark.menagerie
def test_g1_height_weight_outweighs_the_classic_humanoids_and_can_be_given(g1) -> None:
    # The torso half-way between lying and standing, upright: its height terms cost ten
    # times the classic humanoid's weight of 100 (the G1's default is 1000), and a given
    # weight replaces the default in every height term, running and terminal.
    def height_part(task, state):
        feats = task.features(state, task.ctrl_ref)
        terms = [t for t in task.cost.running if t.name.startswith("height")]
        return sum(0.5 * np.sum(t.weight * t.residual(feats) ** 2) for t in terms)

    crouch = g1.reference_state()
    crouch[2] -= 0.35  # the root 0.35 m lower: the torso below the standing mark
    light = G1Getup(settle=0.0, height_cost=100.0)
    assert height_part(g1, crouch) == pytest.approx(10 * height_part(light, crouch))
    assert height_part(light, crouch) > 0
    weights = {t.name: np.max(t.weight) for t in (*light.cost.running, *light.cost.terminal)}
    assert weights["height_left"] == pytest.approx(50.0)
    assert weights["height_left_terminal"] == pytest.approx(50.0 * light.getup_weights["terminal"])


@pytest.mark.menagerie
def test_g1_lying_start_is_on_the_floor_on_its_back(g1) -> None:
    data = _torso(g1, g1.initial_state())
    torso = data.xmat[g1.torso_id].reshape(3, 3)
    assert data.xpos[g1.torso_id, 2] < 0.2
    assert abs(torso[2, 2]) < 0.3  # the long axis lies horizontal
    assert torso[2, 0] > 0.7  # the chest faces up
    floor = mujoco.mj_name2id(g1.model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    touching = [c for c in data.contact[: data.ncon] if floor in (c.geom1, c.geom2)]
    assert len(touching) >= 3 and min(c.dist for c in touching) > -0.01


@pytest.mark.menagerie
def test_g1_cost_decreases_towards_the_standing_keyframe(g1) -> None:
    lying, standing = g1.initial_state(), g1.reference_state()
    turn = np.zeros(3)  # the root's rotation from lying to standing
    mujoco.mju_subQuat(turn, standing[3:7], lying[3:7])
    costs = []
    for s in np.linspace(0.0, 1.0, 6):
        x = (1 - s) * lying + s * standing
        x[3:7] = lying[3:7]
        mujoco.mju_quatIntegrate(x[3:7], turn, s)
        costs.append(g1.running_cost(x, g1.ctrl_ref))
    assert np.all(np.diff(costs) < 0), costs
    time = np.linspace(0.0, g1.hold, 6)  # the last ``hold`` seconds
    assert g1.goal_failure(time, np.tile(standing, (6, 1))) is None
    assert g1.goal_failure(time, np.tile(lying, (6, 1))) is not None


@pytest.mark.menagerie
def test_g1_plans_at_0_02_s_with_servo_armature_and_stays_finite(g1) -> None:
    ctrl = make_controller("ps", g1, backend="cpu", num_samples=8, seed=0)
    plan = ctrl.problem.planning_model
    assert plan.opt.timestep == pytest.approx(0.02)
    kp = -g1.model.actuator_biasprm[:, 1]
    dofs = g1.model.jnt_dofadr[g1.model.actuator_trnid[:, 0]]
    np.testing.assert_allclose(plan.dof_armature[dofs], 0.5 * kp * 0.02**2)
    # The world and the task's own planning model keep the G1's armature.
    for model in (g1.model, g1.planning_model):
        assert np.all(model.dof_armature[dofs] < plan.dof_armature[dofs])
    # Rollouts of random set-points from the lying start stay finite at the coarse step.
    rng = np.random.default_rng(0)
    knots = g1.ctrl_ref + rng.normal(size=(16, 30, g1.nu)) * ctrl.noise_scale
    out = ctrl.problem.rollout(g1.initial_state(), ctrl.problem.clip_ctrl(knots))
    assert np.all(np.isfinite(out.states))


@pytest.mark.menagerie
def test_g1_standing_stage_holds_it_anywhere_on_the_floor(g1) -> None:
    from mpcbox.sim.simulation import simulate
    from mpcbox.tasks.legged.biped import BipedStand

    assert isinstance(g1.stand_problem(), BipedStand)
    ctrl = g1.handover_controller("ps", stand="lqr", backend="cpu", num_samples=4, seed=0)
    start = g1.reference_state()
    start[:2] += (0.5, -0.3)  # standing elsewhere, turned by 60 degrees
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, np.array([0.0, 0.0, 1.0]), np.radians(60.0))
    mujoco.mju_mulQuat(start[3:7], turn, start[3:7].copy())
    assert g1.is_up(start)
    result = simulate(g1, ctrl, 1.5, initial_state=start)
    assert result.failure is None and ctrl.switches == 1 and ctrl.phase == 1
    data = _torso(g1, result.states[-1])
    assert data.xpos[g1.torso_id, 2] > g1.stand_height
    np.testing.assert_allclose(data.xpos[g1.torso_id, :2], start[:2], atol=0.05)
