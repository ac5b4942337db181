r"""The :class:`Problem`: a MuJoCo model, its references and cost, and its state algebra.

State conventions (``nq`` positions, ``nv`` velocities, ``na`` actuator activations):

* a *state* ``x`` is the physical state ``[qpos (nq), qvel (nv), act (na)]``;
* a *state deviation* ``dx`` lives in the tangent space, ``[dq (nv), dv (nv), da (na)]``, with
  ``dq`` as from :func:`mujoco.mj_differentiatePos`, so free and ball joints are handled;
* linearizations map deviations: :math:`dx_{t+1} = A\,dx_t + B\,du_t` with
  ``A`` of shape ``(nx, nx)``, ``B`` of shape ``(nx, nu)`` and ``nx = 2 nv + na``.

The Problem checks its arguments and delegates: stepping, rollouts and linearization to
:mod:`mpcbox.core.dynamics`, cost evaluation and quadratization to :mod:`~.derivatives`.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from types import MappingProxyType
from typing import Any

import mujoco
import numpy as np

from mpcbox.core import inputs
from mpcbox.core.cost import ControlCost, Cost, StateCost
from mpcbox.core.derivatives import Quadratization
from mpcbox.core.divergence import check_planning_step
from mpcbox.core.dynamics import Dynamics, Linearization, Rollout, mujoco_errors
from mpcbox.core.dynamics import read_state as _read_state
from mpcbox.core.dynamics import write_state as _write_state
from mpcbox.core.joint_limits import LIMIT_CLEARANCE, clear_of_limits, moves_kept
from mpcbox.core.model import (
    ModelSource,
    build_planning_model,
    check_model,
    object_id,
    plannable,
    with_sensors,
)
from mpcbox.core.parent_contacts import load_model
from mpcbox.core.problem_costs import ProblemCosts
from mpcbox.core.tangent import TangentSpace
from mpcbox.errors import DivergenceError, InvalidArgumentError, ModelLoadError, ShapeError
from mpcbox.validation import (
    as_array,
    boolean,
    checked_options,
    finite_array,
    in_range,
    instance,
    non_negative,
    one_of,
    positive,
    positive_int,
    string,
)

__all__ = ["DRY_FRICTION", "Linearization", "Problem", "Quadratization", "Rollout"]

#: Largest finite-difference step ``Problem(fd_eps=...)`` takes: the linearization is local.
MAX_FD_EPS = 1e-2

#: Valid values of ``Problem(dry_friction=...)``.
DRY_FRICTION = ("drop", "keep")


class Problem(ProblemCosts):
    """A control problem on a MuJoCo model.

    A Problem owns the :class:`Cost` and two models compiled from one MJCF: ``model``
    simulates, ``planning_model`` predicts (identical unless ``planning_timestep`` is set).
    An RK4 model is planned with ``implicitfast`` (MuJoCo cannot differentiate an RK4 step;
    a :class:`~mpcbox.errors.PlanningModelWarning` and the repr say so), or in RK4 by finite
    differences of steps with ``plan_rk4``. Subclasses override :meth:`build_cost`,
    :meth:`prepare` (a reference posture before the cost is built) and :meth:`failure`;
    tasks may declare :meth:`measures`, a :meth:`noise` model and :attr:`contacts`.

    Args:
        model: MJCF path, XML string, :class:`mujoco.MjSpec`, or compiled
            :class:`mujoco.MjModel` (a compiled model cannot receive the sensors that body
            and site cost terms need).
        cost: The cost; :meth:`build_cost` is called when omitted.
        keyframe: Name or index of the keyframe giving the reference posture and the initial
            state; ``qpos0`` of the model when omitted.
        qpos_ref: Reference positions ``(nq,)``, overriding the keyframe's.
        ctrl_ref: Reference control ``(nu,)``; the keyframe's ``ctrl`` (or zeros, moved into
            the control range with an ``EquilibriumWarning``) when omitted. A given one must
            lie inside the limited actuators' ``ctrlrange`` (``InvalidArgumentError``).
        planning_timestep: Timestep of the planning model (default: the simulation timestep);
            a step at which the model diverges raises a ``PlanningDivergenceError``.
        planning_model: A separate source for the planning model; it must have the same
            ``nq``, ``nv``, ``nu`` and ``na``.
        fd_eps: Finite-difference step, in ``(0, 0.01]``.
        fd_centered: Centered (True) or forward (False) differences by default.
        plan_rk4: Plan an RK4 model in RK4 (:func:`~mpcbox.core.model.plannable`).
        limit_clearance: Distance of each driven joint of the reference from its limits
            (:func:`~mpcbox.core.joint_limits.clear_of_limits`; moves in ``limit_moves``).
        parent_contacts: ``"exclude"`` the contacts of links with the static body they hang
            from, or ``"keep"`` them (:mod:`~mpcbox.core.parent_contacts`; both warn; the
            pairs excluded are in ``excluded_contacts``).
        dry_friction: ``"keep"`` (default) differentiates the joints' and tendons' dry
            friction, which at rest sticks (``B`` ten times smaller on the G1); ``"drop"``
            a copy without it, as a joint that slips (``ArmReach`` drops it; the standing
            tasks keep it: dropped, Talos fell). Simulation and rollouts keep it.
        threads: Threads for batched linearization (default: all cores).
        name: Label used in tables.

    Raises:
        InvalidArgumentError: If the model has no joint or no actuator, or a broken field
            (non-positive timestep, non-finite gravity, negative mass, ...); the message
            names the field.
    """

    name: str = "problem"
    #: Contact geoms, bodies or sites (``"body:foot"``, ...; see
    #: :func:`~mpcbox.core.contact.contact_points`) for :class:`~mpcbox.QPMPC`; empty: found.
    contacts: tuple[str, ...] = ()
    #: Tuned config objects per controller name (``{"ilqr": ILQRConfig(...)}``) that
    #: :func:`mpcbox.make_controller` uses; a comparison runs these controllers by default.
    controller_configs: Mapping[str, Any] = MappingProxyType({})

    @checked_options
    def __init__(
        self,
        model: ModelSource,
        *,
        cost: Cost | None = None,
        keyframe: str | int | None = None,
        qpos_ref: np.ndarray | None = None,
        ctrl_ref: np.ndarray | None = None,
        planning_timestep: float | None = None,
        planning_model: ModelSource | None = None,
        fd_eps: float = 1e-6,
        fd_centered: bool = True,
        plan_rk4: bool = False,
        limit_clearance: float = LIMIT_CLEARANCE,
        parent_contacts: str = "exclude",
        dry_friction: str = "keep",
        threads: int | None = None,
        name: str | None = None,
    ) -> None:
        if name is not None:
            self.name = string("name", name)
        self.fd_eps = in_range("fd_eps", fd_eps, 0.0, MAX_FD_EPS, low_open=True, high_open=False)
        self.fd_centered = boolean("fd_centered", fd_centered)
        self.threads = positive_int("threads", os.cpu_count() or 1 if threads is None else threads)
        self.dry_friction = one_of("dry_friction", dry_friction, DRY_FRICTION)

        spec, base, self.excluded_contacts = load_model(model, parent_contacts)
        check_model(base)
        self.nq, self.nv, self.nu, self.na = base.nq, base.nv, base.nu, base.na
        self.nx = 2 * self.nv + self.na
        self.nstate = self.nq + self.nv + self.na
        self.tangent = TangentSpace(base)

        # Reference posture and initial state.
        self.keyframe = None if keyframe is None else object_id(base, "keyframe", keyframe)
        if self.keyframe is not None:
            self.qpos_ref = base.key_qpos[self.keyframe].copy()
            key_ctrl = base.key_ctrl[self.keyframe].copy()
        else:
            self.qpos_ref = base.qpos0.copy()
            key_ctrl = np.zeros(self.nu)
        if qpos_ref is not None:
            self.qpos_ref = self.tangent.unit_quaternions(
                "qpos_ref", finite_array("qpos_ref", qpos_ref, (self.nq,))
            )
        chosen, clearance = self.qpos_ref, non_negative("limit_clearance", limit_clearance)
        self.qpos_ref, moves = clear_of_limits(base, chosen, clearance)
        cleared = self.qpos_ref.copy()
        given = None if ctrl_ref is None else finite_array("ctrl_ref", ctrl_ref, (self.nu,))
        self.ctrl_ref, self.qvel_ref = key_ctrl if given is None else given, np.zeros(self.nv)
        self.prepare(base)
        kept = moves_kept(chosen, cleared, self.qpos_ref)  # not if prepare chose its own
        if kept:
            clear_of_limits(base, chosen, clearance, warn=True)  # the same moves, said
        self.limit_moves = moves if kept else []
        if given is None:
            self.ctrl_ref = inputs.default_ctrl_in_range(self.ctrl_ref, base, self.keyframe)
        else:
            low, high = inputs.ctrl_limits(base)
            inputs.check_in_range("ctrl_ref", given, low, high, self.fd_eps)

        self.cost = instance("cost", self.build_cost(base) if cost is None else cost, Cost)
        requests = self.cost.sensors(base)
        self.model = with_sensors(base if spec is None else spec, requests)
        pm = build_planning_model(self.model, spec, requests, planning_model, planning_timestep)
        self.planning_model = plannable(pm, type(self).__name__, boolean("plan_rk4", plan_rk4))
        #: The simulation integrator that planning replaced (``"RK4"``), else ``None``.
        self.replaced_integrator = None if self.planning_model is pm else "RK4"
        #: How the planning model differs from the simulated one, besides the integrator.
        self.planning_changes: tuple[str, ...] = ()
        self.cost.bind(self.planning_model)
        self.ctrl_low, self.ctrl_high = inputs.ctrl_limits(pm)  # same in the copy
        self.dynamics = self.make_dynamics(self.planning_model)
        if planning_timestep is not None:
            check_planning_step(self)  # PlanningDivergenceError if the step is too coarse

    def prepare(self, model: mujoco.MjModel) -> None:
        """Hook run before the cost is built, on the compiled ``model`` without cost sensors:
        set ``qpos_ref`` / ``ctrl_ref`` here."""

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        """Default cost: state deviation from the reference plus control effort (``model``:
        compiled, without cost sensors)."""
        return Cost(
            [
                StateCost(self.qpos_ref, weight_qpos=1.0, weight_qvel=0.1),
                ControlCost(self.ctrl_ref, weight=0.1),
            ]
        )

    # ------------------------------------------------------------------ states
    @property
    def drops_friction(self) -> bool:
        """Whether linearizations leave out dry friction (``dry_friction="drop"``)."""
        return self.dry_friction == "drop"

    def make_dynamics(self, model: mujoco.MjModel) -> Dynamics:
        """:class:`~mpcbox.core.dynamics.Dynamics` of ``model`` (this Problem's planning model
        or a copy of it) with this Problem's threads and ``dry_friction`` choice."""
        return Dynamics(model, self.threads, self.drops_friction)

    @property
    def dt(self) -> float:
        """Timestep of the planning model (s)."""
        return float(self.planning_model.opt.timestep)

    def reference_state(self) -> np.ndarray:
        """The reference state ``[qpos_ref, 0, 0]`` of shape ``(nstate,)``."""
        return np.concatenate([self.qpos_ref, self.qvel_ref, np.zeros(self.na)])

    def initial_state(self) -> np.ndarray:
        """The state a simulation starts from (default: the reference state)."""
        return self.reference_state()

    def initial_ctrls(self, state: np.ndarray, horizon: int) -> np.ndarray:
        """Trajectory optimizers' default guess ``(horizon, nu)`` from ``state``: here
        ``ctrl_ref`` at every knot, within the control range; tasks may choose better
        (:meth:`mpcbox.tasks.reach.ArmReach.initial_ctrls`)."""
        self.check_state(state)
        return np.tile(self.clip_ctrl(self.ctrl_ref), (positive_int("horizon", horizon), 1))

    def get_state(self, data: mujoco.MjData) -> np.ndarray:
        """The state ``[qpos, qvel, act]`` held in ``data`` of this Problem's model."""
        inputs.check_data(data, (self.nq, self.nv, self.na))
        return _read_state(data)

    def set_state(self, data: mujoco.MjData, state: np.ndarray) -> None:
        """Write a state ``(nstate,)`` into ``data`` of this Problem's model."""
        inputs.check_data(data, (self.nq, self.nv, self.na))
        _write_state(data, self.check_state(state))

    def state_difference(
        self, state: np.ndarray, state_ref: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Tangent-space deviation ``dx = state ⊖ state_ref``.

        Args:
            state: States, shape ``(..., nstate)``.
            state_ref: Reference state(s), shape ``(nstate,)`` or ``(..., nstate)``.
            out: Optional preallocated float64 output ``(..., nx)`` (e.g. in a loop).

        Returns:
            Deviations, shape ``(..., nx)`` (``out`` when given).
        """
        state = as_array("state", state, (None,) * max(1, np.ndim(state)))
        state_ref = as_array("state_ref", state_ref, (None,) * max(1, np.ndim(state_ref)))
        if state.shape[-1] != self.nstate or state_ref.shape not in ((self.nstate,), state.shape):
            raise ShapeError(
                f"state must have shape (..., {self.nstate}) and state_ref ({self.nstate},) or "
                f"the shape of state, got {state.shape} and {state_ref.shape}"
            )
        inputs.check_out("out", out, (*state.shape[:-1], self.nx))
        return self.tangent.state_difference(state, state_ref, out)

    def state_add(self, state: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """Move one ``state`` by a tangent deviation ``dx`` of shape ``(nx,)``."""
        state = self.check_state(state)
        dx = as_array("dx", dx, (self.nx,))
        return self.tangent.state_add(self.planning_model, state, dx)

    def clip_ctrl(self, ctrl: np.ndarray) -> np.ndarray:
        """Clamp controls ``(..., nu)`` to the actuators' ``ctrlrange`` (where limited)."""
        ctrl = as_array("ctrl", ctrl, (None,) * (max(np.ndim(ctrl), 1) - 1) + (self.nu,))
        return np.clip(ctrl, self.ctrl_low, self.ctrl_high)

    def check_state(self, state: np.ndarray, name: str = "state") -> np.ndarray:
        """A state ``[qpos, qvel, act]`` as float64, checked: :class:`ShapeError` for another
        shape than ``(nstate,)``, :class:`DivergenceError` for NaN or infinity,
        :class:`InvalidArgumentError` for a zero quaternion (``name``: the argument's name)."""
        return self.tangent.check_quaternions(name, inputs.check_state(name, state, self.nstate))

    def check_ctrl(self, ctrl: np.ndarray, name: str = "ctrl") -> np.ndarray:
        """Check a control ``(nu,)``: shape, finite, within MuJoCo's limit (:mod:`.inputs`)."""
        return inputs.check_ctrl(name, ctrl, (self.nu,))

    # ------------------------------------------------------------------ dynamics
    def scratch_data(self) -> mujoco.MjData:
        """The calling thread's ``MjData`` of the planning model, for controllers' own loops
        (the same object on every call from one thread, as its last user left it)."""
        return self.dynamics.scratch_data()

    def executor(self) -> ThreadPoolExecutor:
        """The Problem's persistent thread pool (``threads`` workers)."""
        return self.dynamics.executor()

    def step(self, state: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        """One step of the planning model from ``state`` ``(nstate,)`` under ``ctrl`` ``(nu,)``."""
        return self.dynamics.step(self.check_state(state), self.check_ctrl(ctrl))

    def linearize(
        self,
        state: np.ndarray,
        ctrl: np.ndarray,
        *,
        eps: float | None = None,
        centered: bool | None = None,
    ) -> Linearization:
        """Jacobians ``A`` ``(nx, nx)``, ``B`` ``(nx, nu)`` of one planning step at a state.

        Finite differences of ``mjd_transitionFD`` with step ``eps`` (default ``fd_eps``),
        centered or not (default ``fd_centered``); see :meth:`Dynamics.linearize`. A control
        outside ``ctrlrange`` or ``B = 0`` raises (see :mod:`mpcbox.core.inputs`).
        """
        state, ctrl = self.check_state(state), self.check_ctrl(ctrl)
        eps, centered = self._fd_options(eps, centered)
        inputs.check_in_range("ctrl", ctrl, self.ctrl_low, self.ctrl_high, eps)
        lin = self.dynamics.linearize(state, ctrl, eps, centered)
        inputs.check_authority(lin.B, "linearize")
        return lin

    def linearize_trajectory(
        self,
        states: np.ndarray,
        ctrls: np.ndarray,
        *,
        eps: float | None = None,
        centered: bool | None = None,
        threads: int | None = None,
    ) -> Linearization:
        """:meth:`linearize` at ``T`` knots in parallel (``threads``, default the Problem's).

        Args ``states`` ``(T, nstate)`` and ``ctrls`` ``(T, nu)`` give ``A`` ``(T, nx, nx)`` and
        ``B`` ``(T, nx, nu)``; MuJoCo drops the GIL, each thread has its own ``MjData``.
        """
        states = as_array("states", states, (None, self.nstate))
        if not (states.shape[0] and np.all(np.isfinite(states))):
            raise DivergenceError("states must hold at least one finite state")
        ctrls = inputs.check_ctrl("ctrls", ctrls, (states.shape[0], self.nu))
        eps, centered = self._fd_options(eps, centered)
        threads = None if threads is None else positive_int("threads", threads)
        lin = self.dynamics.linearize_trajectory(states, ctrls, eps, centered, threads)
        inputs.check_authority(lin.B, "linearize_trajectory")
        return lin

    def _fd_options(self, eps: float | None, centered: bool | None) -> tuple[float, bool]:
        eps = self.fd_eps if eps is None else positive("eps", eps)
        return eps, self.fd_centered if centered is None else boolean("centered", centered)

    def rollout(
        self,
        state: np.ndarray,
        ctrls: np.ndarray,
        *,
        model: mujoco.MjModel | Sequence[mujoco.MjModel] | None = None,
    ) -> Rollout:
        """Roll out controls ``(T, nu)`` or ``(B, T, nu)`` from ``state`` on the planning model.

        Controls are clamped to the control range; ``model`` (one, or one per batch row)
        replaces the planning model, e.g. with randomized parameters. The :class:`Rollout`
        has a leading batch axis; a rollout that diverged holds NaN from that step on (see
        :meth:`Dynamics.rollout`).
        """
        state = self.check_state(state)
        ctrls = inputs.check_ctrl("ctrls", ctrls, (None,) * max(2, min(3, np.ndim(ctrls))))
        ctrls = ctrls[None] if ctrls.ndim == 2 else ctrls
        if ctrls.shape[2] != self.nu or ctrls.shape[1] < 1 or ctrls.shape[0] < 1:
            raise ShapeError(
                f"ctrls must have shape (T, {self.nu}) or (B, T, {self.nu}), T >= 1, got "
                f"{ctrls.shape}"
            )
        model = inputs.check_rollout_models(model, self.planning_model, ctrls.shape[0])
        return self.dynamics.rollout(state, self.clip_ctrl(ctrls), model)

    def full_physics_state(self, state: np.ndarray) -> np.ndarray:
        """``mjSTATE_FULLPHYSICS`` vector (time, qpos, qvel, act, ...) for a state."""
        return self.dynamics.full_physics_state(self.check_state(state))

    def find_equilibrium(self, qpos: np.ndarray | None = None, **kwargs):
        """Control that holds a posture, from inverse dynamics (see :func:`find_equilibrium`)."""
        from mpcbox.core.equilibrium import find_equilibrium

        with mujoco_errors("find_equilibrium"):
            return find_equilibrium(self.model, self.qpos_ref if qpos is None else qpos, **kwargs)

    # ------------------------------------------------------------------ monitoring
    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        """Why the simulation should stop, or ``None``: here a non-finite state; subclasses
        add falls."""
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return "non-finite state"
        return None

    def goal_failure(self, time: np.ndarray, states: np.ndarray) -> str | None:
        """Why a run without :meth:`failure` misses the task's goal, or ``None`` (the default:
        surviving is the goal). ``time`` ``(T,)`` (s) and ``states`` ``(T, nstate)`` are the
        run's record; swing-up and reach tasks check the final error here."""
        return None

    def measures(self) -> Sequence[Any]:
        """The task's own :class:`mpcbox.sim.measures.Measure` items (distinct names).

        :func:`mpcbox.simulate` samples each one after every step and summarizes it in
        :attr:`Metrics.measures <mpcbox.Metrics>`. The base class declares none.
        """
        return ()

    def noise(self, scale: float = 1.0) -> Any:
        """The task's :class:`mpcbox.ActuatorNoise` at ``scale`` times its nominal level,
        used by scenarios of :func:`mpcbox.compare` that ask for noise without giving one.

        Raises:
            InvalidArgumentError: Always, in the base class: the task has no noise model.
        """
        raise InvalidArgumentError(
            f"task {self.name!r} ({type(self).__name__}) has no noise model: give an explicit "
            "mpcbox.ActuatorNoise, or noise scale 0"
        )

    def with_planning_timestep(self, timestep: float) -> Problem:
        """A shallow copy whose planning model (its own, same sensors) takes steps of
        ``timestep`` seconds; it shares the simulation model, the cost and the references.

        Raises:
            PlanningDivergenceError: If the model diverges at ``timestep``
                (:func:`~mpcbox.core.divergence.check_planning_step`).
        """
        clone = copy.copy(self)
        clone.planning_model = copy.copy(self.planning_model)
        clone.planning_model.opt.timestep = positive("timestep", timestep)
        clone.dynamics = clone.make_dynamics(clone.planning_model)
        check_planning_step(clone)
        return clone

    def with_dry_friction(self, dry_friction: str) -> Problem:
        """A shallow copy whose linearizations keep (``"keep"``) or leave out (``"drop"``)
        dry friction, sharing everything else (e.g. ``ILQRConfig(dry_friction="drop")``);
        ``self`` when that is its choice already. Raises InvalidArgumentError otherwise."""
        choice = one_of("dry_friction", dry_friction, DRY_FRICTION)
        if choice == self.dry_friction:
            return self
        clone = copy.copy(self)
        clone.dry_friction = choice
        clone.dynamics = clone.make_dynamics(clone.planning_model)
        return clone

    def with_cost(self, cost: Cost) -> Problem:
        """A shallow copy with another :class:`Cost` (bound to the planning model).

        The new cost may only use sensors the models already have. Controllers use this to add
        terms of their own, e.g. an LQR value function as terminal cost.
        """
        instance("cost", cost, Cost)
        pm, sensor = self.planning_model, mujoco.mjtObj.mjOBJ_SENSOR
        missing = [r.name for r in cost.sensors(pm) if mujoco.mj_name2id(pm, sensor, r.name) < 0]
        if missing:
            raise ModelLoadError(f"cost: sensors {missing} are not in the Problem's models")
        clone = copy.copy(self)
        clone.cost = cost
        cost.bind(self.planning_model)
        clone.dynamics = clone.make_dynamics(self.planning_model)
        return clone

    def replace_planning_model(self, model: mujoco.MjModel, change: str) -> None:
        """Plan on ``model`` (the planning model's sizes and sensors) from now on, e.g. on
        :func:`~mpcbox.core.sole_boxes.box_soles`; ``change`` says how, in the repr."""
        self.planning_model = model
        self.cost.bind(model)
        self.dynamics.close()
        self.dynamics = self.make_dynamics(model)
        self.planning_changes = (*self.planning_changes, string("change", change))

    def close(self) -> None:
        """Shut down the thread pool."""
        self.dynamics.close()

    def __repr__(self) -> str:
        pairs = self.excluded_contacts
        planning = "".join(f", excluded contact: {c.parent}/{c.child}" for c in pairs)
        planning += "".join(f", planning: {c}" for c in self.planning_changes)
        if self.replaced_integrator is not None:
            planning = f", planning_integrator='implicitfast' (model: RK4){planning}"
        return (
            f"{type(self).__name__}(name={self.name!r}, nq={self.nq}, nv={self.nv}, nu={self.nu}, "
            f"dt_sim={self.model.opt.timestep}, dt_plan={self.dt}{planning})"
        )
