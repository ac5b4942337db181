"""LeggedBalance on robots nobody here wrote, robot-independent actuator units, and postures.

dm_control's quadruped (general actuators with filter dynamics, acting through tendons,
and feet that are a site, a body and a sphere geom all named ``toe_*``) runs anywhere
dm_control is installed; Menagerie's Go1 and A1 (position servos) need ``MENAGERIE_ROOT``.
"""

from __future__ import annotations

import os
import pathlib
import warnings

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.actuation import actuator_moment
from mpcbox.core.actuator_scales import actuator_scales, to_control
from mpcbox.core.posture import self_collisions, stance_posture
from mpcbox.errors import InvalidArgumentError, PostureWarning, SolverError, UnknownNameError
from mpcbox.sim.effort_noise import effort_noise
from mpcbox.tasks import scene_path
from mpcbox.tasks.humanoid.noise import balance_noise
from mpcbox.tasks.legged.balance import FEET_CENTER, LeggedBalance

TOES = ("front_left", "front_right", "back_right", "back_left")


def dm_quadruped() -> mujoco.MjSpec:
    """dm_control's quadruped without the ball that drops on it from 3 m."""
    suite = pytest.importorskip("dm_control.suite")
    spec = mujoco.MjSpec.from_file(str(pathlib.Path(suite.__file__).parent / "quadruped.xml"))
    spec.delete(spec.body("ball"))
    return spec


def quadruped(**kwargs) -> LeggedBalance:
    # The toes stand in for the four kinds of name: a site (unprefixed names are looked up
    # as a site first), a body, a geom, and a prefixed site. The hip-knee-ankle coupling is
    # an equality constraint that carries part of the load, so the equilibrium does not warn.
    feet = ("toe_front_left", "body:toe_front_right", "geom:toe_back_right", "site:toe_back_left")
    with warnings.catch_warnings():
        warnings.simplefilter("error", mpcbox.errors.EquilibriumWarning)
        return LeggedBalance(dm_quadruped(), feet=feet, threads=1, **kwargs)


@pytest.fixture(scope="module")
def quad() -> LeggedBalance:
    return quadruped()


def test_feet_by_site_body_or_geom_stand_on_the_sphere_bottoms(quad) -> None:
    assert [f.kind for f in quad.feet] == ["site", "body", "geom", "site"]
    assert quad.root == "torso"
    data = mujoco.MjData(quad.model)
    data.qpos[:] = quad.qpos_ref
    mujoco.mj_kinematics(quad.model, data)
    for foot, frame, side in zip(quad.feet, quad.foot_frames, TOES):
        geom = quad.model.geom(f"toe_{side}")
        bottom = data.geom_xpos[geom.id] - np.array([0.0, 0.0, geom.size[0]])
        position = mpcbox.core.model.frame_position(quad.model, data, frame)
        if foot.kind == "site":  # the site sits at the sphere's center
            np.testing.assert_allclose(position, data.geom_xpos[geom.id], atol=1e-12)
        else:  # a sole site added at the bottom of the sphere
            assert frame == f"toe_{side}_sole"
            np.testing.assert_allclose(position, bottom, atol=1e-9)
            assert abs(position[2]) < 5e-3  # on the floor, up to the contact's softness
    # Sites and geoms are their own contacts; a body standing on one sphere, its sole site.
    assert quad.contacts == (
        "site:toe_front_left",
        "site:toe_front_right_sole",
        "geom:toe_back_right",
        "site:toe_back_left",
    )
    center = data.site_xpos[quad.model.site(FEET_CENTER).id]
    assert quad.support_frames() == (FEET_CENTER,) and center[2] == 0.0


def test_fall_height_comes_from_the_reference_root_height(quad) -> None:
    data = mujoco.MjData(quad.model)
    data.qpos[:] = quad.qpos_ref
    mujoco.mj_kinematics(quad.model, data)
    assert quad.fall_height == pytest.approx(0.6 * data.xpos[quad.root_id, 2])
    assert quadruped(fall_height=0.2).fall_height == 0.2


