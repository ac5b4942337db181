"""Comparisons on Ray: a local two-node cluster gives the serial table; a killed worker is
survived with nothing lost; one broken run is a recorded failure, not the end of a sweep."""

from __future__ import annotations

import functools
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mpcbox.comparison.executors import RayExecutor
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import Scenario
from mpcbox.controllers.lqr import LQR

ray = pytest.importorskip("ray")
cluster_utils = pytest.importorskip("ray.cluster_utils")

TIMING = {"compute_mean_ms", "compute_p50_ms", "compute_p99_ms", "realtime_factor", "offline_ms"}


class KillsItsWorkerOnce(LQR):
    """LQR whose process exits in the middle of its first run anywhere (marker file)."""

    def __init__(self, problem, marker: str) -> None:
        super().__init__(problem)
        self.marker = marker
        self.name = "lqr_killer"

    def __call__(self, state, time):
        if time > 0.05 and not os.path.exists(self.marker):
            Path(self.marker).write_text("killed")
            os._exit(1)
        return super().__call__(state, time)


def _killer(problem, marker: str):
    return KillsItsWorkerOnce(problem, marker)


def _broken(problem):
    raise np.linalg.LinAlgError("cannot build this one")


def _same_runs(a, b) -> None:
    assert [(r.controller, r.scenario, r.seed) for r in a.runs] == [
        (r.controller, r.scenario, r.seed) for r in b.runs
    ]
    for x, y in zip(a.runs, b.runs):
        for field in x.metrics._fields:
            if field not in TIMING:
                np.testing.assert_equal(getattr(x.metrics, field), getattr(y.metrics, field))
        assert x.failure == y.failure


@pytest.fixture(scope="module")
def cluster():
    """A head node and one more node process on this machine, one CPU each."""
    import ray.cloudpickle

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    cluster = cluster_utils.Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, include_dashboard=False, logging_level="ERROR")
    yield cluster
    ray.shutdown()
    cluster.shutdown()


def test_ray_table_equals_serial_and_survives_a_killed_worker(cluster, tmp_path):
    marker = str(tmp_path / "killed")
    controllers = ["lqr", functools.partial(_killer, marker=marker), _broken]
    kwargs = dict(
        scenarios=Scenario(duration=0.2, noise_scale=0.0),
        seeds=2,
        problem_options={},
        progress=False,
    )
    on_ray = compare("pendulum_swingup", controllers, executor=RayExecutor(), **kwargs)
    assert Path(marker).exists(), "the worker was not killed: the test tested nothing"
    serial = compare("pendulum_swingup", controllers, executor="serial", **kwargs)
    _same_runs(on_ray, serial)
    # Both nodes took part, and the broken factory is a recorded failure of its runs only.
    assert sum(on_ray.placement.values()) == len(on_ray.runs)
    assert len(on_ray.placement) == 2 and all(" node " in k for k in on_ray.placement)
    broken = [r for r in on_ray.runs if r.controller == "_broken"]
    assert broken and all(r.metrics.outcome == "controller error" for r in broken)
    assert all("LinAlgError" in r.failure for r in broken)
    assert all(r.metrics.outcome != "controller error" for r in on_ray.runs if r not in broken)


def test_checkpoint_skips_finished_jobs(tmp_path):
    from mpcbox.errors import InvalidArgumentError

    folder = tmp_path / "runs"
    kwargs = dict(scenarios=Scenario(duration=0.1, noise_scale=0.0), seeds=2, progress=False)
    first = compare("pendulum_swingup", ["lqr"], executor="serial", checkpoint=folder, **kwargs)
    assert len(list(folder.glob("*/*.pkl"))) == 2
    calls = []

    def counting(problem):
        calls.append(1)
        return LQR(problem)

    # Same setup: nothing runs again, the table is the same, even the timings.
    second = compare("pendulum_swingup", ["lqr"], executor="serial", checkpoint=folder, **kwargs)
    for x, y in zip(first.runs, second.runs):
        np.testing.assert_equal(tuple(x.metrics), tuple(y.metrics))  # NaN settle times too
    # Another setup in the same folder runs in full, in its own subfolder.
    compare("pendulum_swingup", [counting], executor="serial", checkpoint=folder, **kwargs)
    assert len(calls) == 1  # built once, run for both seeds
    assert len(list(folder.glob("*/*.pkl"))) == 4
    (folder / "file").write_text("")
    with pytest.raises(InvalidArgumentError, match="checkpoint must be a folder"):
        compare("pendulum_swingup", ["lqr"], checkpoint=folder / "file", **kwargs)


