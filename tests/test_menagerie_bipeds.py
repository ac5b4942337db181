"""Legged robots nobody here tuned for (MuJoCo Menagerie), standing by name under LQR.

Each robot failed before stop 31 in its own way: Unitree's H1 fell (its keyframe leaves
51 N m of pitch on the root, now balanced by tilting the root; QP-MPC stands it, LQR does
not under this noise); PAL's Talos raised NotStabilizableError (the PBH test took its
clustered, controllable modes near 1 for uncontrollable ones); Agility's Cassie fell in
1.2 s; PNDbotics' Adam Lite stands on mesh soles that had no contact points, Apptronik's
Apollo on soles that touch the floor only through ``<pair>``s; and Adam Lite's B came out
exactly zero (the constraint solver stopped at its default tolerance inside the finite
differences). Each test needs an offline copy with the robot (``MENAGERIE_ROOT``) and
skips without one.
"""

from __future__ import annotations

import os
import warnings

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
    controller = mpcbox.make_controller(ROBOTS[robot][1], problem)
    res = mpcbox.simulate(problem, controller, 3.0, noise=problem.noise(), seed=0)
    assert res.metrics.success, res.failure
    assert res.metrics.measures["tilt_rms_deg"] < 10.0
    problem.close()
