"""iLQR: exactness on a linear-quadratic problem, control limits, swing-ups, and input checks."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.controllers.ilqr.backward_pass import interpolate_linearization
from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.result import StopReason
from mpcbox.core.cost import ControlCost, Cost, StateCost
from mpcbox.errors import (
    InvalidArgumentError,
    InvalidTypeError,
    MpcboxError,
    ShapeError,
    UnknownOptionError,
)
from mpcbox.registry import make_controller
from mpcbox.tasks.swingup import CartpoleSwingup, PendulumSwingup

# A point mass on two sliders without gravity, damping or limits: MuJoCo's semi-implicit
# Euler step is exactly linear, so with a quadratic cost iLQR must match the Riccati solution.
POINT_MASS = """
<mujoco>
  <option timestep="0.05" gravity="0 0 0"/>
  <worldbody>
    <body name="mass">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="y" type="slide" axis="0 1 0"/>
      <geom type="sphere" size="0.1" mass="2" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="x" gear="1" ctrllimited="false"/>
    <motor joint="y" gear="2" ctrllimited="{limited}" ctrlrange="-{bound} {bound}"/>
  </actuator>
</mujoco>
"""
WQ, WV, WU = np.array([1.0, 2.0]), np.array([0.1, 0.3]), np.array([0.05, 0.02])
WQ_T, WV_T = np.array([50.0, 40.0]), np.array([5.0, 8.0])
X0 = np.array([1.0, -0.5, 0.3, 0.2])
T = 40


def point_mass(limited: bool = False, bound: float = 100.0) -> mpcbox.Problem:
    cost = Cost(
        [StateCost(np.zeros(2), weight_qpos=WQ, weight_qvel=WV), ControlCost(weight=WU)],
        [StateCost(np.zeros(2), weight_qpos=WQ_T, weight_qvel=WV_T, name="terminal")],
    )
    xml = POINT_MASS.format(limited=str(limited).lower(), bound=bound)
    return mpcbox.Problem(xml, cost=cost, threads=1)


def riccati(problem: mpcbox.Problem, A=None, B=None, scale: float = 1.0, knots: int = T):
    """Time-varying Riccati recursion written out independently of mpcbox.controllers.ilqr:
    of the model's step, or of the map ``(A, B)`` with the running weights times ``scale``."""
    if A is None:
        A, B = problem.linearize(np.zeros(4), np.zeros(2))
    Q, R = scale * np.diag(np.r_[WQ, WV]), scale * np.diag(WU)
    P = np.diag(np.r_[WQ_T, WV_T])
    gains = np.zeros((knots, 2, 4))
    for t in range(knots - 1, -1, -1):
        K = -np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P = Q + A.T @ P @ (A + B @ K)
        gains[t] = K
    x, xs, us = X0.copy(), [X0.copy()], []
    for t in range(knots):
        u = gains[t] @ x
        x = A @ x + B @ u
        us.append(u)
        xs.append(x)
    return gains, np.array(xs), np.array(us)


@pytest.mark.parametrize("limited", [False, True])
def test_linear_quadratic_one_iteration_is_riccati(limited):
    problem = point_mass(limited=limited)  # limits far away exercise the box-QP path
    gains, xs, us = riccati(problem)
    ilqr = ILQR(problem, horizon=T, regularization=0.0)  # plain Newton step
    one = ilqr.solve(X0, max_iterations=1)
    assert one.iterations == 1
    np.testing.assert_allclose(one.ctrls, us, atol=1e-6)
    np.testing.assert_allclose(one.states, xs, atol=1e-6)
    np.testing.assert_allclose(one.K, gains, rtol=1e-5, atol=1e-6)
    full = ilqr.solve(X0)
    assert full.converged and full.iterations <= 2
    assert full.cost == pytest.approx(one.cost, rel=1e-9)
    assert full.costs[0] > full.cost
    assert set(full.timing._fields) == {"derivatives", "backward", "rollouts", "total"}


