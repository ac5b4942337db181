r"""One grasp trial: close, lift, a push and a shake, then the success check.

Timeline (:class:`TrialConfig`): the fingers close on the object resting on the table for
``close_time``; the wrist then lifts it by ``lift_height`` over ``lift_time`` along a
quintic (smooth) profile; during the hold that follows, a force of ``push`` times the
object's weight pushes it in a random direction for ``push_time``, and for the last
``shake_time`` the wrist shakes it vertically (amplitude ``shake_amplitude``, frequency
``shake_frequency``). The controller is called every ``control_period`` with the wrist's
planned acceleration (the object's, if it is held) and holds its controls in between.

**Success** (:func:`slip_of`): the object's position in the palm's frame moves by at most
``slip_tolerance`` from where it was when the lift began, over the whole lift and hold
(so it was lifted, and not dropped, squeezed out or dragged). The trial also reports the
largest finger force (the sum of a finger's measured normal contact forces), the largest
slip, and whether the force grasp's safety factor rose.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Protocol

import mujoco
import numpy as np

from mpcbox.controllers.grasp.contacts import finger_contacts
from mpcbox.controllers.grasp.controller import GraspCommand
from mpcbox.tasks.grasp.scene import FINGERS, LIFT, OBJECT, PADS, GraspScene
from mpcbox.validation import as_array, checked_options, non_negative, positive


class GraspController(Protocol):
    """What a trial needs of a grasp controller."""

    name: str

    def reset(self) -> None:
        """Start a new grasp."""

    def __call__(self, data: mujoco.MjData, accel: np.ndarray | None = None) -> GraspCommand:
        """The fingers' controls."""


@checked_options
@dataclass(frozen=True, kw_only=True)
class TrialConfig:
    """The timeline and the success tolerance of a trial (see the module docstring).

    Attributes:
        close_time: Time to close on the object before lifting (s).
        lift_time: Duration of the lift (s).
        lift_height: Lift (m).
        push: Push as a fraction of the object's weight.
        push_start: Start of the push after the lift ends (s).
        push_time: Duration of the push (s).
        shake_time: Duration of the shake at the end (s).
        shake_amplitude: Amplitude of the vertical shake (m).
        shake_frequency: Frequency of the shake (Hz).
        hold_time: Time from the end of the lift to the end of the trial (s).
        control_period: Time between controller calls (s).
        slip_tolerance: Largest displacement of the object in the palm's frame (m).
    """

    close_time: float = 0.25
    lift_time: float = 0.25
    lift_height: float = 0.05
    push: float = 0.5
    push_start: float = 0.05
    push_time: float = 0.15
    shake_time: float = 0.3
    shake_amplitude: float = 0.005
    shake_frequency: float = 4.0
    hold_time: float = 0.6
    control_period: float = 0.002
    slip_tolerance: float = 0.01

    def __post_init__(self) -> None:
        for name in (
            "close_time",
            "lift_time",
            "hold_time",
            "control_period",
            "slip_tolerance",
            "shake_frequency",
        ):
            positive(name, getattr(self, name))
        for name in (
            "lift_height",
            "push",
            "push_start",
            "push_time",
            "shake_time",
            "shake_amplitude",
        ):
            non_negative(name, getattr(self, name))

    @property
    def duration(self) -> float:
        """Length of the trial (s)."""
        return self.close_time + self.lift_time + self.hold_time


class TrialResult(NamedTuple):
    """Outcome of one trial.

    Attributes:
        success: Whether the object stayed within ``slip_tolerance`` in the palm's frame.
        slip: Largest displacement of the object in the palm's frame after the lift began
            (m).
        max_finger_force: Largest measured normal force of one finger after closing (N).
        mean_finger_force: Mean over the hold of the fingers' mean normal force (N).
        lifted: Height of the object above its start at the end (m).
        adapted: Whether the controller's safety factor rose above its start (force grasp).
        peak_safety: Largest safety factor (NaN for the position grasp).
    """

    success: bool
    slip: float
    max_finger_force: float
    mean_finger_force: float
    lifted: float
    adapted: bool
    peak_safety: float


