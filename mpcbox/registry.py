"""Names of the controllers and tasks that the command line and :func:`mpcbox.compare` know.

Entries are ``"module:attribute"`` strings imported on first use, so listing names never
imports optional dependencies (CasADi, MJWarp).
"""

from __future__ import annotations

import importlib
from typing import Any

from mpcbox.errors import UnknownNameError

#: Controller name -> class. Each class is built as ``cls(problem, **options)``, with options
#: taken from the task's ``controller_options``.
CONTROLLERS: dict[str, str] = {
    "lqr": "mpcbox.lqr:LQR",
    "ilqr": "mpcbox.ilqr:ILQR",
    "ipopt": "mpcbox.ipopt_reference:IpoptController",
    "qp": "mpcbox.qp_mpc:QPMPC",
    "ps": "mpcbox.sampling:PredictiveSampling",
    "mppi": "mpcbox.sampling:MPPI",
    "cem": "mpcbox.sampling:CEM",
}

#: Task name -> Problem subclass with a no-argument constructor.
TASKS: dict[str, str] = {
    "humanoid_balance": "mpcbox.tasks.humanoid_balance:HumanoidBalance",
    "pendulum_swingup": "mpcbox.tasks.swingup:PendulumSwingup",
    "cartpole_swingup": "mpcbox.tasks.swingup:CartpoleSwingup",
    "humanoid_stand": "mpcbox.tasks.humanoid_stand:HumanoidStand",
    "humanoid_two_feet": "mpcbox.tasks.humanoid_two_feet:HumanoidTwoFeet",
}


def resolve(entry: str) -> Any:
    """Import ``"module:attribute"``."""
    module, attr = entry.split(":")
    return getattr(importlib.import_module(module), attr)


def controller_class(name: str) -> type:
    """The controller class registered under ``name``."""
    if name not in CONTROLLERS:
        raise UnknownNameError("controller", name, CONTROLLERS)
    return resolve(CONTROLLERS[name])


def task_class(name: str) -> type:
    """The Problem subclass registered under ``name``."""
    if name not in TASKS:
        raise UnknownNameError("task", name, TASKS)
    return resolve(TASKS[name])


def make_controller(name: str, problem: Any, **overrides: Any):
    """Build controller ``name`` for ``problem`` with the task's tuned options.

    Args:
        name: A key of :data:`CONTROLLERS`.
        problem: The Problem; its ``controller_options`` (if any) supply keyword arguments.
        **overrides: Keyword arguments that replace the task's options.
    """
    cls = controller_class(name)
    options = dict(getattr(problem, "controller_options", {}).get(name, {}))
    options.update(overrides)
    controller = cls(problem, **options)
    controller.name = name
    return controller


def available_controllers(problem: Any) -> list[str]:
    """Controllers tuned for ``problem`` (keys of its ``controller_options``) that import here.

    A controller whose optional dependency is missing (CasADi, MJWarp) is left out.
    """
    names = []
    for name in CONTROLLERS:
        if name not in getattr(problem, "controller_options", {}):
            continue
        try:
            controller_class(name)
        except ImportError:
            continue
        names.append(name)
    return names
