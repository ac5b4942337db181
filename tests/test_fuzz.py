"""Seeded fuzz of the public API with bad input.

Every call below passes valid arguments except one, which gets a value drawn (seeded) from
the bad values of its kind: wrong types, NaN and infinities, negative or zero numbers, wrong
shapes, unknown names and options, empty sequences. Each call must, within
:data:`CALL_LIMIT_S` seconds, raise an :class:`mpcbox.MpcboxError` whose message names the
argument; a wrong type must also raise a :class:`TypeError`. A call that returns is a bad
input accepted silently.

``python tests/test_fuzz.py`` prints the statistics (calls, share of named errors).
"""

from __future__ import annotations

import re
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

import mpcbox
from mpcbox.comparison.executors import RayExecutor
from mpcbox.comparison.push_limits import largest_push, push_grid, survival
from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.controllers.sampling.config import Randomization
from mpcbox.core.cost import (
    ComOverSupport,
    ControlCost,
    Cost,
    FrameHeight,
    FramePosition,
    QuadraticValue,
    StateCost,
    Upright,
    WrappedAngle,
)
from mpcbox.core.equilibrium import find_equilibrium
from mpcbox.core.posture import stance_posture
from mpcbox.registry import controller_class, make_controller, task_class
from mpcbox.sim.trajectory import replay, trajectory_from_result
from mpcbox.sim.trajectory_files import load_trajectory
from mpcbox.tasks import scene_path
from mpcbox.tasks.legged.balance import LeggedBalance

SEED = 20261122
#: Longest a single bad call may take before it counts as a hang (s).
CALL_LIMIT_S = 10.0
PENDULUM = str(scene_path("pendulum.xml"))
HUMANOID = str(scene_path("humanoid.xml"))
NAN, INF = float("nan"), float("inf")


# ---------------------------------------------------------------------- bad values
class Bad:
    """One bad value; ``type_error``: it has the wrong type (the error must be a TypeError)."""

    def __init__(self, value: Any, type_error: bool = False, label: str = "") -> None:
        self.value = value
        self.type_error = type_error
        self.label = label or _short(value)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) < 40 else text[:37] + "..."


def _magnitude(rng: np.random.Generator) -> float:
    return float(10.0 ** rng.uniform(-3, 3))


def _number_types(optional: bool) -> list[Bad]:
    out = [Bad("fast", True), Bad([1.0, 2.0], True), Bad({"x": 1}, True)]
    return out if optional else [*out, Bad(None, True)]


def positive(rng, optional=False) -> list[Bad]:
    return [
        Bad(0.0),
        Bad(-_magnitude(rng)),
        Bad(NAN),
        Bad(INF),
        Bad(-INF),
        *_number_types(optional),
    ]


def nonneg(rng, optional=False) -> list[Bad]:
    return [Bad(-_magnitude(rng)), Bad(NAN), Bad(INF), *_number_types(optional)]


def finite(rng, optional=False) -> list[Bad]:
    return [Bad(NAN), Bad(INF), Bad(-INF), *_number_types(optional)]


def unit(rng, optional=False) -> list[Bad]:
    """A fraction in [0, 1) or (0, 1] (both ends of the open side are tested by callers)."""
    return [Bad(-_magnitude(rng)), Bad(1.0 + _magnitude(rng)), Bad(NAN), *_number_types(optional)]


def integer(rng, optional=False, minimum=1) -> list[Bad]:
    out = [
        Bad(minimum - 1 - int(rng.integers(0, 50))),
        Bad(1.5, True),
        Bad("3", True),
        Bad(NAN, True),
        Bad(True, True),
    ]
    return out if optional else [*out, Bad(None, True)]


def boolean(rng, optional=False) -> list[Bad]:
    out = [Bad("yes", True), Bad(2.5, True), Bad([True], True)]
    return out if optional else [*out, Bad(None, True)]


def choice(rng, optional=False) -> list[Bad]:
    out = [Bad(f"bogus_{rng.integers(1000)}"), Bad(7, True), Bad(1.5, True)]
    return out if optional else [*out, Bad(None, True)]


def name(rng, optional=False) -> list[Bad]:
    out = [Bad(f"no_such_{rng.integers(1000)}"), Bad(3.5, True), Bad(["tip"], True)]
    return out if optional else [*out, Bad(None, True)]


def text(rng, optional=False) -> list[Bad]:
    out = [Bad(42, True), Bad(["a"], True)]
    return out if optional else [*out, Bad(None, True)]


