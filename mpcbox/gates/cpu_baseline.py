r"""Gate 1: the CPU baseline, MuJoCo (float64) over the gate's controls.

From the start state :math:`x_0`, step ``k`` applies :math:`u_k` and records
:math:`x_{k+1} = f(x_k, u_k)` with ``mj_step``, the contacts ``ncon`` and constraint rows
``nefc`` of that step. Divergence is caught as in :func:`mpcbox.simulate`
(:class:`~mpcbox.sim.divergence.DivergenceMonitor`: MuJoCo's bad-qacc/qpos/qvel/ctrl
warnings, time not advancing, a non-finite state); the run stops there and the gate fails.
"""

from __future__ import annotations

import time as _time
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.gates.controls import GateInput
from mpcbox.sim.divergence import DivergenceMonitor


class CpuBaseline(NamedTuple):
    """The CPU reference run (``S <= T`` steps run, ``S + 1`` recorded states).

    Attributes:
        passed: The run reached the end without diverging.
        time: Times ``(S + 1,)`` (s).
        qpos: Positions ``(S + 1, nq)``.
        qvel: Velocities ``(S + 1, nv)``.
        ncon: Contacts after each step ``(S,)``.
        nefc: Constraint rows after each step ``(S,)``.
        divergence: Why the run stopped early (``"diverged: ..."``), or ``None``.
        seconds: Wall-clock time of the run (s).
    """

    passed: bool
    time: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    ncon: np.ndarray
    nefc: np.ndarray
    divergence: str | None
    seconds: float

    @property
    def steps(self) -> int:
        """Steps run ``S``."""
        return len(self.ncon)

    def summary(self) -> dict:
        """JSON-ready figures of the run."""
        return {
            "passed": self.passed,
            "steps": self.steps,
            "simulated_seconds": float(self.time[-1] - self.time[0]),
            "divergence": self.divergence,
            "max_ncon": int(self.ncon.max(initial=0)),
            "max_nefc": int(self.nefc.max(initial=0)),
            "step_of_max_ncon": int(np.argmax(self.ncon)) if self.steps else None,
            "wall_seconds": self.seconds,
        }


def set_start(model: mujoco.MjModel, data: mujoco.MjData, gate_input: GateInput) -> None:
    """Reset ``data`` to the gate's start (state ``[qpos, qvel, act]``, mocap poses)."""
    mujoco.mj_resetData(model, data)
    nq, nv = model.nq, model.nv
    state = gate_input.initial_state
    data.qpos[:] = state[:nq]
    data.qvel[:] = state[nq : nq + nv]
    data.act[:] = state[nq + nv :]
    if gate_input.mocap_pos is not None:
        data.mocap_pos[:] = gate_input.mocap_pos
    if gate_input.mocap_quat is not None:
        data.mocap_quat[:] = gate_input.mocap_quat
    mujoco.mj_forward(model, data)


def run_cpu_baseline(gate_input: GateInput) -> CpuBaseline:
    """Run gate 1: MuJoCo on the CPU over ``gate_input``'s controls."""
    model = gate_input.model
    data = mujoco.MjData(model)
    set_start(model, data, gate_input)
    steps = gate_input.steps
    time = np.empty(steps + 1)
    qpos = np.empty((steps + 1, model.nq))
    qvel = np.empty((steps + 1, model.nv))
    ncon = np.zeros(steps, dtype=np.int64)
    nefc = np.zeros(steps, dtype=np.int64)
    time[0], qpos[0], qvel[0] = data.time, data.qpos, data.qvel
    monitor = DivergenceMonitor(data)
    divergence = None
    start = _time.perf_counter()
    k = 0
    for k in range(steps):
        data.ctrl[:] = gate_input.ctrls[k]
        monitor.before_step()
        mujoco.mj_step(model, data)
        divergence = monitor.after_step()
        ncon[k], nefc[k] = data.ncon, data.nefc
        time[k + 1], qpos[k + 1], qvel[k + 1] = data.time, data.qpos, data.qvel
        if divergence is not None:
            break
    run = k + 1 if steps else 0
    return CpuBaseline(
        passed=divergence is None,
        time=time[: run + 1],
        qpos=qpos[: run + 1],
        qvel=qvel[: run + 1],
        ncon=ncon[:run],
        nefc=nefc[:run],
        divergence=divergence,
        seconds=_time.perf_counter() - start,
    )


__all__ = ["CpuBaseline", "run_cpu_baseline", "set_start"]
