"""The cost's sensors computed by mpcbox's kernel against MuJoCo's (warp's CPU device)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.sampling import PredictiveSampling, Randomization
from mpcbox.core.cost import ComVelocity, Cost, CostTerm, FrameHeight, SensorRequest, Upright
from mpcbox.core.cost.base import Features
from mpcbox.core.cost.rows import SensorRow

pytest.importorskip("mujoco_warp")

# Two trees (a floating base with a two-link arm, and a hinged pendulum), sites, geoms and
# bodies whose frames differ from their inertial frames, and every sensor kind the kernel
# computes, with the robot's own accelerometer beside them.
SENSED = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body name="base" pos="0 0 1" euler="10 20 30">
      <freejoint/>
      <geom type="box" size="0.2 0.1 0.05" pos="0.05 0 0" mass="3"/>
      <site name="imu" pos="0.1 0.02 0" euler="0 30 0"/>
      <body name="upper" pos="0.2 0 0">
        <joint name="shoulder" axis="0 1 0"/>
        <geom name="upper" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
        <body name="lower" pos="0.3 0 0" euler="0 0 40">
          <joint name="elbow" axis="0 0 1"/>
          <geom name="lower" type="capsule" fromto="0 0 0 0 0.25 0" size="0.02" mass="0.5"/>
          <site name="tip" pos="0 0.25 0"/>
        </body>
      </body>
    </body>
    <body name="pendulum" pos="1 0 1">
      <joint name="swing" axis="1 0 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03" mass="2"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="shoulder"/>
    <motor joint="elbow"/>
    <motor joint="swing"/>
  </actuator>
  <sensor>
    <accelerometer name="acc" site="imu"/>
    <framepos name="p_site" objtype="site" objname="tip"/>
    <framepos name="p_xbody" objtype="xbody" objname="lower"/>
    <framepos name="p_body" objtype="body" objname="lower"/>
    <framepos name="p_geom" objtype="geom" objname="upper"/>
    <framexaxis name="x_site" objtype="site" objname="imu"/>
    <frameyaxis name="y_body" objtype="body" objname="upper"/>
    <framezaxis name="z_xbody" objtype="xbody" objname="base"/>
    <framezaxis name="z_geom" objtype="geom" objname="lower"/>
    <subtreecom name="com_base" body="base"/>
    <subtreecom name="com_world" body="world"/>
    <subtreelinvel name="v_base" body="base"/>
    <subtreelinvel name="v_upper" body="upper"/>
    <subtreelinvel name="v_world" body="world"/>
  </sensor>
</mujoco>
"""
KERNEL_SENSORS = [f"{s}" for s in (
    "p_site", "p_xbody", "p_body", "p_geom", "x_site", "y_body", "z_xbody", "z_geom",
    "com_base", "com_world", "v_base", "v_upper", "v_world",
)]  # fmt: skip


def _ids(model, names):
    return [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, n) for n in names]


def test_kernel_sensors_equal_mujocos_at_random_states(warp_device):
    import mujoco_warp as mjw
    import warp as wp

    from mpcbox.controllers.sampling.backends.warp_sensors import DeviceSensors, sensor_plan

    model = mujoco.MjModel.from_xml_string(SENSED)
    ids = _ids(model, KERNEL_SENSORS)
    plan = sensor_plan(model, ids)
    assert plan is not None and plan.kind.size == len(ids)
    # The accelerometer is not one the kernel computes: MJWarp's pipeline stays.
    assert sensor_plan(model, [*ids, *_ids(model, ["acc"])]) is None
    rng = np.random.default_rng(0)
    nworld = 4
    datas = []
    for _ in range(nworld):
        data = mujoco.MjData(model)
        data.qpos[:3] = rng.normal(0, 0.5, 3)
        quat = rng.normal(size=4)
        data.qpos[3:7] = quat / np.linalg.norm(quat)
        data.qpos[7:] = rng.uniform(-2, 2, model.nq - 7)
        data.qvel[:] = rng.normal(0, 2.0, model.nv)
        mujoco.mj_forward(model, data)
        datas.append(data)
    quiet = mujoco.MjModel.from_xml_string(SENSED)
    quiet.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_SENSOR
    with wp.ScopedDevice(warp_device):
        m = mjw.put_model(quiet)
        d = mjw.make_data(quiet, nworld=nworld, nconmax=16, njmax=64)
        d.qpos.assign(np.array([x.qpos for x in datas]))
        d.qvel.assign(np.array([x.qvel for x in datas]))
        mjw.forward(m, d)
        assert not d.sensordata.numpy().any()  # MJWarp computed none of them
        DeviceSensors(plan, warp_device).launch(m, d, nworld)
        ours = d.sensordata.numpy()
    for w, data in enumerate(datas):
        for name, s in zip(KERNEL_SENSORS, ids, strict=True):
            adr, dim = model.sensor_adr[s], model.sensor_dim[s]
            np.testing.assert_allclose(
                ours[w, adr : adr + dim], data.sensordata[adr : adr + dim], atol=2e-5,
                err_msg=f"{name} in world {w}",
            )  # fmt: skip
        # The velocity sensors are not trivially zero or equal.
        v = [data.sensordata[model.sensor_adr[s] : model.sensor_adr[s] + 3] for s in ids[-3:]]
        assert min(np.linalg.norm(x) for x in v) > 0.1 and np.ptp(np.array(v)) > 0.1


