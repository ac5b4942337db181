"""The warp backend against the CPU backend (on warp's CPU device without a GPU)."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.config import config_options
from mpcbox.controllers.sampling import MPPI, PredictiveSampling, Randomization

pytest.importorskip("mujoco_warp")


def _agreement(problem, device, num_knots=3, horizon_steps=10, randomization=None, seed=0):
    opts = dict(
        num_samples=8,
        horizon=horizon_steps * problem.dt,
        num_knots=num_knots,
        randomization=randomization,
    )
    cpu = PredictiveSampling(problem, **opts)
    warp = PredictiveSampling(problem, backend="warp", device=device, **opts)
    rng = np.random.default_rng(seed)
    cand = problem.clip_ctrl(problem.ctrl_ref + rng.normal(0, 0.3, (8, num_knots, problem.nu)))
    state = problem.initial_state().copy()
    state[problem.nq :] += rng.normal(0, 0.2, problem.nv + problem.na)
    a = cpu.backend.evaluate(state, cand)
    b = warp.backend.evaluate(state, cand)
    assert not b.overflow.any() and not b.nonfinite.any()
    return a.costs, b.costs, warp


def test_cartpole_costs_agree_with_the_cpu_backend(warp_device):
    from mpcbox.tasks.swingup import CartpoleSwingup

    a, b, _ = _agreement(CartpoleSwingup(), warp_device, horizon_steps=30)
    np.testing.assert_allclose(b, a, rtol=2e-5)


def test_humanoid_costs_agree_with_the_cpu_backend(warp_device):
    """Quaternion state cost, sensor terms (height, upright), contacts, terminal forward."""
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    a, b, warp = _agreement(HumanoidStand(), warp_device, horizon_steps=20)
    np.testing.assert_allclose(b, a, rtol=2e-4)
    assert warp.backend.nconmax >= 4 and warp.stats["resizes"] == 0


def test_velocity_and_relative_height_sensor_terms_agree_with_the_cpu_backend(warp_device):
    """A subtree's velocity (a velocity-stage sensor) and a height above a foot, alone."""
    from mpcbox.core.cost import ComVelocity, Cost, HeightAbove
    from mpcbox.tasks import scene_path

    terms = [
        ComVelocity(weight=10.0, root="torso"),
        HeightAbove("torso", "foot_left", 1.2, weight=50.0),
    ]
    problem = mpcbox.Problem(scene_path("humanoid.xml"), keyframe="stand", cost=Cost(terms))
    a, b, _ = _agreement(problem, warp_device, horizon_steps=10)
    assert np.all(a > 0.1)
    np.testing.assert_allclose(b, a, rtol=2e-4)


def test_lqr_terminal_value_agrees_with_the_cpu_backend(warp_device):
    """The LQR value function (a dense quadratic form in the tangent-space state, with the
    free joint's quaternion) as terminal cost, and a quadratic form in the running cost."""
    from mpcbox.controllers.lqr import with_lqr_terminal_value
    from mpcbox.core.cost import Cost, QuadraticValue
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    base = HumanoidStand()
    problem = with_lqr_terminal_value(base)
    a0, b0, _ = _agreement(base, warp_device, horizon_steps=10, seed=3)
    a, b, _ = _agreement(problem, warp_device, horizon_steps=10, seed=3)
    # The value adds a sizeable, state-dependent amount to each candidate's cost.
    assert np.all(a - a0 > 1e-3 * a0)
    np.testing.assert_allclose(b, a, rtol=2e-4)
    np.testing.assert_allclose(b - b0, a - a0, rtol=2e-3)

    rng = np.random.default_rng(0)
    F = rng.normal(size=(2 * base.nv, 5))
    form = QuadraticValue(base.qpos_ref, P=F @ F.T, name="form")
    running = mpcbox.Problem(base.model, keyframe="stand", cost=Cost([form], []))
    a, b, _ = _agreement(running, warp_device, horizon_steps=6, seed=4)
    assert np.all(a > 0.0)
    np.testing.assert_allclose(b, a, rtol=2e-4)


