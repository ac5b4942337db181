r"""Checks of the states and controls given to a :class:`~mpcbox.Problem`.

MuJoCo treats a control beyond its sanity limit ``mjMAXVAL`` (:data:`MAX_CTRL`, 1e10) or
NaN as a sign of divergence: it sets every control to zero, raises the ``BADCTRL`` warning and
carries on, so a step or a linearization would silently act as if the control were zero
(``B = 0``). A control outside an actuator's ``ctrlrange`` is clamped, so at such an operating
point the finite differences see no effect of that control either. These checks turn both
into named errors, and :func:`check_authority` rejects a linearization with no control
authority at all (:math:`B = 0`).
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from mpcbox.errors import (
    DivergenceError,
    EquilibriumWarning,
    InvalidArgumentError,
    InvalidTypeError,
    NoControlAuthorityError,
    ShapeError,
)
from mpcbox.validation import as_array

#: MuJoCo's sanity limit on controls (``mjMAXVAL``): it zeroes every control beyond it.
MAX_CTRL = float(mujoco.mjMAXVAL)


def check_state(name: str, state: object, nstate: int) -> np.ndarray:
    """A state ``(nstate,)`` as float64.

    Raises:
        ShapeError: For another shape.
        DivergenceError: If it holds NaN or infinity, or a magnitude beyond MuJoCo's limit
            :data:`MAX_CTRL` (``mjMAXVAL``, 1e10), at which MuJoCo resets the simulation
            (``BADQPOS``/``BADQVEL``) and a step would silently start over.
    """
    state = as_array(name, state, (nstate,))
    _within_limit(name, state, DivergenceError, "resets the simulation")
    return state


def _within_limit(name: str, values: np.ndarray, error: type, what: str) -> None:
    """Raise :class:`DivergenceError` for NaN or infinity in ``values``, and ``error``
    (saying that MuJoCo then ``what``) for a magnitude beyond :data:`MAX_CTRL`."""
    if values.size and not np.abs(values).max() <= MAX_CTRL:  # one pass; False for NaN too
        if not np.all(np.isfinite(values)):
            raise DivergenceError(f"{name} holds non-finite values (NaN or inf)")
        raise error(
            f"{name} has a magnitude {np.abs(values).max():.3g} beyond MuJoCo's limit "
            f"{MAX_CTRL:.0e} (mjMAXVAL), at which MuJoCo {what}"
        )


def check_data(data: object, sizes: tuple[int, int, int]) -> None:
    """``data`` must be a ``mujoco.MjData`` of a model with ``(nq, nv, na) = sizes``.

    Raises:
        InvalidTypeError: For another type.
        ShapeError: For data of a model of other sizes.
    """
    if not isinstance(data, mujoco.MjData):
        raise InvalidTypeError(f"data must be a mujoco.MjData, got {type(data).__name__}")
    found = (data.qpos.size, data.qvel.size, data.act.size)
    if found != tuple(sizes):
        raise ShapeError(
            f"data must be of this Problem's model (nq, nv, na) = {tuple(sizes)}, got data of "
            f"sizes {found}"
        )


def check_out(name: str, out: object, shape: tuple[int, ...]) -> None:
    """An output array, unless ``None``, must be float64 of ``shape`` (NumPy would cast
    into another dtype).

    Raises:
        ShapeError: Otherwise, naming ``name``.
    """
    if out is None:
        return
    if not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.float64:
        got = f"{out.dtype} {out.shape}" if isinstance(out, np.ndarray) else type(out).__name__
        raise ShapeError(f"{name} must be a float64 array of shape {shape}, got {got}")


def check_ctrl(name: str, ctrl: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """Controls of ``shape`` (``(nu,)``, ``(T, nu)``, ...) within MuJoCo's sanity limit.

    Raises:
        ShapeError: For another shape.
        DivergenceError: If they hold NaN or infinity.
        InvalidArgumentError: If a magnitude exceeds :data:`MAX_CTRL` (MuJoCo would zero
            every control).
    """
    ctrl = as_array(name, ctrl, shape)
    _within_limit(name, ctrl, InvalidArgumentError, "sets every control to zero")
    return ctrl


def check_in_range(
    name: str, ctrl: np.ndarray, low: np.ndarray, high: np.ndarray, tolerance: float
) -> None:
    """An operating control ``(..., nu)`` must lie inside the limited actuators' ``ctrlrange``.

    Args:
        name: Argument name for the message.
        ctrl: Controls ``(..., nu)``.
        low: Lower limits ``(nu,)`` (``-inf`` where unlimited).
        high: Upper limits ``(nu,)`` (``inf`` where unlimited).
        tolerance: Allowed excess (the finite-difference step: within it, MuJoCo's
            one-sided differences still see the control).

    Raises:
        InvalidArgumentError: Naming the first control outside its range.
    """
    outside = (ctrl < low - tolerance) | (ctrl > high + tolerance)
    if np.any(outside):
        index = np.argwhere(outside)[0]
        i = int(index[-1])
        raise InvalidArgumentError(
            f"{name}[{', '.join(map(str, index))}] = {ctrl[tuple(index)]:.6g} is outside "
            f"actuator {i}'s ctrlrange [{low[i]:.6g}, {high[i]:.6g}]: MuJoCo clamps it, so "
            "the linearization there would show no effect of that control (a zero column "
            "of B); linearize at a control inside the range"
        )


def ctrl_limits(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper control limits ``(nu,)`` each; ``-inf`` and ``inf`` where an actuator
    is not ``ctrllimited``."""
    limited = model.actuator_ctrllimited.astype(bool)
    low = np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf)
    return low, np.where(limited, model.actuator_ctrlrange[:, 1], np.inf)


