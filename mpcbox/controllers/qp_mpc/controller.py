r"""Linear MPC with explicit contact forces and friction-pyramid constraints (a sparse QP).

Every tick :class:`QPMPC` builds the QP of
:mod:`~mpcbox.controllers.qp_mpc.formulation` for the measured state (relinearizing the
prediction model of :mod:`~mpcbox.controllers.qp_mpc.prediction` first when
``relinearize`` is set), solves it with a backend of
:mod:`~mpcbox.controllers.qp_mpc.solvers` (by default a persistent OSQP solver, warm-started
from the previous solution shifted by one step) and applies the first planned control. A
failed solve is re-solved by the ``rescue`` backend when one is set; one that stays failed
falls back to LQR (or to the last plan, ``fallback="plan"``). Both are counted in
:attr:`QPMPC.stats`. Options: :class:`~mpcbox.controllers.qp_mpc.config.QPMPCConfig`.
"""

from __future__ import annotations

import time as _time
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from mpcbox.config import resolve_config
from mpcbox.controllers.base import Controller, check_problem
from mpcbox.controllers.lqr import LQR
from mpcbox.controllers.qp_mpc.config import QPMPCConfig
from mpcbox.controllers.qp_mpc.dynamics import ContactDynamics, prediction_models
from mpcbox.controllers.qp_mpc.formulation import (
    QPFormulation,
    control_scale,
    joint_limits,
    quadratic_cost,
)
from mpcbox.controllers.qp_mpc.layout import QPLayout
from mpcbox.controllers.qp_mpc.prediction import PREDICTION_MODELS
from mpcbox.controllers.qp_mpc.solvers import (
    QPData,
    constraint_residual,
    export_qp,
    make_backend,
)
from mpcbox.controllers.qp_mpc.terminal import terminal_matrix
from mpcbox.core.contact import (
    ContactPoints,
    cone_violation,
    contact_points,
    friction_pyramid,
    project_to_pyramid,
)
from mpcbox.core.divergence import check_planning_step
from mpcbox.core.problem import Problem
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.validation import finite


class QPPlan(NamedTuple):
    """A solved plan.

    Attributes:
        dx: Predicted state deviations from the linearization point, ``(N + 1, nx)``.
        ctrls: Planned controls ``(N, nu)``.
        forces: Planned contact forces in newtons, world frame, ``(N, k, 3)``, projected onto
            the friction pyramid (the projection moves them by at most ``violation``).
        violation: Largest friction/unilateral violation of the raw solver output, in
            newtons.
        status: Solver status string.
        iterations: Solver iterations (0 when the backend does not report them).
        solve_time: Solver wall time (s).
        objective: QP objective value.
    """

    dx: np.ndarray
    ctrls: np.ndarray
    forces: np.ndarray
    violation: float
    status: str
    iterations: int
    solve_time: float
    objective: float


class TickTiming(NamedTuple):
    """Wall times (s) of the parts of the last tick."""

    linearize: float
    update: float
    solve: float


def default_contacts(problem: Problem, state: np.ndarray) -> list[str]:
    """Bodies touching the ground at ``state`` in the planning model, as ``body:`` names.

    Raises:
        InvalidArgumentError: If nothing touches the ground.
    """
    m = problem.planning_model
    d = mujoco.MjData(m)
    problem.set_state(d, state)
    mujoco.mj_forward(m, d)
    bodies: list[int] = []
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        for b in (b1, b2):
            if b != 0 and b not in bodies and 0 in (b1, b2):
                bodies.append(b)
    if not bodies:
        raise InvalidArgumentError(
            "contacts: nothing touches the ground at the reference state; name the "
            "contact geoms, sites or bodies (QP-MPC plans contact forces: a model without "
            "contacts, such as a fixed-base arm or a cart-pole, is for LQR, iLQR or sampling)"
        )
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in bodies]
    unnamed = [b for b, name in zip(bodies, names, strict=True) if not name]
    if unnamed:
        raise InvalidArgumentError(
            f"contacts: unnamed bodies (ids {unnamed}) touch the ground at the reference state, "
            "so they cannot be found by name; name them in the MJCF or give "
            "QPMPCConfig(contacts=...) the contact geoms, sites or bodies"
        )
    return ["body:" + name for name in names]


