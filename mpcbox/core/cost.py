r"""Residual cost terms.

A cost term is a weighted least-squares residual:

.. math:: \ell(x, u) = \tfrac12 \sum_i w_i \, r_i(x, u)^2 .

Residuals are computed from the batch :class:`Features` ``(qpos, qvel, ctrl, sensordata)``.
Terms that need positions of bodies or sites ask for MuJoCo sensors (:meth:`CostTerm.sensors`)
which :class:`~mpcbox.Problem` adds to its models. The same numbers are therefore available
after ``mj_forward`` on one state, from :func:`mujoco.rollout.rollout` for thousands of states,
and on the GPU from MJWarp, so every controller scores trajectories with the same function.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from mpcbox.core.model import frame_object, object_id
from mpcbox.core.tangent import TangentSpace
from mpcbox.errors import CostDefinitionError, InvalidArgumentError
from mpcbox.validation import as_array, as_weights


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


def _frame_sensor(model: mujoco.MjModel, name: str) -> tuple[mujoco.mjtObj, str]:
    kind, _ = frame_object(model, name)
    return (mujoco.mjtObj.mjOBJ_SITE if kind == "site" else mujoco.mjtObj.mjOBJ_XBODY), name


def _point_jacobian(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    kind, idx = frame_object(model, name)
    jac = np.zeros((3, model.nv))
    if kind == "site":
        mujoco.mj_jacSite(model, data, jac, None, idx)
    else:
        mujoco.mj_jacBody(model, data, jac, None, idx)
    return jac


class CostTerm(abc.ABC):
    """Base class of residual cost terms.

    Subclasses implement :meth:`residual` and, where cheap, :meth:`jacobian`; terms that need
    body or site positions list sensors in :meth:`sensors` and read them in :meth:`residual`
    through :meth:`sensor_slice`.

    Args:
        weight: Scalar or per-residual weights ``w`` (non-negative).
        name: Short label used in sensor names and reports.
    """

    #: Whether :meth:`jacobian` is the same at every state (computed once per batch).
    constant_jacobian: bool = False

    def __init__(self, weight: float | Sequence[float] | np.ndarray, name: str) -> None:
        self._weight_arg = weight
        self.name = name
        self.weight: np.ndarray = np.zeros(0)
        self._sensor_adr: dict[str, slice] = {}
        self._model: mujoco.MjModel | None = None

    @property
    def bound(self) -> bool:
        """Whether :meth:`bind` has been called."""
        return self._model is not None

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

    def bind(self, model: mujoco.MjModel) -> None:
        """Resolve sensor addresses and weights in the compiled ``model``."""
        self._model = model
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


class StateCost(CostTerm):
    r"""Deviation from a reference state in tangent space: ``r = [q \ominus q_ref, v - v_ref]``.

    Args:
        qpos_ref: Reference positions ``(nq,)``.
        weight_qpos: Weights on the ``nv`` position differences (scalar or ``(nv,)``).
        weight_qvel: Weights on the ``nv`` velocity differences (scalar or ``(nv,)``).
        qvel_ref: Reference velocities ``(nv,)``; zeros by default.
    """

    constant_jacobian = True

    def __init__(
        self,
        qpos_ref: np.ndarray,
        weight_qpos: float | np.ndarray,
        weight_qvel: float | np.ndarray = 0.0,
        qvel_ref: np.ndarray | None = None,
        name: str = "state",
    ) -> None:
        super().__init__(0.0, name)
        self.qpos_ref = np.asarray(qpos_ref, dtype=np.float64)
        self.qvel_ref = None if qvel_ref is None else np.asarray(qvel_ref, dtype=np.float64)
        self._wq, self._wv = weight_qpos, weight_qvel
        self._tangent: TangentSpace | None = None

    def size(self, model: mujoco.MjModel) -> int:
        return 2 * model.nv

    def bind(self, model: mujoco.MjModel) -> None:
        as_array(f"{self.name}.qpos_ref", self.qpos_ref, (model.nq,))
        if self.qvel_ref is None:
            self.qvel_ref = np.zeros(model.nv)
        as_array(f"{self.name}.qvel_ref", self.qvel_ref, (model.nv,))
        wq = as_weights(f"{self.name}.weight_qpos", self._wq, model.nv)
        wv = as_weights(f"{self.name}.weight_qvel", self._wv, model.nv)
        self._weight_arg = np.concatenate([wq, wv])
        self._tangent = TangentSpace(model)
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        assert self._tangent is not None, "bind() first"
        dq = self._tangent.difference(features.qpos, self.qpos_ref)
        return np.concatenate([dq, features.qvel - self.qvel_ref], axis=-1)

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        # Exact for hinge and slide joints; for quaternions d(log)/dq is the identity at the
        # reference and close to it nearby (the Gauss-Newton approximation).
        nv = model.nv
        eye, zero = np.eye(nv), np.zeros((nv, nv))
        return Jacobian(
            np.vstack([eye, zero]), np.vstack([zero, eye]), np.zeros((2 * nv, model.nu))
        )


class ControlCost(CostTerm):
    """Control effort about a reference control: ``r = u - u_ref``.

    Args:
        weight: Scalar or ``(nu,)`` weights.
        ctrl_ref: Reference control ``(nu,)``; zeros by default.
    """

    constant_jacobian = True

    def __init__(
        self,
        weight: float | np.ndarray,
        ctrl_ref: np.ndarray | None = None,
        name: str = "control",
    ) -> None:
        super().__init__(weight, name)
        self.ctrl_ref = None if ctrl_ref is None else np.asarray(ctrl_ref, dtype=np.float64)

    def size(self, model: mujoco.MjModel) -> int:
        return model.nu

    def bind(self, model: mujoco.MjModel) -> None:
        if self.ctrl_ref is None:
            self.ctrl_ref = np.zeros(model.nu)
        as_array(f"{self.name}.ctrl_ref", self.ctrl_ref, (model.nu,))
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        return features.ctrl - self.ctrl_ref

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        nv, nu = model.nv, model.nu
        return Jacobian(np.zeros((nu, nv)), np.zeros((nu, nv)), np.eye(nu))


class ComOverSupport(CostTerm):
    """Horizontal distance of a subtree's center of mass from a support point.

    ``r = com_xy(root) - p_xy(support)``: zero when the center of mass is above the support
    (for example a stance foot).

    Args:
        support: Site or body name of the support point.
        weight: Scalar or ``(2,)`` weights.
        root: Body whose subtree center of mass is used (default: body 1, the first body).
    """

    def __init__(
        self, support: str, weight: float | np.ndarray, root: str | None = None, name: str = ""
    ) -> None:
        super().__init__(weight, name or f"com_over_{support}")
        self.support = support
        self.root = root

    def _root(self, model: mujoco.MjModel) -> str:
        if self.root is not None:
            return self.root
        return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, 1)

    def size(self, model: mujoco.MjModel) -> int:
        return 2

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        object_id(model, "body", self._root(model))
        objtype, objname = _frame_sensor(model, self.support)
        return (
            SensorRequest(
                f"mpcbox_{self.name}_com",
                mujoco.mjtSensor.mjSENS_SUBTREECOM,
                mujoco.mjtObj.mjOBJ_BODY,
                self._root(model),
            ),
            SensorRequest(
                f"mpcbox_{self.name}_support", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        com = self.sensor_slice(features, f"mpcbox_{self.name}_com")
        foot = self.sensor_slice(features, f"mpcbox_{self.name}_support")
        return com[:, :2] - foot[:, :2]

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jac_com = np.zeros((3, model.nv))
        mujoco.mj_jacSubtreeCom(model, data, jac_com, object_id(model, "body", self._root(model)))
        jq = (jac_com - _point_jacobian(model, data, self.support))[:2]
        return Jacobian(jq, np.zeros((2, model.nv)), np.zeros((2, model.nu)))


class FramePosition(CostTerm):
    """Position of a site or body frame against a target: ``r = S (p - p_target)``.

    Args:
        frame: Site or body name.
        target: Target position ``(3,)``.
        weight: Scalar or ``(3,)`` weights; set an axis's weight to zero to ignore it.
    """

    def __init__(
        self, frame: str, target: np.ndarray, weight: float | np.ndarray, name: str = ""
    ) -> None:
        super().__init__(weight, name or f"pos_{frame}")
        self.frame = frame
        self.target = as_array("target", target, (3,))

    def size(self, model: mujoco.MjModel) -> int:
        return 3

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        objtype, objname = _frame_sensor(model, self.frame)
        return (
            SensorRequest(
                f"mpcbox_{self.name}", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}") - self.target

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        return Jacobian(
            _point_jacobian(model, data, self.frame),
            np.zeros((3, model.nv)),
            np.zeros((3, model.nu)),
        )


class FrameHeight(CostTerm):
    """Height of a site or body frame against a target: ``r = z - z_target``.

    Args:
        frame: Site or body name.
        target: Target height in meters.
        weight: Scalar weight.
    """

    def __init__(self, frame: str, target: float, weight: float, name: str = "") -> None:
        super().__init__(weight, name or f"height_{frame}")
        self.frame = frame
        self.target = float(target)

    def size(self, model: mujoco.MjModel) -> int:
        return 1

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        objtype, objname = _frame_sensor(model, self.frame)
        return (
            SensorRequest(
                f"mpcbox_{self.name}", mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype, objname
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, 2:3] - self.target

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        jq = _point_jacobian(model, data, self.frame)[2:3]
        return Jacobian(jq, np.zeros((1, model.nv)), np.zeros((1, model.nu)))


class Upright(CostTerm):
    """Tilt of a body: the horizontal components of its z axis, zero when upright.

    Args:
        body: Body name.
        weight: Scalar or ``(2,)`` weights.
    """

    def __init__(self, body: str, weight: float | np.ndarray, name: str = "") -> None:
        super().__init__(weight, name or f"upright_{body}")
        self.body = body

    def size(self, model: mujoco.MjModel) -> int:
        return 2

    def sensors(self, model: mujoco.MjModel) -> Sequence[SensorRequest]:
        object_id(model, "body", self.body)
        return (
            SensorRequest(
                f"mpcbox_{self.name}",
                mujoco.mjtSensor.mjSENS_FRAMEZAXIS,
                mujoco.mjtObj.mjOBJ_XBODY,
                self.body,
            ),
        )

    def residual(self, features: Features) -> np.ndarray:
        return self.sensor_slice(features, f"mpcbox_{self.name}")[:, :2]

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        bid = object_id(model, "body", self.body)
        jacr = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, None, jacr, bid)
        z = data.xmat[bid].reshape(3, 3)[:, 2]
        skew = np.array([[0.0, -z[2], z[1]], [z[2], 0.0, -z[0]], [-z[1], z[0], 0.0]])
        jq = (-skew @ jacr)[:2]
        return Jacobian(jq, np.zeros((2, model.nv)), np.zeros((2, model.nu)))


class QuadraticValue(CostTerm):
    r"""A quadratic form in the tangent-space state deviation: :math:`\tfrac12\,dx^T P\,dx`.

    Typically the infinite-horizon LQR value function used as a terminal cost, so that a
    short-horizon controller knows the cost-to-go beyond its horizon. The residual is
    :math:`r = L^T dx` with :math:`L L^T = P` (from an eigendecomposition; ``P`` must be
    positive semidefinite).

    Args:
        P: Matrix ``(2 nv, 2 nv)``.
        qpos_ref: Reference positions ``(nq,)``.
        qvel_ref: Reference velocities ``(nv,)``; zeros by default.
    """

    constant_jacobian = True

    def __init__(
        self,
        P: np.ndarray,
        qpos_ref: np.ndarray,
        qvel_ref: np.ndarray | None = None,
        name: str = "value",
    ) -> None:
        super().__init__(1.0, name)
        self.P = np.asarray(P, dtype=np.float64)
        self.qpos_ref = np.asarray(qpos_ref, dtype=np.float64)
        self.qvel_ref = None if qvel_ref is None else np.asarray(qvel_ref, dtype=np.float64)
        self._L = np.zeros((0, 0))
        self._tangent: TangentSpace | None = None

    def size(self, model: mujoco.MjModel) -> int:
        return 2 * model.nv

    def bind(self, model: mujoco.MjModel) -> None:
        nx = 2 * model.nv
        P = as_array(f"{self.name}.P", self.P, (nx, nx))
        if not np.all(np.isfinite(P)):
            raise CostDefinitionError(f"{self.name}.P must be finite")
        P = 0.5 * (P + P.T)
        vals, vecs = np.linalg.eigh(P)
        if vals.min() < -1e-8 * max(1.0, float(np.abs(vals).max())):
            raise CostDefinitionError(
                f"{self.name}.P must be positive semidefinite; smallest eigenvalue {vals.min():.3g}"
            )
        self._L = vecs * np.sqrt(np.clip(vals, 0.0, None))
        as_array(f"{self.name}.qpos_ref", self.qpos_ref, (model.nq,))
        if self.qvel_ref is None:
            self.qvel_ref = np.zeros(model.nv)
        as_array(f"{self.name}.qvel_ref", self.qvel_ref, (model.nv,))
        self._tangent = TangentSpace(model)
        super().bind(model)

    def residual(self, features: Features) -> np.ndarray:
        assert self._tangent is not None, "bind() first"
        dq = self._tangent.difference(features.qpos, self.qpos_ref)
        dx = np.concatenate([dq, features.qvel - self.qvel_ref], axis=-1)
        return dx @ self._L

    def jacobian(self, model: mujoco.MjModel, data: mujoco.MjData) -> Jacobian:
        nv = model.nv
        return Jacobian(self._L[:nv].T.copy(), self._L[nv:].T.copy(), np.zeros((2 * nv, model.nu)))


class Cost:
    """Running and terminal cost terms of a Problem.

    The running cost of one step is ``sum(0.5 * w * r**2)`` over ``running``; the terminal
    cost the same over ``terminal``.

    Args:
        running: Terms evaluated at every knot ``(x_t, u_t)``.
        terminal: Terms evaluated at the final state (controls are ignored there).
    """

    def __init__(self, running: Sequence[CostTerm], terminal: Sequence[CostTerm] = ()) -> None:
        for label, terms in (("running", running), ("terminal", terminal)):
            for term in terms:
                if not isinstance(term, CostTerm):
                    raise InvalidArgumentError(
                        f"Cost {label} terms must be CostTerm instances, got {type(term).__name__}"
                    )
        if not running:
            raise InvalidArgumentError("Cost running must hold at least one term")
        self.running = list(running)
        self.terminal = list(terminal)

    @property
    def terms(self) -> list[CostTerm]:
        """Running then terminal terms."""
        return self.running + self.terminal

    def sensors(self, model: mujoco.MjModel) -> list[SensorRequest]:
        """All sensors the terms need, without duplicates."""
        out: dict[str, SensorRequest] = {}
        for term in self.terms:
            for req in term.sensors(model):
                out.setdefault(req.name, req)
        return list(out.values())

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