def test_parallel_line_search_and_interpolated_linearization_agree():
    problem = point_mass()
    ref = ILQR(problem, horizon=T).solve(X0)
    par = ILQR(problem, horizon=T, line_search="parallel", threads=2).solve(X0)
    sparse = ILQR(problem, horizon=T, linearize_every=4).solve(X0)  # linear system: exact anyway
    assert par.cost == pytest.approx(ref.cost, rel=1e-9)
    assert sparse.cost == pytest.approx(ref.cost, rel=1e-9)


def test_interpolate_linearization():
    A = np.stack([np.eye(2), 3 * np.eye(2)])
    B = np.stack([np.ones((2, 1)), 5 * np.ones((2, 1))])
    lin = interpolate_linearization(A, B, np.array([0, 4]), 5)
    np.testing.assert_allclose(lin.A[:, 0, 0], [1.0, 1.5, 2.0, 2.5, 3.0])
    np.testing.assert_allclose(lin.B[:, 1, 0], [1.0, 2.0, 3.0, 4.0, 5.0])


def test_tight_control_limits_hold_and_clamped_gains_vanish():
    problem = point_mass(limited=True, bound=0.05)
    res = ILQR(problem, horizon=T).solve(X0)
    u = res.ctrls[:, 1]
    assert np.all(np.abs(u) <= 0.05 + 1e-12)
    clamped = np.abs(np.abs(u) - 0.05) < 1e-9
    assert clamped.sum() > 5
    # Saturated knots of the limited actuator get no feedback (control-limited DDP).
    assert np.allclose(res.K[clamped, 1], 0.0)
    assert res.converged


def test_divergent_rollouts_raise_regularization_and_recover():
    problem = point_mass()

    class Flaky(ILQR):
        fails = 0

        def _forward(self, *args):
            if Flaky.fails < 7:  # every step size of the first line search, then one more
                Flaky.fails += 1
                out = super()._forward(*args)
                return out[0] * np.nan, out[1], np.inf
            return super()._forward(*args)

    res = Flaky(problem, horizon=T).solve(X0)
    ref = ILQR(problem, horizon=T).solve(X0)
    assert res.divergences == 7
    assert res.cost == pytest.approx(ref.cost, rel=1e-6)


def test_mpc_feedback_between_replans_and_a_diverged_state_is_reported():
    problem = point_mass()
    ctrl = ILQR(problem, horizon=T, replan_period=0.2)
    assert ctrl.period is None
    u0 = ctrl(X0, 0.0)
    plan = ctrl.last_result
    np.testing.assert_allclose(u0, plan.ctrls[0], atol=1e-12)
    # One planning step later, off the nominal: u = u_1 + K_1 (x - x_1), no replan.
    delta = np.array([0.01, -0.02, 0.03, 0.0])
    u1 = ctrl(plan.states[1] + delta, problem.dt)
    np.testing.assert_allclose(u1, plan.ctrls[1] + plan.K[1] @ delta, atol=1e-10)
    assert ctrl.stats["replans"] == 1
    ctrl(plan.states[4], 4 * problem.dt)
    assert ctrl.stats["replans"] == 2
    with pytest.raises(mpcbox.DivergenceError, match="non-finite"):  # a diverged world
        ctrl(np.full(4, np.nan), 5 * problem.dt)
    with pytest.raises(mpcbox.DivergenceError, match="mjMAXVAL"):  # MuJoCo would reset it
        ctrl(np.full(4, 1e11), 5 * problem.dt)
    assert ctrl.stats["fallbacks"] == 0
    held = ILQR(problem, horizon=T, replan_period=0.1, feedback=False)
    assert held.period == pytest.approx(0.1)


