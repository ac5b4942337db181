"""Names of the controllers and tasks that the command line and :func:`mpcbox.compare` know.

Entries are ``"module:attribute"`` strings imported on first use, so listing names never
imports optional dependencies (CasADi, MJWarp).
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import Any

from mpcbox.errors import InvalidTypeError, UnknownNameError

#: Controller name -> class. Each class is built as ``cls(problem, config, **options)``, with
#: ``config`` taken from the task's ``controller_configs``.
CONTROLLERS: dict[str, str] = {
    "lqr": "mpcbox.controllers.lqr:LQR",
    "ilqr": "mpcbox.controllers.ilqr.controller:ILQR",
    "ipopt": "mpcbox.controllers.ipopt_controller:IpoptController",
    "qp": "mpcbox.controllers.qp_mpc.controller:QPMPC",
    "ps": "mpcbox.controllers.sampling:PredictiveSampling",
    "mppi": "mpcbox.controllers.sampling:MPPI",
    "cem": "mpcbox.controllers.sampling:CEM",
}

#: Task name -> Problem subclass with a no-argument constructor.
TASKS: dict[str, str] = {
    "humanoid_balance": "mpcbox.tasks.humanoid.balance:HumanoidBalance",
    "pendulum_swingup": "mpcbox.tasks.swingup:PendulumSwingup",
    "cartpole_swingup": "mpcbox.tasks.swingup:CartpoleSwingup",
    "acrobot_swingup": "mpcbox.tasks.swingup:AcrobotSwingup",
    "dm_cartpole_swingup": "mpcbox.tasks.swingup.dm_control:DmCartpoleSwingup",
    "dm_acrobot_swingup": "mpcbox.tasks.swingup.dm_control:DmAcrobotSwingup",
    "humanoid_stand": "mpcbox.tasks.humanoid.stand:HumanoidStand",
    "humanoid_getup": "mpcbox.tasks.humanoid.getup:HumanoidGetup",
    "g1_getup": "mpcbox.tasks.humanoid.g1_getup:G1Getup",
    "humanoid_two_feet": "mpcbox.tasks.humanoid.two_feet:HumanoidTwoFeet",
    "quadruped_stand": "mpcbox.tasks.legged.quadruped:QuadrupedStand",
    "quadruped_walk": "mpcbox.tasks.legged.walk:QuadrupedWalk",
    "biped_stand": "mpcbox.tasks.legged.biped:BipedStand",
    "arm_track": "mpcbox.tasks.arm.track:ArmTrack",
    "stack_cubes": "mpcbox.tasks.manipulation.stacking:StackCubes",
    "pot_lift": "mpcbox.tasks.manipulation.pot_lift:PotLift",
}


def resolve(entry: str) -> Any:
    """Import ``"module:attribute"``."""
    module, attr = entry.split(":")
    return getattr(importlib.import_module(module), attr)


def _check_name(kind: str, name: object) -> None:
    if not isinstance(name, str):
        raise InvalidTypeError(f"{kind} name must be a string, got {type(name).__name__} {name!r}")


def controller_class(name: str) -> type:
    """The controller class registered under ``name``."""
    _check_name("controller", name)
    if name not in CONTROLLERS:
        raise UnknownNameError("controller", name, CONTROLLERS)
    return resolve(CONTROLLERS[name])


def task_class(name: str) -> type:
    """The Problem subclass registered under ``name``."""
    _check_name("task", name)
    if name not in TASKS:
        raise UnknownNameError("task", name, TASKS)
    return resolve(TASKS[name])


def make_controller(name: str, problem: Any, *, config: Any = None, **overrides: Any):
    """Build controller ``name`` for ``problem`` with the task's tuned config.

    Args:
        name: A key of :data:`CONTROLLERS`.
        problem: The Problem; its ``controller_configs[name]`` (when present) is the config,
            otherwise the controller's documented defaults apply.
        config: A config of the controller's own class (e.g. an
            :class:`~mpcbox.controllers.ilqr.config.ILQRConfig` for ``"ilqr"``) used instead
            of the task's.
        **overrides: Options that replace fields of that config.

    Raises:
        UnknownNameError: If ``name`` is not registered (lists the registered names).
        InvalidTypeError: If ``config`` is not of the controller's config class.
        UnknownOptionError: If an override is not an option of the controller (lists them).
    """
    cls = controller_class(name)
    if not hasattr(problem, "controller_configs"):  # not a Problem (a lower layer than core)
        raise InvalidTypeError(f"problem must be an mpcbox.Problem, got {type(problem).__name__}")
    if config is None:
        config = problem.controller_configs.get(name)
    controller = cls(problem, config, **overrides)
    controller.name = name
    return controller


def available_controllers(problem: Any) -> list[str]:
    """Controllers tuned for ``problem`` (keys of its ``controller_configs``) that import here.

    A controller whose optional dependency is missing (CasADi, MJWarp) is left out.
    """
    names = []
    for name in CONTROLLERS:
        if name not in problem.controller_configs:
            continue
        try:
            cls = controller_class(name)
        except ImportError:
            continue
        if any(importlib.util.find_spec(module) is None for module in cls.requires):
            continue
        names.append(name)
    return names