def test_generic_units_on_tendon_actuators_with_filter_dynamics(quad) -> None:
    # No force range: the half range is half the control range; the noise recipe is a
    # fraction of it, and the control weights are per squared fraction of it.
    half = 0.5 * np.diff(quad.model.actuator_ctrlrange, axis=1)[:, 0]
    np.testing.assert_allclose(quad.noise().std, 0.05 * half)
    np.testing.assert_allclose(quad.cost.running[-1].weight, 1.0 / half**2)
    scales = actuator_scales(quad.model, quad.qpos_ref)
    # Torque per unit control: the gain (1000) times the largest moment arm (joint gear or
    # tendon coefficient), read from MuJoCo's actuator moment matrix.
    data = mujoco.MjData(quad.model)
    data.qpos[:] = quad.qpos_ref
    mujoco.mj_forward(quad.model, data)
    arm = np.max(np.abs(actuator_moment(quad.model, data)), axis=1)
    np.testing.assert_allclose(scales.torque_per_ctrl, 1000.0 * arm, rtol=1e-9)


def test_lqr_keeps_the_dm_control_quadruped_up_under_the_generic_noise(quad) -> None:
    res = mpcbox.simulate(quad, mpcbox.LQR(quad), 2.0, noise=quad.noise(), seed=0)
    assert res.survived, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 2.0
    assert "tilt_settle_time_s" in res.metrics.measures
    # A hard sideways shove throws it over, and the tilt criterion says so.
    shove = mpcbox.Push(force=(0.0, 6000.0, 0.0), start=0.2, duration=0.1, body="torso")
    res = mpcbox.simulate(quad, mpcbox.LQR(quad), 2.0, pushes=[shove])
    assert not res.survived and "fell" in res.failure


def test_qp_replans_faster_with_feedback_only_where_no_actuator_holds_a_position(quad) -> None:
    from mpcbox.tasks.humanoid.two_feet import HumanoidTwoFeet
    from mpcbox.tasks.legged.balance import QP_OSQP_SETTINGS, TORQUE_QP_PERIOD

    # dm_control's quadruped has position-feedback actuators: the QP keeps 50 Hz.
    assert quad.controller_configs["qp"].period == pytest.approx(0.02)
    assert dict(quad.controller_configs["qp"].osqp_settings) == dict(QP_OSQP_SETTINGS)
    # The same robot with its actuators' bias removed is driven by force alone.
    spec = dm_quadruped()
    for actuator in spec.actuators:
        actuator.biastype = mujoco.mjtBias.mjBIAS_NONE
        actuator.biasprm = np.zeros(10)
    feet = tuple(f"site:toe_{toe}" for toe in TOES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mpcbox.errors.EquilibriumWarning)
        motors = LeggedBalance(spec, feet=feet, threads=1)
    assert motors.controller_configs["qp"].period == pytest.approx(TORQUE_QP_PERIOD)
    # ... and gets the LQR gain about the plan between two solves; servos need none.
    assert motors.controller_configs["qp"].between_ticks == "lqr"
    assert quad.controller_configs["qp"].between_ticks == "hold"
    assert type(motors).controller_configs["qp"].period == pytest.approx(0.02)  # class intact
    # The humanoid presets keep their measured 50 Hz on their torque motors.
    assert HumanoidTwoFeet(threads=1).controller_configs["qp"].period == pytest.approx(0.02)


def test_unknown_names_list_what_exists() -> None:
    spec = dm_quadruped()
    with pytest.raises(UnknownNameError, match="toe_front_left") as err:
        LeggedBalance(spec, feet=["toe_front_lfet"])
    assert "geom:toe_back_left" in str(err.value) and "body:torso" in str(err.value)
    with pytest.raises(UnknownNameError, match=r"geom.*'toe_front_left'"):
        LeggedBalance(spec, feet=["geom:toe_nope"])
    with pytest.raises(UnknownNameError, match="'torso'"):
        LeggedBalance(spec, feet=["toe_front_left"], root="trunk")
    with pytest.raises(UnknownNameError, match="keyframe 'stand'"):
        LeggedBalance(spec, feet=["toe_front_left"], keyframe="stand")
    with pytest.raises(InvalidArgumentError, match="support"):
        LeggedBalance(spec, feet=["toe_front_left"], support="middle")


