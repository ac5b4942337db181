"""Cost terms own all their forms: the row form and the CasADi form agree with the residual."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.core.cost import (
    ComOverSupport,
    ComVelocity,
    ControlCost,
    Cost,
    CostTerm,
    FrameHeight,
    FramePosition,
    HeightAbove,
    StateCost,
    Upright,
    WrappedAngle,
)
from mpcbox.core.cost.rows import (
    AngleRow,
    ControlRow,
    PositionRow,
    QuadraticFormRow,
    QuaternionRow,
    SensorRow,
    VelocityRow,
)
from mpcbox.core.tangent import quat_difference
from mpcbox.errors import CostDefinitionError, UnsupportedCostTermError
from mpcbox.tasks import scene_path


def row_value(row, qpos, qvel, ctrl, sensordata) -> float:
    """``0.5 w r^2`` of one row, written out from the row definitions."""
    if isinstance(row, QuaternionRow):
        d = quat_difference(qpos[row.address : row.address + 4], row.ref)
        return 0.5 * float(np.sum(row.weight * d * d))
    if isinstance(row, QuadraticFormRow):
        dx = np.zeros(row.factor.shape[0])
        nv = dx.size // 2
        dx[row.scalar_dof] = qpos[row.scalar_qpos] - row.qpos_ref[row.scalar_qpos]
        for a, b in zip(row.quat_qpos, row.quat_dof, strict=True):
            dx[b : b + 3] = quat_difference(qpos[a : a + 4], row.qpos_ref[a : a + 4])
        dx[nv:] = qvel - row.qvel_ref
        r = dx @ row.factor
        return 0.5 * row.weight * float(r @ r)
    if isinstance(row, PositionRow):
        r = qpos[row.index] - row.ref
    elif isinstance(row, VelocityRow):
        r = qvel[row.index] - row.ref
    elif isinstance(row, ControlRow):
        r = ctrl[row.index] - row.ref
    elif isinstance(row, AngleRow):
        r = 2.0 * np.sin(0.5 * (qpos[row.index] - row.ref))
    else:
        assert isinstance(row, SensorRow)
        r = sensordata[row.a] - row.offset - (sensordata[row.b] if row.b >= 0 else 0.0)
    return 0.5 * row.weight * r * r


def check_rows(problem: mpcbox.Problem, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = problem.state_add(problem.reference_state(), 0.3 * rng.standard_normal(problem.nx))
    u = problem.clip_ctrl(problem.ctrl_ref + rng.standard_normal(problem.nu))
    features = problem.features(x, u)
    qpos, qvel, ctrl, sens = (f[0] for f in features)
    for term in problem.cost.terms:
        r = term.residual(features)[0]
        want = 0.5 * np.sum(term.weight * r * r)
        got = sum(row_value(row, qpos, qvel, ctrl, sens) for row in term.rows())
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12), term.name


def humanoid_terms(ref: mpcbox.Problem) -> list:
    """One term of each kind on the project's humanoid standing (``ref``)."""
    return [
        StateCost(ref.qpos_ref, weight_qpos=2.0, weight_qvel=0.5),
        ControlCost(np.full(ref.nu, 0.1), weight=np.linspace(0.5, 1.5, ref.nu)),
        ComOverSupport("foot_left", weight=[3.0, 4.0], root="torso", offset=[0.05, -0.02]),
        FramePosition("hand_right", np.array([0.2, -0.3, 1.0]), weight=[1.0, 0.0, 2.0]),
        FrameHeight("torso", 1.3, weight=5.0),
        HeightAbove("torso", "foot_left", 1.2, weight=3.0),
        Upright("torso", weight=[2.0, 3.0]),
        ComVelocity(weight=[2.0, 5.0], root="torso"),
    ]


def test_humanoid_rows_sum_to_the_residual_cost():
    """Quaternion, position, velocity, control and sensor rows (free joint weighted too)."""
    humanoid = scene_path("humanoid.xml")
    ref = mpcbox.Problem(humanoid, keyframe="stand")
    terms = humanoid_terms(ref)
    problem = mpcbox.Problem(humanoid, keyframe="stand", cost=Cost(terms))
    assert any(isinstance(row, QuaternionRow) for row in problem.cost.running[0].rows())
    check_rows(problem, 0)


def test_wrapped_angle_rows_sum_to_the_residual_cost():
    from mpcbox.tasks.swingup import CartpoleSwingup

    check_rows(CartpoleSwingup(), 1)