def grounded_points(
    model: mujoco.MjModel, points: ContactPoints, qpos: np.ndarray, margin: float
) -> ContactPoints:
    """The points less than ``margin`` above the lowest one at posture ``qpos`` ``(nq,)``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    z = points.world(data)[:, 2]
    keep = np.flatnonzero(z < z.min() + margin)
    return ContactPoints(
        points.body[keep], points.local[keep], tuple(points.label[i] for i in keep)
    )


#: Failure status of a solve stopped at ``time_limit`` with an iterate too far from feasible.
TRUNCATED_UNUSABLE = "time limit reached, residual above truncated_residual"


def _usable(x: np.ndarray | None) -> bool:
    """Whether a solver returned a finite primal solution."""
    return x is not None and bool(np.all(np.isfinite(x)))


class QPMPC(Controller):
    r"""Contact-force QP-MPC (see the module docstring and :mod:`.formulation`).

    Args:
        problem: The Problem; its planning model is copied at the QP substep for the
            prediction (:func:`~mpcbox.controllers.qp_mpc.dynamics.prediction_models`).
        config: Options; defaults when omitted.
        **options: Fields of :class:`~mpcbox.controllers.qp_mpc.config.QPMPCConfig` that
            replace those of ``config`` (``horizon=10, dt=0.02, friction=0.7, ...``).

    Attributes:
        config: The resolved options.
        horizon: Number of QP steps ``N``.
        dt: QP step (s).
        period: Seconds between calls: ``replan_period``, or the simulation model's
            timestep with ``between_ticks="lqr"``.
        replan_period: Seconds between solves (the config's ``period``, default ``dt``).
        substeps: Planning-model steps per QP step.
        friction: Friction coefficient of the pyramid.
        facets: Facets of the pyramid.
        stance_model: ``"soft"`` or ``"rigid"``.
        body_weight: Total weight :math:`m g` of the model in newtons (N); the QP's forces
            are in this unit.
        f_max: Largest normal force per point (N).
        points: The :class:`~mpcbox.core.contact.ContactPoints`.
        dynamics: The :class:`~mpcbox.controllers.qp_mpc.dynamics.ContactDynamics`.
        model: Its contact-free model; ``soft_model``: its soft-contact model.
        prediction: The :class:`~mpcbox.controllers.qp_mpc.prediction.PredictionModel`.
        layout: The :class:`~mpcbox.controllers.qp_mpc.layout.QPLayout` (``nvar``,
            ``ncon``: its sizes).
        formulation: The :class:`~mpcbox.controllers.qp_mpc.formulation.QPFormulation`.
        linearization: The current
            :class:`~mpcbox.controllers.qp_mpc.dynamics.Linearization`.
        Q, R, N_ux: Running cost about the reference; ``P_terminal``: terminal matrix.
        last_plan: The last accepted :class:`QPPlan` (``None`` before the first solve).
        last_status: Status of the last solve.
        timing: :class:`TickTiming` of the last tick.
        qp: The last tick's :class:`~mpcbox.controllers.qp_mpc.solvers.QPData`.
    """

    name = "qp"
    config_class = QPMPCConfig
    last_plan: QPPlan | None
    last_status: str
    timing: TickTiming
    qp: QPData | None

    def __init__(self, problem: Problem, config: QPMPCConfig | None = None, **options: Any) -> None:
        self.problem = problem = check_problem(problem, "QPMPC")
        self.config = cfg = resolve_config(QPMPCConfig, config, options, "QPMPC")
        check_planning_step(problem)  # PlanningDivergenceError at a diverging timestep
        self.horizon, self.dt = cfg.horizon, cfg.dt
        self.replan_period = cfg.dt if cfg.period is None else cfg.period
        # With feedback between ticks the simulation calls every step and solves every
        # ``replan_period``; otherwise the two are the same.
        feedback = cfg.between_ticks == "lqr"
        self.period = float(problem.model.opt.timestep) if feedback else self.replan_period
        self.friction, self.facets = cfg.friction, cfg.facets
        self.stance_model = cfg.stance_model
        self.pyramid = friction_pyramid(cfg.friction, cfg.facets)
        # The QP step is composed of ``substeps`` steps of the planning model's own timestep
        # (a single semi-implicit step of 0.02 s mispredicts the 0.005 s simulation badly).
        base_dt = float(problem.planning_model.opt.timestep)
        self.substeps = max(1, round(cfg.dt / base_dt)) if cfg.substeps is None else cfg.substeps
        self.model, self.soft_model = prediction_models(problem, cfg.dt, self.substeps)

        self.state_ref = problem.reference_state()
        self.ctrl_ref = problem.ctrl_ref.copy()
        contacts = cfg.contacts
        if contacts is None:
            contacts = problem.contacts or default_contacts(problem, self.state_ref)
        contacts = [contacts] if isinstance(contacts, str) else list(contacts)
        try:
            self.points = contact_points(self.model, contacts, self.state_ref[: problem.nq])
        except UnknownNameError as exc:
            raise UnknownNameError(exc.kind, exc.name, exc.valid, "contacts") from None
        if cfg.lifted_points == "drop":
            self.points = grounded_points(
                self.model, self.points, self.state_ref[: problem.nq], cfg.contact_margin
            )
        self.dynamics = ContactDynamics(
            problem,
            self.model,
            self.soft_model,
            self.points,
            self.substeps,
            self.state_ref,
            cfg.fd_centered,
            cfg.contact_margin,
        )
        self.body_weight = self.dynamics.body_weight
        self.f_max = 2.0 * self.body_weight if cfg.f_max is None else cfg.f_max

        cost = quadratic_cost(problem, self.state_ref, self.ctrl_ref, cfg.cost_gradient)
        self.Q, self.R, self.N_ux = cost.Q, cost.R, cost.N_ux
        self.prediction = PREDICTION_MODELS[cfg.stance_model](self.dynamics, cfg)
        self.linearization = self.prediction.linearize(self.state_ref, self.ctrl_ref)
        self.P_terminal = terminal_matrix(
            problem, cfg, self.dynamics, self.linearization, cost, self.state_ref, self.ctrl_ref
        )
        limits = joint_limits(self.model, cfg.joint_limits)
        self.layout = QPLayout(
            horizon=cfg.horizon,
            nx=problem.nx,
            nu=problem.nu,
            nv=problem.nv,
            points=self.points.count,
            facets=cfg.facets,
            ns=self.prediction.ns,
            slacks=cfg.stance_weight is not None,
            nl=len(limits.qpos),
        )
        self.nvar, self.ncon, self.nf = self.layout.nvar, self.layout.ncon, self.layout.nf
        self.formulation = QPFormulation(
            problem,
            self.layout,
            self.prediction,
            cost,
            self.P_terminal,
            limits,
            self.pyramid,
            self.f_max / self.body_weight,
            self.state_ref,
            self.ctrl_ref,
            cfg.stance_weight,
            control_scale(self.R, cfg.scale_controls),
            free_first_forces=cfg.first_stage_forces == "free",
        )
        self.formulation.update_matrix(self.linearization)
        settings = dict(cfg.osqp_settings or {})
        if cfg.time_limit is not None:
            settings["time_limit"] = cfg.time_limit
        self.backend = make_backend(cfg.solver, settings)
        self.rescue = None if cfg.rescue is None else make_backend(cfg.rescue)
        # Built now, not on the first failed (already slow) tick.
        self._lqr: LQR | None = LQR(problem) if cfg.fallback == "lqr" or feedback else None
        # Per-run state, set by reset().
        self._prev_z: np.ndarray | None = None
        self._prev_y: np.ndarray | None = None
        self._last_ctrl = self.ctrl_ref.copy()
        self._plan_age = self._tick = self._fallbacks = 0
        self._plan_fallbacks = self._inaccurate = self._unsolved = self._rescued = 0
        self._truncated = 0
        self._violation_max = 0.0
        self._failures: dict[str, int] = {}
        self._iters: list[int] = []
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the warm start, the last plan, stance anchors and counters."""
        self._prev_z = None
        self._prev_y = None
        self.last_plan = None
        self._plan_age = 0
        self._t_solve: float | None = None
        self._t_plan = 0.0
        self._plan_origin = self.state_ref
        self.last_call = "solve"
        self.prediction.reset()
        self._tick = 0
        self._fallbacks = self._plan_fallbacks = self._inaccurate = 0
        self._unsolved = self._rescued = self._truncated = 0
        self._violation_max = 0.0
        self._failures = {}
        self._iters = []
        self.last_status = "unsolved"
        self.timing = TickTiming(0.0, 0.0, 0.0)
        self.qp = None

    @property
    def stats(self) -> dict[str, float]:
        """Counters since :meth:`reset`; nothing the solver did wrong goes unreported.

        * ``solves``: QPs solved (one per call);
        * ``failed_solves``: solves that ended without a usable solution;
        * ``failed:<status>``: failures of ``solver`` by its status, rescued or not;
        * ``rescued_solves``: failures of ``solver`` that the ``rescue`` backend solved;
        * ``fallbacks``: calls whose control did not come from a fresh solve;
          ``fallbacks_lqr`` and ``fallbacks_plan`` split them by what was applied;
        * ``inaccurate_solves``: accepted solves the solver flagged as inaccurate (OSQP's
          ``"solved inaccurate"``);
        * ``truncated_solves``: solves stopped at ``time_limit`` whose last iterate was used
          (one whose first stage violates its rows by more than ``truncated_residual`` is a
          failed solve instead);
        * ``solver_iterations`` (mean; ``iterations`` is the same number) and
          ``solver_iterations_max`` over the accepted solves;
        * ``force_violation_max``: largest friction or bound violation of an accepted raw
          solution, in newtons (the applied forces are projected, see :class:`QPPlan`).
        """
        iters = self._iters
        out: dict[str, float] = {
            "fallbacks": self._fallbacks,
            "fallbacks_lqr": self._fallbacks - self._plan_fallbacks,
            "fallbacks_plan": self._plan_fallbacks,
            "solves": self._tick,
            "failed_solves": self._unsolved,
            "rescued_solves": self._rescued,
            "inaccurate_solves": self._inaccurate,
            "truncated_solves": self._truncated,
            "solver_iterations": float(np.mean(iters)) if iters else 0.0,
            "solver_iterations_max": float(max(iters)) if iters else 0.0,
            "iterations": float(np.mean(iters)) if iters else 0.0,
            "force_violation_max": self._violation_max,
        }
        for status, count in self._failures.items():
            out[f"failed:{status}"] = count
        return out

    # ------------------------------------------------------------------ per tick
    def _warm_start(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Previous primal and dual solutions moved ``period / dt`` stages earlier."""
        if not self.config.warm_start or self._prev_z is None or self._prev_y is None:
            return None
        shift = max(0, min(self.horizon - 1, round(self.replan_period / self.dt)))
        return self.formulation.shifted(self._prev_z, self._prev_y, shift)

    def solve(self, state: np.ndarray) -> QPPlan | None:
        """Build and solve the QP for ``state``; ``None`` (and a counted status) on failure."""
        p, L = self.problem, self.layout
        state = p.check_state(state)
        t0 = _time.perf_counter()
        changed = False
        if self.config.relinearize:
            ctrl = self.ctrl_ref if self.last_plan is None else self._last_ctrl
            self.linearization = self.prediction.linearize(state, ctrl)
            self.formulation.update_matrix(self.linearization)
            changed = True
        lin = self.linearization
        t1 = _time.perf_counter()
        q, lo, hi = self.formulation.vectors(lin, state)
        self.qp = QPData(self.formulation.P, q, self.formulation.A, lo, hi)
        t2 = _time.perf_counter()
        sol = self.backend.solve(self.qp, changed, self._warm_start())
        if sol.truncated and not (
            constraint_residual(self.qp, sol.x, L.first_stage_rows)
            <= self.config.truncated_residual
        ):
            sol = sol._replace(x=None, status=TRUNCATED_UNUSABLE)
        if not _usable(sol.x):
            self._failures[sol.status] = self._failures.get(sol.status, 0) + 1
            if self.rescue is not None:
                sol = self.rescue.solve(self.qp, changed, None)
                self._rescued += _usable(sol.x)
        t3 = _time.perf_counter()
        self.timing = TickTiming(t1 - t0, t2 - t1, t3 - t2)
        self.last_status = sol.status
        if self.config.export_dir is not None:
            self.export(self.config.export_dir / f"tick_{self._tick:05d}.npz")
        self._tick += 1
        z = sol.x
        if not _usable(z):
            self._unsolved += 1
            return None
        self._iters.append(sol.iterations)
        if sol.inaccurate:
            self._inaccurate += 1
        if sol.truncated:
            self._truncated += 1
        # A rescue backend reports no dual: keep the last one for the next warm start.
        y = sol.y if sol.y is not None else self._prev_y
        self._prev_z, self._prev_y = z, (np.zeros(self.ncon) if y is None else y)
        N, nx, nu = L.horizon, L.nx, L.nu
        dx = np.vstack([p.state_difference(state, lin.state), z[: N * nx].reshape(N, nx)])
        ctrls = lin.ctrl + z[L.ou : L.ou + N * nu].reshape(N, nu) * self.formulation.ctrl_scale
        raw = z[L.of : L.osl].reshape(N, L.points, 3) * self.body_weight
        active, _ = self.dynamics.activity(state)
        raw_active = raw.copy()
        viol = cone_violation(raw, self.friction, self.facets, self.f_max)
        if np.any(~active):
            viol = max(viol, float(np.max(np.abs(raw[:, ~active]))))
            raw_active[:, ~active] = 0.0
        forces = project_to_pyramid(raw_active, self.friction, self.facets, self.f_max)
        self._violation_max = max(self._violation_max, viol)
        plan = QPPlan(dx, ctrls, forces, viol, sol.status, sol.iterations, t3 - t2, sol.objective)
        self.last_plan = plan
        self._plan_age = 0
        return plan

    def __call__(self, state: np.ndarray, time: float) -> np.ndarray:
        time = finite("time", time)
        if self._t_solve is not None and time - self._t_solve < self.replan_period - 0.5 * (
            self.period
        ):
            self.last_call = "hold"  # between_ticks="lqr": feedback until the next solve
            return self._between(state, time)
        self.last_call = "solve"
        self._t_solve = time
        plan = self.solve(state)
        if plan is not None:
            self._t_plan, self._plan_origin = time, self.linearization.state
            ctrl = self.problem.clip_ctrl(plan.ctrls[0])
        else:
            self._fallbacks += 1
            self._plan_age += 1
            step = round(self._plan_age * self.replan_period / self.dt)
            plan = self.last_plan
            if self.config.fallback == "plan" and plan is not None and step < self.horizon:
                ctrl = self.problem.clip_ctrl(plan.ctrls[step])
                self._plan_fallbacks += 1
            else:
                ctrl = self._fallback_lqr()(state, time)
        self._last_ctrl = ctrl
        return ctrl

    def _between(self, state: np.ndarray, time: float) -> np.ndarray:
        """The plan with LQR feedback about its predicted states (``between_ticks="lqr"``);
        the fallback's control while the last solve failed."""
        plan, p = self.last_plan, self.problem
        if self._plan_age or plan is None:
            if self.config.fallback == "plan" and plan is not None:
                step = round((time - self._t_plan) / self.dt)
                if step < self.horizon:
                    return p.clip_ctrl(plan.ctrls[step])
            return self._fallback_lqr()(state, time)
        tau = max(0.0, (time - self._t_plan) / self.dt)
        k = min(int(tau), self.horizon - 1)
        frac = min(tau - k, 1.0)
        predicted = (1.0 - frac) * plan.dx[k] + frac * plan.dx[k + 1]
        error = p.state_difference(state, self._plan_origin) - predicted
        return p.clip_ctrl(plan.ctrls[k] - self._fallback_lqr().K @ error)

    def _fallback_lqr(self) -> LQR:
        """The LQR about the reference that a failed solve falls back to (built once)."""
        if self._lqr is None:
            self._lqr = LQR(self.problem)
        return self._lqr

    # ------------------------------------------------------------------ export
    def export(self, path: str | Path) -> Path:
        """Write the last tick's QP to ``path`` (``.npz``: CSC arrays of ``P`` and ``A``,
        ``q``, ``l``, ``u``, and the sizes; :func:`~mpcbox.controllers.qp_mpc.solvers.load_qp`
        reads it)."""
        if self.qp is None:
            raise InvalidArgumentError("export: no QP built yet; call the controller first")
        return export_qp(
            path,
            self.qp,
            horizon=self.horizon,
            dt=self.dt,
            nx=self.problem.nx,
            nu=self.problem.nu,
            nf=self.nf,
        )