def test_contacts_are_checked_when_the_task_is_built() -> None:
    """A misspelt QP-MPC contact was accepted and only failed when QP-MPC was built; a single
    name was split into its characters."""
    feet = ["toe_front_left", "toe_front_right", "toe_back_right", "toe_back_left"]
    with pytest.raises(UnknownNameError, match=r"^contacts: unknown contact geom 'toe_nope'"):
        LeggedBalance(dm_quadruped(), feet=feet, contacts=["geom:toe_back_left", "geom:toe_nope"])
    one = LeggedBalance(dm_quadruped(), feet=feet, contacts="geom:toe_back_left", threads=1)
    assert one.contacts == ("geom:toe_back_left",)


def test_a_fixed_base_needs_a_named_root() -> None:
    xml = """<mujoco><worldbody><geom type="plane" size="1 1 .1"/>
      <body name="leg" pos="0 0 .5"><joint name="j" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -.4" size=".03"/></body></worldbody>
      <actuator><motor joint="j"/></actuator></mujoco>"""
    with pytest.raises(InvalidArgumentError, match=r"no free joint.*leg"):
        LeggedBalance(xml, feet=["leg"])


# ---------------------------------------------------------------- robot-independent units
SERVO = """<mujoco><worldbody><body name="{body}"><freejoint/><geom size=".1"/>
  <body><joint name="{a}" axis="0 1 0"/><geom size=".05" pos="0 0 -.2"/></body>
  <body><joint name="{b}" axis="1 0 0"/><geom size=".05" pos="0 0 -.2"/></body>
  <body><joint name="c" axis="1 0 0"/><geom size=".05" pos="0 0 -.2"/></body></body>
  </worldbody><actuator>
  <position joint="{a}" name="{a}" kp="50" forcerange="-10 10" ctrlrange="-2 2"/>
  <position joint="{b}" name="{b}" kp="400" ctrlrange="-0.01 0.01"/>
  <motor joint="c" name="c" gear="30"/></actuator></mujoco>"""


def test_units_through_gain_and_range_not_names() -> None:
    model = mujoco.MjModel.from_xml_string(SERVO.format(body="torso", a="a", b="b"))
    qpos = model.qpos0
    scales = actuator_scales(model, qpos)
    np.testing.assert_allclose(scales.torque_per_ctrl, [50.0, 400.0, 30.0])
    # Servo a: its force range (10 N m through kp 50) is narrower than its control range.
    np.testing.assert_allclose(scales.half_range[:2], [0.2, 0.01])
    assert scales.half_range[2] == np.inf  # an unlimited motor
    np.testing.assert_allclose(effort_noise(model, qpos, torque=2.0).std, [0.04, 0.005, 2 / 30])
    with pytest.raises(InvalidArgumentError, match=r"range is undefined.*\['c'\]"):
        effort_noise(model, qpos, fraction=0.1)
    servos = scales._replace(
        torque_per_ctrl=scales.torque_per_ctrl[:2],
        half_range=scales.half_range[:2],
        names=scales.names[:2],
    )
    np.testing.assert_allclose(to_control(servos, 0.1, "range"), [0.02, 0.001])
    np.testing.assert_allclose(to_control(servos, 1.0, "range", power=-2), [25.0, 1e4])
    np.testing.assert_allclose(to_control(scales, 2.0, "torque", power=-2), [5000, 320000, 1800])
    # The same robot with the humanoid recipe's favourite substrings in its names.
    renamed = SERVO.format(body="abdomen", a="left_hip_y", b="right_knee")
    std = effort_noise(mujoco.MjModel.from_xml_string(renamed), qpos, torque=2.0).std
    np.testing.assert_array_equal(std, effort_noise(model, qpos, torque=2.0).std)