def _quintic(s: float) -> tuple[float, float]:
    """Quintic 0 -> 1 ramp and its second derivative (per unit time squared) at ``s``."""
    s = min(max(s, 0.0), 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5, 60 * s - 180 * s**2 + 120 * s**3


def wrist_plan(t: float, config: TrialConfig) -> tuple[float, float]:
    """Wrist set-point (m) and planned vertical acceleration (m/s^2) at time ``t``."""
    c = config
    s = (t - c.close_time) / c.lift_time
    ramp, curve = _quintic(s)
    height = c.lift_height * ramp
    accel = c.lift_height * curve / c.lift_time**2 if 0.0 < s < 1.0 else 0.0
    shake_from = c.duration - c.shake_time
    if c.shake_time > 0 and t >= shake_from:
        w = 2 * np.pi * c.shake_frequency
        height += c.shake_amplitude * np.sin(w * (t - shake_from))
        accel += -c.shake_amplitude * w**2 * np.sin(w * (t - shake_from))
    return height, accel


def _in_palm(data: mujoco.MjData, body: int, palm: int) -> np.ndarray:
    rot = data.xmat[palm].reshape(3, 3)
    return rot.T @ (data.xpos[body] - data.xpos[palm])


def run_trial(
    scene: GraspScene,
    controller: GraspController,
    *,
    push_direction: np.ndarray,
    config: TrialConfig | None = None,
) -> TrialResult:
    """Run one trial of ``controller`` on ``scene`` (see the module docstring).

    Args:
        scene: The gripper scene.
        controller: A grasp controller for the scene's fingers (``left``, ``right``).
        push_direction: Direction of the push ``(3,)`` (normalized here).
        config: The timeline (default :class:`TrialConfig`).

    Returns:
        The :class:`TrialResult`.
    """
    config = config or TrialConfig()
    direction = as_array("push_direction", push_direction, (3,))
    direction = direction / max(float(np.linalg.norm(direction)), 1e-12)
    model = scene.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    body = model.body(OBJECT).id
    palm = model.body("palm").id
    fingers = [model.actuator(f).id for f in FINGERS]
    lift = model.actuator(LIFT).id
    pads = [np.array([model.geom(p).id]) for p in PADS]
    weight = scene.object.mass * float(np.linalg.norm(model.opt.gravity))
    start_z = float(data.xpos[body][2])
    controller.reset()
    dt = model.opt.timestep
    every = max(1, round(config.control_period / dt))
    steps = round(config.duration / dt)
    lift_from = config.close_time
    push_from = config.close_time + config.lift_time + config.push_start
    reference = None
    slip, max_force, forces_hold = 0.0, 0.0, []
    peak_safety, adapted = float("nan"), False
    for step in range(steps):
        t = step * dt
        height, accel = wrist_plan(t, config)
        data.ctrl[lift] = height
        if step % every == 0:
            command = controller(data, np.array([0.0, 0.0, accel]))
            data.ctrl[fingers] = command.ctrl
            if not np.isnan(command.safety):
                peak_safety = float(np.nanmax([peak_safety, command.safety]))
                adapted = adapted or command.safety > getattr(
                    getattr(controller, "config", None), "safety", np.inf
                )
            if t >= lift_from:
                contacts = finger_contacts(model, data, pads, body)
                max_force = max(max_force, float(np.max(contacts.normal_force)))
                forces_hold.append(float(np.mean(contacts.normal_force)))
        pushing = push_from <= t < push_from + config.push_time
        data.xfrc_applied[body, :3] = config.push * weight * direction if pushing else 0.0
        if t >= lift_from:
            here = _in_palm(data, body, palm)
            if reference is None:
                reference = here
            slip = max(slip, float(np.linalg.norm(here - reference)))
        mujoco.mj_step(model, data)
    here = _in_palm(data, body, palm)
    if reference is not None:
        slip = max(slip, float(np.linalg.norm(here - reference)))
    return TrialResult(
        bool(slip <= config.slip_tolerance),
        slip,
        max_force,
        float(np.mean(forces_hold)) if forces_hold else 0.0,
        float(data.xpos[body][2]) - start_z,
        bool(adapted),
        peak_safety,
    )
