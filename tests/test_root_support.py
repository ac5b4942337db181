"""Where a floating body rests: root height and tilt at which the contacts carry it and
balance its moments (``find_equilibrium(root_adjust="pose")``)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.core.root_support import MAX_TILT, support_root
from mpcbox.errors import EquilibriumWarning, InfeasibleEquilibriumError

# A 10 kg slab on three sphere legs: two under the front edge (x = +0.3), one at the back
# (x = -0.3). The back leg is `short` shorter, so a level slab leans back onto it.
TABLE = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom type="plane" size="5 5 .1"/>
    <body name="slab" pos="0 0 0.22">
      <freejoint/>
      <geom type="box" size=".35 .25 .02" mass="10" pos="{com} 0 0" contype="0" conaffinity="0"/>
      <geom type="sphere" size=".02" pos=".3 .2 -.2" mass="0"/>
      <geom type="sphere" size=".02" pos=".3 -.2 -.2" mass="0"/>
      <geom type="sphere" size=".02" pos="-.3 0 {back}" mass="0"/>
    </body>
  </worldbody>
</mujoco>
"""


def table(short: float = 0.02, com: float = 0.0) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(TABLE.format(back=-0.2 + short, com=com))


def static_acceleration(model: mujoco.MjModel, qpos: np.ndarray) -> float:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return float(np.max(np.abs(data.qacc)))


def test_a_slab_on_uneven_legs_is_tilted_onto_all_of_them():
    model = table(short=0.02)
    level = model.qpos0.copy()
    height = mpcbox.find_equilibrium(model, level, root_adjust="height")
    pose = mpcbox.find_equilibrium(model, level, root_adjust="pose")
    # Height alone leaves the pitch moment of a slab on legs of unequal length.
    assert abs(height.residual_wrench[4]) > 1.0
    assert static_acceleration(model, height.qpos) > 1.0
    # The tilted pose is a static equilibrium: every root residual vanishes, nothing moves.
    np.testing.assert_allclose(pose.residual_wrench, 0.0, atol=1e-3)
    assert static_acceleration(model, pose.qpos) < 1e-3
    # Leaning back by the legs' geometry, atan(0.02 / 0.6), up to the contacts' uneven
    # penetration (a few tenths of a millimetre).
    assert pose.root_tilt[1] == pytest.approx(-np.arctan2(0.02, 0.6), abs=2e-3)
    assert abs(pose.root_tilt[0]) < 1e-4 and np.all(height.root_tilt == 0.0)


def test_equal_legs_lean_only_by_their_uneven_load():
    # The back leg carries half the weight, each front leg a quarter: the soft contacts sink
    # the back one deeper, a tilt of about 1e-4 rad; the height-only pose is nearly as good.
    model = table(short=0.0)
    pose = mpcbox.find_equilibrium(model, model.qpos0, root_adjust="pose")
    height = mpcbox.find_equilibrium(model, model.qpos0, root_adjust="height")
    assert 0.0 < -pose.root_tilt[1] < 1e-3 and abs(pose.root_tilt[0]) < 1e-6
    assert static_acceleration(model, pose.qpos) < 1e-3
    np.testing.assert_allclose(pose.qpos[:3], height.qpos[:3], atol=1e-3)


def test_a_posture_no_tilt_can_balance_warns_and_keeps_the_height_only_pose():
    # The center of mass 0.4 m behind the back leg: only a tilt of ~60 deg would put it over
    # the support, far beyond MAX_TILT.
    model = table(short=0.0, com=-0.7)
    with pytest.warns(EquilibriumWarning, match="cannot balance the posture"):
        eq = mpcbox.find_equilibrium(model, model.qpos0)
    np.testing.assert_array_equal(eq.root_tilt, 0.0)
    assert abs(eq.vertical_residual) < 1e-3
    with pytest.raises(InfeasibleEquilibriumError, match="cannot balance"):
        mpcbox.find_equilibrium(model, model.qpos0, on_infeasible="raise")
    support = support_root(model, model.qpos0)
    assert support is not None and not support.balanced and MAX_TILT < np.pi / 3


def test_bad_root_adjust_is_named():
    with pytest.raises(mpcbox.InvalidArgumentError, match="root_adjust"):
        mpcbox.find_equilibrium(table(), table().qpos0, root_adjust="tilt")


def test_fixed_base_has_no_root_to_move():
    arm = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><joint name="j" type="hinge"/><geom size=".1" pos=".2 0 0"/>'
        '</body></worldbody><actuator><motor joint="j"/></actuator></mujoco>'
    )
    assert support_root(arm, arm.qpos0) is None
    eq = mpcbox.find_equilibrium(arm, arm.qpos0)
    np.testing.assert_array_equal(eq.root_tilt, 0.0)