def test_published_humanoid_recipe_is_a_fraction_of_range_special_case() -> None:
    # Every motor of the humanoid scene has ctrlrange [-1, 1]: the recipe's 0.01 and 0.08
    # are 1 % and 8 % of each actuator's half range, chosen by joint name.
    model = mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))
    recipe = balance_noise(model, stance="left")
    fractions = np.where(np.asarray(recipe.std) == 0.01, 0.01, 0.08)
    qpos = model.key_qpos[0]
    np.testing.assert_array_equal(effort_noise(model, qpos, fraction=fractions).std, recipe.std)


# ---------------------------------------------------------------- postures
def _hand_in_head(locked: bool) -> tuple[mujoco.MjModel, np.ndarray]:
    """The humanoid with its right hand in its head; ``locked``: the arm's joints limited to
    within 1 mrad of that posture, so no IK can take the hand out."""
    model = mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))
    start = model.key_qpos[model.key("stand").id].copy()
    pose = (("shoulder1_right", -0.254), ("shoulder2_right", 0.768), ("elbow_right", 0.712))
    for joint, value in pose:
        j = model.joint(joint).id
        start[model.jnt_qposadr[j]] = value
        if locked:
            model.jnt_limited[j] = 1
            model.jnt_range[j] = [value - 1e-3, value + 1e-3]
    return model, start


def test_stance_posture_takes_a_hand_out_of_the_head_when_it_can() -> None:
    """A posture in self-collision is solved again keeping the robot's geoms apart."""
    model, start = _hand_in_head(locked=False)
    assert self_collisions(model, start)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        posture = stance_posture(model, start, stance="foot_right", swing="foot_left")
    assert posture.collisions == () and self_collisions(model, posture.qpos) == ()
    assert posture.com_error < 1e-3


def test_stance_posture_reports_self_collision() -> None:
    model, start = _hand_in_head(locked=True)
    kw = dict(stance="foot_right", swing="foot_left")
    with pytest.warns(PostureWarning, match="self-collision.*head"):
        posture = stance_posture(model, start, **kw)
    assert any("head" in pair for pair in posture.collisions)
    with pytest.raises(SolverError, match="head"):
        stance_posture(model, start, on_collision="raise", **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert stance_posture(model, start, on_collision="ignore", **kw).collisions
        plain = mujoco.MjModel.from_xml_path(str(scene_path("humanoid.xml")))
        free = stance_posture(plain, plain.key_qpos[plain.key("stand").id], **kw)
    assert free.collisions == ()


# ---------------------------------------------------------------- Menagerie quadrupeds
def _menagerie(robot: str) -> None:
    from mpcbox.core import menagerie

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available(robot)):
        pytest.skip(f"no offline Menagerie copy with {robot} (set MENAGERIE_ROOT)")


