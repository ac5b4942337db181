"""The grasp held by contact forces: the force QP, the scene's contacts, the controllers."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mpcbox.controllers.grasp import ForceGrasp, ForceGraspConfig, GraspQP, PositionGrasp
from mpcbox.core.contact import cone_violation
from mpcbox.errors import (
    InvalidArgumentError,
    ShapeError,
    UnknownNameError,
    UnknownOptionError,
)
from mpcbox.tasks.grasp import (
    FRICTION_LEVELS,
    GraspObject,
    GripperConfig,
    TrialConfig,
    build_scene,
    contact_solref,
    run_trial,
    run_trials,
    sample_object,
)
from mpcbox.tasks.grasp.objects import KINDS, STIFFNESS_RANGES
from mpcbox.tasks.grasp.scene import FINGERS, OBJECT, PADS

G = 9.81
#: Two fingers on either side of the origin along x, pushing inwards.
POINTS = np.array([[-0.03, 0.0, 0.0], [0.03, 0.0, 0.0]])
NORMALS = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])


@pytest.mark.parametrize(("mass", "mu", "margin"), [(0.3, 0.4, 0.0), (0.8, 1.2, 1.5)])
def test_two_fingers_need_the_closed_form_squeeze(mass, mu, margin):
    """Holding m g between two opposing fingers takes f_n = (m g / 2 + margin) / mu each."""
    qp = GraspQP(2)
    load = np.array([0.0, 0.0, mass * G])
    sol = qp.solve(
        POINTS, NORMALS, np.zeros(3), load, np.zeros(3), friction=mu, torsion=0.1, margin=margin
    )
    assert sol.solved
    expected = (mass * G / 2 + margin) / mu
    np.testing.assert_allclose(sol.normal, expected, rtol=1e-3)
    np.testing.assert_allclose(sol.forces.sum(axis=0), load, atol=1e-5)  # force balance
    assert cone_violation(sol.local, mu, 4, np.inf) < 1e-5
    assert np.max(np.abs(sol.moment_residual)) < 1e-5


def test_forces_stay_in_the_cones_for_any_grasp():
    """Three fingers at random inward normals, random loads: balance holds, cones hold."""
    rng = np.random.default_rng(3)
    qp = GraspQP(3, facets=8)
    for _ in range(10):
        angles = np.sort(rng.uniform(0, 2 * np.pi, 3)) + np.array([0.0, 2.1, 4.2])
        outward = np.column_stack([np.cos(angles), np.sin(angles), rng.uniform(-0.3, 0.3, 3)])
        outward /= np.linalg.norm(outward, axis=1, keepdims=True)
        points = 0.03 * outward
        load = rng.normal(size=3) * 3.0
        mu, torsion, margin = rng.uniform(0.4, 1.5), rng.uniform(0.0, 0.05), rng.uniform(0, 1)
        sol = qp.solve(
            points,
            -outward,
            np.zeros(3),
            load,
            np.zeros(3),
            friction=mu,
            torsion=torsion,
            margin=margin,
            f_min=0.5,
            f_max=200.0,
        )
        if not sol.solved:
            continue
        np.testing.assert_allclose(sol.forces.sum(axis=0), load, atol=1e-4)
        assert cone_violation(sol.local, mu, 8, 200.0) < 1e-4
        assert np.all(np.abs(sol.moments) <= torsion * sol.normal + 1e-5)
        assert np.all(sol.normal >= 0.5 - 1e-5)


def test_a_squeeze_cap_too_low_is_reported():
    """With f_max below m g / (2 mu) no forces balance the weight: the status says so."""
    qp = GraspQP(2)
    sol = qp.solve(
        POINTS,
        NORMALS,
        np.zeros(3),
        np.array([0, 0, 1.0 * G]),
        np.zeros(3),
        friction=0.5,
        torsion=0.0,
        f_max=5.0,
    )
    assert not sol.solved
    np.testing.assert_array_equal(sol.forces, 0.0)


@pytest.mark.parametrize("stiffness", [2e3, 1e5])
def test_contact_stiffness_gives_the_weight_penetration(stiffness):
    """A sphere resting on a plane with solref from contact_solref sinks m g / K."""
    mass, d = 0.4, 0.9
    solref = contact_solref(stiffness, mass, 0.5, d, 0.0005)
    xml = f"""<mujoco><option timestep="0.0005"/><worldbody>
      <geom type="plane" size="1 1 .1" solmix="0"/>
      <body pos="0 0 0.03"><freejoint/><geom type="sphere" size="0.03" mass="{mass}"
        solref="{solref[0]} {solref[1]}" solimp="{d} {d} 0.001 0.5 2"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(2000):
        mujoco.mj_step(model, data)
    sink = 0.03 - data.qpos[2]
    assert sink == pytest.approx(mass * G / stiffness, rel=0.05)


def _box(mu: float, mass: float) -> GraspObject:
    return GraspObject(
        "hard", "box", np.array([0.02, 0.025, 0.035]), mass, np.array([mu, 0.2, 0.1]), 2e5, 0.5
    )


SHORT = TrialConfig(
    close_time=0.2,
    lift_time=0.2,
    hold_time=0.35,
    shake_time=0.15,
    push=0.3,
    push_start=0.02,
    push_time=0.1,
)


