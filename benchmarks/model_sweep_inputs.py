"""Bad inputs for :mod:`model_sweep`: each must raise an :class:`mpcbox.MpcboxError`.

Every case is ``check(record, name, fn, expect_error=True)``: a clean mpcbox error is
``mpcbox_error``, anything else (a raw exception, silent acceptance) is filed as a bug.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import numpy as np

GROUPS = ("problem", "controllers", "simulate", "tasks", "cli")

NAN = float("nan")
PENDULUM = """
<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <body name="pole">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.03" mass="1"/>
      <site name="tip" pos="0 0 0.5"/>
    </body>
  </worldbody>
  <actuator><motor name="m" joint="hinge" ctrlrange="-2 2" ctrllimited="true"/></actuator>
  <keyframe><key name="up" qpos="0.1"/></keyframe>
</mujoco>
"""
NO_ACTUATOR = PENDULUM.replace(
    '<actuator><motor name="m" joint="hinge" ctrlrange="-2 2" ctrllimited="true"/></actuator>',
    "",
)


def _problem():
    import mpcbox

    return mpcbox.Problem(PENDULUM)


def problem_cases(check, record):
    import mpcbox

    P = mpcbox.Problem
    cases = {
        "model_missing_file": lambda: P("/nonexistent/robot.xml"),
        "model_int": lambda: P(123),
        "model_none": lambda: P(None),
        "model_bad_xml": lambda: P("<mujoco><worldbody><body>"),
        "model_empty_string": lambda: P(""),
        "model_no_actuator": lambda: P(NO_ACTUATOR),
        "keyframe_unknown_name": lambda: P(PENDULUM, keyframe="nope"),
        "keyframe_index_out_of_range": lambda: P(PENDULUM, keyframe=5),
        "keyframe_negative_index": lambda: P(PENDULUM, keyframe=-1),
        "keyframe_float": lambda: P(PENDULUM, keyframe=0.5),
        "keyframe_bool": lambda: P(PENDULUM, keyframe=True),
        "qpos_ref_wrong_shape": lambda: P(PENDULUM, qpos_ref=[0.0, 1.0]),
        "qpos_ref_nan": lambda: P(PENDULUM, qpos_ref=[NAN]),
        "qpos_ref_strings": lambda: P(PENDULUM, qpos_ref=["a"]),
        "ctrl_ref_wrong_shape": lambda: P(PENDULUM, ctrl_ref=np.zeros(3)),
        "ctrl_ref_inf": lambda: P(PENDULUM, ctrl_ref=[np.inf]),
        "planning_timestep_zero": lambda: P(PENDULUM, planning_timestep=0.0),
        "planning_timestep_negative": lambda: P(PENDULUM, planning_timestep=-0.01),
        "planning_timestep_nan": lambda: P(PENDULUM, planning_timestep=NAN),
        "planning_timestep_string": lambda: P(PENDULUM, planning_timestep="0.01"),
        "fd_eps_zero": lambda: P(PENDULUM, fd_eps=0.0),
        "fd_eps_nan": lambda: P(PENDULUM, fd_eps=NAN),
        "threads_zero": lambda: P(PENDULUM, threads=0),
        "threads_float": lambda: P(PENDULUM, threads=1.5),
        "cost_string": lambda: P(PENDULUM, cost="quadratic"),
        "unknown_kwarg": lambda: P(PENDULUM, horizon=3),
        "name_int": lambda: P(PENDULUM, name=3),
        "planning_model_mismatch": lambda: P(PENDULUM, planning_model=NO_ACTUATOR),
        "menagerie_unknown": lambda: P("menagerie:nope_robot"),
    }
    for name, fn in cases.items():
        check(record, name, fn, expect_error=True)
    p = _problem()
    x, u = p.reference_state(), p.ctrl_ref
    more = {
        "linearize_state_wrong_shape": lambda: p.linearize(np.zeros(5), u),
        "linearize_state_nan": lambda: p.linearize(np.full_like(x, NAN), u),
        "linearize_ctrl_wrong_shape": lambda: p.linearize(x, np.zeros(4)),
        "linearize_ctrl_nan": lambda: p.linearize(x, np.array([NAN])),
        "linearize_eps_negative": lambda: p.linearize(x, u, eps=-1.0),
        "step_state_wrong_shape": lambda: p.step(np.zeros(1), u),
        "rollout_ctrls_wrong_shape": lambda: p.rollout(x, np.zeros((4, 3))),
        "rollout_ctrls_nan": lambda: p.rollout(x, np.full((4, 1), NAN)),
        "quadratize_state_wrong_shape": lambda: p.quadratize(np.zeros(7), u),
        "find_equilibrium_qpos_wrong_shape": lambda: p.find_equilibrium(np.zeros(4)),
        "find_equilibrium_qpos_nan": lambda: p.find_equilibrium(np.array([NAN])),
        "find_equilibrium_bad_mode": lambda: p.find_equilibrium(on_infeasible="explode"),
        "with_planning_timestep_zero": lambda: p.with_planning_timestep(0.0),
        "with_cost_string": lambda: p.with_cost("x"),
        "set_state_wrong_shape": lambda: p.set_state(p.scratch_data(), np.zeros(9)),
        "state_difference_wrong_shape": lambda: p.state_difference(np.zeros(3), x),
        "noise_negative_scale": lambda: p.noise(-1.0),
    }
    for name, fn in more.items():
        check(record, name, fn, expect_error=True)
    # A few costs built by users.
    from mpcbox import ControlCost, Cost, FrameHeight, FramePosition, StateCost

    costs = {
        "cost_frame_unknown": lambda: P(
            PENDULUM, cost=Cost([FrameHeight("nope", target=1.0, weight=1.0)])
        ),
        "cost_frame_position_shape": lambda: P(
            PENDULUM, cost=Cost([FramePosition("tip", target=[1.0, 2.0], weight=1.0)])
        ),
        "cost_state_weight_shape": lambda: P(
            PENDULUM, cost=Cost([StateCost(np.zeros(1), weight_qpos=[1.0, 2.0, 3.0])])
        ),
        "cost_state_ref_shape": lambda: P(
            PENDULUM, cost=Cost([StateCost(np.zeros(3), weight_qpos=1.0)])
        ),
        "cost_negative_weight": lambda: P(PENDULUM, cost=Cost([ControlCost(weight=-1.0)])),
        "cost_nan_weight": lambda: P(PENDULUM, cost=Cost([ControlCost(weight=NAN)])),
        "cost_ctrl_ref_shape": lambda: P(
            PENDULUM, cost=Cost([ControlCost(np.zeros(4), weight=1.0)])
        ),
        "cost_terms_not_terms": lambda: Cost(["state"]),
        "cost_empty": lambda: P(PENDULUM, cost=Cost([])),
    }
    for name, fn in costs.items():
        check(record, name, fn, expect_error=True)


def controller_cases(check, record):
    import mpcbox

    p = _problem()
    mk = mpcbox.make_controller
    sampling = dict(backend="cpu", num_samples=16, horizon=0.1)
    cases = {
        "make_unknown_name": lambda: mk("lqrr", p),
        "make_name_int": lambda: mk(3, p),
        "make_not_problem": lambda: mk("lqr", "pendulum"),
        "make_unknown_option": lambda: mk("lqr", p, gain=3),
        "lqr_Q_wrong_shape": lambda: mpcbox.LQR(p, Q=np.eye(3)),
        "lqr_R_negative": lambda: mpcbox.LQR(p, R=-np.eye(1)),
        "lqr_R_nan": lambda: mpcbox.LQR(p, R=np.array([[NAN]])),
        "lqr_period_zero": lambda: mk("lqr", p, period=0.0),
        "lqr_period_negative": lambda: mk("lqr", p, period=-0.01),
        "lqr_period_not_multiple": lambda: mk("lqr", p, period=0.015),
        "lqr_state_wrong_shape": lambda: mk("lqr", p, state=np.zeros(5)),
        "lqr_ctrl_nan": lambda: mk("lqr", p, ctrl=np.array([NAN])),
        "lqr_config_wrong_type": lambda: mpcbox.LQR(p, mpcbox.ILQRConfig()),
        "ilqr_horizon_zero": lambda: mk("ilqr", p, horizon=0),
        "ilqr_horizon_negative": lambda: mk("ilqr", p, horizon=-3),
        "ilqr_horizon_float": lambda: mk("ilqr", p, horizon=2.5),
        "ilqr_max_iterations_zero": lambda: mk("ilqr", p, max_iterations=0),
        "ilqr_step_sizes_empty": lambda: mk("ilqr", p, step_sizes=()),
        "ilqr_step_sizes_negative": lambda: mk("ilqr", p, step_sizes=(1.0, -0.5)),
        "ilqr_replan_period_zero": lambda: mk("ilqr", p, replan_period=0.0),
        "ilqr_replan_period_not_multiple": lambda: mk("ilqr", p, replan_period=0.015),
        "ilqr_regularization_negative": lambda: mk("ilqr", p, regularization=-1.0),
        "ilqr_ctrls_init_shape": lambda: mk("ilqr", p, horizon=5, ctrls_init=np.zeros((3, 2))),
        "ilqr_ctrls_init_nan": lambda: mk("ilqr", p, horizon=2, ctrls_init=np.full((2, 1), NAN)),
        "ilqr_ctrl_low_shape": lambda: mk("ilqr", p, ctrl_low=np.zeros(3)),
        "ilqr_ctrl_low_above_high": lambda: mk("ilqr", p, ctrl_low=[1.0], ctrl_high=[-1.0]),
        "ilqr_planning_timestep_not_multiple": lambda: mk("ilqr", p, planning_timestep=0.015),
        "ilqr_planning_timestep_negative": lambda: mk("ilqr", p, planning_timestep=-0.01),
        "ilqr_tolerance_nan": lambda: mk("ilqr", p, tolerance=NAN),
        "ilqr_line_search_unknown": lambda: mk("ilqr", p, line_search="wolfe"),
        "ilqr_linearize_every_zero": lambda: mk("ilqr", p, linearize_every=0),
        "ilqr_threads_zero": lambda: mk("ilqr", p, threads=0),
        "ilqr_terminal_value_unknown": lambda: mk("ilqr", p, terminal_value="dp"),
        "qp_horizon_zero": lambda: mk("qp", p, horizon=0, contacts=()),
        "qp_dt_zero": lambda: mk("qp", p, dt=0.0, contacts=()),
        "qp_dt_not_multiple": lambda: mk("qp", p, dt=0.015, contacts=()),
        "qp_contacts_unknown": lambda: mk("qp", p, contacts=["nope"]),
        "qp_friction_negative": lambda: mk("qp", p, friction=-0.5),
        "qp_facets_zero": lambda: mk("qp", p, facets=0),
        "qp_solver_unknown": lambda: mk("qp", p, solver="gurobi"),
        "qp_osqp_settings_unknown": lambda: mk("qp", p, osqp_settings={"bogus": 1}),
        "qp_terminal_shape": lambda: mk("qp", p, terminal=np.eye(3)),
        "qp_period_negative": lambda: mk("qp", p, period=-1.0),
        "qp_time_limit_zero": lambda: mk("qp", p, time_limit=0.0),
    }
    for ctrl in ("ps", "mppi", "cem"):
        cases.update(
            {
                f"{ctrl}_num_samples_zero": lambda c=ctrl: mk(
                    c, p, **{**sampling, "num_samples": 0}
                ),
                f"{ctrl}_num_samples_float": lambda c=ctrl: mk(
                    c, p, **{**sampling, "num_samples": 8.5}
                ),
                f"{ctrl}_horizon_zero": lambda c=ctrl: mk(c, p, **{**sampling, "horizon": 0.0}),
                f"{ctrl}_horizon_below_dt": lambda c=ctrl: mk(
                    c, p, **{**sampling, "horizon": 0.001}
                ),
                f"{ctrl}_horizon_nan": lambda c=ctrl: mk(c, p, **{**sampling, "horizon": NAN}),
                f"{ctrl}_num_knots_zero": lambda c=ctrl: mk(c, p, **sampling, num_knots=0),
                f"{ctrl}_backend_unknown": lambda c=ctrl: mk(
                    c, p, **{**sampling, "backend": "tpu"}
                ),
                f"{ctrl}_noise_negative": lambda c=ctrl: mk(c, p, **sampling, noise_scale=-1.0),
            }
        )
    cases["mppi_temperature_zero"] = lambda: mk("mppi", p, **sampling, temperature=0.0)
    cases["cem_elites_zero"] = lambda: mk("cem", p, **sampling, num_elites=0)
    cases["cem_elites_above_samples"] = lambda: mk("cem", p, **sampling, num_elites=64)
    for name, fn in cases.items():
        check(record, name, fn, expect_error=True)


def simulate_cases(check, record):
    import mpcbox

    p = _problem()
    lqr = mpcbox.LQR(p)
    ball = mpcbox.Problem(BALL)
    sim = mpcbox.simulate
    Push, Noise, Mismatch = mpcbox.Push, mpcbox.ActuatorNoise, mpcbox.ModelMismatch
    cases = {
        "duration_zero": lambda: sim(p, lqr, 0.0),
        "duration_negative": lambda: sim(p, lqr, -1.0),
        "duration_nan": lambda: sim(p, lqr, NAN),
        "duration_inf": lambda: sim(p, lqr, np.inf),
        "duration_string": lambda: sim(p, lqr, "1"),
        "duration_below_timestep": lambda: sim(p, lqr, 0.001),
        "problem_not_problem": lambda: sim("pendulum", lqr, 0.1),
        "controller_not_controller": lambda: sim(p, "lqr", 0.1),
        "controller_other_problem": lambda: sim(p, mpcbox.LQR(mpcbox.Problem(PENDULUM2)), 0.1),
        "noise_string": lambda: sim(p, lqr, 0.1, noise="0.1"),
        "noise_std_negative": lambda: sim(p, lqr, 0.1, noise=Noise(std=-1.0)),
        "noise_std_nan": lambda: sim(p, lqr, 0.1, noise=Noise(std=NAN)),
        "noise_std_wrong_shape": lambda: sim(p, lqr, 0.1, noise=Noise(std=[0.1, 0.2, 0.3])),
        "noise_width_zero": lambda: sim(p, lqr, 0.1, noise=Noise(std=0.1, width=0.0)),
        "noise_width_negative": lambda: sim(p, lqr, 0.1, noise=Noise(std=0.1, width=-1.0)),
        "push_body_unknown": lambda: sim(p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), body="x")]),
        "push_force_wrong_shape": lambda: sim(
            p, lqr, 0.1, pushes=[Push(force=(1, 0), body="pole")]
        ),
        "push_force_nan": lambda: sim(p, lqr, 0.1, pushes=[Push(force=(NAN, 0, 0), body="pole")]),
        "push_start_negative": lambda: sim(
            p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), start=-1.0, body="pole")]
        ),
        "push_duration_zero": lambda: sim(
            p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), duration=0.0, body="pole")]
        ),
        "push_duration_negative": lambda: sim(
            p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), duration=-0.1, body="pole")]
        ),
        "push_not_push": lambda: sim(p, lqr, 0.1, pushes=[(1.0, 0.0, 0.0)]),
        "pushes_single_push": lambda: sim(p, lqr, 0.1, pushes=Push(force=(1, 0, 0), body="pole")),
        "push_torque_shape": lambda: sim(
            p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), torque=(1, 2), body="pole")]
        ),
        "mismatch_mass_negative": lambda: sim(p, lqr, 0.1, mismatch=Mismatch(mass_scale=-1.0)),
        "mismatch_mass_zero": lambda: sim(p, lqr, 0.1, mismatch=Mismatch(mass_scale=0.0)),
        "mismatch_friction_nan": lambda: sim(p, lqr, 0.1, mismatch=Mismatch(friction_scale=NAN)),
        "mismatch_body_unknown": lambda: sim(
            p, lqr, 0.1, mismatch=Mismatch(body_mass_scale={"nope": 1.1})
        ),
        "mismatch_not_mismatch": lambda: sim(p, lqr, 0.1, mismatch=1.1),
        "seed_string": lambda: sim(p, lqr, 0.1, seed="a"),
        "seed_negative": lambda: sim(p, lqr, 0.1, seed=-1),
        "seed_float": lambda: sim(p, lqr, 0.1, seed=1.5),
        "initial_state_wrong_shape": lambda: sim(p, lqr, 0.1, initial_state=np.zeros(5)),
        "initial_state_nan": lambda: sim(p, lqr, 0.1, initial_state=np.array([NAN, 0.0])),
        "initial_state_zero_quaternion": lambda: sim(
            ball, mpcbox.LQR(ball), 0.1, initial_state=np.zeros(ball.nstate)
        ),
        "lqr_state_zero_quaternion": lambda: mpcbox.LQR(ball, state=np.zeros(ball.nstate)).K,
        "qpos_ref_zero_quaternion": lambda: mpcbox.Problem(BALL, qpos_ref=np.zeros(4)),
        "degraded_limit_negative": lambda: sim(p, lqr, 0.1, degraded_limit=-1.0),
        "viewer_unknown": lambda: sim(p, lqr, 0.1, viewer="vr-headset"),
        "compare_unknown_controller": lambda: mpcbox.compare(
            p, ["lqr", "nope"], mpcbox.Scenario(duration=0.1), seeds=1, progress=False
        ),
        "compare_seeds_zero": lambda: mpcbox.compare(
            p, ["lqr"], mpcbox.Scenario(duration=0.1), seeds=0, progress=False
        ),
        "compare_seeds_negative": lambda: mpcbox.compare(
            p, ["lqr"], mpcbox.Scenario(duration=0.1), seeds=-2, progress=False
        ),
        "compare_workers_negative": lambda: mpcbox.compare(
            p,
            ["lqr"],
            mpcbox.Scenario(duration=0.1, noise_scale=0),
            seeds=1,
            workers=-1,
            progress=False,
        ),
        "push_body_int": lambda: sim(p, lqr, 0.1, pushes=[Push(force=(1, 0, 0), body=1)]),
        "mismatch_body_scale_negative": lambda: sim(
            p, lqr, 0.1, mismatch=Mismatch(body_mass_scale={"pole": -1.0})
        ),
        "mismatch_body_scale_nan": lambda: sim(
            p, lqr, 0.1, mismatch=Mismatch(body_mass_scale={"pole": NAN})
        ),
        "noise_std_list_nan": lambda: sim(p, lqr, 0.1, noise=Noise(std=[NAN])),
        "noise_scale_negative": lambda: sim(p, lqr, 0.1, noise=Noise(std=0.1, scale=-2.0)),
        "stop_on_failure_string": lambda: sim(p, lqr, 0.1, stop_on_failure="no"),
        "compare_seeds_list_negative": lambda: mpcbox.compare(
            p, ["lqr"], mpcbox.Scenario(duration=0.1, noise_scale=0), seeds=[-1], progress=False
        ),
        "compare_seeds_float": lambda: mpcbox.compare(
            p, ["lqr"], mpcbox.Scenario(duration=0.1, noise_scale=0), seeds=1.5, progress=False
        ),
        "compare_seeds_duplicate": lambda: mpcbox.compare(
            p, ["lqr"], mpcbox.Scenario(duration=0.1, noise_scale=0), seeds=[0, 0], progress=False
        ),
        "compare_controllers_empty": lambda: mpcbox.compare(
            p, [], mpcbox.Scenario(duration=0.1, noise_scale=0), seeds=1, progress=False
        ),
        "compare_executor_unknown": lambda: mpcbox.compare(
            p,
            ["lqr"],
            mpcbox.Scenario(duration=0.1, noise_scale=0),
            seeds=1,
            executor="mpi",
            progress=False,
        ),
        "scenario_pushes_list": lambda: mpcbox.Scenario(pushes=[Push(force=(1, 0, 0))]),
        "scenario_duration_negative": lambda: mpcbox.Scenario(duration=-1.0),
        "scenario_noise_scale_negative": lambda: mpcbox.Scenario(noise_scale=-1.0),
        "scenario_speed_zero": lambda: mpcbox.Scenario(speed=0.0),
        "compare_unknown_task": lambda: mpcbox.compare("nope_task", ["lqr"], progress=False),
        "compare_scenario_not_scenario": lambda: mpcbox.compare(p, ["lqr"], 3, progress=False),
    }
    for name, fn in cases.items():
        check(record, name, fn, expect_error=True)


BALL = """
<mujoco>
  <worldbody>
    <body name="pend" pos="0 0 1">
      <joint name="ball" type="ball"/>
      <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.03" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="ball" gear="1 0 0"/><motor joint="ball" gear="0 1 0"/>
    <motor joint="ball" gear="0 0 1"/>
  </actuator>
