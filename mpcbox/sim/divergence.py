"""Catching a simulation that blew up: MuJoCo's own warnings, time stepping back, NaN states.

When an acceleration, position or velocity is NaN, infinite or beyond ``mjMAXVAL`` (1e10),
MuJoCo prints a warning, **resets the data to the model's defaults** and carries on; a control
beyond that limit is silently replaced by zero. Read from the state alone, such a run looks
healthy again (often with time back at 0). :class:`DivergenceMonitor` clears MuJoCo's warning
counters before each step and reads them after it, so every such event is reported.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: MuJoCo warnings that mean the simulation diverged (or a control was discarded), with the
#: words used in reports.
DIVERGENCE_WARNINGS: dict[int, str] = {
    int(mujoco.mjtWarning.mjWARN_BADQACC): "NaN, infinite or huge acceleration (MuJoCo reset)",
    int(mujoco.mjtWarning.mjWARN_BADQPOS): "NaN, infinite or huge position (MuJoCo reset)",
    int(mujoco.mjtWarning.mjWARN_BADQVEL): "NaN, infinite or huge velocity (MuJoCo reset)",
    int(mujoco.mjtWarning.mjWARN_BADCTRL): "NaN, infinite or huge control (MuJoCo zeroed it)",
}


class DivergenceMonitor:
    """Reports why the last :func:`mujoco.mj_step` on ``data`` diverged, if it did.

    Usage: :meth:`before_step`, ``mujoco.mj_step(model, data)``, then :meth:`after_step`,
    which returns ``None`` or a reason starting with ``"diverged: "``.
    """

    def __init__(self, data: mujoco.MjData) -> None:
        self.data = data
        self._time = float(data.time)

    def before_step(self) -> None:
        """Clear the divergence warnings' counters and remember the time."""
        for index in DIVERGENCE_WARNINGS:
            self.data.warning[index].number = 0
        self._time = float(self.data.time)

    def after_step(self) -> str | None:
        """Why the step diverged (MuJoCo warning, time not advancing, non-finite state)."""
        data = self.data
        for index, words in DIVERGENCE_WARNINGS.items():
            if data.warning[index].number > 0:
                where = int(data.warning[index].lastinfo)
                return f"diverged: {words} at index {where}, t = {self._time:.4f} s"
        if not data.time > self._time:
            return (
                f"diverged: simulation time went from {self._time:.4f} s to {data.time:.4f} s "
                "(MuJoCo reset the state)"
            )
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return f"diverged: non-finite state at t = {data.time:.4f} s"
        return None


__all__ = ["DIVERGENCE_WARNINGS", "DivergenceMonitor"]
