"""The MuJoCo-to-MJWarp gates (``mpcbox validate``) on mujoco-warp's own test scenes.

The MJWarp parts run on warp's CPU device (CUDA when Warp sees one) at a few worlds and tens
of steps; each scene's gates run once per module and the tests read the reports.
"""

from __future__ import annotations

import json
import os

import mujoco
import numpy as np
import pytest

from mpcbox.errors import (
    InvalidArgumentError,
    InvalidTypeError,
    ModelNotFoundError,
    UnknownNameError,
    UnknownOptionError,
)
from mpcbox.gates import GatesConfig, format_report, validate_scene, write_report
from mpcbox.gates.run import gate_input

mjw = pytest.importorskip("mujoco_warp")
DATA = os.path.join(os.path.dirname(mjw.__file__), "test_data")
#: Contacts switched off; free, ball, slide and hinge joints with limits; 11 actuators.
CONTACT_FREE = os.path.join(DATA, "pendula.xml")
#: Spheres, capsules and boxes dropped on a plane (dozens of contacts), no actuator.
CONTACTS = os.path.join(DATA, "collision.xml")


def _config(device: str, **options) -> GatesConfig:
    small = dict(device=device, worlds=(2, 3), throughput_steps=10, block_steps=5)
    return GatesConfig(**{**small, **options})


@pytest.fixture(scope="module")
def contact_free(warp_device):
    return validate_scene(CONTACT_FREE, config=_config(warp_device, duration=0.4))


@pytest.fixture(scope="module")
def contacts(warp_device):
    return validate_scene(CONTACTS, config=_config(warp_device, duration=0.1))


def test_contact_free_model_matches_the_cpu_step_by_step(contact_free) -> None:
    report = contact_free
    assert report.error is None
    cpu, parity = report.cpu, report.parity
    assert cpu.passed and cpu.steps == 20
    motion = np.max(np.abs(cpu.qpos[-1] - cpu.qpos[0]))
    # float32 against float64 over 20 steps: far below the motion and the tolerance.
    assert parity.passed and parity.time_beyond_tolerance is None
    assert np.max(parity.qpos_error) < 1e-4 < 1e-2 * motion
    assert len(parity.qpos_error) == cpu.steps + 1 and parity.qpos_error[0] < 1e-6
    assert report.passed, format_report(report)


def test_capacity_covers_what_was_seen_and_nothing_overflows(contacts) -> None:
    report = contacts
    assert report.error is None
    sizing = report.capacity.sizing
    assert sizing.cpu_max_ncon > 10  # a contact-rich scene
    seen = max(sizing.cpu_max_ncon, sizing.warp_max_ncon, sizing.warp_max_ncollision)
    assert sizing.suggested_nconmax >= seen
    assert sizing.suggested_njmax >= max(sizing.cpu_max_nefc, sizing.warp_max_nefc) > 0
    assert report.capacity.passed and len(report.capacity.checks) == 3
    assert all(c.overflow["capacity_overflow_worlds"] == 0 for c in report.capacity.checks)
    # The N worlds stayed within the suggestion, per world and in the shared pool.
    scaling = report.scaling
    assert scaling.passed and scaling.host_reads == 1 and scaling.steps == report.cpu.steps
    assert int(scaling.counts.max_ncon.max()) <= sizing.nconmax
    assert scaling.counts.max_nacon <= sizing.nconmax * scaling.nworld
    assert scaling.final_spread > 0  # the perturbed worlds moved apart


def test_contact_scene_reports_when_parity_is_lost(contacts) -> None:
    parity = contacts.parity
    beyond = parity.time_beyond_tolerance
    if beyond is not None:
        first = int(np.argmax(parity.qpos_error > parity.tolerance))
        assert np.all(parity.qpos_error[:first] <= parity.tolerance)
        assert beyond == pytest.approx(parity.time[first] - parity.time[0])
    else:
        assert np.all(parity.qpos_error <= parity.tolerance)
    times = [parity.first_time_beyond(s) for s in (1.0, 10.0, 100.0)]
    assert times[0] == beyond
    known = [t for t in times if t is not None]
    assert known == sorted(known) and times[: len(known)] == known  # larger errors come later