</mujoco>
"""
PENDULUM2 = PENDULUM.replace(
    '<joint name="hinge" type="hinge" axis="0 1 0"/>',
    '<joint name="hinge" type="hinge" axis="0 1 0"/><joint name="h2" type="slide"/>',
)


def task_cases(check, record):
    from mpcbox.registry import task_class

    menagerie = os.environ.get("MENAGERIE_ROOT")
    from mpcbox.tasks.swingup import Swingup
    from mpcbox.tasks.swingup.dm_control import suite_path

    cart = suite_path("cartpole")
    cases = {
        "task_class_unknown": lambda: task_class("humanoid_balancee"),
        "swingup_joint_unknown": lambda: Swingup(cart, joints={"nope": 0.0}),
        "swingup_joint_slider": lambda: Swingup(cart, joints={"slider": 0.0}),
        "swingup_joints_string": lambda: Swingup(cart, joints="hinge_1"),
        "swingup_site_unknown": lambda: Swingup(cart, sites={"nope": 1.0}),
        "swingup_joint_target_string": lambda: Swingup(cart, joints={"hinge_1": "up"}),
        "swingup_site_target_string": lambda: Swingup(cart, sites={"pole_1": "high"}),
        "swingup_initial_unknown": lambda: Swingup(cart, joints=["hinge_1"], initial="sideways"),
        "swingup_initial_wrong_shape": lambda: Swingup(
            cart, joints=["hinge_1"], initial=np.zeros(3)
        ),
        "swingup_tolerance_negative": lambda: Swingup(cart, joints=["hinge_1"], tolerance=-0.1),
        "swingup_hold_nan": lambda: Swingup(cart, joints=["hinge_1"], hold=NAN),
        "swingup_no_target": lambda: Swingup(cart),
        "swingup_keyframe_unknown": lambda: Swingup(cart, joints=["hinge_1"], keyframe="up"),
        "humanoid_balance_leg_unknown": lambda: task_class("humanoid_balance")(leg="middle"),
        "pendulum_swingup_unknown_option": lambda: task_class("pendulum_swingup")(bogus=1),
    }
    if menagerie:
        from mpcbox.tasks.legged.balance import LeggedBalance
        from mpcbox.tasks.reach import ArmReach

        go1, panda = "menagerie:unitree_go1", "menagerie:franka_emika_panda"
        feet = ["FR", "FL", "RR", "RL"]
        cases.update(
            {
                "legged_feet_unknown": lambda: LeggedBalance(go1, feet=["FR", "nope"]),
                "legged_feet_empty": lambda: LeggedBalance(go1, feet=[]),
                "legged_feet_string": lambda: LeggedBalance(go1, feet="FR"),
                "legged_root_unknown": lambda: LeggedBalance(go1, feet=feet, root="nope"),
                "legged_keyframe_unknown": lambda: LeggedBalance(go1, feet=feet, keyframe="nope"),
                "legged_keyframe_index": lambda: LeggedBalance(go1, feet=feet, keyframe=7),
                "legged_support_unknown": lambda: LeggedBalance(go1, feet=feet, support="knees"),
                "legged_fall_fraction_zero": lambda: LeggedBalance(go1, feet=feet, fall_fraction=0),
                "legged_balance_cost_nan": lambda: LeggedBalance(go1, feet=feet, balance_cost=NAN),
                "legged_joint_cost_shape": lambda: LeggedBalance(
                    go1, feet=feet, joint_cost=np.ones(3)
                ),
                "legged_contacts_unknown": lambda: LeggedBalance(
                    go1, feet=feet, contacts=["geom:nope"]
                ),
                "legged_no_floor_robot": lambda: LeggedBalance(panda, feet=["hand"]),
                "quadruped_stand_unknown_robot": lambda: task_class("quadruped_stand")(
                    model="menagerie:unitree_go9"
                ),
                "quadruped_stand_arm": lambda: task_class("quadruped_stand")(model=panda),
                "reach_frame_unknown": lambda: ArmReach(panda, frame="nope", target=[0.1, 0, 0]),
                "reach_target_shape": lambda: ArmReach(panda, frame="hand", target=[0.1, 0.0]),
                "reach_target_nan": lambda: ArmReach(panda, frame="hand", target=[NAN, 0, 0]),
                "reach_orientation_zero": lambda: ArmReach(
                    panda, frame="hand", target=[0.5, 0, 0.5], orientation=[0, 0, 0, 0]
                ),
                "reach_keyframe_unknown": lambda: ArmReach(
                    panda, frame="hand", target=[0.5, 0, 0.5], keyframe="nope"
                ),
                "reach_start_qpos_shape": lambda: ArmReach(
                    panda, frame="hand", target=[0.5, 0, 0.5], start_qpos=np.zeros(3)
                ),
                "reach_tolerance_zero": lambda: ArmReach(
                    panda, frame="hand", target=[0.5, 0, 0.5], tolerance=0.0
                ),
                "reach_free_objects_unknown": lambda: ArmReach(
                    panda, frame="hand", target=[0.5, 0, 0.5], free_objects="glue"
                ),
                "reach_unreachable": lambda: ArmReach(panda, frame="hand", target=[5.0, 0, 0]),
                "arm_track_unknown_robot": lambda: task_class("arm_track")(model="menagerie:nope"),
                "biped_stance_unknown": lambda: task_class("biped_stand")(stance="middle"),
            }
        )
    for name, fn in cases.items():
        check(record, name, fn, expect_error=True)


def cli_cases(check, record):
    """CLI runs: a bad argument must exit 2 with one ``error:`` line, no traceback."""
    import dm_control.suite

    cart = os.path.join(os.path.dirname(dm_control.suite.__file__), "cartpole.xml")
    commands = {
        "list": (["list"], True),
        # compare takes task names only (a model path goes to `mpcbox validate`): a refusal.
        "compare_model_path": (["compare", cart, "--seeds", "1", "--duration", "0.1"], False),
        "compare_task_model_bad": (["compare", "quadruped_stand", "--model", cart], False),
        "compare_unknown_task": (["compare", "nope_task"], False),
        "compare_seeds_zero": (["compare", "pendulum_swingup", "--seeds", "0"], False),
        "compare_duration_negative": (["compare", "pendulum_swingup", "--duration", "-1"], False),
        "compare_duration_nan": (["compare", "pendulum_swingup", "--duration", "nan"], False),
        "compare_controllers_unknown": (
            ["compare", "pendulum_swingup", "--controllers", "x"],
            False,
        ),
        "compare_set_unknown": (["compare", "pendulum_swingup", "--set", "ilqr.bogus=1"], False),
        "compare_set_malformed": (["compare", "pendulum_swingup", "--set", "ilqr"], False),
        "compare_set_bad_value": (
            ["compare", "pendulum_swingup", "--set", "ilqr.horizon=-3", "--seeds", "1"],
            False,
        ),
        "compare_noise_bad": (["compare", "humanoid_balance", "--noise", "a,b"], False),
        "compare_noise_negative": (["compare", "humanoid_balance", "--noise", "-1"], False),
        "compare_push_body_unknown": (
            ["compare", "pendulum_swingup", "--push", "3", "--push-body", "nope", "--seeds", "1"],
            False,
        ),
        "compare_mass_scale_zero": (
            ["compare", "pendulum_swingup", "--mass-scale", "0", "--seeds", "1"],
            False,
        ),
        "compare_workers_negative": (["compare", "pendulum_swingup", "--workers", "-3"], False),
        "compare_task_option_bad": (["compare", "humanoid_balance", "--leg", "middle"], False),
        "simulate_unknown_controller": (
            ["simulate", "pendulum_swingup", "--controller", "x"],
            False,
        ),
        "replay_missing_file": (["replay", "/nonexistent.csv"], False),
        "validate_missing_file": (["validate", "/nonexistent.xml"], False),
    }
    out_dir = os.path.join(os.environ.get("TMPDIR", "/tmp"), "model_sweep_cli")
    outcome: dict = {}
    for name, (argv, should_pass) in commands.items():

        def run(argv=argv, should_pass=should_pass, name=name):
            cmd = [sys.executable, "-c", "import sys, mpcbox.cli; sys.exit(mpcbox.cli.main())"]
            if argv[0] == "compare":
                cmd += [*argv[:2], "--out", out_dir, "--no-plots", "--no-progress"]
                cmd += ["--workers", "1", *argv[2:]]
            else:
                cmd += argv
            # Run outside the checkout so that PYTHONPATH picks the mpcbox under test.
            proc = subprocess.run(
                cmd, capture_output=True, text=True, timeout=180, cwd=tempfile.gettempdir()
            )
            text = proc.stderr + proc.stdout
            if "Traceback" in text:
                raise RuntimeError(f"rc {proc.returncode}, traceback: {text[-600:]}")
            if should_pass and proc.returncode != 0:
                raise RuntimeError(f"rc {proc.returncode}: {text[-600:]}")
            outcome[name] = (proc.returncode, text[-300:])

        check(record, name, run, expect_error=False)
        value = record[name]
        if name in outcome and not should_pass:
            rc, text = outcome[name]
            value["status"] = "accepted" if rc == 0 else "mpcbox_error"
            value["message"] = f"rc {rc}: {text.strip()[-200:]}"


def bad_inputs(check, group: str) -> dict:
    record: dict = {}
    {
        "problem": problem_cases,
        "controllers": controller_cases,
        "simulate": simulate_cases,
        "tasks": task_cases,
        "cli": cli_cases,
    }[group](check, record)
    return record
