"""The control bounds of an iLQR solver: its config's, inside the Problem's."""

from __future__ import annotations

import numpy as np

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import as_array


def control_bounds(problem: Problem, cfg: ILQRConfig) -> tuple[np.ndarray, np.ndarray]:
    """The config's control bounds ``(nu,)`` each, checked and intersected with the
    Problem's.

    Raises:
        ShapeError: If ``ctrl_low`` or ``ctrl_high`` is not ``(nu,)``.
        InvalidArgumentError: If a bound is NaN, ``ctrl_low > ctrl_high`` anywhere, or the
            bounds do not overlap the model's ``ctrlrange``.
    """
    nu = problem.nu
    low = problem.ctrl_low if cfg.ctrl_low is None else as_array("ctrl_low", cfg.ctrl_low, (nu,))
    high = problem.ctrl_high
    if cfg.ctrl_high is not None:
        high = as_array("ctrl_high", cfg.ctrl_high, (nu,))
    if np.any(np.isnan(low)) or np.any(np.isnan(high)):
        raise InvalidArgumentError("ctrl_low and ctrl_high must not hold NaN")
    if np.any(low > high):
        bad = np.flatnonzero(low > high)
        raise InvalidArgumentError(
            f"ctrl_low must be <= ctrl_high; inverted at actuators {bad.tolist()}: "
            f"ctrl_low={low[bad]}, ctrl_high={high[bad]}"
        )
    low, high = np.maximum(low, problem.ctrl_low), np.minimum(high, problem.ctrl_high)
    if np.any(low > high):
        raise InvalidArgumentError(
            "ctrl_low/ctrl_high do not overlap the model's ctrlrange "
            f"[{problem.ctrl_low}, {problem.ctrl_high}]"
        )
    return low, high


__all__ = ["control_bounds"]
