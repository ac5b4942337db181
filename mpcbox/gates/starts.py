r"""Start states of ``N`` worlds: the gate's start, perturbed in worlds ``1 .. N-1``.

World 0 starts exactly at :math:`x_0`. World ``w >= 1`` gets
:math:`\dot q \leftarrow \dot q + \sigma \varepsilon_v` on every degree of freedom and
:math:`q \leftarrow q + \sigma \varepsilon_q` on hinge and slide joints only (free and ball
joints keep unit quaternions), with :math:`\varepsilon \sim \mathcal N(0, I)` drawn from
``seed``.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np


class WorldStarts(NamedTuple):
    """Start states of ``N`` worlds.

    Attributes:
        qpos: Positions ``(N, nq)``.
        qvel: Velocities ``(N, nv)``.
        act: Actuator activations ``(N, na)``.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    act: np.ndarray


def world_starts(
    model: mujoco.MjModel, state: np.ndarray, nworld: int, perturbation: float, seed: int
) -> WorldStarts:
    """``nworld`` start states around ``state`` ``(nq + nv + na,)`` (see module)."""
    nq, nv = model.nq, model.nv
    qpos = np.tile(state[:nq], (nworld, 1))
    qvel = np.tile(state[nq : nq + nv], (nworld, 1))
    act = np.tile(state[nq + nv :], (nworld, 1))
    if nworld > 1 and perturbation > 0:
        rng = np.random.default_rng(seed)
        scalar = np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE])
        adr = model.jnt_qposadr[scalar]
        qpos[1:, adr] += perturbation * rng.standard_normal((nworld - 1, len(adr)))
        qvel[1:] += perturbation * rng.standard_normal((nworld - 1, nv))
    return WorldStarts(qpos, qvel, act)


__all__ = ["WorldStarts", "world_starts"]