def test_force_grasp_holds_where_a_weak_position_grasp_slips():
    """Low friction (mu 0.35), 0.6 kg, finger servos of 150 N/m: fully closed, they squeeze
    150 * 0.025 = 3.75 N, less than m g / (2 mu) = 8.4 N, so the position grasp lets the box
    slide out; the force grasp squeezes past that bound and holds it within 1 cm."""
    mu, mass = 0.35, 0.6
    scene = build_scene(_box(mu, mass), GripperConfig(finger_kp=150.0))
    force = ForceGrasp(
        scene.model, mass=mass, fingers=FINGERS, pads=PADS, target=OBJECT, friction=0.45
    )
    held = run_trial(scene, force, push_direction=np.array([0.3, 0.2, -1.0]), config=SHORT)
    position = PositionGrasp(scene.model, fingers=FINGERS, closed=scene.config.opening)
    dropped = run_trial(scene, position, push_direction=np.array([0.3, 0.2, -1.0]), config=SHORT)
    bound = mass * G / (2 * mu)
    assert held.success and held.slip < SHORT.slip_tolerance
    assert held.lifted > 0.8 * SHORT.lift_height
    assert held.max_finger_force > bound
    assert not dropped.success and dropped.slip > 2 * SHORT.slip_tolerance
    assert dropped.mean_finger_force < bound
    last = force.last_forces
    assert last is not None and last.solved
    mu_eff = force.friction / force.safety
    assert cone_violation(last.local, mu_eff, 4, force.config.f_max) < 1e-4


def test_slip_raises_the_squeeze():
    """A friction prior twice the true value: the grasp slips, detects it and squeezes
    harder (safety factor up or friction estimate down), ending with more squeeze than its
    prior asked for."""
    mu, mass = 0.35, 0.5
    scene = build_scene(_box(mu, mass))
    force = ForceGrasp(
        scene.model,
        mass=mass,
        fingers=FINGERS,
        pads=PADS,
        target=OBJECT,
        friction=0.7,
        disturbance=0.0,
    )
    result = run_trial(scene, force, push_direction=np.array([0.0, 0.0, -1.0]), config=SHORT)
    assert result.adapted or force.friction < 0.7
    assert force.friction / force.safety < 0.7 / force.config.safety
    assert result.max_finger_force > mass * G / (2 * 0.7 / force.config.safety)


def test_sampled_objects_span_the_ranges():
    rng = np.random.default_rng(0)
    for level, (low, high) in FRICTION_LEVELS.items():
        for kind in KINDS:
            for _ in range(20):
                obj = sample_object(rng, level, kind)
                assert low <= obj.friction[0] <= high
                assert 0.1 <= obj.friction[1] <= 0.3 and 0.05 <= obj.friction[2] <= 0.15
                k_low, k_high = STIFFNESS_RANGES[kind]
                assert k_low <= obj.stiffness <= k_high
    assert min(r[0] for r in STIFFNESS_RANGES.values()) == 1e3
    assert max(r[1] for r in STIFFNESS_RANGES.values()) == 1e6


def test_bad_input_is_named():
    scene = build_scene(_box(1.0, 0.3))
    common = dict(fingers=FINGERS, pads=PADS, target=OBJECT)
    with pytest.raises(InvalidArgumentError, match="mass"):
        ForceGrasp(scene.model, mass=-1.0, **common)
    with pytest.raises(UnknownNameError, match="thumb"):
        ForceGrasp(scene.model, mass=0.3, fingers=("left", "thumb"), pads=PADS, target=OBJECT)
    with pytest.raises(InvalidArgumentError, match="pads"):
        ForceGrasp(scene.model, mass=0.3, fingers=FINGERS, pads=PADS[:1], target=OBJECT)
    with pytest.raises(UnknownOptionError, match="squeeze"):
        ForceGrasp(scene.model, mass=0.3, squeeze=2.0, **common)
    with pytest.raises(InvalidArgumentError, match="safety"):
        ForceGraspConfig(safety=0.5)
    with pytest.raises(InvalidArgumentError, match="level"):
        sample_object(np.random.default_rng(0), "extreme")
    with pytest.raises(InvalidArgumentError, match="trials"):
        run_trials("low", 0)
    with pytest.raises(ShapeError, match="positions"):
        GraspQP(2).solve(
            POINTS[:1], NORMALS, np.zeros(3), np.zeros(3), np.zeros(3), friction=1.0, torsion=0.0
        )
    with pytest.raises(InvalidArgumentError, match="friction"):
        GraspQP(2).solve(
            POINTS, NORMALS, np.zeros(3), np.zeros(3), np.zeros(3), friction=0.0, torsion=0.0
        )


def test_measured_squeeze_tracks_the_commanded_force():
    """Through the actuator model (set-points of 500 N/m servos), the fingers press on a
    resting box with the normal force the QP asked for, within 5 %, and the two fingers'
    forces balance each other."""
    mass, mu = 0.8, 0.5
    scene = build_scene(_box(mu, mass))
    force = ForceGrasp(
        scene.model, mass=mass, fingers=FINGERS, pads=PADS, target=OBJECT, friction=mu
    )
    model = scene.model
    data = mujoco.MjData(model)
    fingers = [model.actuator(f).id for f in FINGERS]
    command = None
    for step in range(800):  # 0.4 s: close, then hold the box on the table
        if step % 4 == 0:
            command = force(data)
            data.ctrl[fingers] = command.ctrl
        mujoco.mj_step(model, data)
    assert command is not None and command.phase == "hold"
    measured = force.last_contacts.normal_force
    expected = (mass * G / 2 + force.config.disturbance * mass * G / 2) / (mu / force.safety)
    np.testing.assert_allclose(command.normal_force, expected, rtol=1e-3)
    np.testing.assert_allclose(measured, command.normal_force, rtol=0.05)
    assert abs(measured[0] - measured[1]) < 0.02 * measured.mean()