def test_capped_euler_planning_model_stays_close_to_the_full_model(warp_device):
    """The humanoid's fast planning model (2 solver iterations, unrolled in the graph, Euler)
    predicts costs within a few percent of the full model and ranks candidates alike."""
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = HumanoidStand()
    fast = dict(solver_iterations=2, planning_integrator="euler")
    a, _, _ = _agreement(problem, warp_device, horizon_steps=20)
    rng = np.random.default_rng(0)
    cand = problem.clip_ctrl(problem.ctrl_ref + rng.normal(0, 0.3, (8, 3, problem.nu)))
    state = problem.initial_state().copy()
    state[problem.nq :] += rng.normal(0, 0.2, problem.nv + problem.na)
    warp = PredictiveSampling(
        problem, num_samples=8, horizon=20 * problem.dt, num_knots=3, backend="warp",
        device=warp_device, **fast,
    )  # fmt: skip
    assert not warp.backend.m.opt.graph_conditional  # a low cap is unrolled
    b = warp.backend.evaluate(state, cand)
    assert not b.overflow.any() and not b.nonfinite.any()
    rel = np.abs(b.costs[:, 0] - a[:, 0]) / np.abs(a[:, 0])
    assert rel.max() < 0.05, rel
    assert np.argmin(b.costs[:, 0]) == np.argmin(a[:, 0])
    full = PredictiveSampling(
        problem, num_samples=8, horizon=0.1, backend="warp", device=warp_device
    )
    assert full.backend.m.opt.graph_conditional


def test_broadphase_candidate_bound_covers_mjwarp(warp_device):
    """The calibration's count bounds MJWarp's own broadphase candidates from above."""
    import mujoco
    import mujoco_warp as mjw
    import warp as wp

    from mpcbox.controllers.sampling.backends.warp import broadphase_candidates
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = HumanoidStand()
    model = problem.planning_model
    rng = np.random.default_rng(3)
    with wp.ScopedDevice(warp_device):
        m = mjw.put_model(model)
        pairs = m.nxn_geom_pair_filtered.numpy().reshape(-1, 2)
        for scale in (0.0, 0.5, 1.0):
            state = problem.initial_state().copy()
            state[7 : problem.nq] += rng.normal(0.0, scale, problem.nq - 7)
            state[2] -= 0.3 * scale  # lower the root: limbs reach the floor
            data = mujoco.MjData(model)
            problem.set_state(data, state)
            mujoco.mj_forward(model, data)
            d = mjw.put_data(model, data, nworld=1, nconmax=len(pairs) * 4, njmax=600)
            mjw.forward(m, d)
            ours = broadphase_candidates(model, data, pairs)
            assert ours >= int(d.ncollision.numpy()[0]) > 0
            assert ours >= data.ncon


def test_randomized_models_agree_with_the_cpu_backend(warp_device):
    from mpcbox.tasks.swingup import CartpoleSwingup

    rand = Randomization(num_models=3, mass_scale=(0.5, 1.5))
    a, b, _ = _agreement(CartpoleSwingup(), warp_device, horizon_steps=20, randomization=rand)
    assert a.shape == (8, 3) and np.ptp(a[0]) > 1e-3
    np.testing.assert_allclose(b, a, rtol=2e-5)


@pytest.mark.gpu
def test_gpu_closed_loop_cartpole_swingup():
    from mpcbox.tasks.swingup import CartpoleSwingup

    problem = CartpoleSwingup()
    opts = dict(
        config_options(problem.controller_configs["mppi"]), num_samples=1024, backend="warp"
    )
    ctrl = MPPI(problem, **opts)
    res = mpcbox.simulate(problem, ctrl, 8.0)
    err = np.array([problem.upright_error(s) for s in res.states])
    assert np.all(err[res.time >= 3.0] < 0.3)


