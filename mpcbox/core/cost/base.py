r"""The cost-term protocol and the cost of a Problem.

A cost term is a weighted least-squares residual:

.. math:: \ell(x, u) = \tfrac12 \sum_i w_i \, r_i(x, u)^2 .

Residuals are computed from the batch :class:`Features` ``(qpos, qvel, ctrl, sensordata)``.
Terms that need positions of bodies or sites ask for MuJoCo sensors (:meth:`CostTerm.sensors`)
which :class:`~mpcbox.Problem` adds to its models. The same numbers are therefore available
after ``mj_forward`` on one state, from :func:`mujoco.rollout.rollout` for thousands of states,
and on the GPU from MJWarp, so every controller scores trajectories with the same function.

Each term owns every form of its residual: the NumPy one (:meth:`CostTerm.residual`, always),
rows for the GPU kernels (:meth:`CostTerm.rows`) and a CasADi expression
(:meth:`CostTerm.casadi_residual`) where it has them.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.core.cost.rows import Row
from mpcbox.core.model import object_id
from mpcbox.errors import (
    CostDefinitionError,
    InvalidArgumentError,
    InvalidTypeError,
    UnsupportedCostTermError,
)
from mpcbox.validation import as_weights, checked_options, instance, string


class Features(NamedTuple):
    """What a residual may read, for a batch of ``B`` states.

    Attributes:
        qpos: Joint positions, shape ``(B, nq)``.
        qvel: Joint velocities, shape ``(B, nv)``.
        ctrl: Controls, shape ``(B, nu)``.
        sensordata: Sensor values computed at ``(qpos, qvel)``, shape ``(B, nsensordata)``.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    sensordata: np.ndarray


def _sensor_key(req: SensorRequest) -> tuple[int, int, str]:
    return int(req.type), int(req.objtype), str(req.objname)


class SensorRequest(NamedTuple):
    """A sensor that a cost term needs added to the model."""

    name: str
    type: mujoco.mjtSensor
    objtype: mujoco.mjtObj
    objname: str


class Jacobian(NamedTuple):
    """Residual Jacobian blocks at one state: ``dr/dq`` and ``dr/dv`` (k, nv), ``dr/du`` (k, nu)."""

    dq: np.ndarray
    dv: np.ndarray
    du: np.ndarray


def _subclasses(cls: type) -> list[type]:
    out = []
    for sub in cls.__subclasses__():
        out += [sub, *_subclasses(sub)]
    return out


def _unsupported(term: CostTerm, form: str, backend: str, method: str, hint: str) -> Exception:
    """The error of a term without ``method``, listing the term types that have it."""
    base = getattr(CostTerm, method)
    names = sorted({c.__name__ for c in _subclasses(CostTerm) if getattr(c, method) is not base})
    return UnsupportedCostTermError(
        f"cost term {term.name!r} of type {type(term).__name__} has no {form}, which {backend} "
        f"needs; the term types with one are {', '.join(names) or '(none)'}. {hint}"
    )


class CostTerm(abc.ABC):
    """Base class of residual cost terms.

    Subclasses implement :meth:`size` and :meth:`residual` and, where cheap, :meth:`jacobian`;
    terms that need body or site positions list sensors in :meth:`sensors` and read them in
    :meth:`residual` through :meth:`sensor_slice`. A term that the GPU sampling backend or the
    IPOPT reference should evaluate natively also implements :meth:`rows` or
    :meth:`casadi_residual`.

    Args:
        weight: Scalar or per-residual weights ``w`` (non-negative).
        name: Short label used in sensor names and reports.
    """

    #: Whether :meth:`jacobian` is the same at every state (computed once per batch).
    constant_jacobian: bool = False
    #: How much of ``mj_forward`` :meth:`residual` and :meth:`jacobian` need when the cost is
    #: quadratized (:data:`STAGES`): ``"none"`` (``qpos``, ``qvel``, ``ctrl`` only),
    #: ``"pos"`` (kinematics, centers of mass and position sensors), ``"vel"`` (velocities
    #: and velocity sensors too) or ``"acc"`` (all of ``mj_forward``: contact forces,
    #: accelerations, actuator forces). A term that does not say gets ``"acc"``.
    stage: str = "acc"

    def __init__(self, weight: float | Sequence[float] | np.ndarray, name: str) -> None:
        self._weight_arg = weight
        self.name = string("name", name)
        self.weight: np.ndarray = np.zeros(0)
        self._sensor_adr: dict[str, slice] = {}

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        """Sensors this term needs in the model (default: none).

        Args:
            model: The model before the sensors are added, for name resolution.
        """
        del model
        return ()

    @abc.abstractmethod
    def size(self, model: mujoco.MjModel) -> int:
        """Number of residuals ``k``."""

    @abc.abstractmethod
    def residual(self, features: Features) -> np.ndarray:
        """Residuals for a batch, shape ``(B, k)``."""

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian | None:
        """Analytic residual Jacobian at the state in ``data`` (after ``mj_forward``).

        Returns ``None`` (the default) to let the Problem use finite differences.
        """
        del model, data
        return None

    def rows(self) -> list[Row]:
        r"""The term as elementary rows (:mod:`mpcbox.core.cost.rows`) after :meth:`bind`.

        The term's value :math:`\tfrac12 \sum_i w_i r_i^2` equals the sum of its rows'
        :math:`\tfrac12 w r^2`. Used by the warp sampling backend; rows with zero weight may
        be left out.

        Raises:
            UnsupportedCostTermError: The default: the term has no row form.
        """
        raise _unsupported(
            self,
            "row form for the GPU cost kernels",
            "the warp sampling backend",
            "rows",
            "Use backend='cpu' for custom terms.",
        )

    def casadi_residual(self, qpos: Any, qvel: Any, ctrl: Any) -> Any:
        """The residual ``(k,)`` as a CasADi expression of one state and control, after
        :meth:`bind` (CasADi is imported by the implementation, on first use).

        Args:
            qpos: Positions, a CasADi column ``(nq,)``.
            qvel: Velocities, a CasADi column ``(nv,)``.
            ctrl: Controls, a CasADi column ``(nu,)``.

        Raises:
            UnsupportedCostTermError: The default: the term has no CasADi form.
        """
        del qpos, qvel, ctrl
        raise _unsupported(
            self,
            "CasADi form",
            "the IPOPT reference",
            "casadi_residual",
            "It evaluates a cost holding other terms through the Problem (a CasADi Callback).",
        )

    def bind(self, model: mujoco.MjModel) -> None:
        """Resolve sensor addresses and weights in the compiled ``model``."""
        self._sensor_adr = {}
        for req in self.sensors(model):
            sid = object_id(model, "sensor", req.name)
            adr, dim = int(model.sensor_adr[sid]), int(model.sensor_dim[sid])
            self._sensor_adr[req.name] = slice(adr, adr + dim)
        self.weight = as_weights(
            f"{type(self).__name__}.weight", self._weight_arg, self.size(model)
        )

    def sensor_slice(self, features: Features, sensor_name: str) -> np.ndarray:
        """Columns of ``features.sensordata`` holding one requested sensor, shape ``(B, dim)``."""
        return features.sensordata[:, self._sensor_adr[sensor_name]]

    def sensor_address(self, sensor_name: str) -> slice:
        """Where one requested sensor sits in ``sensordata``."""
        return self._sensor_adr[sensor_name]


