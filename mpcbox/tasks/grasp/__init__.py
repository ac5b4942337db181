"""A parallel-jaw gripper holding objects by contact forces: scene, objects, trials.

* :mod:`.objects`: hard, soft and irregular objects, friction levels, random draws;
* :mod:`.scene`: the gripper scene built with :class:`mujoco.MjSpec`;
* :mod:`.trial`: one trial (close, lift, push, shake) and its success check;
* :mod:`.trials`: randomized trials of the force-QP grasp against the position grasp.
"""

from mpcbox.tasks.grasp.objects import FRICTION_LEVELS, KINDS, GraspObject, sample_object
from mpcbox.tasks.grasp.scene import GraspScene, GripperConfig, build_scene, contact_solref
from mpcbox.tasks.grasp.trial import TrialConfig, TrialResult, run_trial, wrist_plan
from mpcbox.tasks.grasp.trials import (
    TrialDraw,
    TrialRecord,
    draw_trial,
    run_trials,
    success_table,
)

__all__ = [
    "FRICTION_LEVELS",
    "KINDS",
    "GraspObject",
    "GraspScene",
    "GripperConfig",
    "TrialConfig",
    "TrialDraw",
    "TrialRecord",
    "TrialResult",
    "build_scene",
    "contact_solref",
    "draw_trial",
    "run_trial",
    "run_trials",
    "sample_object",
    "success_table",
    "wrist_plan",
]