def test_pendulum_offline_swingup_matches_ipopt():
    problem = PendulumSwingup(planning_timestep=0.025)
    horizon, u0 = 120, np.array([0.5])  # 3 s; the hanging rest is a critical point
    res = ILQR(problem, horizon=horizon, max_iterations=300, ctrls_init=u0, threads=1).solve(
        problem.initial_state()
    )
    assert res.converged
    assert problem.upright_error(res.states[-1]) < 0.1
    assert np.all(res.ctrls >= problem.ctrl_low) and np.all(res.ctrls <= problem.ctrl_high)
    assert np.abs(res.ctrls).max() == pytest.approx(2.0)  # the torque limit is active
    assert np.all(np.diff(res.costs) < 0)
    pytest.importorskip("casadi")
    from mpcbox.controllers.ipopt import solve_ipopt

    ref = solve_ipopt(problem, problem.initial_state(), horizon, ctrls_init=u0, tolerance=1e-7)
    assert ref.defect < 1e-6
    gap = (res.cost - ref.cost) / ref.cost
    assert gap < 0.01, f"iLQR {res.cost:.4f} vs IPOPT {ref.cost:.4f}"


def test_cartpole_mpc_swings_up_within_3s_and_holds_5s():
    problem = CartpoleSwingup()
    controller = make_controller("ilqr", problem)
    result = mpcbox.simulate(problem, controller, 8.0)
    assert result.failure is None
    err = np.array([problem.upright_error(s) for s in result.states])
    down = np.flatnonzero(err > 0.3)
    t_up = result.time[down[-1] + 1] if len(down) else 0.0
    assert t_up <= 3.0, f"upright only from t = {t_up:.2f} s"
    assert result.time[-1] - t_up >= 5.0 - 1e-9
    assert np.all(np.abs(result.states[:, 0]) < 2.9)  # the cart stays off the rail ends
    assert result.controller_stats["fallbacks"] == 0


def test_bad_inputs_raise_named_errors():
    problem = point_mass()
    for horizon in (0, -3, 2.5, True):
        with pytest.raises(InvalidArgumentError, match="horizon"):
            ILQR(problem, horizon=horizon)
    with pytest.raises(InvalidArgumentError, match="ctrl_low must be <= ctrl_high"):
        ILQR(problem, horizon=10, ctrl_low=np.array([1.0, 0.0]), ctrl_high=np.array([-1.0, 1.0]))
    with pytest.raises(ShapeError, match="ctrl_low"):
        ILQR(problem, horizon=10, ctrl_low=np.zeros(3))
    with pytest.raises(InvalidArgumentError, match="step_sizes"):
        ILQR(problem, horizon=10, step_sizes=(1.0, 0.0))
    with pytest.raises(InvalidArgumentError, match="line_search"):
        ILQR(problem, horizon=10, line_search="golden")
    with pytest.raises(InvalidArgumentError, match="regularization"):
        ILQR(problem, horizon=10, regularization=float("nan"))
    with pytest.raises(InvalidArgumentError, match="problem"):
        ILQR("scene.xml", horizon=10)
    ilqr = ILQR(problem, horizon=10)
    with pytest.raises(ShapeError, match="x0"):
        ilqr.solve(np.zeros(3))
    with pytest.raises(ShapeError, match="ctrls_init"):
        ilqr.solve(X0, np.zeros((9, 2)))
    with pytest.raises(InvalidArgumentError, match="ctrls_init"):
        ilqr.solve(X0, np.full((10, 2), np.inf))
    with pytest.raises(MpcboxError, match="x0"):
        ilqr.solve(np.array([np.nan, 0, 0, 0]))
    with pytest.raises(MpcboxError, match="weight"):
        mpcbox.Problem(
            POINT_MASS.format(limited="false", bound=1),
            cost=Cost([StateCost(np.zeros(2), weight_qpos=[1.0, np.inf])]),
        )
    with pytest.raises(InvalidArgumentError, match="terminal_value"):
        ILQR(problem, horizon=10, terminal_value="riccati")
    # Every error is also the matching built-in exception.
    with pytest.raises(ValueError):
        ILQR(problem, horizon=0)


