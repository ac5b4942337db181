r"""MuJoCo Warp backend: all candidates (times randomized models) as worlds of one batched Data.

One tick, for ``W = N M`` worlds (world ``w`` rolls out candidate ``w // M`` on model
``w % M``):

1. the host uploads the start state ``(nstate,)`` and the knots ``(N, K, nu)``;
2. on the device: broadcast the state to every world and clear costs and overflow flags;
   then for ``t = 0 .. T-1`` one fused launch (a thread per world and actuator or cost row:
   :func:`~mpcbox.controllers.sampling.backends.warp_costs.fused_stage_kernel`) interpolates
   and clamps :math:`u_t`, adds the state/control rows at :math:`x_t` and the sensor rows of
   step ``t - 1`` (sensors at :math:`x_{t-1}`, from that step's kinematics), followed by
   ``mjw.step`` and, when the cost's sensors are all of the kinds
   :mod:`~mpcbox.controllers.sampling.backends.warp_sensors` computes, its one sensor launch
   (MJWarp's own sensor pipeline is then off in the planning model; else MJWarp computes
   them inside the step); then the last sensor rows, the terminal rows at :math:`x_T` (after
   ``mjw.forward`` if they read sensors) and per-world flags for capacity overflow and
   divergence (as MuJoCo checks after each step: a non-finite ``qacc`` or one beyond
   ``1e10``, tested in the fused launch; the same for the final ``qpos`` and ``qvel``);
3. the host reads back only the costs ``(W,)`` and flags ``(W,)``.

On CUDA, step 2 is captured once as a CUDA graph and replayed each tick, so nothing
synchronizes with the host inside the horizon. :meth:`WarpBackend.submit` returns as soon
as the graph is launched, so the controller draws the next iteration's noise while the
device works; :meth:`WarpBackend.collect` waits for the read-back. Models without any
collidable geom pair plan with contacts disabled (MJWarp then skips its collision
pipeline).

Every world waits for the slowest one: MJWarp's constraint solver iterates (inside the
graph) until all worlds have converged, so diverse candidates cost more than identical
worlds; ``solver_iterations`` on the controller caps that (a cap of at most
:data:`UNROLL_MAX_ITERATIONS` is unrolled in the graph). Contact (``nconmax``) and constraint
(``njmax``) capacities come from calibration rollouts on the CPU with ``headroom``; a tick
that overflows marks the affected worlds (their samples are excluded by the controller) and
doubles the capacities for the next tick.
"""

from __future__ import annotations

import copy
import math
import time as _time
import warnings
from collections.abc import Sequence

import mujoco
import numpy as np

from mpcbox.controllers.sampling.backends.interface import AsyncRolloutBackend, RolloutCosts
from mpcbox.controllers.sampling.backends.warp_compile import precompile
from mpcbox.core.problem import Problem
from mpcbox.errors import BackendUnavailableError, InvalidArgumentError, UnsupportedModelError

#: Randomized model fields copied per model into the batched MJWarp Model.
RANDOMIZED_FIELDS: tuple[str, ...] = (
    "body_mass",
    "body_subtreemass",
    "body_inertia",
    "body_invweight0",
    "dof_invweight0",
    "geom_friction",
)

_MAX_RESIZES = 4

#: Solver caps up to this many iterations are unrolled in the captured graph instead of
#: running in a conditional while node: with so few iterations nearly every tick hits the
#: cap, and the unrolled launches are about 1 ms per tick cheaper at N = 2048 on an H200.
UNROLL_MAX_ITERATIONS = 3

#: Solver iterations of the CPU calibration rollouts (MuJoCo's default).
_CALIBRATION_ITERATIONS = 100


def _import_warp():
    try:
        import mujoco_warp as mjw
        import warp as wp
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise BackendUnavailableError(
            "backend='warp' needs the warp-lang and mujoco-warp packages "
            "(pip install warp-lang mujoco-warp)"
        ) from exc
    return wp, mjw


def has_collidable_pairs(model: mujoco.MjModel) -> bool:
    """Whether any two geoms (or an explicit ``<pair>``, or a flex) may collide.

    Conservative: compares contype/conaffinity of every geom pair, ignoring the body filters.
    """
    if model.npair > 0 or model.nflex > 0:
        return True
    ct = model.geom_contype.astype(np.int64)
    ca = model.geom_conaffinity.astype(np.int64)
    hit = ((ct[:, None] & ca[None, :]) != 0) | ((ca[:, None] & ct[None, :]) != 0)
    np.fill_diagonal(hit, False)
    return bool(hit.any())