class Custom(CostTerm):
    def size(self, model):
        return model.nq

    def residual(self, features):
        return features.qpos.copy()


def test_terms_without_a_form_say_which_backend_needs_it():
    problem = mpcbox.Problem(scene_path("cartpole.xml"), cost=Cost([Custom(1.0, "mine")]))
    term = problem.cost.running[0]
    with pytest.raises(UnsupportedCostTermError, match=r"'mine' of type Custom.*warp") as err:
        term.rows()
    assert isinstance(err.value, NotImplementedError) and "StateCost" in str(err.value)
    with pytest.raises(UnsupportedCostTermError, match=r"CasADi form.*IPOPT"):
        term.casadi_residual(None, None, None)


def test_quadratic_form_rows_sum_to_the_value():
    """The LQR value's row (a dense form in the tangent-space state, free joint included)."""
    from mpcbox.controllers.lqr import with_lqr_terminal_value
    from mpcbox.tasks.humanoid.stand import HumanoidStand

    problem = with_lqr_terminal_value(HumanoidStand())
    (row,) = problem.cost.terminal[-1].rows()
    assert isinstance(row, QuadraticFormRow) and row.quat_qpos.size == 1
    check_rows(problem.with_cost(Cost(problem.cost.terminal)), 2)


def test_casadi_forms_match_the_residuals():
    casadi = pytest.importorskip("casadi")
    from mpcbox.tasks.swingup import CartpoleSwingup

    problem = CartpoleSwingup()
    rng = np.random.default_rng(2)
    x = problem.state_add(problem.reference_state(), rng.standard_normal(problem.nx))
    u = rng.standard_normal(problem.nu)
    q, v, c = casadi.SX.sym("q", problem.nq), casadi.SX.sym("v", problem.nv), casadi.SX.sym("u")
    features = problem.features(x, u)
    for term in problem.cost.terms:
        fn = casadi.Function("r", [q, v, c], [term.casadi_residual(q, v, c)])
        got = np.asarray(fn(x[: problem.nq], x[problem.nq :], u)).ravel()
        np.testing.assert_allclose(got, term.residual(features)[0], rtol=1e-12, atol=1e-12)
    with pytest.raises(UnsupportedCostTermError, match="nq == nv"):
        mpcbox.Problem(scene_path("humanoid.xml")).cost.running[0].casadi_residual(q, v, c)


def test_weights_are_keyword_only():
    with pytest.raises(TypeError):
        ControlCost(None, 1.0)
    with pytest.raises(TypeError):
        StateCost(np.zeros(2), None, 1.0)
    with pytest.raises(TypeError):
        WrappedAngle("hinge", np.pi, 1.0)


def test_com_velocity_is_the_subtree_momentum_over_its_mass():
    """The sensor term against the closed form sum_b m_b v_b / sum_b m_b (xy)."""
    import mujoco

    problem = mpcbox.Problem(
        scene_path("humanoid.xml"),
        keyframe="stand",
        cost=Cost([ComVelocity(weight=1.0, root="torso")]),
    )
    rng = np.random.default_rng(3)
    x = problem.state_add(problem.reference_state(), 0.5 * rng.standard_normal(problem.nx))
    r = problem.cost.running[0].residual(problem.features(x, np.zeros(problem.nu)))[0]
    model, data = problem.planning_model, problem.scratch_data()
    problem.set_state(data, x)
    mujoco.mj_forward(model, data)
    momentum = np.zeros(3)
    for body in range(1, model.nbody):
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, vel, 0)
        # mjOBJ_BODY: the velocity at the body's centre of mass, world axes.
        momentum += model.body_mass[body] * vel[3:]
    want = momentum[:2] / model.body_mass[1:].sum()
    assert np.linalg.norm(want) > 0.1
    np.testing.assert_allclose(r, want, rtol=1e-9, atol=1e-9)