def test_lqr_terminal_value_makes_short_horizon_ilqr_match_lqr():
    # On a linear-quadratic problem the LQR value function is the exact cost-to-go, so with
    # it as terminal cost a short-horizon iLQR's first feedback gain equals the LQR gain.
    problem = mpcbox.Problem(
        POINT_MASS.format(limited="false", bound=100.0),
        cost=Cost([StateCost(np.zeros(2), weight_qpos=WQ, weight_qvel=WV), ControlCost(weight=WU)]),
        threads=1,
    )
    lqr = mpcbox.LQR(problem)
    ilqr = ILQR(problem, horizon=3, terminal_value="lqr")
    res = ilqr.solve(problem.reference_state() + np.array([0.1, -0.2, 0.0, 0.0]))
    np.testing.assert_allclose(res.K[0], -lqr.K, rtol=1e-5, atol=1e-6)


def test_lqr_terminal_value_on_the_humanoid_at_its_own_timestep():
    """The humanoid's Riccati solution at 0.005 s has a marginal mode whose eigenvalue comes
    out about -2e-6 of the largest; the terminal value projects it onto the PSD cone instead
    of rejecting it, and changes nothing else."""
    from mpcbox.tasks.humanoid.balance import HumanoidBalance

    problem = HumanoidBalance(threads=1)
    P = mpcbox.LQR(problem).P
    ilqr = ILQR(problem, horizon=3, terminal_value="lqr", max_iterations=1)
    (value,) = [t for t in ilqr.problem.cost.terminal if t.name == "lqr_value"]
    V = np.asarray(value.P)
    assert np.linalg.eigvalsh(V).min() >= -1e-9 * np.abs(V).max()
    np.testing.assert_allclose(V, 0.5 * (P + P.T), atol=1e-5 * np.abs(P).max())
    u = ilqr(problem.reference_state(), 0.0)
    assert u.shape == (problem.nu,) and np.all(np.isfinite(u))


def test_stop_reasons_iteration_cap_and_stall_at_maximum_regularization():
    problem = PendulumSwingup(planning_timestep=0.05)

    def solve(**options):
        ilqr = ILQR(problem, horizon=40, ctrls_init=np.array([0.5]), threads=1, **options)
        return ilqr.solve(problem.initial_state())

    done = solve()
    assert done.stop_reason is StopReason.COST_CHANGE and done.converged
    capped = solve(max_iterations=3)
    assert capped.stop_reason is StopReason.ITERATION_LIMIT and capped.status == "iteration limit"
    assert capped.iterations == 3 and not capped.converged
    # Full steps only: the swing-up soon rejects every step, and the regularization grows
    # past a low cap.
    stalled = solve(step_sizes=(1.0,), regularization_max=1e-4)
    assert stalled.stop_reason is StopReason.REGULARIZATION_LIMIT and stalled.stop_reason.stalled
    assert stalled.status == "regularization limit (line search)"
    assert stalled.regularization > 1e-4 and not stalled.converged
    assert stalled.cost == stalled.costs[-1] and len(stalled.costs) == stalled.iterations
    # The same with the default cap but two retries: the retry limit, not the regularization.
    retried = solve(step_sizes=(1.0,), max_retries=2)
    assert retried.stop_reason is StopReason.RETRY_LIMIT and not retried.converged
    assert retried.regularization < 1e10


