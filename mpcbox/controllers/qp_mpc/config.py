"""Options of the contact-force QP-MPC, as one frozen keyword-only dataclass."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from mpcbox.controllers.qp_mpc.solvers import check_backend
from mpcbox.errors import InvalidArgumentError, InvalidTypeError, UnknownOptionError
from mpcbox.validation import (
    boolean,
    checked_options,
    finite_array,
    in_range,
    one_of,
    positive,
    positive_int,
    string,
)

StanceModelName = Literal["soft", "rigid"]
Fallback = Literal["lqr", "plan"]
LiftedPoints = Literal["drop", "keep"]
LiftedForceLaw = Literal["drop", "cancel"]
#: Names of the terminal costs (an ``(nx, nx)`` matrix is accepted too).
TERMINALS: tuple[str, ...] = ("stance", "lqr", "cost")
STANCE_MODELS: tuple[str, ...] = ("soft", "rigid")
FALLBACKS: tuple[str, ...] = ("lqr", "plan")
LIFTED_POINTS: tuple[str, ...] = ("drop", "keep")
LIFTED_FORCE_LAWS: tuple[str, ...] = ("drop", "cancel")
BetweenTicks = Literal["hold", "lqr"]
BETWEEN_TICKS: tuple[str, ...] = ("hold", "lqr")
FirstStageForces = Literal["bounded", "free"]
FIRST_STAGE_FORCES: tuple[str, ...] = ("bounded", "free")


def _check_osqp_settings(settings: object) -> None:
    """``osqp_settings`` must be a mapping of OSQP setting names (OSQP's own list)."""
    if not isinstance(settings, Mapping):
        raise InvalidTypeError(
            f"osqp_settings must be a mapping of OSQP settings, got {type(settings).__name__}"
        )
    from osqp.ext_builtin import OSQPSettings

    defaults = OSQPSettings()
    valid = [name for name in dir(defaults) if not name.startswith("_")]
    unknown = set(settings) - set(valid)
    if unknown:
        raise UnknownOptionError("osqp_settings", unknown, valid)
    for name, value in settings.items():
        _check_osqp_value(name, value, type(getattr(defaults, name)))


#: OSQP settings that must be positive (the rest of the numbers only non-negative), and the
#: step size's open upper bound.
_OSQP_POSITIVE = ("max_iter", "rho", "sigma", "alpha")
_OSQP_ALPHA_MAX = 2.0


def _check_osqp_value(name: str, value: object, kind: type) -> None:
    """An OSQP setting's value against the type of OSQP's own field (int flags and counts
    take a bool or a non-negative integer, floats a finite non-negative number)."""
    where = f"osqp_settings[{name!r}]"
    if kind is int:
        typed = isinstance(value, (bool, np.bool_, int, np.integer))
        expected = "a bool or an integer >= 0"
    elif kind is float:
        typed = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
            value, (bool, np.bool_)
        )
        expected = "a finite number >= 0"
    else:  # OSQP's enums: OSQP checks them
        return
    if not typed:
        raise InvalidTypeError(f"{where} must be {expected}, got {value!r}")
    if not (math.isfinite(value) and value >= 0):  # type: ignore[arg-type, operator]
        raise InvalidArgumentError(f"{where} must be {expected}, got {value!r}")
    if name in _OSQP_POSITIVE and value <= 0:  # type: ignore[operator]
        raise InvalidArgumentError(f"{where} must be > 0, got {value!r}")
    if name == "alpha" and value >= _OSQP_ALPHA_MAX:  # type: ignore[operator]
        raise InvalidArgumentError(f"{where} must be in (0, 2), got {value!r}")


