"""The get-up's task stages: the get-up planner until the robot is up, a standing
controller while it stays up
(:meth:`mpcbox.tasks.humanoid.getup.HumanoidGetup.handover_controller`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from mpcbox.controllers.handover import HandOver
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.registry import controller_class, make_controller
from mpcbox.validation import one_of

#: Where the standing stage plans (``stand_on``).
STAND_ON = ("stand", "getup")


def getup_handover(
    task: Any,
    name: str,
    *,
    stand: str | None,
    transfer: bool,
    stand_options: dict[str, Any] | None,
    stand_task: dict[str, Any] | None,
    stand_on: str,
    **overrides: Any,
) -> HandOver:
    """:meth:`~mpcbox.tasks.humanoid.getup.HumanoidGetup.handover_controller` of ``task``
    (a ``HumanoidGetup``, not imported here: that module imports this one; see there for
    the arguments and errors)."""
    stand_on = one_of("stand_on", stand_on, STAND_ON)
    for label, value in (("stand_options", stand_options), ("stand_task", stand_task)):
        if value is not None and not isinstance(value, Mapping):
            raise InvalidTypeError(f"{label} must be a dict of options, got {type(value).__name__}")
    if stand_on == "getup" and stand_task:
        raise InvalidArgumentError(
            "stand_task sets the standing problem's options; with stand_on='getup' the "
            "standing stage plans on this task, so leave stand_task out"
        )
    getup = make_controller(name, task, **overrides)
    stand_name = name if stand is None else stand
    fields = _config_fields(controller_class(stand_name))
    options = {k: overrides[k] for k in ("backend", "device", "seed") if k in overrides}
    options = {k: v for k, v in options.items() if k in fields}
    if "period" in fields:
        options["period"] = getup.period
    if "feedback" in fields:  # iLQR-MPC: replan at the get-up period
        if (stand_options or {}).get("feedback", True):
            raise InvalidArgumentError(
                f"stand={stand_name!r} applies its feedback law at every simulation step, "
                f"which a hand-over with a planner of period {getup.period:g} s cannot "
                "interleave; pass stand_options={'feedback': False} to replan at that "
                "period and hold each plan's control in between"
            )
        options["replan_period"] = getup.period
    keeper = make_controller(
        stand_name,
        task if stand_on == "getup" else task.stand_problem(**(stand_task or {})),
        **{**options, **(stand_options or {})},
    )
    return HandOver(
        getup,
        keeper,
        engage=task.is_up,
        release=task.is_down,
        transfer=transfer,
        name=f"{name}+{stand_name}",
    )


def _config_fields(cls: type) -> set[str]:
    """Option names of a controller class's config dataclass (empty without one)."""
    config = getattr(cls, "config_class", None)
    return {f.name for f in dataclasses.fields(config)} if config is not None else set()