def test_stop_reasons_divergence_short_step_and_no_predicted_decrease():
    problem = point_mass()

    class Diverging(ILQR):
        def _forward(self, *args):
            out = super()._forward(*args)
            return out[0] * np.nan, out[1], np.inf

    res = Diverging(problem, horizon=T, max_retries=3).solve(X0)
    assert res.stop_reason is StopReason.DIVERGED and res.stop_reason.stalled
    assert not res.converged and res.divergences == 4 * 6  # 4 line searches of 6 step sizes

    class NoFullStep(ILQR):
        def _forward(self, x0, states, ctrls, k, K, alpha):
            out = super()._forward(x0, states, ctrls, k, K, alpha)
            return (out[0], out[1], np.inf) if alpha == 1.0 else out

    # A huge tolerance stops at the first accepted step: converged only if it was a full one.
    short = NoFullStep(problem, horizon=T, tolerance=1e3).solve(X0)
    assert short.stop_reason is StopReason.SHORT_STEP and not short.converged
    assert short.status.startswith("short step") and not short.stop_reason.stalled
    full = ILQR(problem, horizon=T, tolerance=1e3).solve(X0)
    assert full.stop_reason is StopReason.COST_CHANGE and full.converged
    newton = ILQR(problem, horizon=T, regularization=0.0).solve(X0)
    assert newton.stop_reason is StopReason.NO_PREDICTED_DECREASE and newton.converged


def test_config_object_defaults_and_option_errors():
    problem = point_mass()
    config = ILQRConfig(horizon=T, max_iterations=5)
    ilqr = ILQR(problem, config, tolerance=1e-8)
    assert ilqr.config.horizon == T and ilqr.config.max_iterations == 5
    assert ilqr.config.tolerance == 1e-8 and config.tolerance == 1e-6
    assert ILQR.config_class is ILQRConfig
    # Any Problem gets a working iLQR from the defaults (50 knots).
    default = make_controller("ilqr", problem)
    assert default.horizon == ILQRConfig().horizon == 50
    u = default(X0, 0.0)
    assert u.shape == (2,) and np.all(np.isfinite(u))
    with pytest.raises(UnknownOptionError, match="regularization_max"):
        ILQR(problem, mu_max=1.0)
    with pytest.raises(InvalidTypeError, match="ILQRConfig"):
        ILQR(problem, 10)
    with pytest.raises(InvalidArgumentError, match="regularization_factor"):
        ILQRConfig(regularization_factor=1.0)
    with pytest.raises(InvalidArgumentError, match="armijo"):
        ILQRConfig(armijo=1.0)
    with pytest.raises(InvalidArgumentError, match="regularization_max"):
        ILQRConfig(regularization_min=1.0, regularization_max=0.5)


@pytest.mark.parametrize("first_step", ["short", "underdelivering full"])
def test_small_decrease_is_no_stop_while_the_model_predicts_a_large_one(first_step):
    """A step that lowers the cost by less than ``tolerance`` ends the solve only if the
    backward pass also predicts less: here the first line search is spoiled (the full step
    is refused, or it moves only 1 % of the way, as a poor model would make it) while the
    predicted decrease is about the whole gap to the optimum, so the solver must go on to
    the linear-quadratic optimum instead of stopping after a 2 % decrease."""
    problem = point_mass()

    class SpoiledFirstSearch(ILQR):
        full_steps = 0

        def _forward(self, x0, states, ctrls, k, K, alpha):
            if alpha == 1.0:
                self.full_steps += 1
                if self.full_steps == 1 and first_step == "short":
                    return states, ctrls, np.inf
                if self.full_steps == 1:
                    alpha = 0.01
            return super()._forward(x0, states, ctrls, k, K, alpha)

    optimum = ILQR(problem, horizon=T, regularization=0.0).solve(X0)
    res = SpoiledFirstSearch(problem, horizon=T, tolerance=0.05, step_sizes=(1.0, 0.01)).solve(X0)
    first_decrease = (res.costs[0] - res.costs[1]) / res.costs[1]
    assert 0.0 < first_decrease < 0.05  # the old rule stopped here
    assert res.converged and res.stop_reason is not StopReason.SHORT_STEP, res.status
    assert res.cost == pytest.approx(optimum.cost, rel=1e-6)
    assert res.cost < 0.5 * res.costs[1]
