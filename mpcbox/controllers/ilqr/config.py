"""Keyword-only configuration of the iLQR solver and controller."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from mpcbox.controllers.ilqr.regularization import (
    REGULARIZATION_SCHEDULES,
    RegularizationSchedule,
)
from mpcbox.errors import InvalidArgumentError, InvalidTypeError
from mpcbox.validation import (
    as_array,
    boolean,
    checked_options,
    finite_array,
    in_range,
    integer,
    non_negative,
    number,
    one_of,
    positive,
    positive_int,
)

LineSearch = Literal["backtracking", "parallel"]
TerminalValue = Literal["lqr"]
DynamicsLinearization = Literal["trajectory", "reference"]
CostHessian = Literal["trajectory", "reference"]
DryFriction = Literal["keep", "drop"]
#: Valid values of :attr:`ILQRConfig.line_search`.
LINE_SEARCHES: tuple[str, ...] = ("backtracking", "parallel")
#: Valid values of :attr:`ILQRConfig.terminal_value` besides ``None``.
TERMINAL_VALUES: tuple[str, ...] = ("lqr",)
#: Valid values of :attr:`ILQRConfig.linearization`.
LINEARIZATIONS: tuple[str, ...] = ("trajectory", "reference")
#: Valid values of :attr:`ILQRConfig.cost_hessian`.
COST_HESSIANS: tuple[str, ...] = ("trajectory", "reference")
#: Valid values of :attr:`ILQRConfig.dry_friction` besides ``None``.
DRY_FRICTIONS: tuple[str, ...] = ("keep", "drop")


@checked_options
@dataclass(frozen=True, kw_only=True)
class ILQRConfig:
    r"""Options of :class:`~mpcbox.controllers.ilqr.controller.ILQR`.

    Every field is also a keyword option of ``ILQR(problem, **options)``. The fields that do
    not depend on the Problem are checked (and normalized: numbers to ``float``/``int``,
    ``step_sizes`` to a tuple) when the config is built; the control bounds and the initial
    guess, whose shapes depend on the Problem, are checked by the controller.

    Attributes:
        horizon: Number of knots ``T`` (controls); the plan spans ``T * dt`` seconds with
            ``dt`` the planning timestep. The default, 50 knots, gives any Problem a working
            iLQR; tasks tune it in their ``controller_configs``.
        max_iterations: Iteration cap of :meth:`~mpcbox.controllers.ilqr.solver.ILQRSolver.solve`.
        tolerance: Converged when a full step lowers the cost by less than this fraction of
            it and the backward pass predicts less than that too; a small decrease while the
            predicted one is larger (a poor quadratic model, e.g. near a kink of the
            dynamics) does not stop the iterations.
        mpc_iterations: Iterations per replan in receding-horizon mode.
        first_iterations: Iterations of the first replan after ``reset`` (no warm start
            yet); default ``mpc_iterations``.
        replan_period: Seconds between replans in receding-horizon mode.
        feedback: Apply the feedback law between replans (the controller's ``period`` is then
            ``None`` so that the simulation calls it every step); otherwise the control is
            held for ``replan_period``.
        regularization: Initial Levenberg-Marquardt term :math:`\mu \ge 0` added to the
            diagonal of :math:`Q_{uu}`. In receding-horizon mode every replan starts from the
            smaller of this and the last replan's final :math:`\mu`: an increase that one
            replan needed does not carry into the next (see
            :class:`~mpcbox.controllers.ilqr.controller.ILQR`).
        regularization_min: Below this, :math:`\mu` snaps to 0.
        regularization_max: Give up (keep the current trajectory) above this.
        regularization_factor: Multiplicative step of the :math:`\mu` schedule (> 1).
        regularization_schedule: How :math:`\mu` moves after accepted steps and failures:
            ``"mpcbox"``, ``"crocoddyl"`` or ``"tassa"``
            (:mod:`~mpcbox.controllers.ilqr.regularization`). The default stays
            ``"mpcbox"`` because neither other one is at least as good everywhere on the
            benchmark's pendulum, cart-pole and Panda reaches
            (``benchmarks/results/ilqr_regularization.json``): ``"crocoddyl"`` (factor 10,
            from 1e-9) gives the same iterates except on the hard Panda reach (same local
            minimum, 2 more iterations); ``"tassa"`` (factor 1.6, from 1) closes the
            cart-pole's straight-line state guess in 41 iterations instead of 268, but takes
            3-4 more on the pendulum and the easy reach, and from the hard reach's control
            guess stops 3 % higher after 71 iterations instead of 16. Tassa's schedule
            suits hard swing-ups from poor guesses (the acrobot preset uses it).
        step_sizes: Line-search step sizes ``alpha`` in decreasing order, each in (0, 1].
        line_search: ``"backtracking"`` (try step sizes in order, stop at the first accepted)
            or ``"parallel"`` (roll all of them out on the Problem's thread pool and keep the
            best).
        armijo: Accept a step when the actual decrease is at least this fraction of the
            predicted one, in [0, 1).
        max_retries: Regularization increases (after a failed backward pass or line search)
            allowed per iteration before giving up and keeping the current trajectory.
        mpc_max_retries: The same cap for the receding-horizon replans after the first
            (default ``max_retries``; the first, cold solve always uses ``max_retries``). A
            replan starts from the shifted previous plan, which is already a good
            trajectory; when no step size improves it, raising :math:`\mu` again and again
            buys steps too small to matter at the price of a backward pass and a line search
            each. That happens when the planning model's step is discontinuous, as MuJoCo's
            implicit integrators make it wherever a position servo meets its force limit (the
            servo's damping is integrated implicitly only while unsaturated, so the velocity
            after one step jumps there): the cost along a search direction is then jagged,
            and a replan can sit at a low point of it. A replan that stops at this cap keeps
            its trajectory and counts as a stalled replan (``RETRY_LIMIT``); with ``0`` it
            stops at its first failed line search.
        linearize_every: Linearize the dynamics at every ``linearize_every``-th knot (and the
            last) and interpolate ``A``, ``B`` in between.
        control_steps: Steps of the planning model per knot, each knot's control held for
            all of them (move blocking, :mod:`~mpcbox.controllers.ilqr.held_controls`): the
            plan covers ``horizon * control_steps * problem.dt`` seconds, simulated at the
            model's own timestep, with the backward pass, the cost quadratization and the
            gains on ``horizon`` knots. The knot Jacobians are composed from one
            finite-difference step at each knot; the line search sums the cost over every
            step. Single shooting only (``states_init`` and ``warm_start_states`` are
            refused with it). Unlike ``planning_timestep``, which coarsens the integration
            itself, it keeps a stiff servo's step exact.
        fd_centered: Centered finite differences for the dynamics (default: the Problem's).
        ctrl_low: Lower control bounds ``(nu,)`` (default and outer limit: the Problem's).
        ctrl_high: Upper control bounds ``(nu,)``.
        ctrls_init: Initial control guess ``(T, nu)`` or ``(nu,)`` (default: the Problem's
            guess from the start state, :meth:`mpcbox.Problem.initial_ctrls`: ``ctrl_ref``
            unless the task chooses better).
        states_init: Initial state guess ``(T + 1, nstate)`` of the first solve: multiple
            shooting (:mod:`~mpcbox.controllers.ilqr.multiple_shooting`, FDDP), whose defects
            between shooting nodes are closed during the iterations. ``None``: single
            shooting from ``ctrls_init``.
        defect_tolerance: Largest defect (tangent-space max norm) that counts as closed.
        warm_start_states: In receding-horizon mode, warm-start each replan with the shifted
            plan's states as well as its controls (multiple shooting from the measured state;
            the defect at the first node is the prediction error). Off: the shifted
            plan is rolled out from the measured state (single shooting), as
            ``warm_start_feedback`` says.
        warm_start_feedback: In receding-horizon mode (single shooting), roll each replan's
            warm start out from the measured state under the previous plan's feedback law,
            :math:`u_t = \bar u_t + K_t (x_t \ominus \bar x_t)` shifted by the knots elapsed,
            as the world executes it between replans. Off (the default; the legged tasks
            turn it on): its controls open loop, which on an unstable robot drift from the
            plan's states within the horizon, so that a replan spends its iterations
            repairing its own warm start. On Menagerie's PNDbotics Adam Lite under the noise
            recipe that repair fell short and the robot fell (0/3); from the law it stands
            (3/3), and seven quadrupeds survive 1.00-1.16x LQR's push instead of 0.62-1.04x
            (:class:`~mpcbox.tasks.legged.biped.BipedStand`). On the Panda's 40 cm reach, the
            project humanoid's one-leg balance and the cart-pole swing-up it changed nothing
            measurable (same arrivals, survival and tilt), so those presets keep the default
            (``benchmarks/results/*_warm_start_feedback.json``).
        threads: Threads for derivatives and parallel line search (default: the Problem's).
        planning_timestep: Plan on a copy of the Problem whose planning model has this
            timestep (:meth:`~mpcbox.Problem.with_planning_timestep`); default: ``problem.dt``.
        terminal_value: ``"lqr"`` adds the infinite-horizon LQR value function of the planning
            model at the reference (:class:`~mpcbox.core.cost.QuadraticValue` with the Riccati
            matrix ``P``) to the terminal cost, so a short horizon still sees the cost-to-go;
            ``None`` keeps the Problem's terminal cost.
        linearization: Where the dynamics are linearized: ``"trajectory"`` (at the knots of
            the current trajectory, as iLQR does) or ``"reference"`` (once, at the Problem's
            reference state and ``ctrl_ref``, with ``fd_centered``; every knot then uses
            those ``A``, ``B``, and ``linearize_every`` is moot). The cost is quadratized
            and the line search rolls the nonlinear model out either way. With
            ``"reference"`` and ``terminal_value="lqr"`` the feedback gains are exactly the
            LQR gain, and a replan costs no finite differences: for regulation about an
            equilibrium of a model whose step is only piecewise smooth. MuJoCo's joint dry
            friction (``frictionloss``) is such a model: each joint sticks or slips, and the
            Jacobians of one mode do not hold a few milliradians away. On Menagerie's G1
            (0.3 N m on every joint) ``A - I`` and ``B`` changed by 33-62 % along 0.1 s of
            drift from the standing reference (under 1.2 % with the friction removed), and
            iLQR-MPC linearized along its trajectories fell where the reference
            linearization stood (:class:`~mpcbox.tasks.legged.biped.BipedStand`).
        cost_hessian: Where the cost's Gauss-Newton Hessians
            :math:`\ell_{xx}, \ell_{uu}, \ell_{ux}` come from: ``"trajectory"`` (each knot's
            residual Jacobians) or ``"reference"`` (once, at the reference state and
            ``ctrl_ref`` at every knot; the gradients stay each knot's). Terms with constant
            Jacobians (state and control costs) give the same Hessians either way. With
            ``linearization="reference"`` too, every backward pass of a given :math:`\mu`
            has the same matrices, which the solver keeps
            (:mod:`~mpcbox.controllers.ilqr.riccati_cache`): a pass then costs matrix-vector
            products at every knot where no control is clamped. The solver keeps them
            whenever the dynamics are linearized at the reference and the Hessians repeat,
            whichever this option is.
        dry_friction: Differentiate the joints' dry friction (``"keep"``) or a copy of the
            model without it (``"drop"``, the derivative of a joint that slips:
            :meth:`~mpcbox.Problem.with_dry_friction`) in the dynamics Jacobians and the
            ``terminal_value``; ``None``: the Problem's choice. The rollouts keep the
            friction either way. At rest a stuck joint hides the controls' effect (``B`` ten
            times smaller on the G1); :class:`~mpcbox.tasks.legged.biped.BipedStand` drops
            it for the Menagerie G1's iLQR-MPC, whose feet then recover from rocking onto
            their heels after a hop (not for every robot: PAL's Talos falls with it;
            :data:`~mpcbox.tasks.legged.biped.MENAGERIE_BIPED_ILQR`).

    Raises:
        InvalidArgumentError: Naming the field, if a value is out of range.
    """

    horizon: int = 50
    max_iterations: int = 100
    tolerance: float = 1e-6
    mpc_iterations: int = 1
    first_iterations: int | None = None
    replan_period: float = 0.02
    feedback: bool = True
    regularization: float = 1e-6
    regularization_min: float = 1e-8
    regularization_max: float = 1e10
    regularization_factor: float = 4.0
    regularization_schedule: RegularizationSchedule = "mpcbox"
    step_sizes: Sequence[float] = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01)
    line_search: LineSearch = "backtracking"
    armijo: float = 1e-4
    max_retries: int = 20
    mpc_max_retries: int | None = None
    linearize_every: int = 1
    control_steps: int = 1
    fd_centered: bool | None = None
    ctrl_low: np.ndarray | None = None
    ctrl_high: np.ndarray | None = None
    ctrls_init: np.ndarray | None = None
    states_init: np.ndarray | None = None
    defect_tolerance: float = 1e-8
    warm_start_states: bool = False
    warm_start_feedback: bool = False
    threads: int | None = None
    planning_timestep: float | None = None
    terminal_value: TerminalValue | None = None
    linearization: DynamicsLinearization = "trajectory"
    cost_hessian: CostHessian = "trajectory"
    dry_friction: DryFriction | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        for name in ("horizon", "max_iterations", "mpc_iterations", "max_retries"):
            put(name, positive_int(name, getattr(self, name)))
        put("linearize_every", positive_int("linearize_every", self.linearize_every))
        put("control_steps", positive_int("control_steps", self.control_steps))
        if self.control_steps > 1 and (self.states_init is not None or self.warm_start_states):
            raise InvalidArgumentError(
                f"control_steps={self.control_steps} works with single shooting only: leave "
                "states_init=None and warm_start_states=False, or set control_steps=1"
            )
        if self.first_iterations is not None:
            put("first_iterations", positive_int("first_iterations", self.first_iterations))
        if self.mpc_max_retries is not None:  # 0: a replan stops at its first failed search
            put("mpc_max_retries", integer("mpc_max_retries", self.mpc_max_retries, minimum=0))
        if self.threads is not None:
            put("threads", positive_int("threads", self.threads))
        for name in ("tolerance", "replan_period", "regularization_min", "regularization_max"):
            put(name, positive(name, getattr(self, name)))
        if self.planning_timestep is not None:
            put("planning_timestep", positive("planning_timestep", self.planning_timestep))
        put("feedback", boolean("feedback", self.feedback))
        put("warm_start_states", boolean("warm_start_states", self.warm_start_states))
        put("warm_start_feedback", boolean("warm_start_feedback", self.warm_start_feedback))
        put("defect_tolerance", positive("defect_tolerance", self.defect_tolerance))
        if self.states_init is not None:
            put("states_init", finite_array("states_init", self.states_init, (None, None)))
        if self.fd_centered is not None:
            put("fd_centered", boolean("fd_centered", self.fd_centered))
        self._check_regularization()
        if isinstance(self.step_sizes, (str, bytes)) or not isinstance(
            self.step_sizes, Sequence | np.ndarray
        ):
            raise InvalidTypeError(
                f"step_sizes must be a sequence of numbers, got {type(self.step_sizes).__name__}"
            )
        steps = np.array([number("step_sizes", s) for s in np.ravel(self.step_sizes)])
        if steps.size == 0 or not np.all((steps > 0) & (steps <= 1)):
            raise InvalidArgumentError(
                "step_sizes must be a non-empty sequence of numbers in (0, 1], "
                f"got {self.step_sizes}"
            )
        put("step_sizes", tuple(float(s) for s in steps))
        one_of("line_search", self.line_search, LINE_SEARCHES)
        one_of("regularization_schedule", self.regularization_schedule, REGULARIZATION_SCHEDULES)
        put("armijo", in_range("armijo", self.armijo, 0.0, 1.0, low_open=False, high_open=True))
        if self.terminal_value is not None:
            one_of("terminal_value", self.terminal_value, TERMINAL_VALUES)
        one_of("linearization", self.linearization, LINEARIZATIONS)
        one_of("cost_hessian", self.cost_hessian, COST_HESSIANS)
        if self.dry_friction is not None:
            one_of("dry_friction", self.dry_friction, DRY_FRICTIONS)
        for name in ("ctrl_low", "ctrl_high", "ctrls_init"):  # shapes: by the controller
            value = getattr(self, name)
            if value is not None:  # infinite bounds mean none; an initial guess is finite
                check = finite_array if name == "ctrls_init" else as_array
                put(name, check(name, value, (None,) * max(1, min(2, np.ndim(value)))))

    def _check_regularization(self) -> None:
        reg = non_negative("regularization", self.regularization)
        object.__setattr__(self, "regularization", reg)
        if self.regularization_max <= self.regularization_min:
            raise InvalidArgumentError(
                "regularization_max must exceed regularization_min, got "
                f"{self.regularization_max} <= {self.regularization_min}"
            )
        if reg > self.regularization_max:
            raise InvalidArgumentError(
                f"regularization must not exceed regularization_max "
                f"({self.regularization_max:g}), got {reg!r}"
            )
        factor = positive("regularization_factor", self.regularization_factor)
        if factor <= 1.0:
            raise InvalidArgumentError(f"regularization_factor must be > 1, got {factor}")
        object.__setattr__(self, "regularization_factor", factor)

    @property
    def effective_first_iterations(self) -> int:
        """``first_iterations``, or ``mpc_iterations`` when it is ``None``."""
        return self.mpc_iterations if self.first_iterations is None else self.first_iterations

    @property
    def effective_mpc_max_retries(self) -> int:
        """``mpc_max_retries``, or ``max_retries`` when it is ``None``."""
        return self.max_retries if self.mpc_max_retries is None else self.mpc_max_retries


__all__ = [
    "COST_HESSIANS",
    "DRY_FRICTIONS",
    "LINEARIZATIONS",
    "LINE_SEARCHES",
    "TERMINAL_VALUES",
    "CostHessian",
    "DryFriction",
    "DynamicsLinearization",
    "ILQRConfig",
    "LineSearch",
    "TerminalValue",
]