def test_a_tiny_nconmax_is_an_overflow_failure(warp_device) -> None:
    report = validate_scene(CONTACTS, config=_config(warp_device, duration=0.05, nconmax=1))
    assert report.error is None
    assert not report.capacity.passed and not report.passed
    assert "capacity" in report.failed and "scaling" in report.failed
    flags = {f for c in report.capacity.checks for f in c.overflow["capacity_flags"]}
    assert flags & {"BROADPHASE", "NARROWPHASE"}
    assert "overflowed" in format_report(report)


def test_throughput_rows_and_json(contacts, tmp_path) -> None:
    rows = contacts.throughput.rows
    assert [r.nworld for r in rows] == [2, 3]
    for r in rows:
        assert r.warm_seconds > 0 and r.world_steps_per_second > 0
        assert r.world_steps_per_second == pytest.approx(r.nworld * r.warm_steps / r.warm_seconds)
        assert r.graph == contacts.throughput.device.startswith("cuda")
    path = write_report(contacts, tmp_path)
    data = json.loads(path.read_text())
    assert path.name == "gates_collision.json" and data["format"] == "mpcbox-gates"
    assert data["device"]["name"] and data["gates"]["capacity"]["suggested_nconmax"] > 0
    assert len(data["gates"]["throughput"]["rows"]) == 2
    assert data["gates"]["parity"]["curve"]["qpos_error"][0] < 1e-6


def test_saved_trajectory_is_replayed_exactly_on_the_cpu(tmp_path) -> None:
    from mpcbox.registry import task_class
    from mpcbox.sim.trajectory import make_trajectory
    from mpcbox.sim.trajectory_files import save_trajectory

    problem = task_class("pendulum_swingup")()
    model, data = problem.model, mujoco.MjData(problem.model)
    rng = np.random.default_rng(1)
    ctrls = rng.uniform(problem.ctrl_low, problem.ctrl_high, (30, problem.nu))
    problem.set_state(data, problem.initial_state())
    states, times = [], []
    for u in ctrls:
        times.append(data.time)
        states.append(problem.get_state(data))
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
    traj = make_trajectory(
        problem,
        controller="random",
        time=np.array(times),
        states=np.array(states),
        ctrls=ctrls,
        metadata={"task": "pendulum_swingup"},
    )
    csv_path, _ = save_trajectory(traj, tmp_path / "run")
    inputs = gate_input(None, GatesConfig(), ctrl_trajectory=csv_path)
    np.testing.assert_array_equal(inputs.ctrls, ctrls[:-1])
    from mpcbox.gates.cpu_baseline import run_cpu_baseline

    cpu = run_cpu_baseline(inputs)
    np.testing.assert_array_equal(cpu.qpos[-1], traj.states[-1][: problem.nq])


def test_task_controls_replay_the_closed_loop_on_the_cpu() -> None:
    from mpcbox.gates.cpu_baseline import run_cpu_baseline
    from mpcbox.registry import make_controller, task_class
    from mpcbox.sim.simulation import simulate

    inputs = gate_input(None, GatesConfig(duration=0.3), task="pendulum_swingup", controller="lqr")
    assert inputs.scene == "task:pendulum_swingup" and "'lqr'" in inputs.source
    problem = task_class("pendulum_swingup")()
    result = simulate(problem, make_controller("lqr", problem), 0.3)
    np.testing.assert_array_equal(inputs.ctrls, result.ctrls[:-1])
    cpu = run_cpu_baseline(inputs)  # open loop on the recorded controls: the same run
    np.testing.assert_array_equal(cpu.qpos, result.states[:, : problem.nq])
    held = gate_input("task:pendulum_swingup", GatesConfig(duration=0.1))
    np.testing.assert_array_equal(held.ctrls, np.tile(problem.ctrl_ref, (held.steps, 1)))
    np.testing.assert_array_equal(held.initial_state, problem.initial_state())


def test_keyframe_walk_visits_every_keyframe_control() -> None:
    model = mujoco.MjModel.from_xml_path(os.path.join(DATA, "aloha_pot", "scene.xml"))
    inputs = gate_input(model, GatesConfig(duration=0.1, controls="keyframes"))
    assert inputs.steps == 50
    np.testing.assert_allclose(inputs.ctrls[0], model.key_ctrl[0])
    np.testing.assert_allclose(inputs.ctrls[-1], model.key_ctrl[-1])


