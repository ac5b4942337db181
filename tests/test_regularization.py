"""iLQR's regularization schedules: the rules of each, and the config option that picks one."""

from __future__ import annotations

import numpy as np
import pytest

from mpcbox.controllers.ilqr.config import ILQRConfig
from mpcbox.controllers.ilqr.regularization import Regularization
from mpcbox.errors import InvalidArgumentError


def test_mpcbox_schedule_divides_after_long_steps_multiplies_after_short_ones():
    mu = Regularization(1e-6, "mpcbox", 4.0, 1e-8)
    mu.accepted(1.0)
    assert mu.value == pytest.approx(2.5e-7)
    mu.accepted(0.3)  # neither long nor short: unchanged
    assert mu.value == pytest.approx(2.5e-7)
    mu.accepted(0.1)
    assert mu.value == pytest.approx(1e-6)
    mu.accepted(0.1, feasible=False)  # defects open: short steps do not raise it
    assert mu.value == pytest.approx(1e-6)
    for _ in range(7):
        mu.accepted(0.5)
    assert mu.value == 0.0  # snapped to 0 below the minimum
    mu.increase()
    assert mu.value == 1e-8


def test_crocoddyl_schedule_floors_at_the_minimum_and_raises_only_on_tiny_steps():
    mu = Regularization(1e-9, "crocoddyl", 10.0, 1e-9)
    mu.accepted(1.0)
    assert mu.value == 1e-9  # never below the minimum, never 0
    mu.accepted(0.1)
    assert mu.value == 1e-9  # 0.01 < alpha < 0.5: unchanged
    mu.accepted(0.01)
    assert mu.value == pytest.approx(1e-8)
    mu.increase()
    assert mu.value == pytest.approx(1e-7)


def test_tassa_schedule_accelerates_while_failures_or_successes_repeat():
    rho = 1.6
    mu = Regularization(1.0, "tassa", rho, 1e-6)
    mu.increase()  # delta = rho
    assert mu.value == pytest.approx(rho)
    mu.increase()  # delta = rho^2
    assert mu.value == pytest.approx(rho**3)
    mu.accepted(0.01)  # any accepted step: delta = 1 / rho, whatever alpha
    assert mu.value == pytest.approx(rho**2)
    mu.accepted(1.0)  # delta = 1 / rho^2
    assert mu.value == pytest.approx(1.0)
    for _ in range(6):
        mu.accepted(1.0)
    assert mu.value == 0.0  # below the minimum
    mu.increase()
    assert mu.value == pytest.approx(1e-6)


def test_config_names_the_schedules():
    assert ILQRConfig().regularization_schedule == "mpcbox"
    assert ILQRConfig(regularization_schedule="tassa").regularization_schedule == "tassa"
    with pytest.raises(InvalidArgumentError, match="crocoddyl"):
        ILQRConfig(regularization_schedule="levenberg")


@pytest.mark.parametrize("schedule", ["crocoddyl", "tassa"])
def test_each_schedule_solves_the_pendulum_swingup_to_the_same_optimum(schedule):
    from mpcbox.controllers.ilqr.controller import ILQR
    from mpcbox.tasks.swingup import PendulumSwingup

    problem = PendulumSwingup(planning_timestep=0.02, threads=1)
    x0 = problem.initial_state()
    base = ILQR(problem, horizon=100, threads=1).solve(x0, np.full((100, 1), 0.5))
    other = ILQR(problem, horizon=100, threads=1, regularization_schedule=schedule).solve(
        x0, np.full((100, 1), 0.5)
    )
    assert base.converged and other.converged
    assert other.cost == pytest.approx(base.cost, rel=1e-6)