def broadphase_candidates(model: mujoco.MjModel, data: mujoco.MjData, pairs: np.ndarray) -> int:
    """How many geom pairs pass MJWarp's broadphase tests in one state.

    A pair with a plane passes when the other geom's bounding sphere reaches the plane's
    half-space; any other pair when the bounding spheres (plus margins and gaps) overlap.
    MJWarp may also test boxes, so this is an upper bound on its candidates.

    Args:
        model: The model.
        data: Data after ``mj_forward`` or ``mj_step`` (``geom_xpos``, ``geom_xmat``).
        pairs: Geom id pairs ``(P, 2)`` that may collide (MJWarp's filtered pair list).
    """
    if len(pairs) == 0:
        return 0
    g1, g2 = pairs[:, 0], pairs[:, 1]
    r1, r2 = model.geom_rbound[g1], model.geom_rbound[g2]
    margin = model.geom_margin + model.geom_gap
    margin = margin[g1] + margin[g2]
    x1, x2 = data.geom_xpos[g1], data.geom_xpos[g2]
    z1 = data.geom_xmat[g1].reshape(-1, 3, 3)[:, :, 2]
    z2 = data.geom_xmat[g2].reshape(-1, 3, 3)[:, :, 2]
    spheres = np.sum((x1 - x2) ** 2, axis=1) <= (r1 + r2 + margin) ** 2
    plane1 = np.sum((x2 - x1) * z1, axis=1) <= r2 + margin
    plane2 = np.sum((x1 - x2) * z2, axis=1) <= r1 + margin
    passed = np.where(r1 == 0.0, plane1, np.where(r2 == 0.0, plane2, spheres))
    return int(passed.sum())


def warn_cpu_fallback(device: str) -> None:
    """Warn that the warp backend runs on warp's CPU device (slow; for tests)."""
    warnings.warn(
        f"backend='warp' without CUDA: running MuJoCo Warp on warp's {device!r} device, which "
        "is much slower than backend='cpu'",
        RuntimeWarning,
        stacklevel=3,
    )


def resolve_device(device: str | None) -> str:
    """The Warp device to use: CUDA when present; warp's CPU device with a warning otherwise.

    Raises:
        BackendUnavailableError: If a CUDA device is asked for and none is available.
        InvalidArgumentError: For an unknown device name.
    """
    wp, _ = _import_warp()
    if not isinstance(device, (str, type(None))):
        raise InvalidArgumentError(f"device must be a string or None, got {device!r}")
    cuda = wp.is_cuda_available()
    if device is None:
        if cuda:
            return "cuda:0"
        warn_cpu_fallback("cpu")
        return "cpu"
    if device.startswith("cuda"):
        if not cuda:
            raise BackendUnavailableError(
                f"device={device!r}: no CUDA device is available to Warp; use device='cpu' "
                "(slow) or backend='cpu'"
            )
        try:
            return str(wp.get_device(device))
        except Exception as exc:
            raise InvalidArgumentError(f"device={device!r} is not a Warp device: {exc}") from exc
    if device == "cpu":
        return "cpu"
    raise InvalidArgumentError(f"device must be 'cpu', 'cuda' or 'cuda:<index>', got {device!r}")


