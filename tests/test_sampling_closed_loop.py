"""Closed-loop cart-pole swing-up with predictive sampling and MPPI (CPU backend)."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.tasks.swingup import CartpoleSwingup


@pytest.mark.parametrize("name", ["ps", "mppi"])
def test_cartpole_swings_up_within_3s_and_holds_5s(name):
    problem = CartpoleSwingup()
    ctrl = mpcbox.make_controller(name, problem)
    res = mpcbox.simulate(problem, ctrl, 8.0)
    assert res.survived, res.failure
    err = np.array([problem.upright_error(s) for s in res.states])
    up = err < 0.3
    down = np.flatnonzero(~up)
    t_up = 0.0 if down.size == 0 else res.time[down[-1] + 1]
    assert t_up <= 3.0, f"{name}: upright only from {t_up:.2f} s"
    assert res.time[-1] - t_up >= 5.0 - 1e-9
    assert ctrl.stats["excluded_samples"] == 0
