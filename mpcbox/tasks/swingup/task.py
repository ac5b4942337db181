r"""The generic swing-up: bring an underactuated chain from hanging to upright and hold it.

Running cost, with the named joints :math:`j` (target :math:`q_j^\star`), the named sites
:math:`s` (target height :math:`z_s^\star` or position :math:`p_s^\star`), the other joints'
positions :math:`q_o` (reference :math:`q_o^{ref}`), all velocities :math:`v` and the controls
scaled to their half ranges :math:`\tilde u`:

.. math::
    \ell = \tfrac12 \Big( w_a \sum_j \big(2 \sin\tfrac{q_j - q_j^\star}{2}\big)^2
    + w_s \sum_s \lVert p_s - p_s^\star \rVert^2 + w_p \lVert q_o - q_o^{ref} \rVert^2
    + w_v \lVert v \rVert^2 + w_u \lVert \tilde u - \tilde u_{ref} \rVert^2 \Big)

(:class:`~mpcbox.core.cost.WrappedAngle`, :class:`~mpcbox.core.cost.FrameHeight` or
:class:`~mpcbox.core.cost.FramePosition`, :class:`~mpcbox.core.cost.StateCost`,
:class:`~mpcbox.core.cost.ControlCost`); the terminal cost has the same terms with the
``terminal_*`` weights of :class:`~mpcbox.tasks.swingup.weights.SwingupWeights`, without the
control.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from mpcbox.core.cost import (
    ControlCost,
    Cost,
    CostTerm,
    Energy,
    FrameHeight,
    FramePosition,
    StateCost,
    WrappedAngle,
    rest_energy,
)
from mpcbox.core.model import ModelSource, frame_position, object_id
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.sim.measures import Measure
from mpcbox.tasks.swingup.goal import UprightError, UprightGoal, flipped, joint_targets
from mpcbox.tasks.swingup.weights import SwingupWeights
from mpcbox.validation import as_array

#: Most hinge joints whose hanging combinations :meth:`Swingup.hanging_qpos` enumerates.
MAX_HANGING_JOINTS = 12


class Swingup(Problem):
    """Swing an underactuated chain (pendulum, cart-pole, acrobot, ...) up and hold it.

    "Up" is given by ``joints`` (hinge joints and their upright angles) or ``sites`` (their
    upright height or position); see :class:`~mpcbox.tasks.swingup.goal.UprightGoal` for the
    upright error and the success rule (:meth:`goal_failure`), and the module docstring for
    the cost. The reference posture (``qpos_ref``: the keyframe, ``qpos0`` or given) holds the
    named joints at their targets and the other joints where the cost pulls them.

    Args:
        model: MJCF path, XML string, spec, or ``"menagerie:NAME"``.
        joints: Hinge joints that are upright at given angles: a mapping ``{name: angle}``
            (rad), or a sequence of names, each upright at ``pi`` (the convention of a pole
            modelled hanging at angle 0).
        sites: Sites (or bodies) that are upright at a height (a number, m), a world position
            ``(3,)``, or ``None``: their height at the reference posture (e.g. a tip above the
            base when ``qpos0`` is upright).
        initial: Start of a run: ``"hanging"`` (the lowest center of mass over the named
            joints at their upright or opposite angle, the other joints at the reference,
            at rest), ``"qpos0"``, a keyframe name or index, a posture ``(nq,)`` or a state
            ``(nstate,)``.
        tolerance: Upright error counted as upright (rad with joints, else m); default 0.2
            rad or 0.1 m.
        hold: Seconds the chain must stay upright at the end of a run.
        goal: ``"joints"`` or ``"sites"``: which of the named objects define the upright
            error and success when both are named (default: the joints when any are named).
        weights: The cost weights (:class:`SwingupWeights`).
        controller_configs: Tuned config objects per controller name for this instance
            (default: the class's).
        **kwargs: Passed to :class:`~mpcbox.Problem` (``keyframe``, ``qpos_ref``,
            ``planning_timestep``, ``name`` (default ``"swingup"``), ...).

    Raises:
        InvalidArgumentError: If nothing is named upright, a joint is not a hinge, or an
            argument is out of range.
        UnknownNameError: If a joint, site or keyframe does not exist (lists the names).
    """

    name = "swingup"

    def __init__(
        self,
        model: ModelSource,
        *,
        joints: Mapping[str, float] | Sequence[str] | None = None,
        sites: Mapping[str, float | np.ndarray | None] | None = None,
        initial: str | int | np.ndarray = "hanging",
        tolerance: float | None = None,
        hold: float = 1.0,
        goal: str | None = None,
        weights: SwingupWeights | None = None,
        controller_configs: Mapping[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        self._joints = joint_targets(joints)
        if sites is not None and not isinstance(sites, Mapping):
            raise InvalidTypeError(
                f"sites must map site names to targets (height, position or None), got "
                f"{type(sites).__name__}"
            )
        self._sites = dict(sites or {})
        self._initial = initial
        self._goal_options = {"tolerance": tolerance, "hold": hold, "by": goal}
        if weights is None:
            weights = SwingupWeights()
        elif not isinstance(weights, SwingupWeights):
            raise InvalidTypeError(
                f"weights must be a SwingupWeights, got {type(weights).__name__}"
            )
        self.weights = weights
        if controller_configs is not None:
            if not isinstance(controller_configs, Mapping):
                raise InvalidTypeError(
                    "controller_configs must map controller names to config objects, got "
                    f"{type(controller_configs).__name__}"
                )
            self.controller_configs = dict(controller_configs)
        super().__init__(model, **kwargs)

    # ------------------------------------------------------------------ construction
    def prepare(self, model: mujoco.MjModel) -> None:
        sites = {}
        data = mujoco.MjData(model)
        data.qpos[:] = self.qpos_ref
        for name, target in self._joints.items():
            self.qpos_ref[model.jnt_qposadr[object_id(model, "joint", name)]] = target
        data.qpos[:] = self.qpos_ref
        mujoco.mj_kinematics(model, data)
        for name, target in self._sites.items():
            sites[name] = frame_position(model, data, name)[2] if target is None else target
        #: The upright posture and the success rule
        #: (:class:`~mpcbox.tasks.swingup.goal.UprightGoal`).
        self.goal = UprightGoal(model, joints=self._joints, sites=sites, **self._goal_options)
        self.start_state = self._start_state(model)
        half = 0.5 * (model.actuator_ctrlrange[:, 1] - model.actuator_ctrlrange[:, 0])
        #: Scale of each control in the cost: its half range, 1 where it has none.
        self.ctrl_scale = np.where(model.actuator_ctrllimited.astype(bool), half, 1.0)

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        w = self.weights
        named = np.zeros(model.nv, dtype=bool)
        for name in self.goal.joints:
            named[model.jnt_dofadr[object_id(model, "joint", name)]] = True
        running = self._terms(model, named, w.position, w.velocity, w.angle, w.site, "")
        ctrl_weight = w.ctrl / self.ctrl_scale**2
        if np.any(ctrl_weight > 0):
            running.append(ControlCost(self.ctrl_ref, weight=ctrl_weight))
        if w.energy > 0:
            target = rest_energy(model, self.qpos_ref)
            running.append(Energy(target, weight=w.energy))
        terminal = self._terms(
            model,
            named,
            w.terminal_position,
            w.terminal_velocity,
            w.terminal_angle,
            w.terminal_site,
            "terminal_",
        )
        return Cost(running, terminal)

    def _terms(
        self,
        model: mujoco.MjModel,
        named: np.ndarray,
        position: float,
        velocity: float,
        angle: float,
        site: float,
        prefix: str,
    ) -> list[CostTerm]:
        terms: list[CostTerm] = []
        weight_qpos = np.where(named, 0.0, position)
        if np.any(weight_qpos > 0) or velocity > 0:
            terms.append(
                StateCost(
                    self.qpos_ref,
                    weight_qpos=weight_qpos,
                    weight_qvel=velocity,
                    name=f"{prefix}state",
                )
            )
        if angle > 0:
            for joint, target in self.goal.joints.items():
                terms.append(
                    WrappedAngle(joint, target, weight=angle, name=f"{prefix}angle_{joint}")
                )
        if site > 0:
            for frame, target in self.goal.sites.items():
                label = f"{prefix}site_{frame}"
                if target.ndim == 0:
                    terms.append(FrameHeight(frame, float(target), weight=site, name=label))
                else:
                    terms.append(FramePosition(frame, target, weight=site, name=label))
        return terms

    def _start_state(self, model: mujoco.MjModel) -> np.ndarray:
        initial, nq = self._initial, model.nq
        nstate = nq + model.nv + model.na
        state = np.zeros(nstate)
        if isinstance(initial, str) and initial == "hanging":
            state[:nq] = self.hanging_qpos(model)
        elif isinstance(initial, str) and initial == "qpos0":
            state[:nq] = model.qpos0
        elif isinstance(initial, (str, int)) and not isinstance(initial, bool):
            key = object_id(model, "keyframe", initial)
            state[:nq] = model.key_qpos[key]
            state[nq : nq + model.nv] = model.key_qvel[key]
            state[nq + model.nv :] = model.key_act[key]
        else:
            value = np.asarray(initial, dtype=np.float64)
            if value.shape == (nq,):
                state[:nq] = value
            else:
                state = as_array("initial", value, (nstate,)).copy()
            if not np.all(np.isfinite(state)):
                raise InvalidArgumentError("initial must be finite")
        return state

    def hanging_qpos(self, model: mujoco.MjModel) -> np.ndarray:
        """The posture of lowest center of mass with each named joint at its target or the
        opposite angle (every hinge joint when only sites are named), the rest at
        ``qpos_ref``.

        Raises:
            InvalidArgumentError: If more than :data:`MAX_HANGING_JOINTS` joints would be
                enumerated (give ``initial`` explicitly).
        """
        if self.goal.joints:
            addresses = list(self.goal.qpos_addresses)
        else:
            hinges = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
            addresses = [int(model.jnt_qposadr[j]) for j in hinges]
        if len(addresses) > MAX_HANGING_JOINTS:
            raise InvalidArgumentError(
                f"initial='hanging' would try 2^{len(addresses)} postures; give initial as a "
                "keyframe, 'qpos0' or a posture"
            )
        data = mujoco.MjData(model)
        best, lowest = self.qpos_ref.copy(), np.inf
        options = [(self.qpos_ref[a], flipped(self.qpos_ref[a])) for a in addresses]
        for combination in itertools.product(*(reversed(o) for o in options)):
            data.qpos[:] = self.qpos_ref
            data.qpos[addresses] = combination
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            height = data.subtree_com[0, 2]
            if height < lowest - 1e-9:
                best, lowest = data.qpos.copy(), height
        return best

    # ------------------------------------------------------------------ task
    def initial_state(self) -> np.ndarray:
        """The start state chosen by ``initial`` (a copy)."""
        return self.start_state.copy()

    def upright_error(self, state: np.ndarray) -> float:
        """Upright error of one state (rad with joints, else m; see :class:`UprightGoal`)."""
        return self.goal.qpos_error(self.check_state(state)[: self.nq])

    def upright_errors(self, states: np.ndarray) -> np.ndarray:
        """Upright errors ``(T,)`` of states ``(T, nstate)``."""
        states = as_array("states", states, (None, self.nstate))
        return self.goal.errors(states, self.nq)

    def time_to_upright(self, time: np.ndarray, states: np.ndarray) -> float:
        """First time after which the error stays within tolerance (NaN when never)."""
        return self.goal.settle_time(np.asarray(time), self.upright_errors(states))

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        """Why a run ``time`` ``(T,)``, ``states`` ``(T, nstate)`` misses the goal, or ``None``.

        Success: within ``tolerance`` of upright at the end, and over the final ``hold``
        seconds. Example: ``"not upright at the end: 3.14 rad from upright (tolerance 0.2
        rad)"``.
        """
        time = as_array("time", time, (None,))
        states = as_array("states", states, (time.size, self.nstate))
        return self.goal.failure(time, self.goal.errors(states, self.nq))

    def measures(self) -> Sequence[Measure]:
        """The upright error (:class:`~mpcbox.tasks.swingup.goal.UprightError`)."""
        return (UprightError(goal=self.goal),)