class WarpBackend(AsyncRolloutBackend):
    """Evaluate candidate knots on MuJoCo Warp with the costs computed on the device.

    Args:
        problem: The Problem (planning model and cost).
        weights: Interpolation matrix ``(T, K)``.
        models: ``M`` planning models (nominal or randomized copies of the planning model).
        device: Warp device name.
        headroom: Capacity as a multiple of the calibration maxima.
        use_graph: Capture each tick as a CUDA graph (ignored on the CPU device).
    """

    def __init__(
        self,
        problem: Problem,
        weights: np.ndarray,
        models: Sequence[mujoco.MjModel],
        *,
        device: str,
        headroom: float = 2.0,
        use_graph: bool = True,
    ) -> None:
        wp, mjw = _import_warp()
        from mpcbox.controllers.sampling.backends import warp_costs as wc
        from mpcbox.controllers.sampling.backends.warp_sensors import (
            DeviceSensors,
            own_sensor_plan,
        )
        from mpcbox.controllers.sampling.backends.warp_value import device_forms

        self._wp, self._mjw, self._wc = wp, mjw, wc
        self.problem = problem
        self.device = device
        self.headroom = float(headroom)
        self.weights_host = np.asarray(weights, dtype=np.float32)
        self.horizon_steps, self.num_knots = self.weights_host.shape
        self.models = list(models)
        self.use_graph = bool(use_graph) and device.startswith("cuda")
        # Raises UnsupportedCostTermError for terms without rows, before anything is compiled.
        self.running_rows = wc.build_rows(problem.cost.running)
        self.terminal_rows = wc.build_rows(problem.cost.terminal)
        self._sensor_plan = own_sensor_plan(problem, self.models[0])
        self.nconmax: int | None = None
        self.njmax: int | None = None
        self.nworld = 0
        self._graph = None
        self._num_candidates = 0
        self._pending: int | None = None
        self._precompiled = False
        self._stats = {
            "resizes": 0,
            "graph_captures": 0,
            "solver_limit_samples": 0,
            "setup_seconds": 0.0,
            "nconmax": 0,
            "njmax": 0,
            "contacts_disabled": 0,
            "precompiled_modules": 0,
            # Sensors computed by warp_sensors.sensor_kernel (-1: by MJWarp's pipeline).
            "own_sensors": -1 if self._sensor_plan is None else int(self._sensor_plan.kind.size),
        }
        with wp.ScopedDevice(device):
            m = self._put_model()
            self.m = m
            self.sensors = None
            if self._sensor_plan is not None and self._sensor_plan.kind.size:
                self.sensors = DeviceSensors(self._sensor_plan, device)
            self.running = wc.DeviceRows(self.running_rows, device, problem.nu)
            self.terminal = wc.DeviceRows(self.terminal_rows, device, problem.nu)
            self.running_forms = device_forms(self.running_rows.forms, device)
            self.terminal_forms = device_forms(self.terminal_rows.forms, device)
            self.weights = wp.array(self.weights_host, dtype=wp.float32)
            self.ctrl_low = wp.array(problem.ctrl_low.astype(np.float32), dtype=wp.float32)
            self.ctrl_high = wp.array(problem.ctrl_high.astype(np.float32), dtype=wp.float32)
            self.state = wp.zeros(problem.nstate, dtype=wp.float32)
        from mujoco_warp._src.types import OverflowType

        capacity = OverflowType.ALL & ~(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS)
        self.capacity_mask = int(capacity)
        self.solver_mask = int(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS)

    # ------------------------------------------------------------------ setup
    def _put_model(self):
        wp, mjw = self._wp, self._mjw
        disable = 0
        if not has_collidable_pairs(self.models[0]):
            # Nothing can touch: skip MJWarp's collision pipeline (many launches per step).
            disable |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
            self._stats["contacts_disabled"] = 1
        if self._sensor_plan is not None:
            # The cost's sensors come from warp_sensors.sensor_kernel (or none are read).
            disable |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        if disable:
            models = [copy.copy(model) for model in self.models]
            for model in models:
                model.opt.disableflags |= disable
            self.models = models
        base = self.models[0]
        nmod = len(self.models)
        batch = None if nmod == 1 else {f: nmod for f in RANDOMIZED_FIELDS}
        try:
            m = mjw.put_model(base, batch_sizes=batch)
        except NotImplementedError as exc:
            raise UnsupportedModelError(
                f"backend='warp': MuJoCo Warp cannot run this model ({exc}); use "
                "backend='cpu' (mujoco.rollout), which runs every MuJoCo model"
            ) from exc
        if batch is not None:
            for field in RANDOMIZED_FIELDS:
                arr = getattr(m, field)
                stacked = np.stack([getattr(mi, field) for mi in self.models])
                setattr(m, field, wp.array(stacked.astype(np.float32), dtype=arr.dtype))
        # Overflows are read back per world as flags; printing from kernels is disabled.
        m.opt.warn_overflow = 0
        if 0 < base.opt.iterations <= UNROLL_MAX_ITERATIONS:
            m.opt.graph_conditional = False
        return m

    def calibrate(self, state: np.ndarray, candidates: np.ndarray) -> tuple[int, int]:
        """Largest contact and constraint counts over CPU rollouts of a few candidates.

        MJWarp keeps its broadphase candidates and its contacts in one pool of ``nworld *
        nconmax`` slots shared by all worlds, so the contact count is taken as the larger of
        MuJoCo's contacts and the geom pairs that pass MJWarp's plane and bounding-sphere
        broadphase tests (:func:`broadphase_candidates`).

        Args:
            state: Start state ``(nstate,)``.
            candidates: Knots ``(n, K, nu)`` (a handful is enough).

        Returns:
            ``(max contacts or broadphase candidates, max nefc)`` over all steps and models.
        """
        p = self.problem
        ctrls = np.einsum("tk,nkj->ntj", self.weights_host.astype(np.float64), candidates)
        pairs = self.m.nxn_geom_pair_filtered.numpy().reshape(-1, 2)
        ncon = nefc = 0
        for model in self.models[: min(len(self.models), 4)]:
            if model.opt.iterations < _CALIBRATION_ITERATIONS:
                # A solver capped at a few iterations can blow up in float64 CPU rollouts
                # and inflate the counts; count contacts with a converged solver instead.
                model = copy.copy(model)
                model.opt.iterations = _CALIBRATION_ITERATIONS
            data = mujoco.MjData(model)
            for seq in ctrls:
                mujoco.mj_resetData(model, data)
                p.set_state(data, state)
                for u in seq:
                    data.ctrl[:] = u
                    mujoco.mj_step(model, data)
                    cand = broadphase_candidates(model, data, pairs)
                    ncon = max(ncon, data.ncon, cand)
                    nefc = max(nefc, data.nefc)
        return ncon, nefc

    def _allocate(self, num_candidates: int) -> None:
        wp, mjw = self._wp, self._mjw
        start = _time.perf_counter()
        self._num_candidates = num_candidates
        self.nworld = num_candidates * len(self.models)
        with wp.ScopedDevice(self.device):
            self.d = mjw.make_data(
                self.models[0], nworld=self.nworld, nconmax=self.nconmax, njmax=self.njmax
            )
            self.knots = wp.zeros(
                (num_candidates, self.num_knots, self.problem.nu), dtype=wp.float32
            )
            self.cost = wp.zeros(self.nworld, dtype=wp.float32)
            self.flags = wp.zeros(self.nworld, dtype=wp.int32)
            self._graph = None
            if not self._precompiled:
                # Compile (or load from the kernel cache) the tick's modules in parallel.
                self._stats["precompiled_modules"] = precompile(self._run, self.device)
                self._precompiled = True
            if self.use_graph:
                self._run()  # load every module before capturing
                with wp.ScopedCapture() as capture:
                    self._run()
                self._graph = capture.graph
                self._stats["graph_captures"] += 1
        self._stats["nconmax"], self._stats["njmax"] = self.nconmax, self.njmax
        self._stats["setup_seconds"] += _time.perf_counter() - start

    # ------------------------------------------------------------------ the tick
    def _run(self) -> None:
        """Every device operation of one tick (captured as a graph on CUDA)."""
        wp, mjw, wc = self._wp, self._mjw, self._wc
        m, d, nw = self.m, self.d, self.nworld
        p = self.problem
        per = len(self.models)
        wp.launch(
            wc.broadcast_kernel,
            dim=nw,
            inputs=[self.state, p.nq, p.nv],
            outputs=[
                d.qpos, d.qvel, d.act, d.time, d.qacc_warmstart, d.overflow, self.cost, self.flags,
            ],
        )  # fmt: skip
        run, term = self.running, self.terminal
        ncols = p.nu + run.num_state_rows + run.num_sensor_rows
        common = [
            self.weights, self.knots, self.ctrl_low, self.ctrl_high, d.qpos, d.qvel, d.qacc,
            d.sensordata, run.arrays,
        ]  # fmt: skip
        sensors = int(run.has_sensors)
        # One fused launch per step: controls, state/control rows at x_t, and the sensor rows
        # of the previous step (MJWarp computed them at x_{t-1} inside step t - 1).
        for t in range(self.horizon_steps):
            wp.launch(
                wc.fused_stage_kernel,
                dim=(nw, ncols),
                inputs=[t, per, 1, sensors if t > 0 else 0, *common],
                outputs=[d.ctrl, self.cost, self.flags],
            )
            for form in self.running_forms:
                form.launch(nw, d.qpos, d.qvel, self.cost)
            mjw.step(m, d)
            if self.sensors is not None:
                self.sensors.launch(m, d, nw)
        if run.has_sensors:
            wp.launch(
                wc.fused_stage_kernel,
                dim=(nw, ncols),
                inputs=[self.horizon_steps, per, 0, 1, *common],
                outputs=[d.ctrl, self.cost, self.flags],
            )
        if term.has_sensors:
            mjw.forward(m, d)
            if self.sensors is not None:
                self.sensors.launch(m, d, nw)
        if term.has_state or term.has_sensors:
            wp.launch(
                wc.terminal_kernel,
                dim=nw,
                inputs=[
                    int(term.has_state), int(term.has_sensors), d.qpos, d.qvel,
                    d.sensordata, term.arrays, d.ctrl,
                ],
                outputs=[self.cost],
            )  # fmt: skip
        for form in self.terminal_forms:
            form.launch(nw, d.qpos, d.qvel, self.cost)
        wp.launch(
            wc.finalize_kernel,
            dim=nw,
            inputs=[
                self.cost, d.overflow, self.capacity_mask, self.solver_mask, d.qpos, d.qvel,
                d.qacc,
            ],
            outputs=[self.flags],
        )  # fmt: skip

    def submit(self, state: np.ndarray, candidates: np.ndarray) -> None:
        """Upload ``state`` and the knots and launch the tick without waiting for it."""
        wp = self._wp
        candidates = np.asarray(candidates)
        n = candidates.shape[0]
        if candidates.ndim != 3 or candidates.shape[1:] != (self.num_knots, self.problem.nu):
            raise InvalidArgumentError(
                f"candidates must have shape (N, {self.num_knots}, {self.problem.nu}), "
                f"got {candidates.shape}"
            )
        if self.nconmax is None:
            cal = np.asarray(candidates[: min(n, 8)], dtype=np.float64)
            ncon, nefc = self.calibrate(state, cal)
            self.nconmax = max(math.ceil(self.headroom * ncon), 4)
            self.njmax = max(math.ceil(self.headroom * nefc), 8)
        if n != self._num_candidates:
            self._allocate(n)
        with wp.ScopedDevice(self.device):
            self.state.assign(np.asarray(state, dtype=np.float32))
            self.knots.assign(np.ascontiguousarray(candidates, dtype=np.float32))
            if self._graph is not None:
                wp.capture_launch(self._graph)
            else:
                self._run()
        self._pending = n

    def collect(self) -> RolloutCosts:
        """Wait for the launched tick and read back costs and flags."""
        wp = self._wp
        n, self._pending = self._pending, None
        if n is None:
            raise InvalidArgumentError("collect() needs a submit() first")
        m = len(self.models)
        with wp.ScopedDevice(self.device):
            costs = self.cost.numpy().astype(np.float64).reshape(n, m)
            flags = self.flags.numpy().reshape(n, m)
        wc = self._wc
        overflow = (flags & int(wc.FLAG_CAPACITY)) != 0
        diverged = (flags & int(wc.FLAG_DIVERGED)) != 0
        solver_limit = (flags & int(wc.FLAG_SOLVER_LIMIT)) != 0
        self._stats["solver_limit_samples"] += int(solver_limit.any(axis=1).sum())
        if overflow.any():
            self._grow()
        return RolloutCosts(costs, overflow, diverged)

    def _grow(self) -> None:
        if self._stats["resizes"] >= _MAX_RESIZES:
            return
        warnings.warn(
            f"MuJoCo Warp capacity overflow (nconmax={self.nconmax}, njmax={self.njmax}): "
            "affected samples were excluded; doubling the capacity",
            RuntimeWarning,
            stacklevel=3,
        )
        assert self.nconmax is not None and self.njmax is not None
        self.nconmax *= 2
        self.njmax *= 2
        self._stats["resizes"] += 1
        self._num_candidates = 0  # reallocate (and recapture) on the next tick

    @property
    def stats(self) -> dict[str, float]:
        return dict(self._stats)

    def close(self) -> None:
        """Drop device buffers and the graph."""
        self._graph = None
        self.d = None
        self._num_candidates = 0