@pytest.mark.menagerie
@pytest.mark.parametrize(
    ("robot", "contact", "limits"),
    [
        ("unitree_go1", "geom:FR", [23.7, 23.7, 35.55]),
        ("unitree_a1", "site:FR_calf_sole", [33.5, 33.5, 33.5]),
    ],
)
def test_lqr_stands_a_menagerie_quadruped_under_the_generic_noise(robot, contact, limits):
    from mpcbox.tasks.legged.quadruped import QuadrupedStand

    _menagerie(robot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # visual meshes missing offline
        problem = QuadrupedStand(f"menagerie:{robot}", threads=1)
    assert problem.contacts[0] == contact and problem.root == "trunk"
    # Position servos (kp 100): the recipe's 5 % of the force range, as set-points.
    np.testing.assert_allclose(problem.noise().std[:3], 0.05 * np.array(limits) / 100.0)
    res = mpcbox.simulate(problem, mpcbox.LQR(problem), 3.0, noise=problem.noise(), seed=1)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 1.0


@pytest.mark.menagerie
def test_qp_mpc_stands_the_go1_on_four_friction_cones():
    from mpcbox.tasks.legged.quadruped import QuadrupedStand

    _menagerie("unitree_go1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        problem = QuadrupedStand(threads=1)
    qp = mpcbox.make_controller("qp", problem)
    assert qp.points.count == 4
    res = mpcbox.simulate(problem, qp, 1.0, noise=problem.noise(), seed=0)
    assert res.survived, res.failure
    assert res.metrics.fallbacks <= 0.01 * res.metrics.solve_ticks


@pytest.fixture(scope="module")
def g1_two_feet():
    from mpcbox.tasks.legged.biped import BipedStand

    _menagerie("unitree_g1")
    problem = BipedStand(threads=1)
    yield problem
    problem.close()


@pytest.mark.menagerie
def test_g1_equilibrium_holds_through_its_position_servos(g1_two_feet):
    problem = g1_two_feet
    eq, model = problem.equilibrium, problem.model
    assert problem.contacts == ("body:left_ankle_roll_link", "body:right_ankle_roll_link")
    assert eq.shortfall < 1e-6  # every actuated joint's torque is supplied
    lo, hi = model.actuator_ctrlrange.T
    assert np.all((eq.ctrl >= lo) & (eq.ctrl <= hi))
    # Servo set-points q + tau/kp: close to the posture, not torques read as angles.
    assert np.max(np.abs(eq.ctrl - eq.qpos[7:])) < 0.05
    data = mujoco.MjData(model)
    data.qpos[:], data.ctrl[:] = eq.qpos, eq.ctrl
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator[6:], eq.qfrc[6:], atol=1e-6)
    # The feet carry the weight: no vertical force left on the root.
    assert abs(eq.vertical_residual) < 1e-3


@pytest.mark.menagerie
def test_lqr_stands_the_g1_on_two_feet_under_the_generic_noise(g1_two_feet):
    problem = g1_two_feet
    res = mpcbox.simulate(problem, mpcbox.LQR(problem), 3.0, noise=problem.noise(), seed=3)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 3.0


@pytest.mark.menagerie
def test_qp_mpc_stands_the_g1_on_eight_friction_cones(g1_two_feet):
    problem = g1_two_feet
    # Without the preset's wall-clock budget (15 ms), which a slow machine reaches: a cut-off
    # iterate whose first stage does not hold is a fallback, so the count would depend on
    # the machine's speed.
    qp = mpcbox.make_controller("qp", problem, time_limit=None)
    assert qp.points.count == 8  # four spheres under each foot
    res = mpcbox.simulate(problem, qp, 1.0, noise=problem.noise(), seed=2)
    assert res.metrics.success, res.failure
    assert res.metrics.fallbacks <= 0.01 * res.metrics.solve_ticks


@pytest.mark.menagerie
def test_g1_ilqr_mpc_feedback_is_the_lqr_gain_despite_joint_friction(g1_two_feet):
    # The G1's joints have dry friction: Jacobians along a trajectory belong to other
    # stick-slip modes than the reference's, and the preset linearizes at the reference, so
    # the replan's gains are the LQR gain (the terminal value's) on every motion a control
    # can change. Sliding or turning the whole robot is not one (Pi_u, rank 3): the LQR
    # ignores it, while the replan's running cost (the center of mass over a world-fixed
    # point) still answers it.
    from mpcbox.controllers.uncontrollable import uncontrollable_marginal_projector

    problem = g1_two_feet
    assert np.all(problem.model.dof_frictionloss[6:] > 0)
    ilqr = mpcbox.make_controller("ilqr", problem)
    # The G1's preset differences the model without the friction (stop 49): the gain is
    # the LQR gain of the copy it plans on.
    assert ilqr.problem.dry_friction == "drop" and problem.dry_friction == "keep"
    lqr = mpcbox.LQR(problem.with_dry_friction("drop"))
    x0 = problem.reference_state()
    x0[7:36] += 0.01 * np.random.default_rng(0).standard_normal(29)
    ilqr(x0, 0.0)
    K = ilqr.last_result.K
    # Reference dynamics and cost Hessians: the backward passes repeat, and later replans
    # reuse the first one's matrices (the Riccati cache).
    ilqr(x0, ilqr.config.replan_period)
    assert ilqr.riccati_cache is not None and ilqr.riccati_cache.hits >= 1
    sliding = uncontrollable_marginal_projector(lqr.A, lqr.B)
    assert np.linalg.matrix_rank(sliding, 1e-6) == 3
    np.testing.assert_allclose(lqr.K @ sliding, 0.0, atol=1e-9 * np.abs(lqr.K).max())
    keep = np.eye(problem.nx) - sliding
    rel = np.linalg.norm((K + lqr.K) @ keep, axis=(1, 2)) / np.linalg.norm(lqr.K)
    assert rel.max() < 0.01, rel.max()


@pytest.mark.menagerie
def test_g1_one_foot_stance_is_collision_free_and_lqr_stands_on_it():
    from mpcbox.tasks.legged.biped import BipedStand

    _menagerie("unitree_g1")
    problem = BipedStand(stance="right", threads=1)
    assert problem.contacts == ("body:right_ankle_roll_link",)
    assert problem.posture.collisions == ()
    assert problem.posture.swing_height > 0.09
    assert problem.equilibrium.shortfall < 1e-6
    # The center of mass is over the stance sole, so the root needs almost no wrench.
    assert np.max(np.abs(problem.equilibrium.residual_wrench)) < 1.0
    res = mpcbox.simulate(problem, mpcbox.LQR(problem), 2.0, noise=problem.noise(), seed=1)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["com_deviation_rms_m"] < 0.02
    problem.close()


def test_biped_stand_asks_for_the_feet_it_cannot_find():
    """Standing on one leg in the keyframe, the humanoid shows one foot on the ground: the
    error lists what it found and asks for the feet."""
    from mpcbox.tasks.legged.biped import BipedStand

    with pytest.raises(InvalidArgumentError, match=r"2 feet.*1 leg\(s\).*name the feet"):
        BipedStand(str(scene_path("humanoid.xml")), keyframe="stand_on_left_leg")


def test_balance_suite_pushes_the_root_with_a_fraction_of_the_weight(quad) -> None:
    from mpcbox.comparison.balance_suite import balance_suite

    weight = float(quad.model.body_subtreemass[quad.root_id]) * 9.81
    suite = balance_suite(quad, duration=3.0, weight_fraction=0.3, max_force_weights=5)
    assert suite.force == round(0.3 * weight)
    noise, pushed = suite.scenarios
    assert (noise.name, noise.duration, noise.pushes) == ("noise", 3.0, ())
    (push,) = pushed.pushes
    assert push.body == quad.root and tuple(push.force) == (suite.force, 0.0, 0.0)
    (test,) = suite.push_tests
    assert test.body == quad.root and test.max_force == pytest.approx(5 * weight)
    assert test.scan_step is None
    scanned = balance_suite(
        quad, duration=3.0, weight_fraction=0.3, max_force_weights=5, scan_step=25.0
    )
    assert scanned.push_tests[0].scan_step == 25.0
    given = balance_suite(quad, duration=2.0, weight_fraction=0.3, max_force_weights=5, force=42)
    assert (
        given.force == 42.0
        and not balance_suite(
            quad, duration=2.0, weight_fraction=0.3, max_force_weights=5, largest_push=False
        ).push_tests
    )
    # A push that would start at the end of the run never acts: refused, not "survived".
    with pytest.raises(InvalidArgumentError, match=r"duration \(1 s\) must be longer"):
        balance_suite(quad, duration=1.0, weight_fraction=0.3, max_force_weights=5)


def test_balance_suite_needs_a_root_body_and_names_bad_options(quad) -> None:
    from mpcbox.comparison.balance_suite import balance_suite
    from mpcbox.tasks.swingup.presets import PendulumSwingup

    with pytest.raises(InvalidArgumentError, match="root body"):
        balance_suite(PendulumSwingup(), duration=1.0, weight_fraction=0.3, max_force_weights=5)
    with pytest.raises(InvalidArgumentError, match="duration"):
        balance_suite(quad, duration=0.0, weight_fraction=0.3, max_force_weights=5)
    with pytest.raises(InvalidArgumentError, match="scan_step"):
        balance_suite(quad, duration=2.0, weight_fraction=0.3, max_force_weights=5, scan_step=-1)


def test_model_source_prefixes_bare_menagerie_names_only() -> None:
    from mpcbox.core.menagerie import model_source

    assert model_source("unitree_g1") == "menagerie:unitree_g1"
    assert model_source("menagerie:unitree_go2") == "menagerie:unitree_go2"
    assert model_source("robots/g1.xml") == "robots/g1.xml"
    assert model_source("scene.xml") == "scene.xml"
    assert model_source("SCENE.XML") == "SCENE.XML"


def test_model_source_reads_an_existing_file_as_a_path(tmp_path, monkeypatch) -> None:
    from mpcbox.core.menagerie import model_source

    monkeypatch.chdir(tmp_path)
    (tmp_path / "robot.mjcf").write_text("<mujoco/>")
    assert model_source("robot.mjcf") == "robot.mjcf"  # a file, whatever its extension
    assert model_source("robot") == "menagerie:robot"


def test_the_cost_is_stationary_at_the_equilibrium_unless_asked_otherwise() -> None:
    """With ``balance_target="reference"`` (the default) the balance term wants the center
    of mass where the equilibrium holds it: the whole cost is zero with a zero gradient at
    the reference, the state LQR and QP-MPC regulate to. With ``"support"`` the term pulls
    it over the support point, a gradient iLQR would follow off the equilibrium. (The
    quadruped is symmetric, so its center of mass is over the feet's center: the terms
    over each foot show the difference.)"""
    stationary = quadruped(support="feet")
    pulled = quadruped(support="feet", balance_target="support")
    x = stationary.reference_state()
    offsets = stationary.balance_offsets
    assert offsets.shape == (len(stationary.support_points), 2)
    assert np.min(np.linalg.norm(offsets, axis=1)) > 0.1  # the feet are far apart
    quad = stationary.quadratize(x, stationary.ctrl_ref)
    assert np.max(np.abs(quad.lx)) < 1e-9 and np.max(np.abs(quad.lu)) < 1e-9
    assert stationary.running_cost(x, stationary.ctrl_ref) < 1e-12
    far = pulled.quadratize(x, pulled.ctrl_ref)
    assert np.max(np.abs(far.lx)) > 1.0
    # The same Hessian: LQR's gain does not depend on the target.
    np.testing.assert_allclose(far.lxx, quad.lxx, rtol=1e-9, atol=1e-9)
    with pytest.raises(InvalidArgumentError, match=r"balance_target.*reference.*support"):
        quadruped(balance_target="feet")


@pytest.mark.menagerie
def test_ilqr_mpc_stands_the_adam_lite_whose_com_is_off_the_middle_of_its_soles() -> None:
    """PNDbotics' Adam Lite stands with its center of mass 6 cm behind the middle of its
    soles (each a pair of cylinders lying lengthwise; 17 cm while their soles were taken at
    the cylinders' front ends alone). The balance term used to pull it forward (a gradient
    LQR drops and iLQR follows) and each replan's open-loop warm start drifted off within
    the horizon: iLQR-MPC fell within 3 s, without noise too, where LQR stood."""
    from mpcbox.core import menagerie
    from mpcbox.tasks.legged.biped import BipedStand

    if not menagerie.available("pndbotics_adam_lite"):
        pytest.skip("no offline Menagerie copy with pndbotics_adam_lite")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        problem = BipedStand(
            "menagerie:pndbotics_adam_lite", feet=("body:toeLeft", "body:toeRight"), threads=1
        )
    assert np.linalg.norm(problem.balance_offsets) > 0.05
    ctrl = mpcbox.make_controller("ilqr", problem)
    res = mpcbox.simulate(problem, ctrl, 3.0, noise=problem.noise(), seed=0)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 5.0
    assert ctrl.stats["fallbacks"] == 0
    problem.close()


@pytest.mark.parametrize("fall_height", [-5.0, 50.0])
def test_a_fall_height_outside_floor_to_root_is_refused(fall_height) -> None:
    """Below the floor no run can fall, above the standing root every run falls at once: a
    fuzz run found -5 m accepted, and a humanoid lying on the floor reported as standing."""
    from mpcbox.tasks.humanoid.balance import HumanoidBalance

    with pytest.raises(InvalidArgumentError, match=r"fall_height must lie between the floor"):
        HumanoidBalance(fall_height=fall_height)
    assert HumanoidBalance(fall_height=0.5).fall_height == 0.5
