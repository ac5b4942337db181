"""The CasADi acrobot of ``benchmarks/dm_acrobot_min_time.py`` against MuJoCo's own physics.

The minimum-time evidence for dm_control's acrobot is only as good as the equations of motion
it optimizes: their accelerations and one RK4 step must equal MuJoCo's.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

pytest.importorskip("casadi")
pytest.importorskip("dm_control")

import mujoco

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "dm_acrobot_min_time.py"


def load_benchmark():
    spec = importlib.util.spec_from_file_location("dm_acrobot_min_time", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_casadi_acrobot_matches_mujoco_qacc_and_rk4_step():
    bench = load_benchmark()
    from mpcbox.tasks.swingup.dm_control import suite_path

    model = mujoco.MjModel.from_xml_path(str(suite_path("acrobot")))
    check = bench.dynamics_check(model, samples=30, seed=1)
    assert check["max_qacc_diff"] < 1e-8
    assert check["max_rk4_step_diff"] < 1e-8
    # The check can fail: a model with other damping no longer matches the parameters read
    # from the original.
    params = bench.parameters(model)
    other = mujoco.MjModel.from_xml_path(str(suite_path("acrobot")))
    other.dof_damping[:] = 0.5
    data = mujoco.MjData(other)
    data.qpos[:], data.qvel[:] = [0.3, -0.2], [1.0, 2.0]
    mujoco.mj_forward(other, data)
    mine = bench.qacc(params, data.qpos, data.qvel, 0.0)
    assert abs(float(mine[0]) - data.qacc[0]) > 1e-3
