r"""Stepping, rollouts and finite-difference linearization of a planning model.

:class:`Dynamics` owns a compiled MuJoCo model and the scratch memory that predicting with it
needs: one :class:`mujoco.MjData` per calling thread, the ``MjData`` list of
:func:`mujoco.rollout.rollout`, and a persistent thread pool. Its methods trust their inputs
(:class:`~mpcbox.core.problem.Problem` checks shapes and finiteness before calling them).

A state is ``[qpos (nq), qvel (nv), act (na)]``; a linearization maps tangent-space deviations
``dx = [dq (nv), dv (nv), da (na)]`` of one step: :math:`dx_{t+1} = A\,dx_t + B\,du_t`.
"""

from __future__ import annotations

import copy
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import NamedTuple, TypeVar

import mujoco
import numpy as np

from mpcbox.core.mujoco_warnings import captured_warnings
from mpcbox.core.step_fd import step_jacobians
from mpcbox.errors import MujocoError
from mpcbox.validation import positive_int

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS

#: Constraint-solver tolerance of the model copy that linearizations difference. MuJoCo's
#: solver stops once its improvement falls below ``opt.tolerance`` (1e-8 by default), and a
#: finite-difference step warm-started from the nominal solution can stop at once: on
#: PNDbotics' Adam Lite standing on its mesh feet every column of ``B`` came out exactly zero
#: at the default, and right at 1e-10. On the models measured at 1e-12 the Jacobians equal
#: the default's and take no longer (tolerance 0 runs every iteration: 25-30x slower).
FD_SOLVER_TOLERANCE = 1e-12
_RK4 = mujoco.mjtIntegrator.mjINT_RK4
_NO_FRICTIONLOSS = int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)


def has_dry_friction(model: mujoco.MjModel) -> bool:
    """Whether any joint or tendon of ``model`` has dry friction (``frictionloss > 0``) that
    its options leave on."""
    if model.opt.disableflags & _NO_FRICTIONLOSS:
        return False
    joints = model.nv > 0 and bool(np.any(model.dof_frictionloss > 0))
    return joints or (model.ntendon > 0 and bool(np.any(model.tendon_frictionloss > 0)))


T = TypeVar("T")


class Linearization(NamedTuple):
    """Discrete-time Jacobians ``A`` ``(..., nx, nx)`` and ``B`` ``(..., nx, nu)``."""

    A: np.ndarray
    B: np.ndarray


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


def read_state(data: mujoco.MjData) -> np.ndarray:
    """The state ``[qpos, qvel, act]`` held in ``data``, shape ``(nstate,)``."""
    return np.concatenate([data.qpos, data.qvel, data.act])


def write_state(data: mujoco.MjData, state: np.ndarray) -> None:
    """Write a state ``[qpos, qvel, act]`` into ``data`` (sizes taken from ``data``)."""
    nq, nv = data.qpos.size, data.qvel.size
    data.qpos[:] = state[:nq]
    data.qvel[:] = state[nq : nq + nv]
    data.act[:] = state[nq + nv :]


@contextmanager
def mujoco_errors(what: str) -> Iterator[None]:
    """Turn a :class:`mujoco.FatalError` raised inside the block into :class:`MujocoError`.

    Args:
        what: The operation, for the message (e.g. ``"linearize"``).
    """
    try:
        yield
    except mujoco.FatalError as exc:
        raise MujocoError(f"{what}: MuJoCo stopped with a fatal error: {exc}") from exc