def array(shape: tuple[int, ...], optional=False, limit: float | None = None, inf=True):
    """Bad arrays for an expected ``shape``: wrong shapes, NaN/inf at a random place
    (``inf=False``: infinities are valid, e.g. no bound)."""

    def make(rng) -> list[Bad]:
        good = rng.uniform(-0.1, 0.1, shape)
        out = []
        wrong = list(shape) if shape else [1]
        wrong[int(rng.integers(len(wrong)))] += int(rng.integers(1, 4))
        out.append(Bad(np.zeros(wrong), label=f"shape {tuple(wrong)}"))
        out.append(Bad(np.zeros((*shape, 2)), label=f"shape {(*shape, 2)}"))
        for bad in (NAN, INF) if inf else (NAN,):
            arr = good.copy()
            arr.flat[int(rng.integers(arr.size))] = bad
            out.append(Bad(arr, label=f"{bad} inside"))
        if limit is not None:
            arr = good.copy()
            arr.flat[int(rng.integers(arr.size))] = limit * 10.0 ** rng.uniform(0.5, 3)
            out.append(Bad(arr, label="beyond limit"))
        out += [Bad("abc", True), Bad({"a": 1}, True), Bad(object(), True)]
        return out if optional else [*out, Bad(None, True)]

    return make


def nonempty_sequence(item: Callable) -> Callable:
    def make(rng) -> list[Bad]:
        return [Bad([]), Bad(42, True), *(Bad([b.value], b.type_error) for b in item(rng)[:3])]

    return make


def instance(optional=False) -> Callable:
    def make(rng) -> list[Bad]:
        out = [Bad(42, True), Bad("something", True), Bad(object(), True)]
        return out if optional else [*out, Bad(None, True)]

    return make


def mapping(rng, optional=True) -> list[Bad]:
    out = [Bad(42, True), Bad("key=value", True), Bad([("a", 1)], True)]
    return out if optional else [*out, Bad(None, True)]


def opt(kind: Callable, **kw) -> Callable:
    """The same kind with ``None`` allowed."""
    return lambda rng: kind(rng, optional=True, **kw)


def also(kind: Callable, *extra: Bad) -> Callable:
    return lambda rng: [*kind(rng), *extra]


def only(*values: Bad) -> Callable:
    return lambda rng: list(values)


# ---------------------------------------------------------------------- targets
@dataclass
class Target:
    """A public callable, valid keyword arguments, and how each can go wrong.

    Attributes:
        name: Label.
        call: ``call(ctx, **kwargs)``.
        valid: ``valid(ctx) -> dict`` of valid keyword arguments.
        args: Argument name -> bad-value kind (``kind(rng) -> list[Bad]``).
        labels: Argument name -> the word the message must contain (default: the name).
        options: Whether an unknown keyword option must be refused (listing valid ones).
        pending: Why some of its calls are known to fail still (the test is then an expected
            failure, strict: it reports when they are fixed); empty when none.
    """

    name: str
    call: Callable[..., Any]
    valid: Callable[[Any], dict[str, Any]]
    args: dict[str, Callable]
    labels: dict[str, str] = field(default_factory=dict)
    options: bool = False
    pending: str = ""


class Context:
    """The Problems and controllers the calls share, built once per module."""

    def __init__(self) -> None:
        self.pendulum = mpcbox.Problem(PENDULUM)
        self.lqr = mpcbox.LQR(self.pendulum)
        self.x0 = self.pendulum.reference_state()
        self.u0 = np.zeros(1)
        self.humanoid_model = mpcbox.Problem(HUMANOID, keyframe="stand").model
        run = mpcbox.simulate(self.pendulum, self.lqr, 0.03)
        self.trajectory = trajectory_from_result(run, self.pendulum)


def problem_type(optional=False) -> Callable:
    return lambda rng: [Bad(42, True), Bad("pendulum.xml", True), Bad(None, True)]


def controller_type(rng) -> list[Bad]:
    return [Bad(42, True), Bad("lqr", True), Bad(None, True)]


def sweep_problem_type(rng) -> list[Bad]:
    """The evaluation sweeps also take a task name (to rebuild it in workers)."""
    return [Bad(42, True), Bad("pendulum.xml"), Bad(None, True)]


def sweep_controller_type(rng) -> list[Bad]:
    """The evaluation sweeps also take a controller name."""
    return [Bad(42, True), Bad("no_such_controller"), Bad(None, True)]


def term_problem(term_factory: Callable) -> Callable:
    """A call that builds a cost term and a pendulum Problem that uses it."""

    def call(ctx, **kw):
        return mpcbox.Problem(PENDULUM, cost=Cost([term_factory(**kw)]))

    return call


def pendulum_method(method: str) -> Callable:
    return lambda ctx, **kw: getattr(ctx.pendulum, method)(**kw)