def test_executor_errors_name_the_choices():
    from mpcbox.errors import InvalidArgumentError, UnknownNameError

    with pytest.raises(UnknownNameError, match="'ray'"):
        compare(
            "pendulum_swingup",
            ["lqr"],
            Scenario(duration=0.1, noise_scale=0.0),
            executor="dask",
            progress=False,
        )
    with pytest.raises(InvalidArgumentError, match="cpus_per_run"):
        RayExecutor(cpus_per_run=0)
    with pytest.raises(InvalidArgumentError, match="max_restarts"):
        RayExecutor(max_restarts=-1)
    for bad in ("localhost", "localhost:port", "ray://:10001", "host:70000"):
        with pytest.raises(InvalidArgumentError, match="address"):
            RayExecutor(address=bad)
    # Nothing listens on port 1: a clear error at once, where ray.init would keep retrying.
    from mpcbox.comparison.executors import _check_reachable
    from mpcbox.errors import BackendUnavailableError

    start = time.perf_counter()
    with pytest.raises(BackendUnavailableError, match="no Ray cluster answers at"):
        _check_reachable("127.0.0.1:1", timeout=2.0)
    assert time.perf_counter() - start < 3.0


def test_cli_executor_flags_are_checked(tmp_path, capsys):
    from mpcbox.cli import main

    base = [
        "compare",
        "pendulum_swingup",
        "--controllers",
        "lqr",
        "--duration",
        "0.1",
        "--seeds",
        "1",
    ]
    assert main([*base, "--executor", "dask", "--out", str(tmp_path)]) == 2
    assert "'ray'" in capsys.readouterr().err
    assert main([*base, "--address", "auto", "--out", str(tmp_path)]) == 2
    assert "--address needs --executor ray" in capsys.readouterr().err
    # A serial run streams its jobs to --out/runs and a re-run loads them.
    argv = [*base, "--executor", "serial", "--no-plots", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 0
    assert len(list((tmp_path / "runs").glob("*/*.pkl"))) == 1
    assert main(argv) == 0
    assert "jobs: 1 on " in capsys.readouterr().out
    # The streamed rows and the final table both hold the run; run.json says where it ran.
    import json

    assert len((tmp_path / "runs.jsonl").read_text().splitlines()) == 1
    assert len(json.loads((tmp_path / "runs.json").read_text())) == 1
    placement = json.loads((tmp_path / "run.json").read_text())["placement"]
    assert sum(placement.values()) == 1


def test_warp_runs_ask_ray_for_one_gpu_each():
    """A setup with a warp-backend controller makes every actor ask Ray for a GPU, so a
    2-GPU host runs two closed loops at a time; CPU setups ask for CPUs only (no GPU needed
    to check: the options are computed from the cluster's resources)."""
    from mpcbox.comparison.executors import uses_warp
    from mpcbox.comparison.jobs import Setup
    from mpcbox.errors import BackendUnavailableError

    base = dict(
        task="pendulum_swingup",
        task_options={},
        controllers={"lqr": "lqr", "mppi": "mppi"},
        scenarios=(Scenario(duration=0.1, noise_scale=0.0),),
        push_tests=(),
        trace_seed=0,
    )
    cpu = Setup(overrides={"mppi": {"backend": "cpu"}}, **base)
    gpu = Setup(overrides={"mppi": {"backend": "warp"}}, **base)
    assert not uses_warp(cpu) and uses_warp(gpu)
    host = {"CPU": 16.0, "GPU": 2.0}
    count, options = RayExecutor().actor_options(gpu, host, 200)
    assert count == 2 and options["num_gpus"] == 1.0 and options["num_cpus"] == 1.0
    count, options = RayExecutor().actor_options(cpu, host, 200)
    assert count == 16 and options["num_gpus"] == 0.0
    assert options["max_restarts"] == 3 and options["max_task_retries"] == 3
    assert RayExecutor(cpus_per_run=4.0).actor_options(cpu, host, 200)[0] == 4
    assert RayExecutor().actor_options(cpu, host, 3)[0] == 3  # at most one actor per job
    assert RayExecutor(gpus_per_run=0.5).actor_options(gpu, host, 200)[0] == 4
    assert RayExecutor(gpus_per_run=0.0).actor_options(gpu, host, 200)[1]["num_gpus"] == 0.0
    with pytest.raises(BackendUnavailableError, match="no GPU"):
        RayExecutor().actor_options(gpu, {"CPU": 16.0}, 200)


def test_survival_sweep_on_ray_equals_serial(cluster):
    """The evaluation sweeps spread their runs over the same Ray actors as compare."""
    from mpcbox.comparison.push_limits import survival
    from mpcbox.sim.disturbances import ActuatorNoise

    kw = dict(seeds=[0, 1, 2], duration=0.3, noise=ActuatorNoise(std=0.5, width=0.1))
    on_ray = survival("pendulum_swingup", "lqr", executor=RayExecutor(), **kw)
    serial = survival("pendulum_swingup", "lqr", **kw)
    for a, b in zip(on_ray, serial):
        np.testing.assert_array_equal(a, b)