@checked_options
@dataclass(frozen=True, kw_only=True)
class QPMPCConfig:
    r"""Options of :class:`~mpcbox.controllers.qp_mpc.controller.QPMPC`.

    Every field is checked when the config is built; an error names the field.

    Attributes:
        horizon: Number of QP steps ``N`` (>= 1).
        dt: QP step (s).
        contacts: Geom, site or body names of the contact points (see
            :func:`~mpcbox.core.contact.contact_points`; prefix ``"geom:"``, ``"body:"`` or
            ``"site:"`` to pick one kind). Default: the Problem's ``contacts`` attribute if
            it has one, else the bodies touching the ground at its reference state.
        friction: Friction coefficient :math:`\mu` of the pyramid (> 0).
        facets: Facets of the friction pyramid (an even integer >= 4; 4 or 8 in practice).
        f_max: Largest normal force per point (N); default twice the body weight.
        relinearize: Relinearize about the measured state and the last control every tick
            (otherwise once, about the reference).
        solver: ``"osqp"`` (persistent OSQP solver) or a ``qpsolvers`` backend name.
        rescue: A second backend (e.g. ``"clarabel"``) that re-solves, from scratch, a QP the
            ``solver`` failed; ``None`` (default): a failed solve falls back at once. A
            rescued solve is counted in ``stats["rescued_solves"]``. Measured after large
            pushes (``benchmarks/qp_settings_sweep.py``), Clarabel rescued 2 to 14 of 37 to
            69 failed solves, at a median of 0.05 to 6.4 s per tick, and the A1 fell with it
            where it stood without: for studying failed ticks, not for real time.
        force_weight: Weight :math:`w_f` of the force regularization (forces in body
            weights).
        terminal: ``"stance"`` (Riccati matrix of the prediction model with the forces as
            inputs and the stance constraint as a penalty), ``"lqr"`` (Riccati matrix of the
            soft-contact model at ``dt``, composed of substeps; the default), ``"cost"``
            (the running ``Q``), or an ``(nx, nx)`` matrix.
        terminal_scale: Multiplier on the terminal matrix (> 0).
        drift_gain: Fraction :math:`\alpha` in ``[0, 1]`` of the stance pose error removed
            in one step (rigid stance).
        stance_weight: Weight of slack variables that soften the stance rows (keeps the QP
            feasible when the feet cannot be held); ``None`` for hard stance rows (rigid
            stance only).
        contact_margin: A point higher than this above the lowest reference point is
            lifted (m).
        lifted_points: ``"drop"`` (default): contact points already lifted at the reference
            state are left out of the QP, so a foot named as a body keeps only the points of
            its geoms that touch the ground (on Menagerie's A1 the four feet as bodies give 20
            points, 4 of them on the ground: the QP shrinks from 1680 to 720 variables);
            ``"keep"``: every point stays (a lifted one carries no force until it touches).
        lifted_force_law: What the soft stance model does with the linearized force law of
            a point that is lifted at the measured state (its normal force is bounded to 0):
            ``"drop"`` (default) leaves the law out, so the prediction keeps the linear
            contact model's force there, as LQR's linear model does; ``"cancel"`` keeps
            the law and cancels that force with the penalized slack. Largest survived push
            of 0.1 s (``benchmarks/qp_lifted_force_law.py``, results in
            ``benchmarks/results/``): on Menagerie's Go1, ``"cancel"`` 75 N forward and
            50 N backward, ``"drop"`` the whole 300 N search range forward and 57 N
            backward (with ``"cancel"``, 87 of 150 solves after an 80 N push ended at
            OSQP's iteration cap or "primal infeasible"; 18 with ``"drop"``). On the
            humanoid presets the two are close (one leg backward 113.7 N cancel, 109.0 N
            drop; two feet 102.0/91.4 N cancel, 105.5/92.6 N drop), and the presets keep
            ``"cancel"``, with which their published push limits were measured.
        joint_limits: Add the ranges of the limited hinges and slides as hard constraints
            at every stage. Off by default: on the one-leg humanoid preset (21 limited
            hinges) a 2 s run under the noise recipe stood as without them, at a median tick
            of 48 ms against 6.5 ms, and single solves near a limit stopped at the preset's
            iteration cap unless OSQP ran with adaptive rho and a higher cap. (Before stop
            43 the option added no constraint: a numpy joint type is never ``in`` a tuple
            of MuJoCo's enum values.)
        cost_gradient: Keep the cost gradient at the reference (default: regulate to the
            reference, dropping it, as LQR does).
        warm_start: Warm-start OSQP from the shifted previous solution (else cold start).
        period: Seconds between calls (default ``dt``).
        fd_centered: Centered finite differences for the contact-free linearization.
        substeps: Planning-model steps per QP step (default ``round(dt / h)`` with ``h``
            the planning model's timestep).
        stance_model: ``"soft"`` (default): predict with the soft-contact model and tie the
            explicit forces to its linearized contact-force law
            (:class:`~mpcbox.controllers.qp_mpc.prediction.SoftStance`); ``"rigid"``:
            contact-free prediction with the stance feet held still
            (:class:`~mpcbox.controllers.qp_mpc.prediction.RigidStance`).
        scale_controls: Solve for the controls scaled by their cost, :math:`\delta u_j
            \sqrt{R_{jj}}` (:func:`~mpcbox.controllers.qp_mpc.formulation.control_scale`),
            so that the QP does not depend on the control units; ``False``: in control units
            (as before; an exported QP is in the units used).
        osqp_settings: OSQP settings overriding
            :data:`~mpcbox.controllers.qp_mpc.solvers.OSQP_DEFAULTS`.
        export_dir: When set, every tick's QP is written there as ``tick_00000.npz`` ...
        fallback: What a failed solve (its status counted in ``stats``) does: ``"lqr"``
            (default) applies the LQR about the reference; ``"plan"`` replays the last
            accepted plan open loop while it lasts, then LQR. On two feet after a forward
            push, ``"plan"`` fell at 97.5 N and 100 N yet survived 105 N, because the
            open-loop replay runs just when the state leaves the plan. ``"lqr"`` survived
            every push up to 100 N (``docs/results/humanoid.md``).
        time_limit: Wall-clock budget of one OSQP solve (s; OSQP's ``time_limit``), so that
            a tick ends within the control period on a real robot: a solve that reaches it
            returns its last (warm-started) iterate, which is used as the plan while its
            first stage holds (``truncated_residual``) and counted in
            ``stats["truncated_solves"]``, unlike a solve that reaches ``max_iter``, which
            fails. ``None``: no limit. A budget below one iteration's time leaves
            OSQP's first iterate (benchmarks/qp_tick_one_core.py measures the effect).
        truncated_residual: A truncated iterate is used only while the rows of its first
            stage (dynamics, stance, cones, bounds: those that bind the control applied now)
            hold to this (QP units: rad, m and their rates, forces in body weights; 1e-3 is
            0.1 % of the weight); otherwise the solve counts as failed (status ``"time limit
            reached, residual above truncated_residual"``) and the ``fallback`` runs. On
            Talos (Menagerie, 32 motors) a 2-core machine reached 15 ms after 0-14
            iterations; iterates with a first-stage violation above 1e-3 had first controls
            off the converged ones by up to 45 % of the control range and the robot fell;
            on Apollo the first stage held to 2e-4 while the whole QP's residual passed 0.1,
            and the first controls were within 0.06 % (``benchmarks/qp_truncation_quality.py``).
        between_ticks: What the controller applies between two solves, ``period`` apart:
            ``"hold"`` (default) holds the plan's first control; ``"lqr"`` is called at
            every step of the simulation model and adds the LQR gain :math:`K` about the
            reference (the fallback's) to the plan, tracking its predicted states:
            :math:`u(t) = u_k - K\,\big((x(t) \ominus \bar x) - \delta\hat x(t)\big)`
            with :math:`k = \lfloor (t - t_s)/dt \rfloor` and :math:`\delta\hat x(t)` the
            plan's state deviations from the linearization point :math:`\bar x`,
            interpolated linearly in time from the solve at :math:`t_s`. A robot driven by
            torque alone gets feedback between slow replans, as a servo robot gets from its
            servos. The extra calls are counted as held (``Metrics.held_ticks``), and
            solve-time budgets stay ``period``. After a failed solve the steps until the
            next solve use the ``fallback``.
        first_stage_forces: ``"bounded"`` (default): every stage's point forces keep the
            friction pyramid and normal-force bounds; ``"free"`` (soft stance only): the first
            stage's forces of the points that touch the ground are left unbounded. They
            follow the linearized force law at the measured state, which the first control
            can barely change; bounding each point's linearized force there makes the QP bend
            that control to keep it in the cone, and under stronger noise the plans then
            fall where LQR stands (``benchmarks/qp_force_bounds_diagnosis.py``). Later
            stages keep their bounds, and lifted points carry no force at any stage.
    """

    horizon: int = 10
    dt: float = 0.02
    contacts: Sequence[str] | str | None = None
    friction: float = 0.7
    facets: int = 4
    f_max: float | None = None
    relinearize: bool = False
    solver: str = "osqp"
    rescue: str | None = None
    force_weight: float = 1.0
    terminal: str | np.ndarray = "lqr"
    terminal_scale: float = 1.0
    drift_gain: float = 0.2
    stance_weight: float | None = 1e4
    contact_margin: float = 0.01
    lifted_points: LiftedPoints = "drop"
    lifted_force_law: LiftedForceLaw = "drop"
    joint_limits: bool = False
    cost_gradient: bool = False
    warm_start: bool = True
    period: float | None = None
    fd_centered: bool = False
    substeps: int | None = None
    stance_model: StanceModelName = "soft"
    scale_controls: bool = True
    osqp_settings: Mapping[str, Any] | None = None
    export_dir: str | Path | None = None
    fallback: Fallback = "lqr"
    time_limit: float | None = None
    truncated_residual: float = 1e-3
    between_ticks: BetweenTicks = "hold"
    first_stage_forces: FirstStageForces = "bounded"

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("horizon", positive_int("horizon", self.horizon))
        put("dt", positive("dt", self.dt))
        if self.contacts is not None and not isinstance(self.contacts, str):
            if not isinstance(self.contacts, Sequence):
                raise InvalidTypeError(
                    f"contacts must be names (str), got {type(self.contacts).__name__}"
                )
            put("contacts", tuple(string("contacts", c) for c in self.contacts))
        put("friction", positive("friction", self.friction))
        facets = positive_int("facets", self.facets)
        if facets < 4 or facets % 2:
            raise InvalidArgumentError(f"facets must be an even integer >= 4, got {facets}")
        put("facets", facets)
        if self.f_max is not None:
            put("f_max", positive("f_max", self.f_max))
        check_backend(self.solver)
        if self.rescue is not None:
            check_backend(self.rescue, "rescue")
        put("force_weight", positive("force_weight", self.force_weight))
        if isinstance(self.terminal, str) and self.terminal not in TERMINALS:
            raise InvalidArgumentError(
                "terminal must be 'stance', 'lqr', 'cost' or an (nx, nx) matrix, "
                f"got {self.terminal!r}"
            )
        if not isinstance(self.terminal, str):  # the size is checked by the controller
            put("terminal", finite_array("terminal", self.terminal, (None, None)))
        put("terminal_scale", positive("terminal_scale", self.terminal_scale))
        if self.stance_weight is not None:
            put("stance_weight", positive("stance_weight", self.stance_weight))
        put(
            "drift_gain",
            in_range("drift_gain", self.drift_gain, 0, 1, low_open=False, high_open=False),
        )
        put("contact_margin", positive("contact_margin", self.contact_margin))
        if self.period is not None:
            put("period", positive("period", self.period))
        if self.substeps is not None:
            put("substeps", positive_int("substeps", self.substeps))
        if self.time_limit is not None:
            put("time_limit", positive("time_limit", self.time_limit))
            if self.solver != "osqp":
                raise InvalidArgumentError(
                    f"time_limit needs solver='osqp' (OSQP's time limit), got solver="
                    f"{self.solver!r}"
                )
        put("truncated_residual", positive("truncated_residual", self.truncated_residual))
        one_of("stance_model", self.stance_model, STANCE_MODELS)
        if self.stance_model == "soft" and self.stance_weight is None:
            raise InvalidArgumentError("stance_model='soft' needs a finite stance_weight")
        if self.export_dir is not None:
            if not isinstance(self.export_dir, (str, Path)):
                raise InvalidTypeError(
                    f"export_dir must be a path, got {type(self.export_dir).__name__}"
                )
            put("export_dir", Path(self.export_dir))
            if self.export_dir.exists() and not self.export_dir.is_dir():
                raise InvalidArgumentError(
                    f"export_dir must be a folder (made if missing), got the file "
                    f"{str(self.export_dir)!r}"
                )
        one_of("fallback", self.fallback, FALLBACKS)
        one_of("between_ticks", self.between_ticks, BETWEEN_TICKS)
        one_of("first_stage_forces", self.first_stage_forces, FIRST_STAGE_FORCES)
        if self.first_stage_forces == "free" and self.stance_model != "soft":
            raise InvalidArgumentError(
                "first_stage_forces='free' needs stance_model='soft' (with the rigid stance the "
                f"forces drive the prediction), got stance_model={self.stance_model!r}"
            )
        one_of("lifted_points", self.lifted_points, LIFTED_POINTS)
        one_of("lifted_force_law", self.lifted_force_law, LIFTED_FORCE_LAWS)
        for name in (
            "relinearize",
            "joint_limits",
            "cost_gradient",
            "warm_start",
            "fd_centered",
            "scale_controls",
        ):
            put(name, boolean(name, getattr(self, name)))
        if self.osqp_settings is not None:
            _check_osqp_settings(self.osqp_settings)
