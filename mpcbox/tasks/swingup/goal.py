r"""What "upright" means for a swing-up, how far a state is from it, and the measure of it.

An :class:`UprightGoal` is defined by named hinge joints with target angles, or by named
sites with target heights or positions. The *upright error* of a state is

* with joints: :math:`e = \max_j |\mathrm{wrap}(q_j - q_j^\star)|` in radians, with
  :math:`\mathrm{wrap}` onto :math:`[-\pi, \pi]`, so every turn of the target counts as
  upright;
* with sites (only sites named, or ``by="sites"``): :math:`e = \max_s d_s` in meters,
  :math:`d_s` the site's distance from its target height (:math:`|z_s - z_s^\star|`) or
  target position (:math:`\lVert p_s - p_s^\star \rVert`).

The goal is met at the end of a run when :math:`e \le` ``tolerance`` over the final ``hold``
seconds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from mpcbox.core.model import frame_object, frame_position, object_id
from mpcbox.errors import InvalidArgumentError
from mpcbox.sim.measures import Measure
from mpcbox.validation import as_array, number, one_of, positive

#: Default tolerance of a goal given by joints (rad) and by sites only (m).
DEFAULT_TOLERANCE = {"rad": 0.2, "m": 0.1}


def wrap_angle(angle: np.ndarray | float) -> np.ndarray:
    """``angle`` wrapped onto ``[-pi, pi]`` (the principal argument of ``exp(i angle)``)."""
    return np.angle(np.exp(1j * np.asarray(angle, dtype=np.float64)))


def flipped(angle: float) -> float:
    """``angle + pi`` wrapped onto ``(-pi, pi]``: the opposite direction of a hinge."""
    return float(np.pi - np.mod(np.pi - (angle + np.pi), 2.0 * np.pi))


class UprightGoal:
    """The upright posture of a swing-up, by joints or by sites (see the module docstring).

    Args:
        model: The compiled model (names are resolved in it).
        joints: Hinge joint name -> target angle (rad).
        sites: Site (or body) name -> target height (m, a number) or position ``(3,)``.
        tolerance: Largest upright error counted as upright (rad with joints, m with sites
            only); default :data:`DEFAULT_TOLERANCE`.
        hold: Seconds the error must stay within ``tolerance`` at the end of a run.
        by: ``"joints"`` or ``"sites"``: what the upright error measures (default: the
            joints when any are named).

    Raises:
        InvalidArgumentError: If neither joints nor sites are named, a joint is not a hinge,
            or a target, the tolerance or ``hold`` is out of range.
        UnknownNameError: If a joint or site does not exist (lists the model's names).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        joints: Mapping[str, float],
        sites: Mapping[str, float | np.ndarray],
        tolerance: float | None = None,
        hold: float = 1.0,
        by: str | None = None,
    ) -> None:
        if not joints and not sites:
            raise InvalidArgumentError(
                "joints or sites must name what is upright (a hinge joint and its target "
                "angle, or a site and its target height or position)"
            )
        self.joints = {str(k): float(v) for k, v in joints.items()}
        self.qpos_addresses = []
        for name, target in self.joints.items():
            jid = object_id(model, "joint", name)
            if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
                raise InvalidArgumentError(
                    f"joints: {name!r} is not a hinge joint; a swing-up's angles are hinges"
                )
            if not np.isfinite(target):
                raise InvalidArgumentError(f"joints: target of {name!r} must be finite")
            self.qpos_addresses.append(int(model.jnt_qposadr[jid]))
        self.sites: dict[str, np.ndarray] = {}
        for name, target in sites.items():
            frame_object(model, name)  # raises UnknownNameError listing sites and bodies
            try:
                value = np.asarray(target, dtype=np.float64)
            except (TypeError, ValueError):
                value = np.zeros(0)  # not numbers: refused below
            if value.shape not in ((), (3,)):
                raise InvalidArgumentError(
                    f"sites: target of {name!r} must be a height (number) or a position "
                    f"(3,), got {target!r}"
                )
            self.sites[str(name)] = as_array(f"sites[{name!r}]", value, value.shape)
        by = ("joints" if self.joints else "sites") if by is None else by
        one_of("goal", by, ("joints", "sites"))
        if not (self.joints if by == "joints" else self.sites):
            raise InvalidArgumentError(f"goal={by!r} needs at least one named {by[:-1]}")
        #: What the upright error measures: ``"joints"`` or ``"sites"``.
        self.by = by
        #: Unit of the upright error: ``"rad"`` for joints, ``"m"`` for sites.
        self.unit = "rad" if by == "joints" else "m"
        self.tolerance = positive(
            "tolerance", DEFAULT_TOLERANCE[self.unit] if tolerance is None else tolerance
        )
        self.hold = positive("hold", hold)
        self._model = model
        self._data: mujoco.MjData | None = None

    # ------------------------------------------------------------------ errors
    def qpos_error(self, qpos: np.ndarray) -> float:
        """Upright error of one posture ``(nq,)`` (rad with joints, else m)."""
        if self.by == "joints":
            angles = qpos[self.qpos_addresses] - np.fromiter(self.joints.values(), float)
            return float(np.max(np.abs(wrap_angle(angles))))
        if self._data is None:
            self._data = mujoco.MjData(self._model)
        self._data.qpos[:] = qpos
        mujoco.mj_kinematics(self._model, self._data)
        distances = []
        for name, target in self.sites.items():
            position = frame_position(self._model, self._data, name)
            distances.append(
                abs(position[2] - target) if target.ndim == 0 else np.linalg.norm(position - target)
            )
        return float(max(distances))

    def errors(self, states: np.ndarray, nq: int) -> np.ndarray:
        """Upright errors ``(T,)`` of states ``(T, nstate)`` whose first ``nq`` are qpos."""
        states = np.atleast_2d(np.asarray(states, dtype=np.float64))
        return np.array([self.qpos_error(state[:nq]) for state in states])

    def settle_time(self, time: np.ndarray, errors: np.ndarray) -> float:
        """First time after which ``errors`` stay within tolerance (NaN when never)."""
        outside = np.flatnonzero(~(errors <= self.tolerance))
        if outside.size == 0:
            return float(time[0])
        if outside[-1] == len(errors) - 1:
            return float("nan")
        return float(time[outside[-1] + 1])

    def failure(self, time: np.ndarray, errors: np.ndarray) -> str | None:
        """Why a run with upright ``errors`` ``(T,)`` at ``time`` ``(T,)`` misses the goal.

        Returns:
            ``None`` when the error is within tolerance at the end and over the final
            ``hold`` seconds (the whole run when shorter), otherwise a sentence such as
            ``"not upright at the end: 3.14 rad from upright (tolerance 0.2 rad)"``.
        """
        unit, tol = self.unit, self.tolerance
        if errors.size == 0:
            return "no states recorded"
        if not errors[-1] <= tol:
            return (
                f"not upright at the end: {errors[-1]:.3g} {unit} from upright "
                f"(tolerance {tol:g} {unit})"
            )
        window = time >= time[-1] - self.hold
        bad = np.flatnonzero(window & ~(errors <= tol))
        if bad.size:
            worst = bad[np.argmax(errors[bad])]
            return (
                f"not held upright over the final {self.hold:g} s: {errors[worst]:.3g} {unit} "
                f"from upright at t = {time[worst]:.2f} s (tolerance {tol:g} {unit})"
            )
        return None

    def describe(self) -> str:
        """A short description, e.g. ``"hinge_1 at 3.14 rad"`` or ``"tip at height 4 m"``."""
        if self.by == "joints":
            return ", ".join(f"{j} at {t:.3g} rad" for j, t in self.joints.items())
        return ", ".join(
            f"{s} at height {t:.3g} m" if t.ndim == 0 else f"{s} at {np.round(t, 3).tolist()} m"
            for s, t in self.sites.items()
        )


