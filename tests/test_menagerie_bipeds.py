"""Legged robots nobody here tuned for (MuJoCo Menagerie), standing by name under LQR.

Each robot failed before stop 31 in its own way: Unitree's H1 fell (its keyframe leaves
51 N m of pitch on the root, now balanced by tilting the root; QP-MPC stands it, LQR does
not under this noise); PAL's Talos raised NotStabilizableError (the PBH test took its
clustered, controllable modes near 1 for uncontrollable ones); Agility's Cassie fell in
1.2 s; PNDbotics' Adam Lite stands on mesh soles that had no contact points, Apptronik's
Apollo on soles that touch the floor only through ``<pair>``s; and Adam Lite's B came out
exactly zero (the constraint solver stopped at its default tolerance inside the finite
differences); Fourier's N1 fell in 0.13 s, its flat mesh soles' contact set jumping within
the finite differences (it now plans on boxes, :mod:`mpcbox.core.sole_boxes`). Each test
needs an offline copy with the robot (``MENAGERIE_ROOT``) and skips without one.
"""

from __future__ import annotations

import os
import warnings

import mujoco
import numpy as np
import pytest

import mpcbox

pytestmark = pytest.mark.menagerie

ROBOTS = {
    "unitree_h1": (("body:left_ankle_link", "body:right_ankle_link"), "qp"),
    "pal_talos/scene_motor": (("body:leg_left_6_link", "body:leg_right_6_link"), "lqr"),
    "agility_cassie": (("body:left-foot", "body:right-foot"), "lqr"),
    "apptronik_apollo": (("body:l_foot_link", "body:r_foot_link"), "lqr"),
    "pndbotics_adam_lite": (("body:toeLeft", "body:toeRight"), "lqr"),
    "fourier_n1": (("body:left_foot_pitch_link", "body:right_foot_pitch_link"), "lqr"),
}


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_biped_stands_on_its_balanced_keyframe(robot):
    from mpcbox.core import menagerie
    from mpcbox.tasks.legged.biped import BipedStand

    name, _, entry = robot.partition("/")
    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available(name, entry or None)):
        pytest.skip(f"no offline Menagerie copy with {robot} (set MENAGERIE_ROOT)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # visual meshes missing offline
        problem = BipedStand(f"menagerie:{robot}", feet=ROBOTS[robot][0], threads=1)
    eq = problem.equilibrium
    assert eq.shortfall < 1e-6
    weight = float(np.sum(problem.model.body_mass)) * 9.81
    np.testing.assert_allclose(eq.residual_wrench[:3], 0.0, atol=1e-3)
    np.testing.assert_allclose(eq.residual_wrench[3:5], 0.0, atol=1e-3 * weight)  # 1 mm
    assert np.any(mpcbox.LQR(problem).B)
    name = ROBOTS[robot][1]
    # QP-MPC without BipedStand's wall-clock budget: what a cut-off solve gives depends on
    # the machine's speed.
    overrides = {"time_limit": None} if name == "qp" else {}
    controller = mpcbox.make_controller(name, problem, **overrides)
    res = mpcbox.simulate(problem, controller, 3.0, noise=problem.noise(), seed=0)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 10.0
    problem.close()


def test_adam_lite_elbows_leave_their_limits_and_the_qp_is_well_posed():
    """Adam Lite's keyframe has both elbows on their upper limit (0 rad). Linearized there,
    the QP's 2 ms step had eigenvalues of 48 and 81 and its contact-input matrix entries of
    1.6e16; with the elbows 0.01 rad inside, the step is a stable rest again."""
    from mpcbox.core import menagerie
    from mpcbox.tasks.legged.biped import BipedStand

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("pndbotics_adam_lite")):
        pytest.skip("no offline Menagerie copy with pndbotics_adam_lite (set MENAGERIE_ROOT)")
    feet = ROBOTS["pndbotics_adam_lite"][0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        problem = BipedStand("menagerie:pndbotics_adam_lite", feet=feet, threads=1)
    assert sorted(m.joint for m in problem.limit_moves) == ["elbow_Left", "elbow_Right"]
    assert all(m.old == 0.0 and m.new == pytest.approx(-0.01) for m in problem.limit_moves)
    qp = mpcbox.make_controller("qp", problem, time_limit=None)
    lin = qp.linearization
    assert np.max(np.abs(np.linalg.eigvals(lin.Ah))) < 1.1
    assert np.max(np.abs(lin.Bc)) < 1e4
    problem.close()


def test_booster_t1_one_foot_stance_keeps_its_hand_out_of_its_hip():
    """The plain IK step took the T1's right hand 1.3 cm into its right hip; the retry with
    mink's collision-avoidance limit and slow joints ends collision-free, and the posture's
    remaining problem, a hip-roll motor too weak to hold it, is named."""
    from mpcbox.core import menagerie
    from mpcbox.core.posture import self_collisions
    from mpcbox.errors import EquilibriumWarning
    from mpcbox.tasks.legged.biped import BipedStand

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("booster_t1", None)):
        pytest.skip("no offline Menagerie copy with booster_t1 (set MENAGERIE_ROOT)")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        problem = BipedStand("menagerie:booster_t1", stance="left", threads=1)
    assert problem.posture.collisions == ()
    assert self_collisions(problem.model, problem.posture.qpos) == ()
    assert problem.posture.com_error < 1e-3
    assert any(
        issubclass(w.category, EquilibriumWarning) and "Left_Hip_Roll" in str(w.message)
        for w in caught
    )
    problem.close()


def test_the_g1_plans_ilqr_without_dry_friction_and_lands_a_hop_flat():
    """The G1's own iLQR options (``MENAGERIE_BIPED_ILQR``): its iLQR-MPC differentiates the
    model without the joints' dry friction, the class's config and other robots' stay as
    they are. A 250 N push under noise with a simulated 14 ms latency makes it hop; it must
    land back on flat feet and stand (with the friction-aware Jacobians this seed rocked
    onto its heels and fell backwards at 5.1 s, stop 49)."""
    from mpcbox.core import menagerie
    from mpcbox.tasks.legged.biped import BipedStand

    if not (os.environ.get("MENAGERIE_ROOT") and menagerie.available("unitree_g1")):
        pytest.skip("no offline Menagerie copy with unitree_g1 (set MENAGERIE_ROOT)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        problem = BipedStand("menagerie:unitree_g1", threads=1)
    assert problem.controller_configs["ilqr"].dry_friction == "drop"
    assert BipedStand.controller_configs["ilqr"].dry_friction is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        one_foot = BipedStand("menagerie:unitree_g1", stance="left", threads=1)
    assert one_foot.controller_configs["ilqr"].dry_friction is None  # measured on two feet
    one_foot.close()
    controller = mpcbox.make_controller("ilqr", problem)
    assert controller.problem.dry_friction == "drop" and problem.dry_friction == "keep"
    push = mpcbox.Push(force=(250.0, 0.0, 0.0), start=2.0, duration=0.1, body=problem.root)
    res = mpcbox.simulate_realtime(
        problem, controller, 6.0, delay=0.014, noise=problem.noise(), pushes=[push], seed=400
    )
    assert res.metrics.success, res.failure
    data = mujoco.MjData(problem.model)
    problem.set_state(data, res.states[-1])
    mujoco.mj_kinematics(problem.model, data)
    for foot in problem.feet:  # flat: the sole's normal within 2 deg of vertical
        assert data.xmat[foot.body][8] > np.cos(np.radians(2.0))
    problem.close()
