"""Disturbances for closed-loop simulation: actuator noise, pushes and model mismatch."""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from mpcbox.core.model import check_mjmodel, object_id
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import checked_options, finite_array, integer, non_negative, positive, string
from mpcbox.validation import seed as check_seed

#: Largest push force or torque magnitude accepted (N, N m): beyond it a push is an input
#: error (a 1e12 N push only makes MuJoCo diverge), and push searches stop there.
MAX_FORCE = 1e8


#: Most samples of :class:`ActuatorNoise`'s smoothing kernel (its ``width`` over the
#: timestep): 1e6, 2000 s at a 2 ms step, far beyond any run; a larger one only costs memory.
MAX_KERNEL = 1_000_000


@checked_options
@dataclass(frozen=True, kw_only=True)
class ActuatorNoise:
    r"""Smooth actuator noise added to the control at every simulation step.

    White noise :math:`w \sim \mathcal N(0, I)` of shape ``(steps, nu)`` from numpy's legacy
    generator (``RandomState(seed).randn``) is convolved per actuator (``mode="same"``) with
    the unit-norm Gaussian kernel :math:`k_i \propto \exp(-s_i^2 / 2)`,
    :math:`s \in [-3, 3]` spanning ``width`` seconds, then scaled per actuator by ``std``
    times ``scale``. The unit-norm kernel keeps the per-step standard deviation at ``std``.

    Attributes:
        std: Standard deviation per actuator ``(nu,)`` or one for all.
        width: Time span of the smoothing kernel (s).
        scale: Multiplier on ``std`` (noise level in sweeps).
    """

    std: float | Sequence[float] | np.ndarray
    width: float = 0.8
    scale: float = 1.0

    def __post_init__(self) -> None:
        std = finite_array("std", self.std, (None,) * min(1, np.ndim(self.std)))
        if np.any(std < 0):
            raise InvalidArgumentError(f"std must be non-negative, got {std.tolist()}")
        positive("width", self.width)
        non_negative("scale", self.scale)

    def sample(self, steps: int, nu: int, dt: float, seed: int) -> np.ndarray:
        """Noise ``(steps, nu)`` for a simulation with timestep ``dt`` (s), drawn from ``seed``.

        Raises:
            ShapeError: If ``std`` has one value per actuator and ``nu`` differs.
            InvalidArgumentError: If ``width`` spans more than :data:`MAX_KERNEL` steps.
        """
        steps, nu = integer("steps", steps, 1), integer("nu", nu, 1)
        dt, seed = positive("dt", dt), check_seed("seed", seed)
        std = np.asarray(self.std, dtype=np.float64)
        std = np.full(nu, float(std)) if std.ndim == 0 else finite_array("std", std, (nu,))
        white = np.random.RandomState(seed).randn(steps, nu)
        width = max(1, int(positive("width", self.width) / dt))
        if width > MAX_KERNEL:
            raise InvalidArgumentError(
                f"width must span at most {MAX_KERNEL:.0e} timesteps of {dt:g} s (the "
                f"smoothing kernel's samples), got {self.width!r} s = {width:.3g} steps"
            )
        kernel = np.exp(-0.5 * np.linspace(-3.0, 3.0, width) ** 2)
        kernel /= np.linalg.norm(kernel)
        smooth = np.empty_like(white)
        start = (width - 1) // 2  # the centred slice of "full" that mode="same" returns
        for i in range(nu):
            # Slicing "full" keeps runs shorter than the kernel working.
            full = np.convolve(white[:, i], kernel, mode="full")
            smooth[:, i] = full[start : start + steps]
        return smooth * std * self.scale


@checked_options
@dataclass(frozen=True, kw_only=True)
class Push:
    """A constant force on a body's center of mass over a time interval (``xfrc_applied``).

    Attributes:
        force: World-frame force ``(3,)`` in newtons.
        start: Start time (s).
        duration: Duration (s).
        body: Body name.
        torque: Optional world-frame torque ``(3,)``.
    """

    force: Sequence[float] | np.ndarray
    start: float = 1.0
    duration: float = 0.1
    body: str = "torso"
    torque: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("force", "torque"):
            value = finite_array(name, getattr(self, name), (3,))
            if np.linalg.norm(value) > MAX_FORCE:
                raise InvalidArgumentError(
                    f"{name} magnitude must be at most {MAX_FORCE:g} (MAX_FORCE), got "
                    f"{np.linalg.norm(value):.3g}"
                )
        non_negative("start", self.start)
        positive("duration", self.duration)
        string("body", self.body)

    @property
    def impulse(self) -> float:
        """Magnitude of the linear impulse (N s)."""
        return float(np.linalg.norm(self.force) * self.duration)

    def active(self, time: float) -> bool:
        """Whether the push acts at ``time``."""
        return self.start <= time < self.start + self.duration

    def wrench(self) -> np.ndarray:
        """``[force, torque]`` of shape ``(6,)``."""
        return np.concatenate(
            [finite_array("force", self.force, (3,)), finite_array("torque", self.torque, (3,))]
        )


@checked_options
@dataclass(frozen=True, kw_only=True)
class ModelMismatch:
    """Differences between the simulated plant and the model the controller plans with.

    Attributes:
        mass_scale: Multiplier on every body's mass and inertia.
        friction_scale: Multiplier on every geom's sliding friction.
        body_mass_scale: Extra per-body multipliers by name, e.g. ``{"torso": 1.2}``.
    """

    mass_scale: float = 1.0
    friction_scale: float = 1.0
    body_mass_scale: dict[str, float] | None = None

    def __post_init__(self) -> None:
        positive("mass_scale", self.mass_scale)
        positive("friction_scale", self.friction_scale)
        if self.body_mass_scale is not None:
            if not isinstance(self.body_mass_scale, Mapping):
                raise InvalidTypeError(
                    "body_mass_scale must be a mapping of body names to factors, got "
                    f"{type(self.body_mass_scale).__name__}"
                )
            for name, value in self.body_mass_scale.items():
                string("body_mass_scale", name)
                positive(f"body_mass_scale[{name!r}]", value)

    def apply(self, model: mujoco.MjModel) -> mujoco.MjModel:
        """A modified copy of ``model``."""
        model = check_mjmodel(model)
        out = copy.copy(model)
        scale = np.full(model.nbody, positive("mass_scale", self.mass_scale))
        for name, value in (self.body_mass_scale or {}).items():
            scale[object_id(model, "body", name, "body_mass_scale")] *= value
        out.body_mass[:] = model.body_mass * scale
        out.body_inertia[:] = model.body_inertia * scale[:, None]
        out.geom_friction[:, 0] = model.geom_friction[:, 0] * positive(
            "friction_scale", self.friction_scale
        )
        # MuJoCo keeps mass-derived constants; recompute them for the new masses.
        mujoco.mj_setConst(out, mujoco.MjData(out))
        return out


Disturbance = ActuatorNoise | Push | ModelMismatch
PushSchedule = Sequence[Push] | Callable[[float], np.ndarray]
