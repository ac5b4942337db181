"""The registry: tasks' tuned configs, controllers built by name, unknown options named."""

from __future__ import annotations

import numpy as np
import pytest

import mpcbox
from mpcbox.errors import InvalidArgumentError, UnknownOptionError
from mpcbox.registry import CONTROLLERS, TASKS, controller_class, make_controller, task_class
from mpcbox.tasks import scene_path


@pytest.mark.parametrize("task", sorted(TASKS))
def test_task_configs_are_config_objects_of_their_controller(task: str) -> None:
    configs = task_class(task).controller_configs
    # The manipulation tasks bring their own phase controller (stacking_controller,
    # pot_lift_controller) and tune none of the registry's.
    assert configs or task in ("stack_cubes", "pot_lift"), f"{task} tunes no controller"
    for name, config in configs.items():
        cls = controller_class(name)
        assert isinstance(config, cls.config_class), (task, name, type(config))


@pytest.fixture(scope="module")
def plain_pendulum() -> mpcbox.Problem:
    return mpcbox.Problem(str(scene_path("pendulum.xml")), qpos_ref=np.array([np.pi]))


@pytest.mark.parametrize("name", ["lqr", "ilqr", "ps", "mppi", "cem"])
def test_every_controller_builds_on_a_plain_problem_with_defaults(plain_pendulum, name) -> None:
    controller = make_controller(name, plain_pendulum)
    u = controller(plain_pendulum.reference_state(), 0.0)
    assert u.shape == (plain_pendulum.nu,) and np.all(np.isfinite(u))


def test_qp_mpc_on_a_problem_without_ground_contact_names_the_option(plain_pendulum) -> None:
    with pytest.raises(InvalidArgumentError, match="contacts"):
        make_controller("qp", plain_pendulum)


@pytest.mark.parametrize("name", sorted(set(CONTROLLERS) - {"ipopt"}))
def test_unknown_option_is_a_type_error_listing_the_valid_ones(plain_pendulum, name) -> None:
    with pytest.raises(UnknownOptionError, match=r"bogus_option.*valid options") as info:
        make_controller(name, plain_pendulum, bogus_option=1)
    assert isinstance(info.value, TypeError) and isinstance(info.value, InvalidArgumentError)
    assert info.value.valid  # the valid options are listed


def test_wrong_config_type_is_rejected(plain_pendulum) -> None:
    with pytest.raises(TypeError, match="ILQRConfig"):
        mpcbox.ILQR(plain_pendulum, mpcbox.LQRConfig())


def test_make_controller_takes_a_config_of_its_own_and_overrides_on_top(plain_pendulum) -> None:
    config = mpcbox.ILQRConfig(horizon=7, replan_period=0.05)
    controller = make_controller("ilqr", plain_pendulum, config=config, mpc_iterations=3)
    assert controller.horizon == 7 and controller.replan_period == 0.05
    assert controller.config.mpc_iterations == 3 and controller.name == "ilqr"
    # It was a raw "got multiple values for argument 'config'".
    with pytest.raises(TypeError, match="ILQRConfig"):
        make_controller("ilqr", plain_pendulum, config=mpcbox.LQRConfig())


def test_controller_with_a_missing_optional_module_is_left_out(monkeypatch) -> None:
    from mpcbox.controllers.lqr import LQR
    from mpcbox.registry import available_controllers

    problem = task_class("humanoid_two_feet")
    assert "lqr" in available_controllers(problem)
    monkeypatch.setattr(LQR, "requires", ("mpcbox_no_such_module",))
    assert "lqr" not in available_controllers(problem)
    assert "qp" in available_controllers(problem)
