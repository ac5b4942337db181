"""The standard balance comparison of a legged robot: noise, noise with a push, largest push."""

from __future__ import annotations

from typing import NamedTuple

from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.disturbances import Push
from mpcbox.validation import non_negative, positive


class BalanceSuite(NamedTuple):
    """Scenarios and push tests of :func:`balance_suite`.

    Attributes:
        scenarios: ``"noise"`` and ``"noise + F N push"``, each ``duration`` seconds.
        push_tests: The largest forward push test, or empty.
        force: The push force ``F`` (N).
    """

    scenarios: list[Scenario]
    push_tests: list[PushTest]
    force: float


def balance_suite(
    problem: Problem,
    *,
    duration: float,
    weight_fraction: float,
    max_force_weights: float,
    force: float = 0.0,
    largest_push: bool = True,
    start: float = 1.0,
    push_duration: float = 0.1,
    settle: float = 2.0,
    tolerance: float = 5.0,
    rest_speed: float | None = None,
    scan_step: float | None = None,
) -> BalanceSuite:
    """Noise alone, noise with a forward push on the root body, and the largest such push.

    The push is ``force`` newtons along +x on the problem's root body, or, when ``force`` is
    0, ``weight_fraction`` times the robot's weight :math:`m g` (the root's subtree mass);
    the largest-push bisection searches up to ``max_force_weights`` times that weight.

    Args:
        problem: A legged Problem with a root body (``root`` and ``root_id``, as
            :class:`~mpcbox.tasks.legged.balance.LeggedBalance` has).
        duration: Seconds per scenario run.
        weight_fraction: Push force as a fraction of the weight when ``force`` is 0.
        max_force_weights: Upper end of the largest-push search, in weights.
        force: Push force (N); 0 derives it from ``weight_fraction``.
        largest_push: Whether to add the largest-push test.
        start: Push start (s).
        push_duration: How long the push acts (s).
        settle: Seconds that must be survived after a test push.
        tolerance: Bisection bracket (N).
        rest_speed: A test push counts as survived only when the root's centre of mass
            ends slower than this (m/s; :class:`~mpcbox.comparison.scenario.PushTest`);
            ``None``: staying up is enough.
        scan_step: Try this force and its multiples up to the first failure before
            bisecting (N; :class:`~mpcbox.comparison.scenario.PushTest`); ``None``:
            bisection alone.

    Raises:
        InvalidArgumentError: If ``problem`` has no root body, an option is out of range,
            or the push would start at or after the end of the run (``start >=
            duration``): its scenario would read as a push survived.
    """
    root = getattr(problem, "root", None)
    root_id = getattr(problem, "root_id", None)
    if not isinstance(root, str) or root_id is None:
        raise InvalidArgumentError(
            "problem must have a root body (attributes 'root' and 'root_id', as LeggedBalance "
            f"tasks have); got a {type(problem).__name__}"
        )
    duration = positive("duration", duration)
    if non_negative("start", start) >= duration:
        raise InvalidArgumentError(
            f"duration ({duration:g} s) must be longer than the push's start ({start:g} s): "
            "a push that never acts would read as survived"
        )
    weight = float(problem.model.body_subtreemass[root_id]) * 9.81
    force = non_negative("force", force) or round(
        positive("weight_fraction", weight_fraction) * weight
    )
    push = Push(force=(force, 0.0, 0.0), start=start, duration=push_duration, body=root)
    scenarios = [
        Scenario(name="noise", duration=duration),
        Scenario(name=f"noise + {force:g} N push", duration=duration, pushes=(push,)),
    ]
    tests = []
    if largest_push:
        tests.append(
            PushTest(
                body=root,
                start=start,
                duration=push_duration,
                settle=settle,
                tolerance=tolerance,
                max_force=positive("max_force_weights", max_force_weights) * weight,
                rest_speed=rest_speed,
                scan_step=scan_step,
            )
        )
    return BalanceSuite(scenarios, tests, float(force))


__all__ = ["BalanceSuite", "balance_suite"]