def default_ctrl_in_range(
    ctrl: np.ndarray, model: mujoco.MjModel, keyframe: int | None
) -> np.ndarray:
    """A default reference control ``(nu,)`` clipped into ``ctrlrange``, with a warning.

    A model without a keyframe gets zeros as its reference control, and zero may lie outside
    an actuator's ``ctrlrange`` (a servo whose range excludes 0); a keyframe's ``ctrl`` may
    too. MuJoCo would clamp it, and a linearization there would see no effect of that
    control.

    Args:
        ctrl: The default reference control ``(nu,)``.
        model: The model (its ``ctrlrange`` and actuator names).
        keyframe: The keyframe ``ctrl`` came from, or ``None`` (zeros).

    Warns:
        EquilibriumWarning: Naming the actuators outside their range; the reference posture
            may then not be held (pass ``ctrl_ref``, or find it with
            :func:`~mpcbox.find_equilibrium`).
    """
    low, high = ctrl_limits(model)
    clipped = np.clip(ctrl, low, high)
    moved = np.flatnonzero(clipped != ctrl)
    if moved.size:
        source = "zeros: no keyframe" if keyframe is None else f"keyframe {keyframe}'s ctrl"
        listed = ", ".join(
            f"actuator {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or i!r} "
            f"({ctrl[i]:.6g} outside [{low[i]:.6g}, {high[i]:.6g}])"
            for i in moved[:5]
        )
        warnings.warn(
            f"the reference control ({source}) lies outside ctrlrange for {moved.size} "
            f"actuator(s): {listed}; it is clipped into the range, and the reference "
            "posture may not be held there: pass ctrl_ref, or use mpcbox.find_equilibrium",
            EquilibriumWarning,
            stacklevel=4,
        )
    return clipped


def check_authority(B: np.ndarray, what: str) -> None:
    """Raise :class:`NoControlAuthorityError` when ``B`` ``(..., nx, nu)`` is zero.

    Args:
        B: Control Jacobian(s) of a linearization.
        what: The operation, for the message.
    """
    if B.size and not np.any(B):
        raise NoControlAuthorityError(
            f"{what}: B = 0, the controls have no effect on the next state here (no "
            "control authority): check the actuators' gear, gain and transmission, and "
            "that the operating control is inside ctrlrange"
        )


def check_rollout_models(
    models: object, planning_model: mujoco.MjModel, batch: int
) -> mujoco.MjModel | list[mujoco.MjModel] | None:
    """``model`` of :meth:`~mpcbox.Problem.rollout`: ``None``, one model, or one per batch row,
    each with the planning model's sizes (``nq``, ``nv``, ``nu``, ``na``).

    Raises:
        InvalidTypeError: For something that is not an ``MjModel`` (or a sequence of them).
        ShapeError: For another number of models than ``batch``, or models of other sizes.
    """
    if models is None:
        return None
    single = isinstance(models, mujoco.MjModel)
    if not single and not isinstance(models, (list, tuple)):
        raise InvalidTypeError(
            f"model must be a mujoco.MjModel or a sequence of them, got {type(models).__name__}"
        )
    listed = [models] if single else list(models)
    if not single and len(listed) != batch:
        raise ShapeError(f"model must hold one MjModel per batch row ({batch}), got {len(listed)}")
    sizes = ("nq", "nv", "nu", "na")
    want = tuple(getattr(planning_model, s) for s in sizes)
    for i, one in enumerate(listed):
        if not isinstance(one, mujoco.MjModel):
            raise InvalidTypeError(f"model[{i}] must be a mujoco.MjModel, got {type(one).__name__}")
        got = tuple(getattr(one, s) for s in sizes)
        if got != want:
            raise ShapeError(
                f"model[{i}] must have the planning model's (nq, nv, nu, na) = {want}, got {got}"
            )
    return models if single else listed
