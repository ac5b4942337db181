"""Rollout backends: ``cpu`` (:func:`mujoco.rollout`) and ``warp`` (MuJoCo Warp).

Both implement :class:`~mpcbox.controllers.sampling.backends.interface.RolloutBackend`;
:func:`make_backend` builds one by name. MJWarp is imported only when the warp backend is
built.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from mpcbox.controllers.sampling.backends.cpu import CpuBackend
from mpcbox.controllers.sampling.backends.interface import (
    AsyncRolloutBackend,
    RolloutBackend,
    RolloutCosts,
)
from mpcbox.controllers.sampling.backends.warp import WarpBackend, resolve_device
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import one_of

#: Names of the backends :func:`make_backend` builds.
BACKENDS: tuple[str, ...] = ("cpu", "warp")


def make_backend(
    name: str,
    problem: Problem,
    weights: np.ndarray,
    models: Sequence[mujoco.MjModel],
    *,
    device: str | None = None,
    headroom: float = 2.0,
    use_graph: bool = True,
    policy: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> RolloutBackend:
    """The backend ``name`` for a Problem, an interpolation matrix and planning models.

    Args:
        name: ``"cpu"`` (:class:`CpuBackend`) or ``"warp"`` (:class:`WarpBackend`).
        problem: The Problem whose planning model and cost the rollouts use.
        weights: Interpolation matrix ``(T, K)`` from knots to planning steps.
        models: ``M`` planning models (the nominal one, or randomized copies).
        device: Warp device (``"cuda"``, ``"cuda:0"``, ``"cpu"``; default: CUDA if present);
            only ``None`` or ``"cpu"`` with the cpu backend.
        headroom: Warp: contact and constraint capacity over the calibration maxima.
        use_graph: Warp: capture each tick as one CUDA graph (CUDA only).
        policy: CPU: a state feedback every rollout step goes through (see
            :class:`CpuBackend`).

    Raises:
        InvalidArgumentError: For an unknown name, a device with the cpu backend, or a
            policy with the warp backend.
        BackendUnavailableError: If the warp backend's packages or CUDA device are missing.
    """
    one_of("backend", name, BACKENDS)
    if name == "cpu":
        if device not in (None, "cpu"):
            raise InvalidArgumentError(
                f"device={device!r} needs backend='warp'; the cpu backend has no device"
            )
        return CpuBackend(problem, weights, models, policy)
    if policy is not None:
        raise InvalidArgumentError(
            "policy: the warp backend rolls out open-loop controls only; use backend='cpu'"
        )
    return WarpBackend(
        problem,
        weights,
        models,
        device=resolve_device(device),
        headroom=headroom,
        use_graph=use_graph,
    )


__all__ = [
    "BACKENDS",
    "AsyncRolloutBackend",
    "CpuBackend",
    "RolloutBackend",
    "RolloutCosts",
    "WarpBackend",
    "make_backend",
]
