"""``SamplingConfig.servo_armature``: armature that keeps stiff position servos stable at a
coarse planning step."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.sampling import PredictiveSamplingConfig
from mpcbox.controllers.sampling.planning import planning_problem, servo_armature
from mpcbox.errors import InvalidArgumentError

# A light link on a stiff position servo (kp 400: k dt^2 / I = 80 at 0.02 s, far past the
# explicit step's limit of 4), a general actuator with a length bias through gear 2 on a
# slide, a motor, a servo whose joint already has more armature than asked, a servo on a
# tendon (not a joint transmission) and a general actuator whose bias parameters are unused
# (no bias): the last four are left alone.
BOX = '<geom type="box" size="0.1 0.02 0.02" mass="0.1" contype="0" conaffinity="0"/>'
HINGES = ("hinge", "free_hinge", "heavy", "tendon_hinge", "unbiased")
ARMATURE = {"heavy": ' armature="5"'}
LINKS = "".join(
    f'<body pos="{2 * i} 0 0"><joint name="{name}" type="hinge" axis="0 0 1"'
    f"{ARMATURE.get(name, '')}/>{BOX}</body>"
    for i, name in enumerate(HINGES)
)
SERVOS = f"""
<mujoco>
  <option timestep="0.02" integrator="implicitfast" gravity="0 0 0"/>
  <worldbody>
    {LINKS}
    <body name="b" pos="1 0 0">
      <joint name="slide" type="slide" axis="1 0 0"/>
      <geom type="sphere" size="0.05" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="t"><joint joint="tendon_hinge" coef="1"/></fixed>
  </tendon>
  <actuator>
    <position name="servo" joint="hinge" kp="400"/>
    <general name="general" joint="slide" gear="2" gainprm="30" biastype="affine"
             biasprm="0 -30 0"/>
    <motor name="motor" joint="free_hinge"/>
    <position name="heavy_servo" joint="heavy" kp="400"/>
    <position name="tendon_servo" tendon="t" kp="400"/>
    <general name="no_bias" joint="unbiased" biastype="none" biasprm="0 -400 0"/>
  </actuator>
</mujoco>
"""


def _model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SERVOS)


def test_armature_is_the_factor_times_the_servo_stiffness_times_the_step_squared():
    model = _model()
    before = model.dof_armature.copy()
    raised = servo_armature(model, 0.5)
    dt2 = 0.02**2
    names = ("hinge", "slide", "free_hinge", "heavy", "tendon_hinge", "unbiased")
    hinge, slide, motor, heavy, tendon, unbiased = (model.joint(n).dofadr[0] for n in names)
    assert model.dof_armature[hinge] == pytest.approx(0.5 * 400 * dt2)
    # Stiffness on the joint is kp g^2 for gear g.
    assert model.dof_armature[slide] == pytest.approx(0.5 * 30 * 4 * dt2)
    for dof in (motor, heavy, tendon, unbiased):
        assert model.dof_armature[dof] == before[dof]
    assert sorted(raised.tolist()) == sorted([hinge, slide])


def _swing(model: mujoco.MjModel, steps: int = 200) -> float:
    """Largest hinge angle over ``steps`` from 0.1 rad with the servo's target at 0
    (infinite when MuJoCo flagged a bad acceleration and reset the state)."""
    data = mujoco.MjData(model)
    adr = model.joint("hinge").qposadr[0]
    data.qpos[adr] = 0.1
    largest = 0.0
    for _ in range(steps):
        mujoco.mj_step(model, data)
        angle = abs(float(data.qpos[adr]))
        if not np.isfinite(angle) or data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            return float("inf")
        largest = max(largest, angle)
    return largest


def test_the_raised_armature_keeps_a_stiff_servo_stable_at_the_coarse_step(capfd):
    model = _model()
    assert _swing(model) > 1.0  # the explicit spring blows up at 0.02 s
    capfd.readouterr()  # MuJoCo's printed warning
    servo_armature(model, 0.5)
    # Semi-implicit Euler on q'' = -k q / I from rest at q0 oscillates with the largest
    # |q| = q0 / sqrt(1 - h / 4), h = k dt^2 / I (here a little under 1 / c = 2: the
    # box's own inertia about its joint, m (a^2 + b^2) / 3 = 3.4667e-4 kg m^2, adds to it).
    inertia = float(model.dof_armature[model.joint("hinge").dofadr[0]]) + 3.4667e-4
    h = 400 * 0.02**2 / inertia
    assert _swing(model) == pytest.approx(0.1 / np.sqrt(1 - h / 4), rel=1e-3)
    # The servo still pulls the link to its target, only more slowly (I = k dt^2 / 2).
    data = mujoco.MjData(model)
    data.qpos[model.joint("hinge").qposadr[0]] = 0.1
    model.dof_damping[model.joint("hinge").dofadr[0]] = 2.0
    for _ in range(100):
        mujoco.mj_step(model, data)
    assert abs(float(data.qpos[model.joint("hinge").qposadr[0]])) < 0.01


def test_the_config_changes_only_the_planning_copy_and_checks_its_value():
    problem = mpcbox.Problem(SERVOS)
    hinge = problem.model.joint("hinge").dofadr[0]
    config = PredictiveSamplingConfig(servo_armature=1.0, planning_timestep=0.01, horizon=0.1)
    config.validate(problem.nu, problem.dt)
    planner = planning_problem(problem, config)
    assert planner.planning_model.dof_armature[hinge] == pytest.approx(400 * 0.01**2)
    assert problem.planning_model.dof_armature[hinge] == 0.0
    assert problem.model.dof_armature[hinge] == 0.0
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InvalidArgumentError, match="servo_armature"):
            PredictiveSamplingConfig(servo_armature=bad).validate(problem.nu, problem.dt)
