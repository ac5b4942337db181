"""The total-energy cost term: MuJoCo's energies against closed forms, and in a swing-up."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mpcbox.core.cost import Energy, rest_energy
from mpcbox.errors import InvalidArgumentError
from mpcbox.tasks.swingup import AcrobotSwingup


@pytest.fixture(scope="module")
def problem() -> AcrobotSwingup:
    weights = dataclasses.replace(AcrobotSwingup.WEIGHTS, energy=2.0)
    return AcrobotSwingup(weights=weights, threads=1)


def _energy_term(problem) -> Energy:
    terms = [t for t in problem.cost.running if isinstance(t, Energy)]
    assert len(terms) == 1
    return terms[0]


def _residual(problem, state) -> float:
    term = _energy_term(problem)
    return float(term.residual(problem.features(state))[0, 0])


def test_zero_at_the_upright_at_rest_and_the_height_deficit_hanging(problem) -> None:
    upright = problem.reference_state()
    assert _residual(problem, upright) == pytest.approx(0.0, abs=1e-9)
    # hanging at rest: minus the potential energy sum_i m_i g (z_i(upright) - z_i(hanging))
    model, data = problem.model, mujoco.MjData(problem.model)
    heights = []
    for state in (upright, problem.initial_state()):
        data.qpos[:] = state[: model.nq]
        mujoco.mj_kinematics(model, data)
        heights.append(data.xipos[:, 2].copy())
    g = -model.opt.gravity[2]
    deficit = float(np.sum(model.body_mass * g * (heights[0] - heights[1])))
    assert deficit > 1.0
    assert _residual(problem, problem.initial_state()) == pytest.approx(-deficit, rel=1e-9)


def test_velocity_adds_half_v_m_v(problem) -> None:
    model, data = problem.model, mujoco.MjData(problem.model)
    state = problem.initial_state()
    state[: model.nq] += [0.3, -0.7]
    still = _residual(problem, state)
    v = np.array([1.5, -2.0])
    state[model.nq :] = v
    data.qpos[:] = state[: model.nq]
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    assert _residual(problem, state) - still == pytest.approx(0.5 * v @ mass @ v, rel=1e-9)


def test_rest_energy_and_a_weight_of_zero_leave_the_term_out(problem) -> None:
    assert rest_energy(problem.model, problem.qpos_ref) == pytest.approx(
        _energy_term(problem).target
    )
    plain = AcrobotSwingup(threads=1)
    assert not any(isinstance(t, Energy) for t in plain.cost.running)


def test_bad_energy_inputs_are_refused_by_name() -> None:
    with pytest.raises(InvalidArgumentError, match="target"):
        Energy(float("nan"), weight=1.0)
    with pytest.raises(InvalidArgumentError, match="energy"):
        dataclasses.replace(AcrobotSwingup.WEIGHTS, energy=-1.0)
