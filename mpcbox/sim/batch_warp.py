r"""The same closed-loop trials as ``N`` parallel MuJoCo Warp worlds, one controller each.

:func:`simulate_batch_warp` runs world ``i`` from ``initial_states[i]`` under
``controllers[i]``, which sees its world's state every ``period`` seconds exactly as under
:func:`mpcbox.simulate` (same period, same held control between calls). Per control tick:

1. the device steps all worlds ``period / dt`` times with the controls held (on CUDA one
   captured graph, replayed every tick);
2. the host reads back the states ``(N, nstate)`` and the per-world overflow flags ``(N,)``
   (one small copy per control tick, none per physics step);
3. each world's controller computes its control; the host uploads ``(N, nu)``.

Capacity: ``nconmax`` and ``njmax`` (per world) come from CPU calibration runs of the first
worlds (four by default) under their controllers, taken at every step (the largest contact
count, or broadphase candidates, and constraint rows), times ``headroom``. A world whose
contacts or constraints overflow is marked and counts as failed
(:attr:`BatchResult.overflow`), as is a world whose state stops being finite or whose
acceleration exceeds MuJoCo's divergence bound.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.controllers.base import Controller
from mpcbox.controllers.sampling.backends.warp import (
    _import_warp,
    broadphase_candidates,
    resolve_device,
)
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array, integer, positive

#: MuJoCo's bound on accelerations before it calls a state diverged (``mjMAXVAL``).
MAX_ACCELERATION = 1e10


class BatchResult(NamedTuple):
    """Outcome of :func:`simulate_batch_warp` for ``N`` worlds.

    Attributes:
        time: Times ``(R,)`` of the recorded states (s).
        states: States ``(R, N, nstate)`` every ``record_period`` (the last row is the
            final state).
        overflow: Worlds whose contact or constraint capacity overflowed ``(N,)``.
        diverged: Worlds whose state became non-finite or whose acceleration blew up
            ``(N,)``.
        errors: Controller error message per world (``""`` for none) ``(N,)``.
        nconmax: Contacts allocated per world.
        njmax: Constraint rows allocated per world.
        calibration: ``(contacts or broadphase candidates, constraint rows)`` at the most
            contact-dense steps of the CPU calibration runs.
        device: The Warp device.
        wall_s: Wall time of the batched loop (s), setup excluded.
        controller_s: Of it, the time in the controllers on the host (s).
        setup_s: Model upload, calibration and graph capture (s).
        world_steps_per_s: ``N * steps / wall_s``.
    """

    time: np.ndarray
    states: np.ndarray
    overflow: np.ndarray
    diverged: np.ndarray
    errors: list[str]
    nconmax: int
    njmax: int
    calibration: tuple[int, int]
    device: str
    wall_s: float
    controller_s: float
    setup_s: float
    world_steps_per_s: float


def calibrate_capacity(
    problem: Problem, controller: Controller, state: np.ndarray, duration: float
) -> tuple[int, int]:
    """Largest contact (or broadphase-candidate) count and constraint rows of one CPU run.

    Args:
        problem: The Problem (its simulation model).
        controller: The controller of the run (reset before and after).
        state: Start state ``(nstate,)``.
        duration: Simulated time (s).
    """
    model = problem.model
    data = mujoco.MjData(model)
    problem.set_state(data, state)
    mujoco.mj_forward(model, data)
    pairs = _filtered_pairs(model)
    period = controller.period or model.opt.timestep
    every = max(1, round(period / model.opt.timestep))
    controller.reset()
    ncon = nefc = 0
    for k in range(round(duration / model.opt.timestep)):
        if k % every == 0:
            data.ctrl[:] = controller(problem.get_state(data), float(data.time))
        mujoco.mj_step(model, data)
        ncon = max(ncon, data.ncon, broadphase_candidates(model, data, pairs))
        nefc = max(nefc, data.nefc)
    controller.reset()
    return ncon, nefc


def _filtered_pairs(model: mujoco.MjModel) -> np.ndarray:
    _, mjw = _import_warp()
    m = mjw.put_model(model)
    return m.nxn_geom_pair_filtered.numpy().reshape(-1, 2)


def simulate_batch_warp(
    problem: Problem,
    controllers: Sequence[Controller],
    initial_states: np.ndarray,
    duration: float,
    *,
    device: str | None = None,
    headroom: float = 2.0,
    nconmax: int | None = None,
    njmax: int | None = None,
    record_period: float = 0.1,
    calibration_worlds: int = 4,
) -> BatchResult:
    """Run ``N`` closed-loop trials as parallel MJWarp worlds (see the module docstring).

    Args:
        problem: The Problem (its simulation model is uploaded).
        controllers: One controller per world, all with the same ``period``.
        initial_states: Start states ``(N, nstate)``.
        duration: Simulated time (s).
        device: Warp device (``"cuda"``, ``"cuda:1"``, ``"cpu"``; default CUDA if present).
        headroom: Capacity as a multiple of the calibration maxima.
        nconmax: Contacts per world (default: from the calibration run).
        njmax: Constraint rows per world (default: from the calibration run).
        record_period: Seconds between recorded states.
        calibration_worlds: How many of the first worlds the CPU calibration runs.

    Raises:
        InvalidArgumentError: For a count of controllers other than of states, or
            controllers with different periods.
        BackendUnavailableError: Without mujoco-warp, or for CUDA without a GPU.
    """
    wp, mjw = _import_warp()
    device = resolve_device(device)
    states0 = as_array("initial_states", initial_states, (None, problem.nstate))
    n = states0.shape[0]
    if len(controllers) != n or n == 0:
        raise InvalidArgumentError(
            f"controllers: need one per initial state ({n}), got {len(controllers)}"
        )
    periods = {c.period for c in controllers}
    if len(periods) != 1:
        raise InvalidArgumentError(f"controllers must share one period, got {sorted(periods)}")
    model = problem.model
    dt = model.opt.timestep
    period = periods.pop() or dt
    every = max(1, round(positive("period", period) / dt))
    ticks = math.ceil(positive("duration", duration) / (every * dt))
    record_every = max(1, round(positive("record_period", record_period) / (every * dt)))
    setup0 = _time.perf_counter()
    integer("calibration_worlds", calibration_worlds, 1)
    calibration = (0, 0)
    if nconmax is None or njmax is None:
        for i in range(min(n, calibration_worlds)):
            ncon, nefc = calibrate_capacity(problem, controllers[i], states0[i], duration)
            calibration = (max(calibration[0], ncon), max(calibration[1], nefc))
    nconmax = nconmax or max(4, math.ceil(headroom * calibration[0]))
    njmax = njmax or max(8, math.ceil(headroom * calibration[1]))
    nq, nv, na = problem.nq, problem.nv, problem.na
    with wp.ScopedDevice(device):
        m = mjw.put_model(model)
        m.opt.warn_overflow = 0  # read back per world as flags instead

        def make() -> object:
            data = mjw.make_data(model, nworld=n, nconmax=nconmax, njmax=njmax)
            data.qpos.assign(states0[:, :nq].astype(np.float32))
            data.qvel.assign(states0[:, nq : nq + nv].astype(np.float32))
            data.ctrl.assign(np.tile(problem.ctrl_ref, (n, 1)).astype(np.float32))
            if na:
                data.act.assign(states0[:, nq + nv :].astype(np.float32))
            return data

        d = make()

        def chunk() -> None:
            for _ in range(every):
                mjw.step(m, d)

        graph = None
        if device.startswith("cuda"):
            # Compile every kernel on a copy of the data at the same states, then capture.
            warm = make()
            mjw.step(m, warm)
            del warm
            with wp.ScopedCapture() as capture:
                chunk()
            graph = capture.graph
    setup_s = _time.perf_counter() - setup0

    for c in controllers:
        c.reset()
    overflow = np.zeros(n, dtype=bool)
    diverged = np.zeros(n, dtype=bool)
    errors = [""] * n
    ctrl = np.tile(problem.ctrl_ref, (n, 1))
    states = states0.copy()
    times, record = [], []
    capacity = int(_capacity_mask())
    host = 0.0
    wall0 = _time.perf_counter()
    with wp.ScopedDevice(device):
        for k in range(ticks + 1):
            t = k * every * dt
            if k:
                states = np.concatenate(
                    [d.qpos.numpy(), d.qvel.numpy(), d.act.numpy()], axis=1
                ).astype(np.float64)
                flags = d.overflow.numpy()
                overflow |= (flags & capacity) != 0
                qacc = np.abs(d.qacc.numpy()).max(axis=1)
                diverged |= ~np.isfinite(states).all(axis=1) | ~(qacc < MAX_ACCELERATION)
            if k % record_every == 0 or k == ticks:
                times.append(t)
                record.append(states.copy())
            if k == ticks:
                break
            host0 = _time.perf_counter()
            for i, c in enumerate(controllers):
                if diverged[i] or errors[i]:
                    continue
                try:
                    u = np.asarray(c(states[i].copy(), t), dtype=float)
                    if u.shape != (problem.nu,) or not np.all(np.isfinite(u)):
                        raise InvalidArgumentError(f"invalid control of shape {u.shape}")
                    ctrl[i] = u
                except Exception as exc:  # a controller error fails its world only
                    errors[i] = f"{type(exc).__name__}: {exc}"
            host += _time.perf_counter() - host0
            d.ctrl.assign(problem.clip_ctrl(ctrl).astype(np.float32))
            if graph is not None:
                wp.capture_launch(graph)
            else:
                chunk()
        wp.synchronize()
    wall = _time.perf_counter() - wall0
    return BatchResult(
        time=np.asarray(times),
        states=np.stack(record),
        overflow=overflow,
        diverged=diverged,
        errors=errors,
        nconmax=int(nconmax),
        njmax=int(njmax),
        calibration=calibration,
        device=device,
        wall_s=wall,
        controller_s=host,
        setup_s=setup_s,
        world_steps_per_s=n * ticks * every / wall if wall > 0 else float("nan"),
    )


def _capacity_mask() -> int:
    """The overflow bits that mean lost contacts or constraints (not solver iterations)."""
    from mujoco_warp._src.types import OverflowType

    return int(OverflowType.ALL & ~(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS))
