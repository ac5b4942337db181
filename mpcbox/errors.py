"""Exceptions raised by mpcbox.

Every error derives from :class:`MpcboxError` and from the built-in exception that matches
its meaning, so ``except ValueError`` keeps working for callers that do not know mpcbox.
"""

from __future__ import annotations

from collections.abc import Iterable


class MpcboxError(Exception):
    """Root of every mpcbox exception."""


class InvalidArgumentError(MpcboxError, ValueError):
    """An argument has the wrong value, type or range."""


class ShapeError(InvalidArgumentError):
    """An array argument has the wrong shape."""


class UnknownNameError(InvalidArgumentError):
    """A name (body, site, keyframe, joint, controller, ...) does not exist.

    The message lists the names that do exist.
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        valid = sorted({str(v) for v in valid})
        self.kind = kind
        self.name = name
        self.valid = valid
        shown = ", ".join(repr(v) for v in valid[:40])
        if len(valid) > 40:
            shown += f", ... ({len(valid)} in all)"
        super().__init__(f"unknown {kind} {name!r}; valid {kind} names: {shown or '(none)'}")


class ModelNotFoundError(MpcboxError, FileNotFoundError):
    """An MJCF file does not exist."""


class ModelLoadError(MpcboxError, ValueError):
    """MuJoCo could not compile a model."""


class NotStabilizableError(InvalidArgumentError):
    """The pair (A, B) has an uncontrollable mode outside the unit circle (PBH test)."""


class CostDefinitionError(InvalidArgumentError):
    """Cost weights are not symmetric, not definite, or not finite."""


class DivergenceError(MpcboxError, RuntimeError):
    """A rollout, simulation or optimizer produced non-finite numbers."""


class SolverError(MpcboxError, RuntimeError):
    """A numerical solver (Riccati, QP, NLP) failed."""


class BackendUnavailableError(MpcboxError, RuntimeError):
    """An optional backend (GPU, CasADi, ...) is not installed or has no device."""


class UnsupportedModelError(MpcboxError, NotImplementedError):
    """A backend does not implement a MuJoCo feature that the model uses."""


def require_finite(name: str, value: object) -> None:
    """Raise :class:`InvalidArgumentError` if ``value`` holds NaN or infinity.

    Args:
        name: Argument name used in the message.
        value: Array-like to check.
    """
    import numpy as np

    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise InvalidArgumentError(f"{name} must be finite, got non-finite entries: {arr!r}")
