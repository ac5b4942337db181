r"""Reference trajectory optimizer: direct multiple shooting with CasADi and IPOPT.

The transcription uses exactly the discretization of :class:`~mpcbox.ILQR`: knots
``x_0 .. x_T`` and controls ``u_0 .. u_{T-1}`` on the Problem's planning model, with

.. math::

    \min_{x, u}\ \sum_{t=0}^{T-1} \ell(x_t, u_t) + \ell_T(x_T) \quad \text{s.t.}\quad
    x_0 = \hat x_0,\ \ x_{t+1} = f(x_t, u_t),\ \ u_{lo} \le u_t \le u_{hi}.

``f`` is one MuJoCo step wrapped as a :class:`casadi.Callback` whose Jacobian comes from
:meth:`mpcbox.Problem.linearize` (finite differences). A running (or terminal) cost whose terms
all have a CasADi form (:meth:`~mpcbox.core.cost.CostTerm.casadi_residual`: ``StateCost``,
``ControlCost``, ``WrappedAngle``) becomes an analytic CasADi expression; a cost with other
terms is evaluated by the Problem through a Callback with the Gauss-Newton gradient of
:meth:`~mpcbox.Problem.quadratize`. Second derivatives of ``f`` are not available, so IPOPT
runs with a limited-memory (L-BFGS) Hessian.

It serves as an oracle for the iLQR tests and as the plan of the ``"ipopt"`` controller of
comparison tables on small problems
(:class:`~mpcbox.controllers.ipopt_controller.IpoptController`: an offline plan tracked with
time-varying LQR feedback). Only models without free or ball joints (``nq == nv``) are supported.

CasADi is optional: it is imported on first use and a missing install raises
:class:`~mpcbox.errors.BackendUnavailableError`.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from mpcbox.core.cost import CostTerm
from mpcbox.core.problem import Problem
from mpcbox.errors import (
    BackendUnavailableError,
    InvalidArgumentError,
    UnsupportedCostTermError,
)
from mpcbox.validation import as_array, positive, positive_int


def require_casadi() -> Any:
    """The ``casadi`` module, or :class:`~mpcbox.errors.BackendUnavailableError` if missing."""
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise BackendUnavailableError(
            "the IPOPT reference needs CasADi: pip install 'mpcbox[casadi]' (or pip install casadi)"
        ) from exc
    return casadi


_casadi = require_casadi


class IpoptSolution(NamedTuple):
    """Result of :func:`solve_ipopt`.

    Attributes:
        states: Optimal states ``(T + 1, nstate)``.
        ctrls: Optimal controls ``(T, nu)``.
        cost: Objective value (same definition as
            :attr:`mpcbox.controllers.ilqr.result.ILQRResult.cost`).
        iterations: IPOPT iterations.
        success: IPOPT reported success.
        status: IPOPT's return status.
        defect: Largest dynamics violation ``|f(x_t, u_t) - x_{t+1}|`` at the solution.
        solve_time: Wall-clock seconds.
    """

    states: np.ndarray
    ctrls: np.ndarray
    cost: float
    iterations: int
    success: bool
    status: str
    defect: float
    solve_time: float


def _callback_class(
    ins: tuple[tuple[int, int], ...],
    outs: tuple[tuple[int, int], ...],
    fn: Callable[[np.ndarray, np.ndarray], list[Any]],
    jacobian: Any = None,
) -> Any:
    """A CasADi Callback class evaluating ``fn(x, u)`` with NumPy.

    Args:
        ins: Shapes of the dense inputs; the first two are ``x`` and ``u`` (a Jacobian's
            third input, the nominal output, is not used).
        outs: Shapes of the dense outputs.
        fn: ``(x (nstate,), u (nu,)) -> outputs``, each convertible by ``casadi.DM``.
        jacobian: The class of the Jacobian callback, or ``None`` for none.

    Instances are built as ``cls(name, opts)``; an instance keeps its Jacobian alive.
    """
    ca = _casadi()

    class _NumpyCallback(ca.Callback):
        def __init__(self, name: str, opts: dict) -> None:
            ca.Callback.__init__(self)
            self._jac: Any = None
            self.construct(name, opts)

        def get_n_in(self) -> int:
            return len(ins)

        def get_n_out(self) -> int:
            return len(outs)

        def get_sparsity_in(self, i: int) -> Any:
            return ca.Sparsity.dense(*ins[i])

        def get_sparsity_out(self, i: int) -> Any:
            return ca.Sparsity.dense(*outs[i])

        def eval(self, arg: list) -> list:
            x = np.asarray(arg[0]).ravel()
            u = np.asarray(arg[1]).ravel()
            return [ca.DM(value) for value in fn(x, u)]

        def has_jacobian(self) -> bool:
            return jacobian is not None

        def get_jacobian(self, name: str, inames: list, onames: list, opts: dict) -> Any:
            self._jac = jacobian(name, opts)
            return self._jac

    return _NumpyCallback


def _make_callbacks(problem: Problem) -> tuple[Any, list[Any]]:
    """The step ``f(x, u)`` as a CasADi Callback (and objects that must stay alive)."""
    ns, nu = problem.nstate, problem.nu

    def jacobian(x: np.ndarray, u: np.ndarray) -> list[Any]:
        lin = problem.linearize(x, problem.clip_ctrl(u))
        return [lin.A, lin.B]

    step_jacobian = _callback_class(((ns, 1), (nu, 1), (ns, 1)), ((ns, ns), (ns, nu)), jacobian)
    step_class = _callback_class(
        ((ns, 1), (nu, 1)),
        ((ns, 1),),
        lambda x, u: [problem.step(x, problem.clip_ctrl(u))],
        step_jacobian,
    )
    step = step_class("mujoco_step", {"enable_fd": False})
    return step, [step]


def _cost_callback(problem: Problem, terminal: bool) -> Any:
    """Running (or terminal) cost evaluated by the Problem, with its Gauss-Newton gradient."""
    ns, nu = problem.nstate, problem.nu

    def gradient(x: np.ndarray, u: np.ndarray) -> list[Any]:
        q = problem.quadratize(x, u, terminal=terminal)
        lu = np.zeros(nu) if terminal else q.lu
        return [q.lx[None], lu[None]]

    def cost(x: np.ndarray, u: np.ndarray) -> list[Any]:
        if terminal:
            return [problem.terminal_cost(x)]
        return [problem.running_cost(x, u)]

    gradient_class = _callback_class(((ns, 1), (nu, 1), (1, 1)), ((1, ns), (1, nu)), gradient)
    cost_class = _callback_class(((ns, 1), (nu, 1)), ((1, 1),), cost, gradient_class)
    return cost_class("terminal_cost" if terminal else "running_cost", {"enable_fd": False})


def _symbolic_terms(problem: Problem, terms: list[CostTerm], x: Any, u: Any) -> Any | None:
    """``sum 0.5 w r^2`` as a CasADi expression, or ``None`` if a term has no CasADi form."""
    ca = _casadi()
    nq, nv = problem.nq, problem.nv
    total = 0
    for term in terms:
        try:
            r = term.casadi_residual(x[:nq], x[nq : nq + nv], u)
        except UnsupportedCostTermError:
            return None
        total = total + 0.5 * ca.sumsqr(ca.sqrt(term.weight) * r)
    return total


def solve_ipopt(
    problem: Problem,
    x0: np.ndarray,
    horizon: int,
    *,
    ctrls_init: np.ndarray | None = None,
    states_init: np.ndarray | None = None,
    max_iterations: int = 3000,
    tolerance: float = 1e-9,
    lbfgs_history: int = 20,
    print_level: int = 0,
    options: dict[str, Any] | None = None,
) -> IpoptSolution:
    """Solve the trajectory optimization problem with IPOPT (direct multiple shooting).

    Args:
        problem: The Problem (``nq == nv``: no free or ball joints).
        x0: Start state ``(nstate,)``.
        horizon: Number of knots ``T``.
        ctrls_init: Initial controls ``(T, nu)`` or ``(nu,)`` (default: the task's first
            guess, :meth:`mpcbox.Problem.initial_ctrls`, ``ctrl_ref`` unless it chooses
            better).
        states_init: Initial states ``(T + 1, nstate)`` (default: rollout of ``ctrls_init``).
        max_iterations: IPOPT iteration cap.
        tolerance: IPOPT's ``tol``.
        lbfgs_history: Pairs kept by the limited-memory Hessian.
        print_level: IPOPT verbosity (0 silent, 5 verbose).
        options: Extra ``nlpsol`` options (e.g. ``{"ipopt.acceptable_tol": 1e-6}``).

    Returns:
        An :class:`IpoptSolution`.

    Raises:
        BackendUnavailableError: If CasADi is not installed.
        InvalidArgumentError: If the model has quaternion joints or an argument is invalid.
    """
    ca = _casadi()
    if problem.nq != problem.nv:
        raise InvalidArgumentError(
            "problem: the IPOPT reference supports models without free or ball joints "
            f"(nq == nv), got nq={problem.nq}, nv={problem.nv}"
        )
    horizon = positive_int("horizon", horizon)
    max_iterations = positive_int("max_iterations", max_iterations)
    tolerance = positive("tolerance", tolerance)
    ns, nu = problem.nstate, problem.nu
    x0 = as_array("x0", x0, (ns,))
    if not np.all(np.isfinite(x0)):
        raise InvalidArgumentError("x0 must be finite")
    if ctrls_init is None:
        ctrls_init = problem.initial_ctrls(x0, horizon)
    ctrls_init = np.asarray(ctrls_init, dtype=np.float64)
    if ctrls_init.ndim == 1:
        ctrls_init = np.tile(as_array("ctrls_init", ctrls_init, (nu,)), (horizon, 1))
    ctrls_init = problem.clip_ctrl(as_array("ctrls_init", ctrls_init, (horizon, nu)))
    if states_init is None:
        states_init = problem.rollout(x0, ctrls_init).states[0]
    states_init = as_array("states_init", states_init, (horizon + 1, ns))
    if not (np.all(np.isfinite(states_init)) and np.all(np.isfinite(ctrls_init))):
        raise InvalidArgumentError("states_init and ctrls_init must be finite")

    step, keep_alive = _make_callbacks(problem)
    X = ca.MX.sym("X", ns, horizon + 1)
    U = ca.MX.sym("U", nu, horizon)
    xs, us = ca.MX.sym("x", ns), ca.MX.sym("u", nu)
    running = _symbolic_terms(problem, problem.cost.running, xs, us)
    if running is None:
        cb = _cost_callback(problem, terminal=False)
        keep_alive.append(cb)
        running = cb(xs, us)
    terminal = _symbolic_terms(problem, problem.cost.terminal, xs, us)
    if terminal is None:
        cb = _cost_callback(problem, terminal=True)
        keep_alive.append(cb)
        terminal = cb(xs, us)
    running_fn = ca.Function("running", [xs, us], [running])
    terminal_fn = ca.Function("terminal", [xs, us], [terminal])

    objective = ca.sum2(running_fn.map(horizon)(X[:, :horizon], U))
    objective = objective + terminal_fn(X[:, horizon], U[:, horizon - 1])
    gaps = [X[:, 0] - x0]
    for t in range(horizon):
        gaps.append(step(X[:, t], U[:, t]) - X[:, t + 1])
    g = ca.vertcat(*gaps)
    z = ca.vertcat(ca.vec(X), ca.vec(U))
    lbz = np.r_[np.full(ns * (horizon + 1), -np.inf), np.tile(problem.ctrl_low, horizon)]
    ubz = np.r_[np.full(ns * (horizon + 1), np.inf), np.tile(problem.ctrl_high, horizon)]
    opts: dict[str, Any] = {
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.limited_memory_max_history": int(lbfgs_history),
        "ipopt.max_iter": max_iterations,
        "ipopt.tol": tolerance,
        "ipopt.print_level": int(print_level),
        "print_time": False,
    }
    opts.update(options or {})
    solver = ca.nlpsol("mpcbox_ipopt", "ipopt", {"x": z, "f": objective, "g": g}, opts)
    z0 = np.r_[states_init.T.ravel(order="F"), ctrls_init.T.ravel(order="F")]
    t0 = _time.perf_counter()
    sol = solver(x0=z0, lbx=lbz, ubx=ubz, lbg=0.0, ubg=0.0)
    elapsed = _time.perf_counter() - t0
    stats = solver.stats()
    zopt = np.asarray(sol["x"]).ravel()
    states = zopt[: ns * (horizon + 1)].reshape(horizon + 1, ns)
    ctrls = problem.clip_ctrl(zopt[ns * (horizon + 1) :].reshape(horizon, nu))
    defect = float(np.max(np.abs(np.asarray(sol["g"]).ravel())))
    del keep_alive
    return IpoptSolution(
        states=states,
        ctrls=ctrls,
        cost=float(sol["f"]),
        iterations=int(stats.get("iter_count", -1)),
        success=bool(stats.get("success", False)),
        status=str(stats.get("return_status", "")),
        defect=defect,
        solve_time=elapsed,
    )


__all__ = ["IpoptSolution", "require_casadi", "solve_ipopt"]