class Spin(CostTerm):
    """A site's angular velocity about its x axis (a gyro: not a sensor of the kernel)."""

    def size(self, model: mujoco.MjModel) -> int:
        return 1

    def sensors(self, model: mujoco.MjModel) -> list[SensorRequest]:
        site = mujoco.mjtObj.mjOBJ_SITE
        return [SensorRequest(f"mpcbox_{self.name}", mujoco.mjtSensor.mjSENS_GYRO, site, "imu")]

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, :1]

    def rows(self) -> list:
        adr = self.sensor_address(f"mpcbox_{self.name}").start
        return [SensorRow(adr, -1, 0.0, float(self.weight[0]))]


def _terms() -> list[CostTerm]:
    return [
        ComVelocity(weight=10.0, root="base"),
        FrameHeight("tip", 1.3, weight=50.0),
        Upright("base", weight=5.0),
    ]


def _costs(problem, device, randomization=None, seed=3):
    """Both backends' costs of six random candidates over 12 steps from a jittered start,
    and the warp backend's ``own_sensors`` count."""
    opts = dict(num_samples=6, horizon=12 * problem.dt, num_knots=3, randomization=randomization)
    cpu = PredictiveSampling(problem, **opts)
    warp = PredictiveSampling(problem, backend="warp", device=device, **opts)
    rng = np.random.default_rng(seed)
    cand = rng.normal(0, 0.5, (6, 3, problem.nu))
    state = problem.initial_state().copy()
    state[problem.nq :] += rng.normal(0, 0.5, problem.nv)
    b = warp.backend.evaluate(state, cand)
    assert not b.overflow.any() and not b.nonfinite.any()
    return cpu.backend.evaluate(state, cand).costs, b.costs, warp.backend.stats["own_sensors"]


def test_planning_costs_with_kernel_sensors_agree_with_the_cpu_backend(warp_device):
    """A cost that reads a subtree's velocity, a site's height and a body's axis, on
    randomized masses (the kernel reads each world's masses); the model's own accelerometer
    is left out of the planning model, not computed. A term whose sensor the kernel does
    not compute (a gyro) keeps MJWarp's sensors, with the same costs."""
    base = mpcbox.Problem(SENSED, cost=Cost(_terms(), _terms()))
    gyro = mpcbox.Problem(SENSED, cost=Cost([*_terms(), Spin(1.0, "spin")], _terms()))
    rand = Randomization(num_models=2, mass_scale=(0.5, 1.5), seed=1)
    for problem, own in ((base, True), (gyro, False)):
        a, b, count = _costs(problem, warp_device, randomization=rand, seed=2)
        assert (count > 0) == own, count
        assert a.shape == (6, 2) and np.all(np.ptp(a, axis=0) > 1e-3)
        np.testing.assert_allclose(b, a, rtol=2e-4)


# No site at all: a frame sensor on a body must not read the (empty) site arrays.
NO_SITES = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.05"/>
      <body name="tip" pos="0 0 0.5">
        <joint name="elbow" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge"/>
    <motor joint="elbow"/>
  </actuator>
</mujoco>
"""


def test_body_frames_of_a_model_without_sites_agree_with_the_cpu_backend(warp_device):
    terms = [FrameHeight("tip", 1.2, weight=10.0), Upright("tip", weight=1.0)]
    a, b, own = _costs(mpcbox.Problem(NO_SITES, cost=Cost(terms)), warp_device)
    assert own == 2 and np.ptp(a) > 1e-3
    np.testing.assert_allclose(b, a, rtol=2e-4)


def test_rk4_planning_keeps_mjwarps_sensors(warp_device):
    """An RK4 step leaves its last stage's kinematics in Data, so the kernel, which reads
    them after the step, would sense the wrong state: MJWarp computes the sensors then."""
    rk4 = SENSED.replace('timestep="0.01"', 'timestep="0.01" integrator="RK4"')
    problem = mpcbox.Problem(rk4, cost=Cost(_terms()), plan_rk4=True)
    assert problem.planning_model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    a, b, own = _costs(problem, warp_device)
    assert own == -1 and np.ptp(a) > 1e-3
    np.testing.assert_allclose(b, a, rtol=2e-4)