@pytest.mark.gpu
@pytest.mark.parametrize("name", ["mppi", "cem"])
def test_gpu_humanoid_stands_10s_under_the_noise_recipe(name):
    """Issue #5 acceptance: the tuned controllers keep the humanoid standing on the GPU.

    GPU rollouts are not bit-reproducible (atomics in the contact pipeline), so one seed can
    go either way near the edge; the defaults stood 2-3 of 3 seeds in
    ``benchmarks/results/humanoid_stand_defaults_h100.json``, and the test asks for 2 of 3.
    """
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = HumanoidStand()
    ctrl = mpcbox.make_controller(name, problem, backend="warp")
    failures = []
    for seed in range(3):
        res = mpcbox.simulate(problem, ctrl, 10.0, noise=problem.noise(), seed=seed)
        if not res.survived:
            failures.append((seed, res.failure))
    assert len(failures) <= 1, failures


def test_a_model_mjwarp_cannot_run_gets_a_clear_error(warp_device):
    """MJWarp rejects some MuJoCo features (here the forward/inverse comparison flag); the
    warp backend says so and points to the CPU backend, which runs the same model."""
    xml = """
    <mujoco>
      <option><flag fwdinv="enable"/></option>
      <worldbody><body><joint name="j" type="hinge"/><geom size="0.1" mass="1"/></body></worldbody>
      <actuator><motor joint="j" ctrlrange="-1 1"/></actuator>
    </mujoco>"""
    problem = mpcbox.Problem(xml, cost=mpcbox.Cost([mpcbox.ControlCost(weight=1.0)]))
    with pytest.raises(mpcbox.UnsupportedModelError, match="backend='cpu'") as err:
        MPPI(problem, num_samples=4, horizon=0.05, num_knots=2, backend="warp", device=warp_device)
    assert isinstance(err.value, NotImplementedError)
    cpu = MPPI(problem, num_samples=4, horizon=0.05, num_knots=2)
    assert np.all(np.isfinite(cpu(problem.initial_state(), 0.0)))


def test_diverging_rollouts_are_flagged_like_on_the_cpu(warp_device):
    """Explicit Euler with stiff velocity feedback on light links diverges once the links
    move. MuJoCo resets on a huge ``qacc`` (the CPU backend then sees NaN); MJWarp does not
    check, and within 5 steps its states are still finite (``|qvel|`` ~ 1e15) and the
    control-only cost is small, so the warp backend must flag these rollouts itself. The
    candidate with zero control never moves and stays valid."""
    xml = """
    <mujoco>
      <worldbody>
        <body><joint name="a" axis="1 0 0"/><geom size=".03"/>
          <body><joint name="b" axis="1 0 0"/><geom size=".03"/></body>
        </body>
      </worldbody>
      <actuator><position joint="a" kp="1" kv="2"/><position joint="b" kp="11" kv="12"/></actuator>
    </mujoco>"""
    problem = mpcbox.Problem(xml, cost=mpcbox.Cost([mpcbox.ControlCost(weight=1.0)]))
    opts = dict(num_samples=8, horizon=5 * problem.dt, num_knots=2)
    cpu = PredictiveSampling(problem, **opts)
    warp = PredictiveSampling(problem, backend="warp", device=warp_device, **opts)
    cand = np.linspace(0.0, 3.0, 8)[:, None, None] * np.ones((8, 2, problem.nu))
    state = problem.initial_state()
    a = cpu.backend.evaluate(state, cand)
    b = warp.backend.evaluate(state, cand)
    expected = np.arange(8)[:, None] > 0
    np.testing.assert_array_equal(a.nonfinite, expected)
    np.testing.assert_array_equal(b.nonfinite, expected)
    assert np.all(np.isfinite(b.costs))  # finite: only the flag tells the rollouts diverged
    np.testing.assert_allclose(b.costs[0], a.costs[0], atol=1e-6)
