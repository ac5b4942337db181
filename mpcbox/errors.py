"""Exceptions raised by mpcbox.

Every error derives from :class:`MpcboxError` and from the built-in exception that matches
its meaning, so ``except ValueError`` keeps working for callers that do not know mpcbox.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class MpcboxError(Exception):
    """Root of every mpcbox exception."""


class InvalidArgumentError(MpcboxError, ValueError):
    """An argument has the wrong value, type or range."""


class InvalidTypeError(InvalidArgumentError, TypeError):
    """An argument has the wrong type (also a :class:`TypeError`)."""


class NotAControllerError(InvalidTypeError):
    """A controller factory given to a comparison returned something other than a
    ``Controller`` (raised, not recorded as a failed run: every run would fail alike)."""


class UnknownOptionError(InvalidArgumentError, TypeError):
    """A keyword option that the receiver does not have; the message lists the valid ones.

    Also a :class:`TypeError`, as Python raises for an unexpected keyword argument.
    """

    def __init__(self, owner: str, unknown: Iterable[str], valid: Iterable[str]) -> None:
        self.owner = owner
        self.unknown = sorted(unknown)
        self.valid = sorted(valid)
        super().__init__(
            f"unknown option(s) {', '.join(map(repr, self.unknown))} for {owner}; "
            f"valid options: {', '.join(self.valid) or '(none)'}"
        )


class ShapeError(InvalidArgumentError):
    """An array argument has the wrong shape."""


class UnknownNameError(InvalidArgumentError):
    """A name (body, site, keyframe, joint, controller, ...) does not exist.

    The message lists the names that do exist.
    """

    def __init__(
        self, kind: str, name: str, valid: Iterable[str], argument: str | None = None
    ) -> None:
        valid = sorted({str(v) for v in valid})
        self.kind = kind
        self.name = name
        self.valid = valid
        shown = ", ".join(repr(v) for v in valid[:40])
        if len(valid) > 40:
            shown += f", ... ({len(valid)} in all)"
        close = difflib.get_close_matches(str(name), valid, n=3)
        hint = f" (did you mean {' or '.join(map(repr, close))}?)" if close else ""
        where = f"{argument}: " if argument else ""
        super().__init__(
            f"{where}unknown {kind} {name!r}{hint}; valid {kind} names: {shown or '(none)'}"
        )


class ModelNotFoundError(MpcboxError, FileNotFoundError):
    """An MJCF file does not exist."""


class ModelLoadError(MpcboxError, ValueError):
    """MuJoCo could not compile a model."""


class NotStabilizableError(InvalidArgumentError):
    """The pair (A, B) has an uncontrollable mode outside the unit circle (PBH test)."""


class NoControlAuthorityError(InvalidArgumentError):
    """A linearization has ``B = 0``: no control acts on the state at that point."""


class CostDefinitionError(InvalidArgumentError):
    """Cost weights are not symmetric, not definite, or not finite."""


class DivergenceError(MpcboxError, RuntimeError):
    """A rollout, simulation or optimizer produced non-finite numbers."""


class SolverError(MpcboxError, RuntimeError):
    """A numerical solver (Riccati, QP, NLP) failed."""


class RunError(MpcboxError, RuntimeError):
    """A run of a sweep raised before or outside its closed loop (building the problem or
    the controller, or a push search), so it measured nothing.

    The message carries the original error's type and text.
    """


class BackendUnavailableError(MpcboxError, RuntimeError):
    """An optional backend (GPU, CasADi, ...) is not installed or has no device."""


class UnsupportedModelError(MpcboxError, NotImplementedError):
    """A backend does not implement a MuJoCo feature that the model uses."""


class UnsupportedCostTermError(UnsupportedModelError):
    """A backend has no form of a cost term (no GPU rows, no CasADi expression).

    The message names the term, the backend and the term types that have that form.
    """


class InfeasibleEquilibriumError(SolverError):
    """The actuators cannot hold a posture within their control, activation and force limits.

    The message names the worst joint, its shortfall and the actuators at a limit there.
    """


class EquilibriumWarning(UserWarning):
    """Warning that the actuators cannot fully hold a posture (see
    :class:`InfeasibleEquilibriumError` for the same condition as an error)."""


class PostureWarning(UserWarning):
    """A reference posture is doubtful (e.g. in self-collision); the message says why."""


class ModelWarning(UserWarning):
    """The model was changed, or should be, to simulate what it describes (for example a
    link colliding with the static base it hangs from); the message says what and why."""


class PeriodWarning(UserWarning):
    """A controller's period, or a simulated latency, is not a whole number of simulation
    steps, so it runs at a whole number instead (the message gives both)."""


class MujocoError(MpcboxError, RuntimeError):
    """MuJoCo stopped a computation with a fatal error (``mujoco.FatalError``)."""


class PlanningModelWarning(UserWarning):
    """The planning model differs from the model in a way the user did not ask for.

    For example a model with the RK4 integrator is planned with ``implicitfast``, because
    MuJoCo cannot differentiate an RK4 step.
    """


class PlanningDivergenceError(DivergenceError, InvalidArgumentError):
    """The planning model diverges at its timestep (MuJoCo's bad-acceleration warning).

    Also an :class:`InvalidArgumentError`: the fix is a smaller ``planning_timestep``, which
    the message suggests.
    """