class Dynamics:
    """One model's step, rollouts and linearizations, with per-thread scratch data.

    Args:
        model: The model to predict with (a Problem's planning model).
        threads: Worker threads for batched work, and ``MjData`` objects for rollouts.
        drop_friction: Linearize without the model's dry friction (:meth:`fd_model`);
            steps and rollouts keep it.
    """

    def __init__(self, model: mujoco.MjModel, threads: int, drop_friction: bool = False) -> None:
        self.model = model
        self.threads = threads
        self.drop_friction = bool(drop_friction)
        self.nq, self.nv, self.nu, self.na = model.nq, model.nv, model.nu, model.na
        self.nx = 2 * self.nv + self.na
        self.nstate = self.nq + self.nv + self.na
        self._local = threading.local()
        self._pool: ThreadPoolExecutor | None = None
        self._rollout_datas: list[mujoco.MjData] | None = None
        self._full_size = mujoco.mj_stateSize(model, _FULL)
        self._fd_lock = threading.Lock()
        self._fd: tuple[tuple, mujoco.MjModel] | None = None

    # ------------------------------------------------------------------ scratch memory
    def scratch_data(self) -> mujoco.MjData:
        """An ``MjData`` of :attr:`model` that belongs to the calling thread.

        The same object is returned on every call from one thread; it holds whatever the
        last user left in it, so write the full state (and ``ctrl``) before using it.
        """
        data = getattr(self._local, "data", None)
        if data is None:
            data = mujoco.MjData(self.model)
            self._local.data = data
        return data

    def executor(self) -> ThreadPoolExecutor:
        """The persistent thread pool (``threads`` workers), created on first use."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="mpcbox")
        return self._pool

    def map(self, fn: Callable[[int], T], count: int, threads: int | None = None) -> list[T]:
        """``[fn(i) for i in range(count)]`` on contiguous chunks, one chunk per thread.

        Args:
            fn: Work item; MuJoCo calls inside it drop the GIL.
            count: Number of items.
            threads: Threads to use (default :attr:`threads`); more than :attr:`threads`
                uses a temporary pool.
        """
        threads = self.threads if threads is None else positive_int("threads", threads)
        threads = min(threads, count)
        if threads <= 1:
            return [fn(i) for i in range(count)]
        bounds = np.linspace(0, count, threads + 1).astype(int)

        def chunk(j: int) -> list[T]:
            return [fn(i) for i in range(bounds[j], bounds[j + 1])]

        if threads <= self.threads:
            parts = list(self.executor().map(chunk, range(threads)))
        else:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                parts = list(pool.map(chunk, range(threads)))
        return [item for part in parts for item in part]

    def close(self) -> None:
        """Shut down the thread pool."""
        if self._pool is not None:
            self._pool.shutdown(wait=False)
            self._pool = None

    # ------------------------------------------------------------------ prediction
    def step(self, state: np.ndarray, ctrl: np.ndarray) -> np.ndarray:
        """The state after one ``mj_step`` from ``state`` under ``ctrl``."""
        data = self.scratch_data()
        write_state(data, state)
        data.ctrl[:] = ctrl
        with mujoco_errors("step"):
            mujoco.mj_step(self.model, data)
        return read_state(data)

    def linearize(
        self, state: np.ndarray, ctrl: np.ndarray, eps: float, centered: bool
    ) -> Linearization:
        """Jacobians ``A`` ``(nx, nx)``, ``B`` ``(nx, nu)`` of one step (``mjd_transitionFD``;
        for RK4, which it refuses, :func:`~mpcbox.core.step_fd.step_jacobians`).

        Args:
            state: State ``(nstate,)``.
            ctrl: Control ``(nu,)``.
            eps: Finite-difference step.
            centered: Centered (True) or forward (False) differences.
        """
        with mujoco_errors("linearize"):
            return self._linearize(state, ctrl, eps, centered)

    def fd_model(self) -> mujoco.MjModel:
        """The model that linearizations difference: :attr:`model` itself, or a copy with the
        solver tolerance at most :data:`FD_SOLVER_TOLERANCE` and, with ``drop_friction``, dry
        friction off (``mjDSBL_FRICTIONLOSS``), made on first use and again whenever
        ``model.opt`` changes (other fields changed in place after the first linearization
        are not seen: build a new Problem instead)."""
        model = self.model
        drop = self.drop_friction and has_dry_friction(model)
        if model.opt.tolerance <= FD_SOLVER_TOLERANCE and not drop:
            return model
        opt = model.opt
        signature = (
            opt.timestep, opt.integrator, opt.iterations, opt.tolerance, opt.ls_iterations,
            opt.ls_tolerance, opt.noslip_iterations, opt.disableflags, opt.enableflags,
            opt.cone, opt.solver, opt.impratio, tuple(opt.gravity),
        )  # fmt: skip
        with self._fd_lock:
            if self._fd is None or self._fd[0] != signature:
                tight = copy.copy(model)
                tight.opt.tolerance = min(opt.tolerance, FD_SOLVER_TOLERANCE)
                if drop:
                    tight.opt.disableflags |= _NO_FRICTIONLOSS
                self._fd = (signature, tight)
            return self._fd[1]

    def _linearize(self, state, ctrl, eps, centered) -> Linearization:
        data = self.scratch_data()
        write_state(data, state)
        data.ctrl[:] = ctrl
        A = np.zeros((self.nx, self.nx))
        B = np.zeros((self.nx, self.nu))
        model = self.fd_model()
        if model.opt.integrator == _RK4:  # mjd_transitionFD refuses RK4
            step_jacobians(model, data, eps, centered, A, B)
        else:
            mujoco.mjd_transitionFD(model, data, eps, centered, A, B, None, None)
        return Linearization(A, B)

    def linearize_trajectory(
        self,
        states: np.ndarray,
        ctrls: np.ndarray,
        eps: float,
        centered: bool,
        threads: int | None = None,
    ) -> Linearization:
        """:meth:`linearize` at ``T`` knots ``(T, nstate)``, ``(T, nu)`` in parallel.

        Returns:
            ``A`` ``(T, nx, nx)`` and ``B`` ``(T, nx, nu)``.
        """
        with mujoco_errors("linearize_trajectory"):
            out = self.map(
                lambda i: self._linearize(states[i], ctrls[i], eps, centered), len(states), threads
            )
        return Linearization(np.stack([o.A for o in out]), np.stack([o.B for o in out]))

    def rollout(
        self,
        state: np.ndarray,
        ctrls: np.ndarray,
        model: mujoco.MjModel | Sequence[mujoco.MjModel] | None = None,
    ) -> Rollout:
        """Roll out control sequences ``(B, T, nu)`` from ``state`` (:func:`mujoco.rollout`).

        Args:
            state: Start state ``(nstate,)``.
            ctrls: Controls ``(B, T, nu)``, already inside the control range.
            model: A model, or one per batch row, to use instead of :attr:`model`.

        Returns:
            The :class:`Rollout`; a rollout that MuJoCo reset after diverging holds NaN from
            the reset on. MuJoCo's warning for it is kept from stderr
            (:func:`~mpcbox.core.mujoco_warnings.captured_warnings`): the NaN rows report it.
        """
        from mujoco import rollout as mj_rollout

        nbatch, horizon = ctrls.shape[:2]
        padded = np.concatenate([ctrls, ctrls[:, -1:]], axis=1)
        init = self.full_physics_state(state)
        # Start the clock at 1 s: a reset (time 0, then one step) then always reads as time
        # stepping back, even on the first step. The state carries no time, so nothing else
        # sees the offset.
        init[0] = 1.0
        models = self.model if model is None else model
        with mujoco_errors("rollout"), captured_warnings():
            out_state, out_sens = mj_rollout.rollout(
                models,
                self.rollout_datas(),
                np.tile(init, (nbatch, 1)),
                padded,
                persistent_pool=True,
            )
        cols = slice(1, 1 + self.nstate)  # the full-physics state starts with the time
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

    def rollout_policy(
        self,
        state: np.ndarray,
        ctrls: np.ndarray,
        policy: Callable[[np.ndarray, np.ndarray], np.ndarray],
        model: mujoco.MjModel | Sequence[mujoco.MjModel] | None = None,
    ) -> Rollout:
        """Roll out ``(B, T, nu)`` controls through a state feedback, one step at a time,
        from one start state ``(nstate,)`` or one per rollout ``(B, nstate)``.

        Before step ``t`` every rollout's control is ``policy(states[:, t], ctrls[:, t])``
        (both batched, ``(B, nstate)`` and ``(B, nu)``; it returns ``(B, nu)`` controls inside
        the control range), so a rollout can hand over to a feedback law where it applies.
        With ``policy`` returning its second argument this is :meth:`rollout`. Each step is
        one :func:`mujoco.rollout.rollout` call over the batch (``T + 1`` calls), so it costs
        more than :meth:`rollout` on small models.

        Returns:
            The :class:`Rollout`, with ``ctrls`` the controls the policy applied; NaN from a
            divergence on, as in :meth:`rollout`.
        """
        from mujoco import rollout as mj_rollout

        nbatch, horizon = ctrls.shape[:2]
        starts = np.broadcast_to(state, (nbatch, self.nstate))
        if np.ndim(state) == 1:
            current = np.tile(self.full_physics_state(state), (nbatch, 1))
        else:
            current = np.stack([self.full_physics_state(s) for s in starts])
        current[:, 0] = 1.0  # see rollout(): a reset then reads as time stepping back
        models = self.model if model is None else model
        cols = slice(1, 1 + self.nstate)
        states = np.empty((nbatch, horizon + 1, self.nstate))
        states[:, 0] = starts
        applied = np.empty_like(ctrls)
        sensor = np.empty((nbatch, horizon + 1, self.model.nsensordata))
        diverged = np.zeros(nbatch, dtype=bool)
        with mujoco_errors("rollout"), captured_warnings():
            for t in range(horizon + 1):
                if t < horizon:
                    applied[:, t] = policy(states[:, t], ctrls[:, t])
                step = applied[:, min(t, horizon - 1)]
                out_state, out_sens = mj_rollout.rollout(
                    models,
                    self.rollout_datas(),
                    current,
                    step[:, None, :],
                    persistent_pool=True,
                )
                sensor[:, t] = out_sens[:, 0]
                sensor[diverged, t] = np.nan
                diverged |= out_state[:, 0, 0] <= current[:, 0]
                current = out_state[:, 0]
                if t < horizon:
                    states[:, t + 1] = current[:, cols]
                    states[diverged, t + 1] = np.nan
        return Rollout(states, sensor, applied)

    def rollout_datas(self) -> list[mujoco.MjData]:
        """The ``MjData`` list of :func:`mujoco.rollout.rollout`, one per thread, made once."""
        if self._rollout_datas is None:
            self._rollout_datas = [mujoco.MjData(self.model) for _ in range(self.threads)]
        return self._rollout_datas

    def full_physics_state(self, state: np.ndarray) -> np.ndarray:
        """The ``mjSTATE_FULLPHYSICS`` vector (time, qpos, qvel, act, ...) of a state."""
        data = self.scratch_data()
        mujoco.mj_resetData(self.model, data)
        write_state(data, state)
        full = np.zeros(self._full_size)
        mujoco.mj_getState(self.model, data, full, _FULL)
        return full