def test_quadratization_on_each_terms_stage_equals_full_forward(monkeypatch):
    """Each term runs only the part of mj_forward its stage names; the quadratization (value,
    gradients, Hessians) is the one with the whole of mj_forward, term by term and together,
    at states away from the reference, for analytic and finite-difference Jacobians."""
    from mpcbox.core import derivatives

    humanoid = scene_path("humanoid.xml")
    ref = mpcbox.Problem(humanoid, keyframe="stand")
    terms = humanoid_terms(ref)
    assert [t.stage for t in terms] == ["none", "none", "pos", "pos", "pos", "pos", "pos", "vel"]
    rng = np.random.default_rng(5)
    x0 = ref.reference_state()
    states = np.array([ref.state_add(x0, 0.2 * rng.standard_normal(ref.nx)) for _ in range(4)])
    ctrls = ref.clip_ctrl(ref.ctrl_ref + rng.standard_normal((3, ref.nu)))
    for chosen in [[t] for t in terms] + [terms]:
        problem = mpcbox.Problem(humanoid, keyframe="stand", cost=Cost(chosen), threads=1)
        fast = problem.quadratize_trajectory(states, ctrls)
        with monkeypatch.context() as patch:
            patch.setattr(derivatives, "forward_stage", lambda terms: "acc")
            full = problem.quadratize_trajectory(states, ctrls)
        for name, a, b in zip(fast._fields, fast, full, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10, err_msg=name)
    # Without the Hessian blocks: the same values and gradients, the blocks left zero.
    bare = problem.quadratize_trajectory(states, ctrls, hessians=False)
    for name in ("value", "lx", "lu"):
        np.testing.assert_array_equal(getattr(bare, name), getattr(fast, name), err_msg=name)
    assert not (bare.lxx.any() or bare.luu.any() or bare.lux.any()) and fast.lxx.any()


def test_a_term_with_an_unknown_stage_is_named():
    from mpcbox.core.cost import forward_stage

    class Odd(ControlCost):
        stage = "position"

    with pytest.raises(CostDefinitionError, match=r"stage 'position'.*'none', 'pos'"):
        forward_stage([Odd(np.zeros(2), weight=1.0, name="odd")])


TWO_BALLS = """<mujoco><worldbody>
<body name="a" pos="0 0 1"><joint name="ja" type="slide" axis="1 0 0"/>
  <geom size=".1" mass="1"/></body>
<body name="b" pos="1 0 1"><joint name="jb" type="slide" axis="1 0 0"/>
  <geom size=".1" mass="1"/></body>
</worldbody><actuator><motor joint="ja"/><motor joint="jb"/></actuator></mujoco>"""


def test_terms_of_one_name_on_different_objects_are_refused_not_merged():
    """Two terms asking for one sensor name on different bodies used to share the first
    one's sensor, so the second read the wrong body without a word."""
    from mpcbox.core.cost import ComVelocity, FrameHeight
    from mpcbox.errors import ModelLoadError

    pairs = (
        [ComVelocity(weight=1.0, root="a"), ComVelocity(weight=1.0, root="b")],
        [FrameHeight("a", 0.0, weight=1.0, name="h"), FrameHeight("b", 0.0, weight=1.0, name="h")],
    )
    for terms in pairs:
        with pytest.raises(CostDefinitionError, match="distinct names"):
            mpcbox.Problem(TWO_BALLS, cost=Cost(terms))
    # With names of their own each reads its body: 0.5 (1^2 + 3^2).
    terms = [ComVelocity(weight=1.0, root="a"), ComVelocity(weight=1.0, root="b", name="vb")]
    problem = mpcbox.Problem(TWO_BALLS, cost=Cost(terms))
    x = problem.reference_state()
    x[problem.nq :] = [1.0, 3.0]
    assert problem.running_cost(x, np.zeros(2)) == pytest.approx(5.0)
    # A compiled model whose sensor of that name senses another body is refused too.
    with pytest.raises(ModelLoadError, match="on 'a'"):
        mpcbox.Problem(problem.model, cost=Cost([ComVelocity(weight=1.0, root="b")]))
    same = mpcbox.Problem(problem.model, cost=Cost([ComVelocity(weight=1.0, root="a")]))
    assert same.running_cost(x, np.zeros(2)) == pytest.approx(0.5)


def test_subtree_roots_are_names_and_an_unnamed_default_is_explained():
    from mpcbox.core.cost import ComVelocity
    from mpcbox.errors import InvalidArgumentError, InvalidTypeError

    with pytest.raises(InvalidTypeError, match="root must be a string"):
        ComVelocity(weight=1.0, root=1)
    unnamed = TWO_BALLS.replace('body name="a"', "body")
    with pytest.raises(InvalidArgumentError, match="first body, which has no name"):
        mpcbox.Problem(unnamed, cost=Cost([ComVelocity(weight=1.0)]))
