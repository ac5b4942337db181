"""Bad inputs that a fuzz of mixed arguments and run-time paths found getting past the checks.

Each case once raised a bare NumPy/Python error, aborted the interpreter, or was accepted
silently; each must now raise a named :class:`mpcbox.MpcboxError` (or warn) before any run.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mpcbox
from mpcbox.cli import main as cli_main
from mpcbox.comparison.scenario import Scenario
from mpcbox.registry import task_class

PENDULUM = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <body name="pole">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.03" mass="1"/>
    </body>
    <body name="cart" pos="0 0 -1">
      <joint name="slider" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="hinge" ctrlrange="-5 5" ctrllimited="true"/>
    <motor joint="slider" ctrlrange="-5 5" ctrllimited="true"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def problem() -> mpcbox.Problem:
    return mpcbox.Problem(PENDULUM)


@pytest.mark.parametrize("seed", [2**32, 2**40])
def test_seeds_beyond_32_bits_are_refused_by_name(problem, seed):
    noise = mpcbox.ActuatorNoise(std=0.1)
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"seed must be an integer in \[0, "):
        mpcbox.simulate(problem, mpcbox.LQR(problem), 0.03, noise=noise, seed=seed)
    with pytest.raises(mpcbox.InvalidArgumentError, match="seed"):
        noise.sample(3, problem.nu, 0.01, seed)
    with pytest.raises(mpcbox.InvalidArgumentError, match="seeds"):
        mpcbox.compare("pendulum_swingup", ["lqr"], Scenario(duration=0.05), seeds=[seed])
    # The largest seed still runs.
    mpcbox.simulate(problem, mpcbox.LQR(problem), 0.02, noise=noise, seed=2**32 - 1)


def test_a_controller_class_instead_of_an_instance_is_named(problem):
    with pytest.raises(mpcbox.InvalidTypeError, match=r"controller .*class LQR.*LQR\(problem\)"):
        mpcbox.simulate(problem, mpcbox.LQR, 0.03)


def test_wrapped_angle_needs_a_hinge():
    cost = mpcbox.Cost([mpcbox.WrappedAngle("slider", 0.0, weight=1.0)])
    with pytest.raises(mpcbox.InvalidArgumentError, match="hinge joint, got the slide joint"):
        mpcbox.Problem(PENDULUM, cost=cost)
    mpcbox.Problem(PENDULUM, cost=mpcbox.Cost([mpcbox.WrappedAngle("hinge", 0.0, weight=1.0)]))


def test_effort_noise_checks_its_model_and_posture(problem):
    with pytest.raises(mpcbox.InvalidTypeError, match="model"):
        mpcbox.effort_noise(problem, problem.qpos_ref, fraction=0.1)
    with pytest.raises(mpcbox.InvalidArgumentError, match="qpos"):
        mpcbox.effort_noise(problem.model, np.full(problem.nq, np.nan), fraction=0.1)
    noise = mpcbox.effort_noise(problem.model, problem.qpos_ref, fraction=0.1)
    # 10 % of the half range of +-5 N m motors of unit gear.
    np.testing.assert_allclose(noise.std, [0.5, 0.5])


@pytest.mark.parametrize("task", ["pendulum_swingup", "cartpole_swingup", "acrobot_swingup"])
def test_swingup_presets_refuse_another_model_by_name(task):
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"^model: .* own scene"):
        task_class(task)(model=PENDULUM)


def test_a_push_after_the_end_warns(problem):
    push = mpcbox.Push(force=[5.0, 0.0, 0.0], body="pole")  # starts at 1 s
    with pytest.warns(UserWarning, match=r"pushes\[0\] start at or after the run's end"):
        res = mpcbox.simulate(problem, mpcbox.LQR(problem), 0.2, pushes=[push])
    assert res.survived


def test_more_knots_than_planning_steps_is_refused(problem):
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"num_knots must be at most .* \(6"):
        mpcbox.MPPI(problem, horizon=0.05, num_knots=7, num_samples=4, backend="cpu")
    mpcbox.MPPI(problem, horizon=0.05, num_knots=6, num_samples=4, backend="cpu")


def test_ctrl_ref_outside_the_range_is_named():
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"^ctrl_ref\[0\] = 50"):
        mpcbox.Problem(PENDULUM, ctrl_ref=[50.0, 0.0])
    mpcbox.Problem(PENDULUM, ctrl_ref=[5.0, -5.0])


@pytest.mark.parametrize("eps", [0.5, 10.0])
def test_a_finite_difference_step_that_is_not_local_is_refused(eps):
    with pytest.raises(mpcbox.InvalidArgumentError, match="fd_eps"):
        mpcbox.Problem(PENDULUM, fd_eps=eps)


def test_an_ilqr_replan_period_longer_than_its_plan_warns(problem):
    with pytest.warns(UserWarning, match=r"replan_period 0.2 s is longer .* 5 x 0.01 s"):
        ilqr = mpcbox.ILQR(problem, horizon=5, replan_period=0.2, max_iterations=1)
    state = problem.reference_state()
    first = ilqr(state, 0.0)
    # Past the plan's end it holds the last knot (with its gain), not zeros.
    np.testing.assert_allclose(ilqr(state, 0.15), ilqr(state, 0.19))
    assert np.all(np.isfinite(first))


def test_lqr_config_checks_its_finite_difference_options():
    with pytest.raises(mpcbox.InvalidTypeError, match="eps"):
        mpcbox.LQRConfig(eps="abc")
    with pytest.raises(mpcbox.InvalidArgumentError, match="eps"):
        mpcbox.LQRConfig(eps=-1.0)
    with pytest.raises(mpcbox.InvalidTypeError, match="centered"):
        mpcbox.LQRConfig(centered="yes")


def test_compare_checks_option_values_before_any_run():
    """They used to reach every worker and come back as rows of failed runs."""
    with pytest.raises(mpcbox.InvalidArgumentError, match="horizon"):
        mpcbox.compare(
            "pendulum_swingup",
            ["ilqr"],
            Scenario(duration=0.05),
            seeds=1,
            controller_options={"ilqr": {"horizon": -1}},
            workers=1,
            progress=False,
        )


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ({"num_samples": -1}, "num_samples"),
        ({"servo_armature": -1.0}, "servo_armature"),
        ({"num_knots": 1000}, "num_knots"),  # more knots than the horizon's steps
        ({"noise_scale": [0.1, 0.2, 0.3]}, "noise_scale"),  # one per control, not three
    ],
)
def test_compare_checks_sampling_values_that_need_the_problem_before_any_run(options, named):
    """A sampling config checks its values against the Problem's sizes; compare builds the
    task once to check them, where they used to come back as rows of failed runs."""
    for task in ("cartpole_swingup", "pendulum_swingup"):  # a tuned config, and the defaults
        with pytest.raises(mpcbox.MpcboxError, match=named):
            mpcbox.compare(
                task,
                ["mppi"],
                Scenario(duration=0.05, noise_scale=0.0),
                seeds=1,
                controller_options={"mppi": options},
                workers=1,
                progress=False,
            )


def test_cli_sampling_option_values_exit_2(tmp_path, capsys):
    args = ["compare", "cartpole_swingup", "--controllers", "mppi", "--seeds", "1"]
    args += ["--duration", "0.05", "--set", "mppi.num_samples=0", "--no-plots", "--no-progress"]
    assert cli_main([*args, "--out", str(tmp_path)]) == 2
    assert "num_samples must be" in capsys.readouterr().err


def test_cli_option_values_exit_2(tmp_path, capsys):
    args = ["compare", "pendulum_swingup", "--controllers", "lqr", "--seeds", "1"]
    args += ["--duration", "0.05", "--set", "lqr.eps=-1", "--no-plots", "--no-progress"]
    assert cli_main([*args, "--out", str(tmp_path)]) == 2
    assert "eps must be" in capsys.readouterr().err


def test_qp_mpc_names_its_contacts_and_rescue_arguments():
    with pytest.raises(mpcbox.UnknownNameError, match=r"^rescue: unknown solver 'nope'"):
        mpcbox.QPMPCConfig(rescue="nope")
    problem = task_class("humanoid_balance")()
    with pytest.raises(mpcbox.UnknownNameError, match=r"^contacts: unknown .* 'nosuch'"):
        mpcbox.QPMPC(problem, contacts=["nosuch"])


def test_a_failed_opengl_start_is_not_retried(tmp_path):
    """After GLFW failed without a display, a second renderer aborted the interpreter."""
    script = textwrap.dedent(
        f"""
        import mpcbox
        import mpcbox.sim.rendering as rendering
        p = mpcbox.Problem({PENDULUM!r})
        rendering._GL_FAILURE = "no OpenGL here (test)"
        for i in range(2):
            try:
                mpcbox.simulate(p, mpcbox.LQR(p), 0.02, viewer={str(tmp_path / "a.gif")!r})
            except mpcbox.BackendUnavailableError as exc:
                print("named", exc)
        """
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.count("named no OpenGL here (test)") == 2


@pytest.mark.parametrize(
    ("settings", "error"),
    [
        ({"max_iter": -5}, mpcbox.InvalidArgumentError),
        ({"max_iter": 0}, mpcbox.InvalidArgumentError),
        ({"max_iter": "a"}, mpcbox.InvalidTypeError),
        ({"eps_abs": float("nan")}, mpcbox.InvalidArgumentError),
        ({"rho": -0.1}, mpcbox.InvalidArgumentError),
        ({"alpha": 2.5}, mpcbox.InvalidArgumentError),
        ({"rho": True}, mpcbox.InvalidTypeError),
    ],
)
def test_osqp_setting_values_are_checked_when_the_config_is_built(settings, error):
    name = next(iter(settings))
    with pytest.raises(error, match=rf"^osqp_settings\['{name}'\]"):
        mpcbox.QPMPCConfig(osqp_settings=settings)


def test_usual_osqp_settings_pass():
    settings = {"rho": 0.3, "check_dualgap": False, "adaptive_rho": True, "max_iter": 400}
    assert mpcbox.QPMPCConfig(osqp_settings=settings).osqp_settings == settings


def test_rollout_models_are_checked(problem):
    state, ctrls = problem.reference_state(), np.zeros((2, 3, problem.nu))
    with pytest.raises(mpcbox.InvalidTypeError, match=r"model must be a mujoco\.MjModel"):
        problem.rollout(state, ctrls, model=42)
    with pytest.raises(mpcbox.ShapeError, match=r"one MjModel per batch row \(2\), got 1"):
        problem.rollout(state, ctrls, model=[problem.planning_model])
    other = mpcbox.Problem(
        PENDULUM.replace('<motor joint="slider" ctrlrange="-5 5" ctrllimited="true"/>', "")
    )
    with pytest.raises(mpcbox.ShapeError, match=r"model\[0\] must have the planning model's"):
        problem.rollout(state, ctrls[0], model=other.planning_model)
    both = problem.rollout(state, ctrls, model=[problem.planning_model] * 2)
    np.testing.assert_allclose(both.states, problem.rollout(state, ctrls).states)


def test_keyword_only_classes_name_a_positional_call():
    with pytest.raises(mpcbox.InvalidTypeError, match=r"Push takes keyword arguments only"):
        mpcbox.Push([1.0, 0.0, 0.0])
    with pytest.raises(mpcbox.InvalidTypeError, match=r"ActuatorNoise\(std=\.\.\.\)"):
        mpcbox.ActuatorNoise(0.1)
    with pytest.raises(mpcbox.InvalidTypeError, match=r"only joint, target by position, got 3"):
        mpcbox.WrappedAngle("hinge", 0.0, 1.0)
    assert mpcbox.WrappedAngle("hinge", 0.0, weight=1.0).joint == "hinge"


def test_clip_ctrl_and_set_state_check_their_arguments(problem):
    with pytest.raises(mpcbox.ShapeError, match=r"ctrl must have shape \(2,\), got \(3,\)"):
        problem.clip_ctrl(np.zeros(3))
    with pytest.raises(mpcbox.InvalidTypeError, match="ctrl must be a numeric array"):
        problem.clip_ctrl("a")
    np.testing.assert_allclose(problem.clip_ctrl([[9.0, -9.0]]), [[5.0, -5.0]])
    with pytest.raises(mpcbox.InvalidTypeError, match="data"):
        problem.set_state(42, problem.reference_state())


@pytest.mark.parametrize("bad", ["states", "ctrls"])
def test_quadratize_trajectory_refuses_non_finite_input(problem, bad):
    states = np.tile(problem.reference_state(), (4, 1))
    ctrls = np.tile(problem.ctrl_ref, (3, 1))
    quad = problem.quadratize_trajectory(states, ctrls)
    assert np.all(np.isfinite(quad.lx))
    {"states": states, "ctrls": ctrls}[bad][1, 0] = np.nan
    with pytest.raises(mpcbox.DivergenceError, match=f"{bad} holds non-finite"):
        problem.quadratize_trajectory(states, ctrls)


def test_task_state_readers_name_a_wrong_shape_and_an_unknown_cube():
    stack = task_class("stack_cubes")()
    state = stack.initial_state()
    np.testing.assert_allclose(
        stack.cube_position(state, "red_cube"), state[stack._cube_adr["red_cube"] :][:3]
    )
    with pytest.raises(mpcbox.UnknownNameError, match="'blue_cube', 'red_cube'"):
        stack.cube_position(state, "green_cube")
    with pytest.raises(mpcbox.UnknownNameError, match="cube"):
        stack.cube_speed(state, "c")
    with pytest.raises(mpcbox.ShapeError, match="state must have shape"):
        stack.cube_speed(state[:3], "red_cube")
    pot = task_class("pot_lift")()
    for reader in (pot.pot_height, pot.pot_tilt):
        with pytest.raises(mpcbox.ShapeError, match="state must have shape"):
            reader(np.zeros(3))
    with pytest.raises(mpcbox.ShapeError, match="states"):
        pot.goal_failure(np.zeros(2), np.zeros((2, 3)))
    # The default first guess checks what it is given, though it does not read the state.
    with pytest.raises(mpcbox.ShapeError, match="state"):
        pot.initial_ctrls(np.zeros(3), 10)
    with pytest.raises(mpcbox.InvalidArgumentError, match="horizon"):
        pot.initial_ctrls(pot.initial_state(), 0)
    assert pot.initial_ctrls(pot.initial_state(), 4).shape == (4, pot.nu)


@pytest.mark.parametrize("name", ["lqr", "ilqr", "mppi", "ps"])
def test_a_controller_names_a_time_that_is_not_a_finite_number(name):
    task = task_class("cartpole_swingup")()
    options = {"backend": "cpu", "num_samples": 4} if name in ("mppi", "ps") else {}
    ctrl = mpcbox.make_controller(name, task, **options)
    state = task.initial_state()
    with pytest.raises(mpcbox.InvalidArgumentError, match="time must be a finite number"):
        ctrl(state, float("nan"))
    with pytest.raises(mpcbox.InvalidTypeError, match="time must be a number"):
        ctrl(state, "0.1")
    assert ctrl(state, 0.0).shape == (task.nu,)


def test_lqr_refuses_a_non_finite_state_rather_than_returning_nan():
    task = task_class("cartpole_swingup")()
    lqr = mpcbox.LQR(task)
    bad = task.initial_state()
    bad[0] = np.nan
    with pytest.raises(mpcbox.DivergenceError, match="state"):
        lqr(bad, 0.0)


@pytest.mark.parametrize(
    ("script", "args", "named"),
    [
        ("grasp_hold", ["--trials", "0"], "--trials"),
        ("grasp_hold", ["--seed", "-1"], "--seed"),
        ("stack_cubes", ["--trials", "-3"], "--trials"),
        ("stack_cubes", ["--first-seed", "-1"], "--first-seed"),
        ("panda_reach", ["--offline-horizon", "nan"], "--offline-horizon"),
        ("panda_reach", ["--duration", "-1"], "--duration"),
    ],
)
def test_problem_scripts_name_a_bad_number_and_exit_2(problem_script, capsys, script, args, named):
    """Checked before anything is built (these once raised NumPy's errors, or printed
    "0/-3 stacked" and exited 0)."""
    assert problem_script(script).main(args) == 2
    assert f"error: {named}" in capsys.readouterr().err


def test_compare_refuses_a_push_that_starts_after_the_run(tmp_path, capsys):
    args = ["compare", "pendulum_swingup", "--push", "3", "--push-time", "2", "--duration", "1"]
    assert cli_main([*args, "--out", str(tmp_path)]) == 2
    assert "--push-time (2 s) must be before the end of the run" in capsys.readouterr().err


def test_options_that_contradict_each_other_are_refused_by_name(problem, tmp_path):
    """Each once built and then did nothing, or failed only in every run."""
    from mpcbox.comparison.scenario import PushTest
    from mpcbox.controllers.ilqr.config import ILQRConfig
    from mpcbox.controllers.qp_mpc.config import QPMPCConfig
    from mpcbox.controllers.sampling.config import CEMConfig

    with pytest.raises(mpcbox.InvalidArgumentError, match="tolerance must be below max_force"):
        PushTest(tolerance=5000.0, max_force=2000.0)
    with pytest.raises(mpcbox.InvalidArgumentError, match="regularization_max"):
        ILQRConfig(horizon=10, regularization=1e12)
    with pytest.raises(mpcbox.InvalidArgumentError, match="std_min"):
        CEMConfig(std_min=10.0, noise_scale=0.1).validate(problem.nu, problem.dt)
    folder = tmp_path / "file"
    folder.write_text("")
    with pytest.raises(mpcbox.InvalidArgumentError, match="export_dir must be a folder"):
        QPMPCConfig(export_dir=folder)
    with pytest.raises(mpcbox.InvalidArgumentError, match="width must span at most"):
        mpcbox.ActuatorNoise(std=0.1, width=1e6).sample(5, problem.nu, problem.dt, 0)
    with pytest.raises(mpcbox.InvalidArgumentError, match="delay must be at most"):
        mpcbox.simulate_realtime(problem, mpcbox.LQR(problem), 0.1, delay=1.0)
    with pytest.raises(mpcbox.InvalidArgumentError, match=r"replan_period .* has no effect"):
        mpcbox.make_controller("mppi", problem, period=0.02, replan_period=0.01)


def test_compare_names_an_unknown_pushed_body_before_any_run(problem):
    push = mpcbox.Push(force=(1.0, 0.0, 0.0), start=0.01, body="torso")
    scenario = Scenario(duration=0.05, noise_scale=0.0, pushes=(push,))
    with pytest.raises(mpcbox.UnknownNameError, match=r"Push body: unknown body 'torso'.*pole"):
        mpcbox.compare(problem, ["lqr"], scenario, seeds=1, progress=False)


@pytest.mark.parametrize(
    ("option", "value", "match"),
    [("fall_fraction", 2.0, r"fall_fraction must be in \(0, 1\)"), ("fall_tilt", 500.0, "180")],
)
def test_legged_fall_criteria_out_of_their_range_are_refused(option, value, match):
    from mpcbox.tasks.legged.quadruped import QuadrupedStand

    with pytest.raises(mpcbox.InvalidArgumentError, match=match):
        QuadrupedStand(**{option: value})
