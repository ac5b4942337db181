"""BLAS keeps to one thread while iLQR plans (mpcbox.core.blas_threads), and only then."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from mpcbox.controllers.ilqr.controller import ILQR
from mpcbox.controllers.ilqr.solver import ILQRSolver
from mpcbox.core.blas_threads import single_blas_thread
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.swingup import PendulumSwingup


def blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


@pytest.fixture
def two_blas_threads():
    if not blas_threads():
        pytest.skip("no BLAS library that threadpoolctl can see")
    with threadpool_limits(limits=2, user_api="blas"):
        assert set(blas_threads()) == {2}
        yield


def test_the_block_limits_blas_to_one_thread_and_restores_it(two_blas_threads, monkeypatch):
    monkeypatch.delenv("MPCBOX_PLANNER_BLAS_THREADS", raising=False)
    with single_blas_thread():
        assert set(blas_threads()) == {1}
    assert set(blas_threads()) == {2}
    monkeypatch.setenv("MPCBOX_PLANNER_BLAS_THREADS", "0")  # no limit
    with single_blas_thread():
        assert set(blas_threads()) == {2}
    monkeypatch.setenv("MPCBOX_PLANNER_BLAS_THREADS", "two")
    with pytest.raises(InvalidArgumentError, match=r"MPCBOX_PLANNER_BLAS_THREADS.*'two'"):
        with single_blas_thread():
            pass


def test_ilqr_solves_and_replans_under_the_limit(two_blas_threads, monkeypatch):
    monkeypatch.delenv("MPCBOX_PLANNER_BLAS_THREADS", raising=False)
    seen: list[set[int]] = []
    optimize = ILQRSolver._optimize

    def recording(self, *args, **kwargs):
        seen.append(set(blas_threads()))
        return optimize(self, *args, **kwargs)

    monkeypatch.setattr(ILQRSolver, "_optimize", recording)
    problem = PendulumSwingup(planning_timestep=0.05)
    controller = ILQR(problem, horizon=10, max_iterations=2, first_iterations=2)
    controller.solve(problem.initial_state())  # offline
    x0 = problem.initial_state()
    for k in range(3):  # the first call plans, then every replan_period
        controller(x0, k * controller.replan_period)
    assert len(seen) >= 3 and all(s == {1} for s in seen)
    assert set(blas_threads()) == {2}  # the user's setting is back
    assert np.all(np.isfinite(controller.last_result.ctrls))
    # A bad setting is the user's error, not a replan that failed and fell back.
    monkeypatch.setenv("MPCBOX_PLANNER_BLAS_THREADS", "many")
    fallbacks = controller.stats["fallbacks"]
    with pytest.raises(InvalidArgumentError, match="MPCBOX_PLANNER_BLAS_THREADS"):
        controller(x0, 10 * controller.replan_period)
    assert controller.stats["fallbacks"] == fallbacks