@pytest.mark.parametrize(
    ("make", "error", "words"),
    [
        (lambda: GatesConfig(worlds=(0, 4)), InvalidArgumentError, "worlds"),
        (lambda: GatesConfig(worlds="4"), InvalidTypeError, "worlds"),
        (lambda: GatesConfig(controls="random"), InvalidArgumentError, "controls"),
        (lambda: GatesConfig(parity_tolerance=0), InvalidArgumentError, "parity_tolerance"),
        (lambda: GatesConfig(headroom=0.5), InvalidArgumentError, "headroom"),
        (lambda: GatesConfig(nconmax=-1), InvalidArgumentError, "nconmax"),
        (lambda: GatesConfig(speed=2), UnknownOptionError, "speed"),
        (lambda: validate_scene(), InvalidArgumentError, "scene"),
        (lambda: validate_scene(42), InvalidTypeError, "scene"),
        (lambda: validate_scene("/no/such/scene.xml"), ModelNotFoundError, "scene"),
        (lambda: validate_scene(CONTACTS, config={}), InvalidTypeError, "config"),
        (
            lambda: validate_scene(CONTACTS, task="x", ctrl_trajectory="y"),
            InvalidArgumentError,
            "ctrl_trajectory",
        ),
        (lambda: validate_scene(CONTACTS, controller="lqr"), InvalidArgumentError, "controller"),
        (
            lambda: validate_scene(CONTACTS, config=GatesConfig(keyframe="nope")),
            UnknownNameError,
            "keyframe",
        ),
        (
            lambda: validate_scene(CONTACTS, config=GatesConfig(device="gpu")),
            InvalidArgumentError,
            "device",
        ),
        (
            lambda: validate_scene(CONTACTS, ctrl_trajectory="/no/run.csv"),
            InvalidArgumentError,
            "ctrl_trajectory",
        ),
        (
            lambda: validate_scene(CONTACT_FREE, config=GatesConfig(controls="keyframes")),
            InvalidArgumentError,
            "1 keyframe",
        ),
        (
            lambda: GatesConfig(throughput_steps=5, block_steps=20),
            InvalidArgumentError,
            "throughput_steps must be at least block_steps",
        ),
    ],
)
def test_bad_input_names_the_argument(make, error, words) -> None:
    with pytest.raises(error, match=words):
        make()


def test_cli_validate_writes_the_json(tmp_path, warp_device, capsys) -> None:
    from mpcbox.cli import main

    args = ["validate", CONTACT_FREE, "--device", warp_device, "--duration", "0.1"]
    args += ["--worlds", "2", "--throughput-steps", "5", "--block-steps", "5"]
    assert main([*args, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "[PASS] 2 MJWarp parity" in out and "result: PASS" in out
    data = json.loads((tmp_path / "gates_pendula.json").read_text())
    assert data["passed"] and data["config"]["worlds"] == [2]
    assert main(["validate", CONTACT_FREE, "--parity-tolerance", "-1"]) == 2
    assert "parity_tolerance" in capsys.readouterr().err
    assert main([*args, "--nconmax", "0", "--njmax", "1"]) == 1  # rows overflow: a failure


def test_a_scene_mjwarp_cannot_run_still_reports_the_cpu_gate(monkeypatch, warp_device) -> None:
    from mpcbox.errors import UnsupportedModelError
    from mpcbox.gates import warp_worlds

    def refuse(self, model, ctrls, device):
        raise UnsupportedModelError("scene: MuJoCo Warp cannot run this model (test)")

    monkeypatch.setattr(warp_worlds.WarpScene, "__init__", refuse)
    report = validate_scene(CONTACTS, config=_config(warp_device, duration=0.02))
    assert report.cpu.passed and report.parity is None and not report.passed
    assert "cannot run this model" in report.error and "Traceback" in report.error_traceback
    assert report.failed == ["parity", "capacity", "scaling", "throughput"]
    assert "did not run" in format_report(report)