#: Valid values of :attr:`CostTerm.stage`, from the least of ``mj_forward`` to all of it.
STAGES: tuple[str, ...] = ("none", "pos", "vel", "acc")


def forward_stage(terms: Sequence[CostTerm]) -> str:
    """The largest :attr:`~CostTerm.stage` of ``terms`` (``"none"`` for no terms).

    Raises:
        CostDefinitionError: If a term's ``stage`` is not one of :data:`STAGES`.
    """
    level = 0
    for term in terms:
        if term.stage not in STAGES:
            raise CostDefinitionError(
                f"cost term {term.name!r} of type {type(term).__name__} has stage "
                f"{term.stage!r}; expected one of {', '.join(map(repr, STAGES))}"
            )
        level = max(level, STAGES.index(term.stage))
    return STAGES[level]


class Cost:
    """Running and terminal cost terms of a Problem.

    The running cost of one step is ``sum(0.5 * w * r**2)`` over ``running``; the terminal
    cost the same over ``terminal``.

    Args:
        running: Terms evaluated at every knot ``(x_t, u_t)``.
        terminal: Terms evaluated at the final state (controls are ignored there).
    """

    @checked_options
    def __init__(self, running: Sequence[CostTerm], terminal: Sequence[CostTerm] = ()) -> None:
        for label, terms in (("running", running), ("terminal", terminal)):
            if isinstance(terms, (str, bytes)) or not isinstance(terms, Sequence):
                raise InvalidTypeError(
                    f"Cost {label} must be a sequence of CostTerm, got {type(terms).__name__}"
                )
            for term in terms:
                instance(label, term, CostTerm, "a sequence of CostTerm instances")
        if not running:
            raise InvalidArgumentError("Cost running must hold at least one term")
        self.running = list(running)
        self.terminal = list(terminal)

    @property
    def terms(self) -> list[CostTerm]:
        """Running then terminal terms."""
        return self.running + self.terminal

    def sensors(self, model: mujoco.MjModel) -> list[SensorRequest]:
        """All sensors the terms need, without duplicates.

        Raises:
            CostDefinitionError: If two terms ask for sensors of one name on different
                objects or of different types (two terms of one name, e.g. two
                ``ComVelocity`` terms on different roots without their own ``name``).
        """
        out: dict[str, tuple[SensorRequest, CostTerm]] = {}
        for term in self.terms:
            for req in term.sensors(model):
                seen = out.setdefault(req.name, (req, term))
                if _sensor_key(seen[0]) != _sensor_key(req):
                    first, other = seen[1], term
                    raise CostDefinitionError(
                        f"cost terms {first.name!r} ({type(first).__name__}) and "
                        f"{other.name!r} ({type(other).__name__}) both need a sensor "
                        f"named {req.name!r}, on {seen[0].objname!r} and {req.objname!r}: "
                        "give the terms distinct names (name=...)"
                    )
        return [req for req, _ in out.values()]

    def bind(self, model: mujoco.MjModel) -> None:
        """Bind every term to the compiled model and check weights."""
        for term in self.terms:
            term.bind(model)
            if not np.all(np.isfinite(term.weight)):
                raise CostDefinitionError(f"cost term {term.name!r} has non-finite weights")

    @staticmethod
    def _sum(terms: Sequence[CostTerm], features: Features) -> np.ndarray:
        total = np.zeros(features.qpos.shape[0])
        for term in terms:
            r = term.residual(features)
            total += 0.5 * np.sum(term.weight * r * r, axis=-1)
        return total

    def running_value(self, features: Features) -> np.ndarray:
        """Running cost per row, shape ``(B,)``."""
        return self._sum(self.running, features)

    def terminal_value(self, features: Features) -> np.ndarray:
        """Terminal cost per row, shape ``(B,)``; zero without terminal terms."""
        return self._sum(self.terminal, features)
