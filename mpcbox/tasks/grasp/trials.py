r"""Randomized grasp trials: the force-QP grasp against the position grasp, per friction level.

Each trial draws an object (:func:`~mpcbox.tasks.grasp.objects.sample_object`: kind, shape,
size, mass, friction, stiffness), the force grasp's mass estimate (the true mass times a
factor drawn uniformly in :math:`1 \pm` ``mass_error``) and the push direction (uniform on
the sphere). Both controllers then run the same trial
(:func:`~mpcbox.tasks.grasp.trial.run_trial`):

* ``"force"``: :class:`~mpcbox.controllers.grasp.controller.ForceGrasp` with the friction
  prior at the middle of the level's range (it does not know the drawn value) and the mass
  estimate;
* ``"position"``: :class:`~mpcbox.controllers.grasp.controller.PositionGrasp` with both
  fingers commanded fully closed (pads meeting at the centre), so its squeeze is the servo
  gain times the object's half width (10-15 N with the default 500 N/m).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from mpcbox.controllers.grasp.config import ForceGraspConfig
from mpcbox.controllers.grasp.controller import ForceGrasp, PositionGrasp
from mpcbox.tasks.grasp.objects import FRICTION_LEVELS, KINDS, GraspObject, sample_object
from mpcbox.tasks.grasp.scene import FINGERS, OBJECT, PADS, GripperConfig, build_scene
from mpcbox.tasks.grasp.trial import TrialConfig, TrialResult, run_trial
from mpcbox.validation import in_range, one_of, positive_int

#: The controllers a trial compares.
CONTROLLERS: tuple[str, ...] = ("force", "position")


class TrialDraw(NamedTuple):
    """What one trial draws.

    Attributes:
        object: The object.
        mass_estimate: The force grasp's mass estimate (kg).
        push_direction: Unit direction of the push ``(3,)``.
    """

    object: GraspObject
    mass_estimate: float
    push_direction: np.ndarray


class TrialRecord(NamedTuple):
    """One controller's run of one trial.

    Attributes:
        level: Friction level.
        index: Trial number within the level.
        controller: ``"force"`` or ``"position"``.
        draw: What the trial drew.
        result: The outcome.
    """

    level: str
    index: int
    controller: str
    draw: TrialDraw
    result: TrialResult


def draw_trial(
    rng: np.random.Generator, level: str, kind: str | None = None, *, mass_error: float = 0.2
) -> TrialDraw:
    """Draw one trial of friction level ``level`` (see the module docstring).

    Raises:
        InvalidArgumentError: On an unknown level or kind, or ``mass_error`` outside [0, 1).
    """
    mass_error = in_range("mass_error", mass_error, 0.0, 1.0, low_open=False, high_open=True)
    obj = sample_object(rng, level, kind)
    estimate = obj.mass * float(rng.uniform(1.0 - mass_error, 1.0 + mass_error))
    direction = rng.normal(size=3)
    return TrialDraw(obj, estimate, direction / np.linalg.norm(direction))


def run_trials(
    level: str,
    trials: int,
    *,
    seed: int = 0,
    kinds: Sequence[str] | None = None,
    controllers: Sequence[str] = CONTROLLERS,
    gripper: GripperConfig | None = None,
    trial: TrialConfig | None = None,
    grasp: ForceGraspConfig | None = None,
    mass_error: float = 0.2,
) -> list[TrialRecord]:
    """Run ``trials`` randomized trials of friction level ``level`` with each controller.

    Trial ``i`` cycles through ``kinds`` (default all three), so each kind gets a third of
    the trials; its draws come from ``numpy.random.default_rng([seed, i, level index])``,
    so a trial is the same whatever else runs.

    Args:
        level: ``"low"``, ``"medium"`` or ``"high"``.
        trials: Number of trials (>= 1).
        seed: Seed of the draws.
        kinds: Object kinds to cycle through.
        controllers: Any of ``"force"`` and ``"position"``.
        gripper: The gripper's build.
        trial: The trial's timeline.
        grasp: Options of the force grasp (its ``friction`` is replaced by the level's
            middle).
        mass_error: Relative error bound of the mass estimate.

    Returns:
        One :class:`TrialRecord` per trial and controller.

    Raises:
        InvalidArgumentError: On an unknown level, kind or controller, or ``trials < 1``.
    """
    one_of("level", level, tuple(FRICTION_LEVELS))
    trials = positive_int("trials", trials)
    kinds = list(KINDS if kinds is None else kinds)
    for kind in kinds:
        one_of("kinds", kind, KINDS)
    for name in controllers:
        one_of("controllers", name, CONTROLLERS)
    gripper = gripper or GripperConfig()
    grasp = grasp or ForceGraspConfig()
    prior = float(np.mean(FRICTION_LEVELS[level]))
    level_index = list(FRICTION_LEVELS).index(level)
    records = []
    for i in range(trials):
        rng = np.random.default_rng([seed, i, level_index])
        draw = draw_trial(rng, level, kinds[i % len(kinds)], mass_error=mass_error)
        scene = build_scene(draw.object, gripper)
        for name in controllers:
            if name == "force":
                controller: ForceGrasp | PositionGrasp = ForceGrasp(
                    scene.model,
                    mass=draw.mass_estimate,
                    fingers=FINGERS,
                    pads=PADS,
                    target=OBJECT,
                    config=grasp,
                    friction=prior,
                )
            else:
                controller = PositionGrasp(scene.model, fingers=FINGERS, closed=gripper.opening)
            result = run_trial(scene, controller, push_direction=draw.push_direction, config=trial)
            records.append(TrialRecord(level, i, name, draw, result))
    return records


def success_table(records: Sequence[TrialRecord]) -> dict[str, dict[str, dict[str, float]]]:
    """Success rate, finger forces and slip by controller and object kind (and ``"all"``).

    Returns:
        ``table[controller][kind]`` with ``trials``, ``success_rate``, ``max_finger_force``
        (largest over the trials, N), ``median_max_finger_force`` (N), ``median_slip`` and
        ``max_slip`` (m), and ``adapted_rate`` (share of trials whose safety factor rose).
    """
    table: dict[str, dict[str, dict[str, float]]] = {}
    for name in dict.fromkeys(r.controller for r in records):
        mine = [r for r in records if r.controller == name]
        table[name] = {}
        for kind in [*dict.fromkeys(r.draw.object.kind for r in mine), "all"]:
            rows = [r.result for r in mine if kind == "all" or r.draw.object.kind == kind]
            forces = np.array([r.max_finger_force for r in rows])
            slips = np.array([r.slip for r in rows])
            table[name][kind] = {
                "trials": len(rows),
                "success_rate": float(np.mean([r.success for r in rows])),
                "max_finger_force": float(forces.max()),
                "median_max_finger_force": float(np.median(forces)),
                "median_slip": float(np.median(slips)),
                "max_slip": float(slips.max()),
                "adapted_rate": float(np.mean([r.adapted for r in rows])),
            }
    return table
