r"""The :class:`Problem`: a MuJoCo model, its cost, and finite-difference derivatives.

State conventions (``nq`` positions, ``nv`` velocities, ``na`` actuator activations):

* a *state* ``x`` is the physical state ``[qpos (nq), qvel (nv), act (na)]``;
* a *state deviation* ``dx`` lives in the tangent space, ``[dq (nv), dv (nv), da (na)]``, with
  ``dq`` from :func:`mujoco.mj_differentiatePos`, so free and ball joints are handled;
* linearizations map deviations: :math:`dx_{t+1} = A\,dx_t + B\,du_t` with
  ``A`` of shape ``(nx, nx)``, ``B`` of shape ``(nx, nu)`` and ``nx = 2 nv + na``.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.core.cost import ControlCost, Cost, Features, StateCost, check_features
from mpcbox.core.model import ModelSource, compile_spec, load_spec, object_id
from mpcbox.core.tangent import TangentSpace
from mpcbox.errors import DivergenceError, InvalidArgumentError, ModelLoadError, ShapeError
from mpcbox.validation import as_array, positive, positive_int


class Linearization(NamedTuple):
    """Discrete-time Jacobians ``A`` ``(..., nx, nx)`` and ``B`` ``(..., nx, nu)``."""

    A: np.ndarray
    B: np.ndarray


class Quadratization(NamedTuple):
    """Second-order (Gauss-Newton) model of a cost about ``(x, u)``.

    Attributes:
        value: Cost value(s), shape ``(...)``.
        lx: Gradient in the state deviation, ``(..., nx)``.
        lu: Gradient in the control, ``(..., nu)``.
        lxx: Hessian block, ``(..., nx, nx)``.
        luu: Hessian block, ``(..., nu, nu)``.
        lux: Hessian block, ``(..., nu, nx)``.
    """

    value: np.ndarray
    lx: np.ndarray
    lu: np.ndarray
    lxx: np.ndarray
    luu: np.ndarray
    lux: np.ndarray


class Rollout(NamedTuple):
    """Open-loop rollouts from one start state.

    Attributes:
        states: ``(B, T + 1, nstate)`` states, ``states[:, 0]`` the start state.
        sensordata: ``(B, T + 1, nsensordata)``; row ``t`` is computed at ``states[:, t]``.
        ctrls: ``(B, T, nu)`` the controls that were applied (clamped to ctrlrange).
    """

    states: np.ndarray
    sensordata: np.ndarray
    ctrls: np.ndarray


_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


class Problem:
    """A control problem on a MuJoCo model.

    A Problem owns two compiled models built from the same MJCF: ``model`` is the simulation
    model and ``planning_model`` the one controllers predict with (by default identical; a
    coarser ``planning_timestep`` makes planning cheaper). It also owns the :class:`Cost`.

    Subclasses typically override :meth:`build_cost` (and :meth:`prepare` to compute a
    reference posture before the cost is built) and :meth:`failure` (what counts as a fall);
    tasks may also declare :meth:`measures` (reported by :func:`~mpcbox.simulate`), a
    :meth:`noise` model and :attr:`contacts`.

    Args:
        model: MJCF path, XML string, :class:`mujoco.MjSpec`, or compiled
            :class:`mujoco.MjModel` (a compiled model cannot receive the sensors that body
            and site cost terms need).
        cost: The cost; :meth:`build_cost` is called when omitted.
        keyframe: Name or index of the keyframe giving the reference posture and the initial
            state; ``qpos0`` of the model when omitted.
        qpos_ref: Reference positions ``(nq,)``, overriding the keyframe's.
        ctrl_ref: Reference control ``(nu,)``; the keyframe's ``ctrl`` (or zeros) when omitted.
        planning_timestep: Timestep of the planning model (default: the simulation timestep).
        planning_model: A separate source for the planning model; it must have the same
            ``nq``, ``nv``, ``nu`` and ``na``.
        fd_eps: Finite-difference step.
        fd_centered: Centered (True) or forward (False) differences by default.
        threads: Threads for batched linearization (default: all cores).
        name: Label used in tables.
    """

    name: str = "problem"
    #: Contact geoms, bodies or sites (names, optionally prefixed ``"geom:"``, ``"body:"`` or
    #: ``"site:"``; see :func:`~mpcbox.core.contact.contact_points`) that contact-aware
    #: controllers (:class:`~mpcbox.QPMPC`) use when given none; empty: they find their own.
    contacts: tuple[str, ...] = ()

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
        threads: int | None = None,
        name: str | None = None,
    ) -> None:
        if name is not None:
            self.name = name
        self.fd_eps = positive("fd_eps", fd_eps)
        self.fd_centered = bool(fd_centered)
        self.threads = positive_int(
            "threads", threads if threads is not None else os.cpu_count() or 1
        )

        spec = None if isinstance(model, mujoco.MjModel) else load_spec(model)
        base = model if isinstance(model, mujoco.MjModel) else compile_spec(spec)
        if base.nv == 0:
            raise InvalidArgumentError(
                "model has no degrees of freedom (nv = 0): a Problem needs at least one joint "
                "or free body to predict and control"
            )
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
            self.qpos_ref = as_array("qpos_ref", qpos_ref, (self.nq,)).copy()
        self.ctrl_ref = key_ctrl if ctrl_ref is None else as_array("ctrl_ref", ctrl_ref, (self.nu,))
        self.qvel_ref = np.zeros(self.nv)
        self.prepare(base)

        self.cost = cost if cost is not None else self.build_cost(base)
        if not isinstance(self.cost, Cost):
            raise InvalidArgumentError(
                f"cost must be an mpcbox.Cost, got {type(self.cost).__name__}"
            )
        requests = self.cost.sensors(base)
        self.model = self._with_sensors(spec, base, requests, None)
        if planning_model is not None:
            pspec = (
                None if isinstance(planning_model, mujoco.MjModel) else load_spec(planning_model)
            )
            pbase = planning_model if isinstance(planning_model, mujoco.MjModel) else None
            self.planning_model = self._with_sensors(pspec, pbase, requests, planning_timestep)
        elif planning_timestep is not None:
            if spec is None:
                self.planning_model = _copy_model(self.model)
                self.planning_model.opt.timestep = positive("planning_timestep", planning_timestep)
            else:
                self.planning_model = self._with_sensors(spec, None, requests, planning_timestep)
        else:
            self.planning_model = self.model
        pm = self.planning_model
        if (pm.nq, pm.nv, pm.nu, pm.na) != (self.nq, self.nv, self.nu, self.na):
            raise ShapeError(
                "planning_model must have the same nq, nv, nu, na as model: "
                f"got {(pm.nq, pm.nv, pm.nu, pm.na)}, "
                f"expected {(self.nq, self.nv, self.nu, self.na)}"
            )
        self.cost.bind(self.planning_model)
        if self.model.nsensordata != pm.nsensordata:
            raise ShapeError("planning_model and model must have the same sensors")
        self.ctrl_low = np.where(pm.actuator_ctrllimited, pm.actuator_ctrlrange[:, 0], -np.inf)
        self.ctrl_high = np.where(pm.actuator_ctrllimited, pm.actuator_ctrlrange[:, 1], np.inf)

        self._local = threading.local()
        self._pool: ThreadPoolExecutor | None = None
        full = mujoco.mj_stateSize(self.planning_model, _FULL)
        self._full_size = full

    # ------------------------------------------------------------------ construction hooks
    def prepare(self, model: mujoco.MjModel) -> None:
        """Hook run before the cost is built: set ``qpos_ref`` / ``ctrl_ref`` here.

        Args:
            model: The compiled model without cost sensors.
        """

    def build_cost(self, model: mujoco.MjModel) -> Cost:
        """Default cost: state deviation from the reference plus control effort.

        Args:
            model: The compiled model without cost sensors.
        """
        return Cost(
            [
                StateCost(self.qpos_ref, weight_qpos=1.0, weight_qvel=0.1),
                ControlCost(0.1, self.ctrl_ref),
            ]
        )

    @staticmethod
    def _with_sensors(spec, base, requests, timestep) -> mujoco.MjModel:
        if spec is None:
            missing = [
                r.name
                for r in requests
                if mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SENSOR, r.name) < 0
            ]
            if missing:
                raise ModelLoadError(
                    f"model: the cost needs sensors {missing} that a compiled MjModel cannot "
                    "receive; pass an MJCF path, XML string or MjSpec instead"
                )
            model = _copy_model(base)
        else:
            spec = spec.copy()
            for req in requests:
                spec.add_sensor(
                    name=req.name, type=req.type, objtype=req.objtype, objname=req.objname
                )
            if timestep is not None:
                spec.option.timestep = positive("planning_timestep", timestep)
            model = compile_spec(spec)
        if timestep is not None:
            model.opt.timestep = positive("planning_timestep", timestep)
        return model

    # ------------------------------------------------------------------ states
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

    def get_state(self, data: mujoco.MjData) -> np.ndarray:
        """The state ``[qpos, qvel, act]`` held in ``data``."""
        return np.concatenate([data.qpos, data.qvel, data.act])

    def set_state(self, data: mujoco.MjData, state: np.ndarray) -> None:
        """Write a state ``(nstate,)`` into ``data``."""
        state = self.check_state(state)
        data.qpos[:] = state[: self.nq]
        data.qvel[:] = state[self.nq : self.nq + self.nv]
        data.act[:] = state[self.nq + self.nv :]

    def state_difference(self, state: np.ndarray, state_ref: np.ndarray) -> np.ndarray:
        """Tangent-space deviation ``dx = state ⊖ state_ref``.

        Args:
            state: States, shape ``(..., nstate)``.
            state_ref: Reference state(s), shape ``(nstate,)`` or ``(..., nstate)``.

        Returns:
            Deviations, shape ``(..., nx)``.
        """
        state = np.asarray(state, dtype=np.float64)
        state_ref = np.asarray(state_ref, dtype=np.float64)
        if state.shape[-1] != self.nstate or state_ref.shape[-1] != self.nstate:
            raise ShapeError(
                f"state and state_ref must end in nstate={self.nstate}, "
                f"got {state.shape} and {state_ref.shape}"
            )
        nq = self.nq
        dq = self.tangent.difference(
            state[..., :nq], np.broadcast_to(state_ref[..., :nq], state[..., :nq].shape)
        )
        return np.concatenate([dq, state[..., nq:] - state_ref[..., nq:]], axis=-1)

    def state_add(self, state: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """Move one ``state`` by a tangent deviation ``dx`` of shape ``(nx,)``."""
        state = self.check_state(state)
        dx = as_array("dx", dx, (self.nx,))
        out = state.copy()
        out[: self.nq] = self.tangent.integrate(
            self.planning_model, state[: self.nq], dx[: self.nv]
        )
        out[self.nq :] += dx[self.nv :]
        return out

    def clip_ctrl(self, ctrl: np.ndarray) -> np.ndarray:
        """Clamp controls to the actuators' ``ctrlrange`` (where limited)."""
        return np.clip(ctrl, self.ctrl_low, self.ctrl_high)

    def check_state(self, state: np.ndarray, name: str = "state") -> np.ndarray:
        """Check a state ``(nstate,)`` of this Problem: its shape and that it is finite.

        Args:
            state: ``[qpos, qvel, act]``.
            name: Argument name used in error messages.

        Returns:
            The state as a float64 array.

        Raises:
            ShapeError: If the shape is not ``(nstate,)``.
            DivergenceError: If it holds NaN or infinity.
        """
        state = as_array(name, state, (self.nstate,))
        if not np.all(np.isfinite(state)):
            raise DivergenceError(f"{name} holds non-finite values (NaN or inf)")
        return state

    def check_ctrl(self, ctrl: np.ndarray, name: str = "ctrl") -> np.ndarray:
        """Check a control ``(nu,)``: its shape and that it is finite (see :meth:`check_state`)."""
        ctrl = as_array(name, ctrl, (self.nu,))
        if not np.all(np.isfinite(ctrl)):
            raise DivergenceError(f"{name} holds non-finite values (NaN or inf)")
        return ctrl

    # ------------------------------------------------------------------ per-thread data
    def _data(self) -> mujoco.MjData:
        data = getattr(self._local, "data", None)
        if data is None:
            data = mujoco.MjData(self.planning_model)
            self._local.data = data
        return data

    def executor(self) -> ThreadPoolExecutor:
        """The Problem's persistent thread pool (``threads`` workers)."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="mpcbox")
        return self._pool

    def _map(self, fn: Callable[[int], object], count: int, threads: int | None) -> list:
        """``[fn(i) for i in range(count)]`` on contiguous chunks, one chunk per thread."""
        threads = self.threads if threads is None else positive_int("threads", threads)
        threads = min(threads, count)
        if threads <= 1:
            return [fn(i) for i in range(count)]
        bounds = np.linspace(0, count, threads + 1).astype(int)

        def chunk(j: int) -> list:
            return [fn(i) for i in range(bounds[j], bounds[j + 1])]

        if threads <= self.threads:
            parts = list(self.executor().map(chunk, range(threads)))
        else:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                parts = list(pool.map(chunk, range(threads)))
        return [item for part in parts for item in part]

    # ------------------------------------------------------------------ dynamics
    def step(self, state: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        """One step of the planning model from ``state`` under ``ctrl``."""
        data = self._data()
        self.set_state(data, state)
        data.ctrl[:] = self.check_ctrl(ctrl)
        mujoco.mj_step(self.planning_model, data)
        return self.get_state(data)

    def linearize(
        self,
        state: np.ndarray,
        ctrl: np.ndarray,
        *,
        eps: float | None = None,
        centered: bool | None = None,
    ) -> Linearization:
        """Finite-difference Jacobians of one planning-model step (``mjd_transitionFD``).

        Args:
            state: State ``(nstate,)``.
            ctrl: Control ``(nu,)``.
            eps: Finite-difference step (default ``fd_eps``).
            centered: Centered differences (default ``fd_centered``).

        Returns:
            ``A`` ``(nx, nx)`` and ``B`` ``(nx, nu)``.
        """
        state = self.check_state(state)
        ctrl = self.check_ctrl(ctrl)
        return self._linearize_one(state, ctrl, eps, centered)

    def _linearize_one(self, state, ctrl, eps, centered) -> Linearization:
        data = self._data()
        self.set_state(data, state)
        data.ctrl[:] = ctrl
        A = np.zeros((self.nx, self.nx))
        B = np.zeros((self.nx, self.nu))
        mujoco.mjd_transitionFD(
            self.planning_model,
            data,
            self.fd_eps if eps is None else positive("eps", eps),
            self.fd_centered if centered is None else bool(centered),
            A,
            B,
            None,
            None,
        )
        return Linearization(A, B)

    def linearize_trajectory(
        self,
        states: np.ndarray,
        ctrls: np.ndarray,
        *,
        eps: float | None = None,
        centered: bool | None = None,
        threads: int | None = None,
    ) -> Linearization:
        """Linearize many knots in parallel (one MjData per thread; MuJoCo drops the GIL).

        Args:
            states: States ``(T, nstate)``.
            ctrls: Controls ``(T, nu)``.
            eps: Finite-difference step.
            centered: Centered differences.
            threads: Worker threads (default: the Problem's).

        Returns:
            ``A`` ``(T, nx, nx)`` and ``B`` ``(T, nx, nu)``.
        """
        states = as_array("states", states, (None, self.nstate))
        ctrls = as_array("ctrls", ctrls, (states.shape[0], self.nu))
        if not (np.all(np.isfinite(states)) and np.all(np.isfinite(ctrls))):
            raise DivergenceError("states or ctrls hold non-finite values")
        out = self._map(
            lambda i: self._linearize_one(states[i], ctrls[i], eps, centered), len(states), threads
        )
        return Linearization(np.stack([o.A for o in out]), np.stack([o.B for o in out]))

    def rollout(
        self,
        state: np.ndarray,
        ctrls: np.ndarray,
        *,
        model: mujoco.MjModel | Sequence[mujoco.MjModel] | None = None,
    ) -> Rollout:
        """Roll out control sequences on the planning model with :func:`mujoco.rollout.rollout`.

        Args:
            state: Start state ``(nstate,)``.
            ctrls: Controls ``(T, nu)`` or a batch ``(B, T, nu)``.
            model: A model (or one per batch row) to use instead of the planning model, for
                example with randomized parameters.

        Returns:
            A :class:`Rollout` with a leading batch axis (``B = 1`` for a single sequence).
            A rollout that diverged (MuJoCo reset it) holds NaN from that step on.
        """
        from mujoco import rollout as mj_rollout

        state = self.check_state(state)
        ctrls = np.asarray(ctrls, dtype=np.float64)
        if ctrls.ndim == 2:
            ctrls = ctrls[None]
        if ctrls.ndim != 3 or ctrls.shape[2] != self.nu or ctrls.shape[1] < 1:
            raise ShapeError(
                f"ctrls must have shape (T, {self.nu}) or (B, T, {self.nu}), got {ctrls.shape}"
            )
        nbatch, horizon = ctrls.shape[:2]
        ctrls = self.clip_ctrl(ctrls)
        padded = np.concatenate([ctrls, ctrls[:, -1:]], axis=1)
        init = self.full_physics_state(state)
        datas = self._rollout_datas()
        models = self.planning_model if model is None else model
        out_state, out_sens = mj_rollout.rollout(
            models, datas, np.tile(init, (nbatch, 1)), padded, persistent_pool=True
        )
        qa = 1
        cols = slice(qa, qa + self.nstate)
        states = np.empty((nbatch, horizon + 1, self.nstate))
        states[:, 0] = state
        states[:, 1:] = out_state[:, :horizon, cols]
        # MuJoCo resets a diverged simulation (warning mjWARN_BADQACC) and carries on from the
        # model's reference pose, time 0: the time column then steps back. Mark those
        # rollouts non-finite from the reset on, so that no one scores the reset pose.
        times = np.concatenate([np.full((nbatch, 1), init[0]), out_state[:, :, 0]], axis=1)
        stepped_back = np.diff(times, axis=1) <= 0.0  # (B, T + 1)
        if stepped_back.any():
            after = np.cumsum(stepped_back, axis=1) > 0
            states[:, 1:][after[:, :horizon]] = np.nan
            out_sens = np.array(out_sens)
            out_sens[after] = np.nan
        return Rollout(states, out_sens, ctrls)

    def _rollout_datas(self) -> list[mujoco.MjData]:
        datas = getattr(self, "_rollout_data_list", None)
        if datas is None:
            datas = [mujoco.MjData(self.planning_model) for _ in range(self.threads)]
            self._rollout_data_list = datas
        return datas

    def full_physics_state(self, state: np.ndarray) -> np.ndarray:
        """``mjSTATE_FULLPHYSICS`` vector (time, qpos, qvel, act, ...) for a state."""
        data = self._data()
        mujoco.mj_resetData(self.planning_model, data)
        self.set_state(data, state)
        full = np.zeros(self._full_size)
        mujoco.mj_getState(self.planning_model, data, full, _FULL)
        return full

    # ------------------------------------------------------------------ costs
    def features(self, state: np.ndarray, ctrl: np.ndarray | None = None) -> Features:
        """Cost features of one state (after ``mj_forward`` on the planning model)."""
        data = self._data()
        self.set_state(data, self.check_state(state))
        data.ctrl[:] = self.ctrl_ref if ctrl is None else self.check_ctrl(ctrl)
        mujoco.mj_forward(self.planning_model, data)
        return self._features_of(data)

    def _features_of(self, data: mujoco.MjData) -> Features:
        return Features(
            data.qpos[None].copy(),
            data.qvel[None].copy(),
            data.ctrl[None].copy(),
            data.sensordata[None].copy(),
        )

    def running_cost(self, state: np.ndarray, ctrl: np.ndarray) -> float:
        """Running cost ``l(x, u)`` of one knot."""
        return float(self.cost.running_value(self.features(state, ctrl))[0])

    def terminal_cost(self, state: np.ndarray) -> float:
        """Terminal cost ``l_T(x)``."""
        return float(self.cost.terminal_value(self.features(state))[0])

    def rollout_cost(self, rollout: Rollout) -> np.ndarray:
        """Total cost of each rollout: running costs over ``T`` knots plus the terminal cost.

        Returns:
            Costs ``(B,)``.
        """
        states, sens, ctrls = rollout.states, rollout.sensordata, rollout.ctrls
        nb, horizon = ctrls.shape[:2]
        nq, nv = self.nq, self.nv
        flat = Features(
            states[:, :horizon, :nq].reshape(-1, nq),
            states[:, :horizon, nq : nq + nv].reshape(-1, nv),
            ctrls.reshape(-1, self.nu),
            sens[:, :horizon].reshape(nb * horizon, -1),
        )
        running = self.cost.running_value(flat).reshape(nb, horizon).sum(axis=1)
        last = Features(
            states[:, horizon, :nq],
            states[:, horizon, nq : nq + nv],
            ctrls[:, -1],
            sens[:, horizon],
        )
        return running + self.cost.terminal_value(last)

    def cost_of_features(self, features: Features, terminal: bool = False) -> np.ndarray:
        """Running (or terminal) cost for a batch of features, shape ``(B,)``."""
        check_features(features, self.planning_model)
        if terminal:
            return self.cost.terminal_value(features)
        return self.cost.running_value(features)

    def quadratize(
        self, state: np.ndarray, ctrl: np.ndarray, *, terminal: bool = False
    ) -> Quadratization:
        r"""Gauss-Newton quadratization of the running (or terminal) cost.

        With residual Jacobians :math:`J_x, J_u` and weights :math:`W`:
        :math:`\ell_x = J_x^T W r`, :math:`\ell_{xx} = J_x^T W J_x`,
        :math:`\ell_{ux} = J_u^T W J_x`.
        Terms without an analytic :meth:`~mpcbox.core.cost.CostTerm.jacobian` are differentiated by
        finite differences in the tangent space.
        """
        state = self.check_state(state)
        ctrl = self.check_ctrl(ctrl)
        return self._quadratize_one(state, ctrl, terminal)

    def _quadratize_one(self, state, ctrl, terminal) -> Quadratization:
        out = self._quadratize_batch(state[None], ctrl[None], terminal)
        return Quadratization(*(getattr(out, f)[0] for f in Quadratization._fields))

    def _quadratize_batch(self, states, ctrls, terminal) -> Quadratization:
        """Gauss-Newton quadratization of ``B`` knots (one term type at a time, vectorized).

        Terms whose Jacobian does not depend on the state (``constant_jacobian``) contribute
        the same Hessian blocks at every knot, computed once; the others are evaluated per
        knot (analytically, or by finite differences).
        """
        terms = self.cost.terminal if terminal else self.cost.running
        nx, nu, nv = self.nx, self.nu, self.nv
        nb = len(states)
        value = np.zeros(nb)
        lx, lu = np.zeros((nb, nx)), np.zeros((nb, nu))
        lxx, luu, lux = np.zeros((nb, nx, nx)), np.zeros((nb, nu, nu)), np.zeros((nb, nu, nx))
        if not terms:
            return Quadratization(value, lx, lu, lxx, luu, lux)
        m = self.planning_model
        data = self._data()
        varying = [t for t in terms if not t.constant_jacobian]
        sens = np.empty((nb, m.nsensordata))
        jacs: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {id(t): [] for t in varying}
        for b in range(nb):
            self.set_state(data, states[b])
            data.ctrl[:] = ctrls[b]
            mujoco.mj_forward(m, data)
            sens[b] = data.sensordata
            for term in varying:
                jacs[id(term)].append(self._term_jacobian(term, data, states[b], ctrls[b]))
        feats = Features(states[:, : self.nq], states[:, self.nq : self.nq + nv], ctrls, sens)
        for term in terms:
            r = term.residual(feats)
            w = term.weight
            wr = w * r
            value += 0.5 * np.sum(wr * r, axis=1)
            if term.constant_jacobian:
                jx, ju = self._term_jacobian(term, data, states[-1], ctrls[-1])
                lx += wr @ jx
                lu += wr @ ju
                wjx = jx * w[:, None]
                lxx += jx.T @ wjx
                luu += ju.T @ (ju * w[:, None])
                lux += ju.T @ wjx
            else:
                jx = np.stack([j[0] for j in jacs[id(term)]])
                ju = np.stack([j[1] for j in jacs[id(term)]])
                lx += np.einsum("bk,bkn->bn", wr, jx)
                lu += np.einsum("bk,bkn->bn", wr, ju)
                wjx = jx * w[None, :, None]
                lxx += np.einsum("bki,bkj->bij", jx, wjx)
                luu += np.einsum("bki,bkj->bij", ju, ju * w[None, :, None])
                lux += np.einsum("bki,bkj->bij", ju, wjx)
        lxx = 0.5 * (lxx + lxx.transpose(0, 2, 1))
        luu = 0.5 * (luu + luu.transpose(0, 2, 1))
        return Quadratization(value, lx, lu, lxx, luu, lux)

    def _term_jacobian(self, term, data, state, ctrl) -> tuple[np.ndarray, np.ndarray]:
        """``(dr/dx (k, nx), dr/du (k, nu))`` of one term at the state held in ``data``."""
        jac = term.jacobian(self.planning_model, data)
        if jac is None:
            feats = self._features_of(data)
            r0 = term.residual(feats)[0]
            jx, ju = self._residual_fd(term, state, ctrl, r0)
            self.set_state(data, state)
            data.ctrl[:] = ctrl
            mujoco.mj_forward(self.planning_model, data)
            return jx, ju
        jx = np.zeros((jac.dq.shape[0], self.nx))
        jx[:, : self.nv] = jac.dq
        jx[:, self.nv : 2 * self.nv] = jac.dv
        return jx, jac.du

    def _residual_fd(self, term, state, ctrl, r0) -> tuple[np.ndarray, np.ndarray]:
        eps = self.fd_eps
        m = self.planning_model
        data = self._data()
        jx = np.zeros((len(r0), self.nx))
        ju = np.zeros((len(r0), self.nu))

        def eval_at(x, u):
            self.set_state(data, x)
            data.ctrl[:] = u
            mujoco.mj_forward(m, data)
            return term.residual(self._features_of(data))[0]

        for i in range(self.nx):
            dx = np.zeros(self.nx)
            dx[i] = eps
            jx[:, i] = (eval_at(self.state_add(state, dx), ctrl) - r0) / eps
        for i in range(self.nu):
            du = np.zeros(self.nu)
            du[i] = eps
            ju[:, i] = (eval_at(state, ctrl + du) - r0) / eps
        return jx, ju

    def quadratize_trajectory(
        self, states: np.ndarray, ctrls: np.ndarray, *, threads: int | None = None
    ) -> Quadratization:
        """Quadratize the running cost at ``T`` knots and the terminal cost at the last state.

        Args:
            states: ``(T + 1, nstate)``.
            ctrls: ``(T, nu)``.

        Returns:
            Stacked arrays with leading size ``T + 1`` (the last row is the terminal cost;
            its control blocks are zero).
        """
        states = as_array("states", states, (None, self.nstate))
        ctrls = as_array("ctrls", ctrls, (states.shape[0] - 1, self.nu))
        horizon = len(ctrls)
        threads = self.threads if threads is None else positive_int("threads", threads)
        # Chunks of knots: the C calls drop the GIL, the vectorized numpy work is per chunk.
        bounds = np.linspace(0, horizon, min(threads, horizon) + 1).astype(int)
        parts = self._map(
            lambda j: self._quadratize_batch(
                states[bounds[j] : bounds[j + 1]], ctrls[bounds[j] : bounds[j + 1]], False
            ),
            len(bounds) - 1,
            threads,
        )
        last = self._quadratize_batch(states[-1:], ctrls[-1:], True)
        return Quadratization(
            *(
                np.concatenate([getattr(q, f) for q in [*parts, last]])
                for f in Quadratization._fields
            )
        )

    # ------------------------------------------------------------------ equilibrium
    def find_equilibrium(self, qpos: np.ndarray | None = None, **kwargs):
        """Control that holds a posture, from inverse dynamics (see :func:`find_equilibrium`)."""
        from mpcbox.core.equilibrium import find_equilibrium

        return find_equilibrium(self.model, self.qpos_ref if qpos is None else qpos, **kwargs)

    # ------------------------------------------------------------------ monitoring
    def failure(self, model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
        """Why the simulation should stop (a fall, non-finite state), or ``None``.

        The base class only checks that the state is finite. Subclasses add falls.
        """
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return "non-finite state"
        return None

    def measures(self) -> Sequence[Any]:
        """The task's own measures, sampled at every step of a closed-loop run.

        :func:`mpcbox.simulate` samples each one after every step and summarizes it in
        :attr:`Metrics.measures <mpcbox.Metrics>`; comparison tables show a column per
        summary. The base class declares none; the humanoid tasks report the center of mass
        over the support and the torso tilt (:mod:`mpcbox.tasks.humanoid.measures`).

        Returns:
            A sequence of :class:`mpcbox.sim.measures.Measure` with distinct names.
        """
        return ()

    def noise(self, scale: float = 1.0) -> Any:
        """The task's actuator-noise model at ``scale`` times its nominal level.

        Scenarios of :func:`mpcbox.compare` that ask for noise without giving one use it.
        The base class has none.

        Args:
            scale: Multiplier on the nominal standard deviations.

        Returns:
            A :class:`mpcbox.ActuatorNoise`.

        Raises:
            InvalidArgumentError: Always, in the base class: the task has no noise model.
        """
        raise InvalidArgumentError(
            f"task {self.name!r} ({type(self).__name__}) has no noise model: give an explicit "
            "mpcbox.ActuatorNoise, or noise scale 0"
        )

    def with_planning_timestep(self, timestep: float) -> Problem:
        """A shallow copy whose planning model takes steps of ``timestep`` seconds.

        The copy shares the simulation model, the cost and the references; only the planning
        model (a copy with ``opt.timestep`` changed, same sensors) and the per-thread scratch
        data are its own. Controllers that want a coarser prediction model than the others
        (for example iLQR on a humanoid) build one this way.

        Args:
            timestep: Planning timestep (s).
        """
        import copy

        clone = copy.copy(self)
        clone.planning_model = _copy_model(self.planning_model)
        clone.planning_model.opt.timestep = positive("timestep", timestep)
        clone._local = threading.local()
        clone._pool = None
        clone.__dict__.pop("_rollout_data_list", None)
        return clone

    def with_cost(self, cost: Cost) -> Problem:
        """A shallow copy with another :class:`Cost` (bound to the planning model).

        The new cost may only use sensors the models already have. Controllers use this to add
        terms of their own, e.g. an LQR value function as terminal cost.
        """
        import copy

        if not isinstance(cost, Cost):
            raise InvalidArgumentError(f"cost must be an mpcbox.Cost, got {type(cost).__name__}")
        missing = [
            r.name
            for r in cost.sensors(self.planning_model)
            if mujoco.mj_name2id(self.planning_model, mujoco.mjtObj.mjOBJ_SENSOR, r.name) < 0
        ]
        if missing:
            raise ModelLoadError(f"cost: sensors {missing} are not in the Problem's models")
        clone = copy.copy(self)
        clone.cost = cost
        cost.bind(self.planning_model)
        clone._local = threading.local()
        clone._pool = None
        return clone

    def close(self) -> None:
        """Shut down the thread pool."""
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(name={self.name!r}, nq={self.nq}, nv={self.nv}, nu={self.nu}, "
            f"dt_sim={self.model.opt.timestep}, dt_plan={self.dt})"
        )


def _copy_model(model: mujoco.MjModel) -> mujoco.MjModel:
    import copy

    return copy.copy(model)