STATE = array((2,))
CTRL = array((1,), limit=1e10)
MODEL = only(
    Bad("/no/such/model.xml"),
    Bad("<mujoco><worldbody><bogus/></worldbody></mujoco>"),
    Bad(42, True),
    Bad(None, True),
    Bad(3.5, True),
)
#: Weights: a scalar or one per residual (a list of another length is a shape error).
WEIGHT = only(
    Bad(-2.5),
    Bad(NAN),
    Bad(INF),
    Bad(np.array([1.0, -1.0, 1.0]), label="negative entry"),
    Bad(np.ones(7), label="shape (7,)"),
    Bad("fast", True),
    Bad({"x": 1}, True),
    Bad(None, True),
)
#: A scalar, or an array of a given size (a list of another length is a shape error).
SCALE = only(Bad(-0.3), Bad(NAN), Bad(np.array([0.1, 0.2]), label="shape (2,)"), Bad("fast", True))

#: A task's model: None is its own scene.
TASK_MODEL = lambda rng: [b for b in MODEL(rng) if b.value is not None]  # noqa: E731
SAMPLING = {
    "num_samples": integer,
    "horizon": also(positive, Bad(1e-4, label="below one step")),
    "num_knots": integer,
    "interpolation": choice,
    "noise_scale": SCALE,
    "iterations": integer,
    "shift": choice,
    "terminal_value": opt(choice),
    "planning_timestep": opt(positive),
    "planning_integrator": opt(choice),
    "planning_disable": only(Bad(["bogus_flag"]), Bad(42, True), Bad([3], True)),
    "solver_iterations": opt(integer),
    "solver_tolerance": opt(positive),
    "period": opt(positive),
    "replan_period": opt(positive),
    "backend": choice,
    "device": opt(text),
    "seed": lambda rng: integer(rng, minimum=0),
    "randomization": instance(optional=True),
    "risk": choice,
    "cvar_alpha": also(unit, Bad(0.0)),
    "headroom": positive,
    "use_graph": boolean,
}
ILQR_ARGS = {
    "horizon": integer,
    "max_iterations": integer,
    "tolerance": positive,
    "mpc_iterations": integer,
    "first_iterations": opt(integer),
    "replan_period": positive,
    "feedback": boolean,
    "regularization": nonneg,
    "regularization_min": positive,
    "regularization_max": positive,
    "regularization_factor": also(positive, Bad(0.5)),
    "step_sizes": only(Bad([]), Bad([1.5]), Bad([NAN]), Bad(["a"], True), Bad(42, True)),
    "line_search": choice,
    "armijo": also(unit, Bad(1.0)),
    "max_retries": integer,
    "linearize_every": integer,
    "fd_centered": opt(boolean),
    "ctrl_low": also(array((1,), optional=True, inf=False), Bad(np.array([5.0]), label="above")),
    "ctrl_high": also(array((1,), optional=True, inf=False), Bad(np.array([-5.0]), label="below")),
    "ctrls_init": array((5, 1), optional=True),
    "threads": opt(integer),
    "planning_timestep": opt(positive),
    "terminal_value": opt(choice),
    "linearization": choice,
}
PUSH_ARGS = {
    "force": array((3,), limit=1e8),
    "start": nonneg,
    "duration": positive,
    "body": text,
    "torque": array((3,), limit=1e8),
}
TARGETS: list[Target] = [
    # ------------------------------------------------------------------ Problem
    Target(
        "Problem",
        lambda ctx, **kw: mpcbox.Problem(**kw),
        lambda ctx: {"model": PENDULUM},
        {
            "model": MODEL,
            "keyframe": opt(name),
            "qpos_ref": array((1,), optional=True),
            "ctrl_ref": array((1,), optional=True),
            "planning_timestep": opt(positive),
            "fd_eps": positive,
            "fd_centered": boolean,
            "threads": opt(integer),
            "name": opt(text),
            "cost": instance(optional=True),
        },
        options=True,
    ),
    Target(
        "Problem.step",
        pendulum_method("step"),
        lambda ctx: {"state": ctx.x0, "ctrl": ctx.u0},
        {"state": STATE, "ctrl": CTRL},
    ),
    Target(
        "Problem.linearize",
        pendulum_method("linearize"),
        lambda ctx: {"state": ctx.x0, "ctrl": ctx.u0},
        {
            "state": STATE,
            "ctrl": also(CTRL, Bad(np.array([50.0]), label="outside ctrlrange")),
            "eps": opt(positive),
            "centered": opt(boolean),
        },
    ),
    Target(
        "Problem.linearize_trajectory",
        pendulum_method("linearize_trajectory"),
        lambda ctx: {"states": np.tile(ctx.x0, (3, 1)), "ctrls": np.zeros((3, 1))},
        {
            "states": array((3, 2)),
            "ctrls": also(array((3, 1), limit=1e10), Bad(np.zeros((0, 1)), label="empty")),
            "threads": opt(integer),
        },
    ),
    Target(
        "Problem.rollout",
        pendulum_method("rollout"),
        lambda ctx: {"state": ctx.x0, "ctrls": np.zeros((4, 1))},
        {
            "state": STATE,
            "ctrls": also(array((4, 1), limit=1e10), Bad(np.zeros((0, 1)), label="empty")),
        },
    ),
    Target(
        "Problem.quadratize",
        pendulum_method("quadratize"),
        lambda ctx: {"state": ctx.x0, "ctrl": ctx.u0},
        {"state": STATE, "ctrl": CTRL, "terminal": boolean},
    ),
    Target(
        "Problem.with_planning_timestep",
        pendulum_method("with_planning_timestep"),
        lambda ctx: {"timestep": 0.02},
        {"timestep": positive},
    ),
    Target(
        # Batches (..., nstate) are valid, and NaN propagates (diverged rollouts hold NaN).
        "Problem.state_difference",
        pendulum_method("state_difference"),
        lambda ctx: {"state": ctx.x0, "state_ref": ctx.x0},
        {
            "state": only(
                Bad(np.zeros(3)), Bad(np.zeros((4, 1))), Bad("ab", True), Bad(None, True)
            ),
            "state_ref": only(Bad(np.zeros(5)), Bad(np.zeros((3, 2))), Bad({"a": 1}, True)),
        },
    ),
    # ------------------------------------------------------------------ controllers
    Target(
        "LQR",
        lambda ctx, **kw: mpcbox.LQR(**kw),
        lambda ctx: {"problem": ctx.pendulum},
        {
            "problem": problem_type(),
            "config": instance(optional=True),
            "Q": array((2, 2), optional=True),
            "R": array((1, 1), optional=True),
            "state": array((2,), optional=True),
            "ctrl": also(array((1,), optional=True), Bad(np.array([100.0]), label="outside")),
            "eps": opt(positive),
            "centered": opt(boolean),
        },
        options=True,
    ),
    Target(
        "ILQR",
        lambda ctx, **kw: mpcbox.ILQR(**kw),
        lambda ctx: {"problem": ctx.pendulum, "horizon": 5, "max_iterations": 2},
        {"problem": problem_type(), "config": instance(optional=True), **ILQR_ARGS},
        options=True,
    ),
    Target(
        "QPMPCConfig",
        lambda ctx, **kw: mpcbox.QPMPCConfig(**kw),
        lambda ctx: {},
        {
            "horizon": integer,
            "dt": positive,
            "contacts": only(Bad(42, True), Bad([3], True)),
            "friction": positive,
            "facets": also(integer, Bad(5, label="odd")),
            "f_max": opt(positive),
            "relinearize": boolean,
            "solver": choice,
            "force_weight": positive,
            "terminal": only(
                Bad("bogus"), Bad(None, True), Bad(np.array([[NAN]]), label="NaN matrix")
            ),
            "terminal_scale": positive,
            "drift_gain": unit,
            "stance_weight": opt(positive),
            "contact_margin": positive,
            "joint_limits": boolean,
            "cost_gradient": boolean,
            "warm_start": boolean,
            "period": opt(positive),
            "fd_centered": boolean,
            "substeps": opt(integer),
            "stance_model": choice,
            "osqp_settings": also(mapping, Bad({"bogus_setting": 1})),
            "export_dir": only(Bad(42, True), Bad(["a"], True)),
            "fallback": choice,
        },
        options=True,
    ),
    Target(
        "QPMPC",
        lambda ctx, **kw: mpcbox.QPMPC(**kw),
        lambda ctx: {"problem": ctx.pendulum},
        {"problem": problem_type(), "config": instance(optional=True)},
        options=True,
    ),
    Target(
        "IpoptConfig",
        lambda ctx, **kw: mpcbox.IpoptConfig(**kw),
        lambda ctx: {},
        {
            "horizon": integer,
            "warm_start_ilqr": boolean,
            "ilqr_options": also(mapping, Bad({"bogus_option": 1})),
            "regularization": positive,
            "planning_timestep": opt(positive),
            "max_iterations": integer,
            "tolerance": positive,
            "lbfgs_history": integer,
            "print_level": lambda rng: integer(rng, minimum=0),
            "nlpsol_options": mapping,
        },
        options=True,
    ),
    *(
        Target(
            cls,
            (lambda c: lambda ctx, **kw: getattr(mpcbox, c)(**kw))(cls),
            (
                lambda e: (
                    lambda ctx: {"problem": ctx.pendulum, "num_samples": 4, "horizon": 0.05, **e}
                )
            )({"num_elites": 2} if cls == "CEM" else {}),
            {"problem": problem_type(), "config": instance(optional=True), **SAMPLING, **extra},
            options=True,
        )
        for cls, extra in (
            ("PredictiveSampling", {}),
            ("MPPI", {"temperature": positive}),
            (
                "CEM",
                {
                    "num_elites": also(integer, Bad(999, label="above num_samples")),
                    "std_min": nonneg,
                    "smoothing": also(unit, Bad(1.0)),
                },
            ),
        )
    ),
    Target(
        "Randomization",
        lambda ctx, **kw: mpcbox.MPPI(
            ctx.pendulum, num_samples=4, randomization=Randomization(**kw)
        ),
        lambda ctx: {},
        {
            "num_models": integer,
            "mass_scale": only(Bad((0.0, 1.0)), Bad((1.2, 1.1)), Bad((NAN, 1.0)), Bad("ab", True)),
            "friction_scale": only(Bad((-1.0, 1.0)), Bad((1.0, INF)), Bad("ab", True)),
            "seed": lambda rng: integer(rng, minimum=0),
        },
        options=True,
    ),
    Target(
        "make_controller",
        lambda ctx, **kw: make_controller(**kw),
        lambda ctx: {"name": "lqr", "problem": ctx.pendulum},
        {"name": choice, "problem": problem_type()},
        labels={"name": "controller"},
        options=True,
    ),
    Target(
        "controller_class",
        lambda ctx, **kw: controller_class(**kw),
        lambda ctx: {"name": "lqr"},
        {"name": choice},
        labels={"name": "controller"},
    ),
    Target(
        "task_class",
        lambda ctx, **kw: task_class(**kw),
        lambda ctx: {"name": "pendulum_swingup"},
        {"name": choice},
        labels={"name": "task"},
    ),
    # ------------------------------------------------------------------ tasks
    *(
        Target(
            f"task {task}",
            (lambda t: lambda ctx, **kw: task_class(t)(**kw))(task),
            lambda ctx: {},
            {
                "keyframe": opt(name),
                "fd_eps": positive,
                "threads": opt(integer),
                "planning_timestep": opt(positive),
                **extra,
            },
            options=True,
        )
        for task, extra in (
            ("pendulum_swingup", {"qpos_ref": array((1,), optional=True)}),
            ("cartpole_swingup", {"qpos_ref": array((2,), optional=True)}),
            (
                "humanoid_balance",
                {
                    "leg": choice,
                    "model": TASK_MODEL,
                    **{
                        f"{w}_cost": nonneg
                        for w in ("balance", "balance_joint", "other_joint", "velocity", "ctrl")
                    },
                    "fall_height": finite,
                },
            ),
            (
                "humanoid_stand",
                {
                    "model": TASK_MODEL,
                    **{
                        f"{w}_cost": nonneg
                        for w in ("height", "upright", "posture", "root", "velocity", "ctrl")
                    },
                    "balance_cost": nonneg,
                    "terminal_scale": nonneg,
                    "fall_height": finite,
                },
            ),
            (
                "humanoid_two_feet",
                {
                    "model": TASK_MODEL,
                    **{
                        f"{w}_cost": nonneg
                        for w in ("balance", "balance_joint", "other_joint", "velocity", "ctrl")
                    },
                    "fall_height": finite,
                },
            ),
        )
    ),
    Target(
        "LeggedBalance",
        lambda ctx, **kw: LeggedBalance(**kw),
        lambda ctx: {"model": HUMANOID, "feet": ("foot_left", "foot_right"), "threads": 1},
        {
            "model": TASK_MODEL,
            "feet": only(
                Bad("no_such_foot"),
                Bad(["foot_left", "tip"]),
                Bad(()),
                Bad(("foot_left", "foot_left")),
                Bad(3.5, True),
                Bad([3], True),
                Bad(None, True),
            ),
            "root": opt(name),
            "keyframe": opt(name),
            "fall_height": opt(finite),
            "fall_fraction": positive,
            "fall_tilt": opt(positive),
            "support": choice,
            "balance_cost": nonneg,
            "velocity_cost": nonneg,
            "joint_cost": WEIGHT,
            "ctrl_cost": WEIGHT,
            "ctrl_units": choice,
            "recovery_tilt": opt(positive),
        },
        options=True,
    ),
    # ------------------------------------------------------------------ cost terms
    Target(
        "StateCost",
        term_problem(StateCost),
        lambda ctx: {"qpos_ref": np.zeros(1), "weight_qpos": 1.0},
        {
            "qpos_ref": array((1,)),
            "qvel_ref": array((1,), optional=True),
            "weight_qpos": WEIGHT,
            "weight_qvel": WEIGHT,
            "name": text,
        },
        options=True,
    ),
    Target(
        "ControlCost",
        term_problem(ControlCost),
        lambda ctx: {"weight": 1.0},
        {"ctrl_ref": array((1,), optional=True), "weight": WEIGHT, "name": text},
        options=True,
    ),
    Target(
        "FramePosition",
        term_problem(FramePosition),
        lambda ctx: {"frame": "tip", "target": np.zeros(3), "weight": 1.0},
        {"frame": name, "target": array((3,)), "weight": WEIGHT, "name": opt(text)},
        options=True,
    ),
    Target(
        "FrameHeight",
        term_problem(FrameHeight),
        lambda ctx: {"frame": "tip", "target": 0.5, "weight": 1.0},
        {"frame": name, "target": finite, "weight": WEIGHT, "name": opt(text)},
        options=True,
    ),
    Target(
        "Upright",
        term_problem(Upright),
        lambda ctx: {"body": "pole", "weight": 1.0},
        {"body": name, "weight": WEIGHT, "name": opt(text)},
        options=True,
    ),
    Target(
        "ComOverSupport",
        term_problem(ComOverSupport),
        lambda ctx: {"support": "tip", "weight": 1.0},
        {"support": name, "weight": WEIGHT, "root": opt(name), "name": opt(text)},
        options=True,
    ),
    Target(
        "WrappedAngle",
        term_problem(WrappedAngle),
        lambda ctx: {"joint": "hinge", "target": 3.0, "weight": 1.0},
        {"joint": name, "target": finite, "weight": WEIGHT, "name": opt(text)},
        options=True,
    ),
    Target(
        "QuadraticValue",
        term_problem(QuadraticValue),
        lambda ctx: {"qpos_ref": np.zeros(1), "P": np.eye(2)},
        {
            "qpos_ref": array((1,)),
            "qvel_ref": array((1,), optional=True),
            "P": also(array((2, 2)), Bad(-np.eye(2), label="negative definite")),
            "name": text,
        },
        options=True,
    ),
    Target(
        "Cost",
        lambda ctx, **kw: Cost(**kw),
        lambda ctx: {"running": [ControlCost(weight=1.0)]},
        {
            "running": only(Bad([]), Bad([42], True), Bad(42, True), Bad(None, True)),
            "terminal": only(Bad([42], True), Bad(42, True), Bad("ab", True)),
        },
        options=True,
    ),
    # ------------------------------------------------------------------ disturbances
    Target(
        "Push",
        lambda ctx, **kw: mpcbox.Push(**kw),
        lambda ctx: {"force": np.array([10.0, 0.0, 0.0]), "body": "pole"},
        PUSH_ARGS,
        options=True,
    ),
    Target(
        "ActuatorNoise",
        lambda ctx, **kw: mpcbox.ActuatorNoise(**kw),
        lambda ctx: {"std": 0.1},
        {
            "std": only(
                Bad(-0.1),
                Bad(NAN),
                Bad(np.array([0.1, NAN]), label="NaN inside"),
                Bad(np.array([0.1, -0.2]), label="negative inside"),
                Bad(np.zeros((2, 2)), label="shape (2, 2)"),
                Bad("fast", True),
                Bad(None, True),
            ),
            "width": positive,
            "scale": nonneg,
        },
        options=True,
    ),
    Target(
        "ModelMismatch",
        lambda ctx, **kw: mpcbox.ModelMismatch(**kw),
        lambda ctx: {},
        {
            "mass_scale": positive,
            "friction_scale": positive,
            "body_mass_scale": also(mapping, Bad({"pole": -1.0}), Bad({"pole": NAN})),
        },
        labels={},
        options=True,
    ),
    Target(
        "ActuatorNoise.sample",
        lambda ctx, **kw: mpcbox.ActuatorNoise(std=0.1).sample(**kw),
        lambda ctx: {"steps": 10, "nu": 1, "dt": 0.01, "seed": 0},
        {
            "steps": integer,
            "nu": integer,
            "dt": positive,
            "seed": lambda rng: integer(rng, minimum=0),
        },
    ),
    # ------------------------------------------------------------------ comparison
    Target(
        "simulate",
        lambda ctx, **kw: mpcbox.simulate(**kw),
        lambda ctx: {
            "problem": ctx.pendulum,
            "controller": ctx.lqr,
            "duration": 0.03,
            "noise": mpcbox.ActuatorNoise(std=0.01),
        },
        {
            "problem": problem_type(),
            "controller": controller_type,
            "duration": positive,
            "noise": instance(optional=True),
            "pushes": only(Bad([42], True), Bad(42, True), Bad([mpcbox.Push(force=[1, 0, 0])])),
            "mismatch": instance(optional=True),
            "seed": lambda rng: integer(rng, minimum=0),
            "initial_state": array((2,), optional=True),
            "stop_on_failure": boolean,
            "degraded_limit": unit,
        },
        options=True,
    ),
    Target(
        "Scenario",
        lambda ctx, **kw: Scenario(**kw),
        lambda ctx: {},
        {
            "name": text,
            "duration": positive,
            "noise_scale": nonneg,
            "noise": instance(optional=True),
            "pushes": only(Bad([42], True), Bad(42, True)),
            "mismatch": instance(optional=True),
        },
        options=True,
    ),
    Target(
        "PushTest",
        lambda ctx, **kw: PushTest(**kw),
        lambda ctx: {},
        {
            "direction": also(array((3,)), Bad((0.0, 0.0, 0.0), label="zero")),
            "duration": positive,
            "start": nonneg,
            "settle": positive,
            "body": text,
            "max_force": also(positive, Bad(1e300, label="huge")),
            "tolerance": positive,
            "noise_scale": nonneg,
            "name": text,
        },
        options=True,
    ),
    Target(
        "largest_push",
        lambda ctx, **kw: largest_push(**kw),
        lambda ctx: {
            "problem": ctx.pendulum,
            "controller": ctx.lqr,
            "test": PushTest(body="pole", settle=0.05, start=0.01, duration=0.01),
        },
        {
            "problem": sweep_problem_type,
            "controller": sweep_controller_type,
            "test": instance(),
            "seed": lambda rng: integer(rng, minimum=0),
        },
        options=True,
    ),
    Target(
        "push_grid",
        lambda ctx, **kw: push_grid(**kw),
        lambda ctx: {
            "problem": ctx.pendulum,
            "controller": ctx.lqr,
            "forces": [1.0],
            "test": PushTest(body="pole", settle=0.05, start=0.01, duration=0.01),
        },
        {
            "problem": sweep_problem_type,
            "controller": sweep_controller_type,
            "forces": only(Bad([]), Bad([NAN]), Bad([-1.0]), Bad([1e300]), Bad("ab", True)),
            "test": instance(),
            "seed": lambda rng: integer(rng, minimum=0),
        },
        options=True,
    ),
    Target(
        "survival",
        lambda ctx, **kw: survival(**kw),
        lambda ctx: {
            "problem": ctx.pendulum,
            "controller": ctx.lqr,
            "seeds": [0],
            "duration": 0.02,
        },
        {
            "problem": sweep_problem_type,
            "controller": sweep_controller_type,
            "seeds": only(Bad([]), Bad([-1]), Bad(["a"], True), Bad(1.5, True), Bad([0.5], True)),
            "duration": positive,
        },
        options=True,
    ),
    Target(
        "compare",
        lambda ctx, **kw: mpcbox.compare(**kw),
        lambda ctx: {
            "problem": "pendulum_swingup",
            "controllers": ["lqr"],
            "scenarios": Scenario(duration=0.02, noise_scale=0.0),
            "seeds": 1,
            "workers": 1,
            "progress": False,
        },
        {
            "problem": only(Bad("no_such_task"), Bad(42, True), Bad(None, True)),
            "controllers": only(Bad(["nope"]), Bad([]), Bad(42, True), Bad([3.5], True)),
            "scenarios": only(Bad([]), Bad(42, True), Bad([42], True)),
            "seeds": only(Bad(0), Bad(-3), Bad([]), Bad([-1]), Bad(1.5, True), Bad("a", True)),
            "push_tests": only(Bad(42, True), Bad([42], True)),
            "problem_options": only(Bad({"bogus_option": 1}), Bad(42, True)),
            "controller_options": only(
                Bad({"nope": {}}), Bad({"lqr": {"bogus_option": 1}}), Bad(42, True)
            ),
            "workers": opt(integer),
            "executor": opt(choice),
            "checkpoint": only(Bad(42, True), Bad(["a"], True)),
            "progress": boolean,
        },
        labels={"problem": "task"},
        options=True,
    ),
    Target(
        "RayExecutor",
        lambda ctx, **kw: RayExecutor(**kw),
        lambda ctx: {},
        {
            "address": opt(text),
            "workers": opt(integer),
            "cpus_per_run": positive,
            "gpus_per_run": opt(nonneg),
            "max_restarts": lambda rng: integer(rng, minimum=0),
            "max_task_retries": lambda rng: integer(rng, minimum=0),
        },
        options=True,
    ),
    Target(
        "load_trajectory",
        lambda ctx, **kw: load_trajectory(**kw),
        lambda ctx: {},
        {"path": only(Bad("/no/such/run"), Bad(42, True), Bad(None, True))},
        options=True,
    ),
    Target(
        "replay",
        lambda ctx, **kw: replay(**kw),
        lambda ctx: {"traj": ctx.trajectory, "problem": ctx.pendulum},
        {"traj": instance(), "problem": problem_type()},
        options=True,
    ),
    # ------------------------------------------------------------------ core functions
    Target(
        "find_equilibrium",
        lambda ctx, **kw: find_equilibrium(**kw),
        lambda ctx: {"model": ctx.pendulum.model, "qpos": np.zeros(1)},
        {
            "model": only(Bad(42, True), Bad("pendulum", True), Bad(None, True)),
            "qpos": array((1,)),
            "tolerance": positive,
            "search_range": positive,
            "feasibility_tolerance": positive,
            "on_infeasible": choice,
        },
        options=True,
    ),
    Target(
        "Problem.find_equilibrium",
        lambda ctx, **kw: ctx.pendulum.find_equilibrium(**kw),
        lambda ctx: {},
        {"qpos": array((1,), optional=True), "tolerance": positive, "on_infeasible": choice},
        options=True,
    ),
    Target(
        "stance_posture",
        lambda ctx, **kw: stance_posture(**kw),
        lambda ctx: {
            "model": ctx.humanoid_model,
            "qpos_init": ctx.humanoid_model.key_qpos[0],
            "stance": "foot_left",
            "swing": "foot_right",
            "iterations": 2,
        },
        {
            "model": only(Bad(42, True), Bad(None, True)),
            "qpos_init": array((28,)),
            "stance": name,
            "swing": name,
            "lift": finite,
            "com_body": also(opt(name), Bad(-1), Bad(10_000), Bad(True, True)),
            "upright_body": opt(name),
            "keep_upright": boolean,
            "iterations": integer,
            "tolerance": positive,
            "solver": choice,
            "on_collision": choice,
        },
        options=True,
    ),
]