@dataclass(frozen=True, kw_only=True)
class UprightError(Measure):
    """A swing-up's upright error (:class:`UprightGoal`), in rad (joints) or m (sites).

    Summarized by its final value and its settle time, the time to get within the goal's
    tolerance for good (NaN when the run ends outside it).

    Attributes:
        goal: The goal whose error is sampled; it sets ``unit`` and ``tolerance``.
    """

    name: str = "upright_error"
    label: str = "upright error"
    summaries: tuple[str, ...] = ("final", "settle_time")
    goal: UprightGoal | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.goal, UprightGoal):
            raise InvalidArgumentError("goal must be an UprightGoal")
        if not self.unit:
            object.__setattr__(self, "unit", self.goal.unit)
        if self.tolerance is None:
            object.__setattr__(self, "tolerance", self.goal.tolerance)
        super().__post_init__()

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> float:
        assert self.goal is not None
        return self.goal.qpos_error(np.asarray(data.qpos))


def joint_targets(joints: Mapping[str, float] | Sequence[str] | None) -> dict[str, float]:
    """``joints`` as a name -> target mapping; a bare name targets ``pi``."""
    if joints is None:
        return {}
    if isinstance(joints, str):
        raise InvalidArgumentError(
            f"joints must be a sequence of names or a name -> angle mapping, got {joints!r}"
        )
    if isinstance(joints, Mapping):
        return {name: number(f"joints[{name!r}]", target) for name, target in joints.items()}
    return {str(name): float(np.pi) for name in joints}
