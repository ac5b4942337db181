"""Options of the force-controlled grasp, as one frozen keyword-only dataclass."""

from __future__ import annotations

from dataclasses import dataclass

from mpcbox.controllers.qp_mpc.solvers import check_backend
from mpcbox.core.contact import friction_pyramid
from mpcbox.errors import InvalidArgumentError
from mpcbox.validation import checked_options, in_range, non_negative, positive


@checked_options
@dataclass(frozen=True, kw_only=True)
class ForceGraspConfig:
    r"""Options of :class:`~mpcbox.controllers.grasp.controller.ForceGrasp`.

    The QP uses the friction estimate divided by the safety factor :math:`s`,
    :math:`\mu_{\text{eff}} = \hat\mu / s`. :math:`s` starts at ``safety``; while slip is
    detected (a finger's slip speed above ``slip_speed``, or its measured tangential/normal
    force ratio above ``slip_ratio`` times :math:`\hat\mu`) it rises at ``safety_rate`` per
    second up to ``safety_max``, and otherwise relaxes back to ``safety`` with time constant
    ``safety_decay``. A slip that shows a friction ratio below :math:`\hat\mu` also lowers
    :math:`\hat\mu` to that ratio (not below ``friction_floor``).

    Attributes:
        friction: Prior estimate :math:`\hat\mu` of the sliding friction coefficient.
        torsion: Estimate of the torsional coefficient (m) for the soft-finger moments.
        safety: Initial and resting safety factor :math:`s_0 \ge 1`.
        safety_max: Largest safety factor.
        safety_rate: Rise of :math:`s` per second of detected slip.
        safety_decay: Time constant of the return of :math:`s` to ``safety`` (s).
        slip_speed: Slip speed that counts as slip (m/s).
        slip_ratio: Fraction of :math:`\hat\mu` that a measured friction ratio counts as
            slip at (> 1 disables the ratio test).
        friction_floor: Least friction estimate that slip may lower :math:`\hat\mu` to.
        disturbance: Fraction of the estimated weight that the grasp resists in any
            direction on top of the known loads: a margin :math:`\delta = d\,\hat m g / k`
            on every pyramid facet of the :math:`k` fingers.
        f_min: Least normal force per finger while holding (N).
        f_max: Largest normal force per finger (N); the actuators' force range applies too.
        approach_force: Closing force of a finger that does not touch yet (N).
        center_stiffness: Stiffness on the fingers' differential mode (each finger's joint
            value minus their mean; N/m for slide fingers): without it force-controlled
            fingers drift together under a sideways push, having no position to return to.
        center_damping: Damping on the differential mode (N s/m).
        map_tolerance: Finger joint motion (joint units) after which the actuator map
            (:func:`~mpcbox.core.actuation.actuation_map`) is evaluated again; in between,
            the last one is reused.
        facets: Facets of the friction pyramid.
        solver: QP backend (``"osqp"`` or a ``qpsolvers`` backend).
    """

    friction: float = 1.0
    torsion: float = 0.05
    safety: float = 1.25
    safety_max: float = 4.0
    safety_rate: float = 20.0
    safety_decay: float = 2.0
    slip_speed: float = 0.005
    slip_ratio: float = 0.95
    friction_floor: float = 0.1
    disturbance: float = 0.5
    f_min: float = 1.0
    f_max: float = 60.0
    approach_force: float = 4.0
    center_stiffness: float = 500.0
    center_damping: float = 10.0
    map_tolerance: float = 2e-4
    facets: int = 4
    solver: str = "osqp"

    def __post_init__(self) -> None:
        positive("friction", self.friction)
        non_negative("torsion", self.torsion)
        in_range("safety", self.safety, 1.0, float("inf"), low_open=False, high_open=True)
        if not self.safety_max >= self.safety:
            raise InvalidArgumentError(
                f"safety_max must be >= safety = {self.safety}, got {self.safety_max!r}"
            )
        for name in ("safety_rate", "safety_decay", "slip_speed", "slip_ratio"):
            positive(name, getattr(self, name))
        positive("friction_floor", self.friction_floor)
        non_negative("disturbance", self.disturbance)
        non_negative("f_min", self.f_min)
        if not positive("f_max", self.f_max) > self.f_min:
            raise InvalidArgumentError(f"f_max must exceed f_min = {self.f_min}")
        positive("approach_force", self.approach_force)
        for name in ("center_stiffness", "center_damping", "map_tolerance"):
            non_negative(name, getattr(self, name))
        friction_pyramid(1.0, self.facets)
        check_backend(self.solver)