# ---------------------------------------------------------------------- running a call
class CallTimeout(BaseException):
    """A call ran past :data:`CALL_LIMIT_S` (BaseException: no library handler catches it)."""


@dataclass
class Case:
    target: Target
    arg: str | None  # None: an unknown keyword option
    bad: Bad

    @property
    def id(self) -> str:
        what = "unknown option" if self.arg is None else f"{self.arg}={self.bad.label}"
        return f"{self.target.name}({what})"


def cases(seed: int = SEED) -> Iterator[Case]:
    """Every (target, argument, bad value), the bad values drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    for target in TARGETS:
        for arg, kind in target.args.items():
            for bad in kind(rng):
                yield Case(target, arg, bad)
        if target.options:
            option = f"bogus_option_{rng.integers(1000)}"
            yield Case(target, None, Bad({option: 1}, True, label=option))


def _on_alarm(signum, frame):
    raise CallTimeout


def run(case: Case, ctx: Context) -> str | None:
    """Make the call; ``None`` when it failed as it must, else what went wrong."""
    kwargs = dict(case.target.valid(ctx))
    if case.arg is None:
        kwargs.update(case.bad.value)
        label = next(iter(case.bad.value))
    else:
        kwargs[case.arg] = case.bad.value
        label = case.target.labels.get(case.arg, case.arg)
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, CALL_LIMIT_S)
    start = time.perf_counter()
    try:
        case.target.call(ctx, **kwargs)
    except CallTimeout:
        return f"no answer within {CALL_LIMIT_S} s"
    except mpcbox.MpcboxError as exc:
        message = str(exc)
        if not re.search(rf"(?<![A-Za-z0-9_]){re.escape(label)}(?![A-Za-z0-9_])", message):
            return f"{type(exc).__name__} does not name {label!r}: {message}"
        if case.bad.type_error and not isinstance(exc, TypeError):
            return f"{type(exc).__name__} for a wrong type is not a TypeError: {message}"
        return None
    except Exception as exc:
        return f"{type(exc).__name__} (not an MpcboxError): {exc}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    return f"accepted silently ({time.perf_counter() - start:.2f} s)"


# ---------------------------------------------------------------------- tests
@pytest.fixture(scope="module")
def ctx() -> Context:
    return Context()


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(
    "target",
    [
        pytest.param(t, marks=pytest.mark.xfail(strict=True, reason=t.pending) if t.pending else ())
        for t in TARGETS
    ],
    ids=[t.name for t in TARGETS],
)
def test_every_bad_call_raises_a_named_mpcbox_error(target, ctx):
    failures = []
    for case in cases():
        if case.target is target:
            problem = run(case, ctx)
            if problem is not None:
                failures.append(f"{case.id}: {problem}")
    assert not failures, "\n".join(failures)


def test_the_fuzz_is_large_and_covers_each_kind_of_bad_input():
    all_cases = list(cases())
    assert len(all_cases) >= 500
    assert sum(c.bad.type_error for c in all_cases) >= 150
    assert sum(c.arg is None for c in all_cases) >= 30
    # The draw depends on the seed: another seed gives other values.
    other = [c.bad.label for c in cases(SEED + 1)]
    assert other != [c.bad.label for c in all_cases]


if __name__ == "__main__":
    import collections
    import warnings

    warnings.simplefilter("ignore")
    context, counts, start = Context(), collections.Counter(), time.perf_counter()
    lines = []
    import sys

    prefixes = tuple(sys.argv[1:]) or ("",)
    for one in cases():
        if not one.target.name.startswith(prefixes):
            continue
        outcome = run(one, context)
        kind = "named" if outcome is None else outcome.split(":")[0].split(" (")[0]
        counts["named" if outcome is None else "failed"] += 1
        counts[kind] += outcome is not None
        if outcome is not None:
            lines.append(f"{one.id}: {outcome[:200]}")
    total = counts["named"] + counts["failed"]
    print("\n".join(lines))
    print(f"{total} calls in {time.perf_counter() - start:.1f} s")
    print(f"named MpcboxError: {counts['named']} ({100 * counts['named'] / total:.1f}%)")
    for kind, n in counts.most_common():
        if kind not in ("named", "failed"):
            print(f"  {kind}: {n}")
