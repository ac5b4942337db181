"""Argument checks shared by the public API; messages always name the argument."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mpcbox.errors import InvalidArgumentError, ShapeError


def as_array(name: str, value: object, shape: Sequence[int | None]) -> np.ndarray:
    """Convert ``value`` to a float64 array and check its shape.

    Args:
        name: Argument name used in error messages.
        value: Array-like input.
        shape: Expected shape; ``None`` entries match any size.

    Returns:
        A float64 array (a copy only when conversion needs one).

    Raises:
        ShapeError: If the number of dimensions or a fixed dimension differs.
        InvalidArgumentError: If ``value`` is not numeric.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidArgumentError(f"{name} must be a numeric array, got {type(value)}") from exc
    want = tuple("*" if s is None else s for s in shape)
    if arr.ndim != len(shape) or any(s is not None and a != s for a, s in zip(arr.shape, shape)):
        raise ShapeError(f"{name} must have shape {want}, got {arr.shape}")
    return arr


def as_weights(name: str, value: object, size: int) -> np.ndarray:
    """A non-negative, finite weight vector of length ``size`` from a scalar or array."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    arr = as_array(name, arr, (size,))
    if not np.all(np.isfinite(arr)):
        raise InvalidArgumentError(f"{name} must be finite, got {arr}")
    if np.any(arr < 0):
        raise InvalidArgumentError(f"{name} must be non-negative, got {arr}")
    return arr


def positive(name: str, value: float) -> float:
    """Check ``value > 0`` and return it as float."""
    try:
        val = float(value)
    except (TypeError, ValueError) as exc:
        raise InvalidArgumentError(f"{name} must be a positive number, got {value!r}") from exc
    if not np.isfinite(val) or val <= 0:
        raise InvalidArgumentError(f"{name} must be a positive finite number, got {value!r}")
    return val


def positive_int(name: str, value: int) -> int:
    """Check that ``value`` is an integer >= 1 and return it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InvalidArgumentError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def one_of(name: str, value: str, choices: Sequence[str]) -> str:
    """Check that ``value`` is one of ``choices``; the error lists them."""
    if value not in choices:
        raise InvalidArgumentError(
            f"{name} must be one of {', '.join(repr(c) for c in choices)}; got {value!r}"
        )
    return value
