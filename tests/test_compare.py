"""mpcbox.compare, its table/CSV/plot output, and the mpcbox command line."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from mpcbox.cli import main, run_task_script
from mpcbox.comparison.plots import plot_comparison
from mpcbox.comparison.report import Comparison
from mpcbox.comparison.runner import compare
from mpcbox.comparison.scenario import PushTest, Scenario
from mpcbox.controllers.base import Controller
from mpcbox.controllers.lqr import LQR
from mpcbox.errors import InvalidArgumentError, UnknownNameError
from mpcbox.sim.disturbances import ModelMismatch, Push

DETERMINISTIC = (
    "survived",
    "time_to_fall",
    "cost",
    "control_effort",
    "fallbacks",
    "measures",  # com_deviation_rms_m, tilt_rms_deg
)


@pytest.fixture(scope="module")
def balance():
    from mpcbox.tasks.humanoid.balance import HumanoidBalance

    return HumanoidBalance()


def _lqr_factory(problem):
    return LQR(problem)


def test_serial_and_parallel_runs_are_identical():
    scenarios = [
        Scenario(duration=1.0, noise_scale=1.0),
        Scenario(
            duration=1.0,
            noise_scale=4.0,
            pushes=(Push(force=(60.0, 0.0, 0.0), start=0.3, duration=0.1),),
            mismatch=ModelMismatch(mass_scale=1.05),
        ),
    ]
    kwargs = dict(seeds=[3, 4, 5], progress=False)
    serial = compare("humanoid_balance", ["lqr"], scenarios, workers=1, **kwargs)
    parallel = compare("humanoid_balance", ["lqr"], scenarios, workers=2, **kwargs)
    assert len(serial.runs) == len(parallel.runs) == 6
    for a, b in zip(serial.runs, parallel.runs):
        assert (a.controller, a.scenario, a.seed) == (b.controller, b.scenario, b.seed)
        for name in DETERMINISTIC:
            assert getattr(a.metrics, name) == getattr(b.metrics, name), name
        assert a.failure == b.failure
        assert (a.trace is None) == (b.trace is None)
        if a.trace is not None:
            np.testing.assert_array_equal(a.trace.ctrls, b.trace.ctrls)
    # Different seeds see different noise.
    assert len({r.metrics.measures["tilt_rms_deg"] for r in serial.runs_of("lqr", 0)}) == 3
    # The trace is kept for the first seed only.
    assert [r.trace is not None for r in serial.runs_of("lqr", 1)] == [True, False, False]


def test_table_csv_and_plots(balance, tmp_path):
    result = compare(
        balance,
        ["lqr", _lqr_factory],
        Scenario.noise_sweep([0.5, 2.0], duration=0.5),
        seeds=2,
        push_tests=PushTest(settle=0.5, max_force=400.0, tolerance=100.0, name="fwd"),
        progress=False,
    )
    assert isinstance(result, Comparison)
    assert result.controllers == ("lqr", "_lqr_factory")
    markdown = result.to_markdown().splitlines()
    header = [c.strip() for c in markdown[0].strip("|").split("|")]
    assert header == [
        "scenario",
        "controller",
        "seeds",
        "success",
        "not successful",
        "mean time to fall (s)",
        "COM dev RMS (cm)",
        "tilt RMS (deg)",
        "effort",
        "largest push fwd (N)",
        "compute mean (ms)",
        "compute p99 (ms)",
        "period (ms)",
        "real-time factor",
        "fallbacks",
    ]
    assert len(markdown) == 2 + 4  # header, rule, 2 scenarios x 2 controllers
    assert "| noise x0.5 | lqr | 2 | 100% | - |" in markdown[2]
    # LQR is called every 5 ms simulation step: the period column says so; whether p99
    # fits depends on the machine, and the column says which.
    row = result.rows()[0]
    assert row.period_ms == pytest.approx(5.0)
    assert row.p99_fits == (row.compute_p99_ms <= 5.0)
    assert ("(over)" in markdown[2]) != row.p99_fits

    path = tmp_path / "out" / "results.csv"
    text = result.to_csv(path)
    assert path.read_text() == text
    rows = list(csv.DictReader(io.StringIO(text)))
    assert list(rows[0]) == [
        "scenario",
        "controller",
        "runs",
        "success_rate",
        "outcomes",
        "mean_time_to_fall",
        "com_deviation_rms_cm",
        "tilt_rms_deg",
        "control_effort",
        "largest_push_fwd",
        "compute_mean_ms",
        "compute_p99_ms",
        "period_ms",
        "p99_fits",
        "offline_ms",
        "realtime_factor",
        "fallbacks",
        "fallback_rate",
    ]
    assert len(rows) == 4
    # An instance and a factory of the same LQR measure the same thing.
    assert rows[0]["tilt_rms_deg"] == rows[1]["tilt_rms_deg"]
    assert float(rows[0]["largest_push_fwd"]) == result.push_limits["lqr"]["fwd"].force

    files = plot_comparison(result, tmp_path / "plots")
    names = sorted(p.name for p in files)
    assert names == [
        "compute_time.png",
        "survival_vs_noise.png",
        "timeseries_noise_x0.5.png",
        "timeseries_noise_x2.png",
    ]
    assert all(p.stat().st_size > 10_000 for p in files)


def test_unknown_names_list_the_valid_ones(balance):
    with pytest.raises(UnknownNameError, match="'humanoid_balance'") as info:
        compare("humanoid_balanse", ["lqr"])
    assert "pendulum_swingup" in str(info.value)
    with pytest.raises(UnknownNameError, match="'lqr'") as info:
        compare(balance, ["lqr", "ilqrr"])
    assert "ilqrr" in str(info.value) and "'mppi'" in str(info.value)
    with pytest.raises(InvalidArgumentError, match="scenarios"):
        compare(balance, ["lqr"], scenarios=[])
    with pytest.raises(InvalidArgumentError, match="duration"):
        Scenario(duration=0.0)
    with pytest.raises(InvalidArgumentError, match="noise_scale"):
        Scenario(noise_scale=-1.0)
    with pytest.raises(InvalidArgumentError, match="direction"):
        PushTest(direction=(0.0, 0.0, 0.0))
    with pytest.raises(InvalidArgumentError, match=r"seeds must be distinct, got \[3\]"):
        compare(balance, ["lqr"], seeds=[3, 1, 3])  # each row was counted twice


def test_columns_follow_the_task_measures():
    """A swing-up measures its upright error (no COM or tilt columns), and has no noise model."""
    with pytest.raises(InvalidArgumentError, match="no noise model"):
        compare("pendulum_swingup", ["lqr"], Scenario(duration=0.1), seeds=1, progress=False)
    result = compare(
        "pendulum_swingup",
        ["lqr"],
        Scenario(duration=0.1, noise_scale=0.0),
        seeds=1,
        workers=1,
        progress=False,
    )
    assert [m.name for m in result.measures] == ["upright_error"]
    assert set(result.runs[0].metrics.measures) == {
        "upright_error_final_rad",
        "upright_error_settle_time_s",
    }
    assert np.isfinite(result.runs[0].metrics.cost)
    header = result.to_markdown().splitlines()[0]
    assert "COM" not in header and "tilt" not in header
    assert result.to_csv().splitlines()[0] == (
        "scenario,controller,runs,success_rate,outcomes,mean_time_to_fall,"
        "upright_error_final_rad,upright_error_settle_time_s,control_effort,"
        "compute_mean_ms,compute_p99_ms,period_ms,p99_fits,offline_ms,realtime_factor,"
        "fallbacks,fallback_rate"
    )


def _broken_factory(problem):
    raise ValueError("broken controller")


_broken_factory.name = "broken"


def test_a_controller_that_errors_in_every_run_gets_a_row_not_a_crash():
    """Its runs record no measures; the table shows NaN there (it raised KeyError, e.g. for
    ``mpcbox compare pendulum_swingup --set ilqr.horizon=-3``)."""
    result = compare(
        "pendulum_swingup",
        ["lqr", _broken_factory],
        Scenario(duration=0.05, noise_scale=0.0),
        seeds=1,
        workers=1,
        progress=False,
    )
    lqr, broken = result.rows()
    assert np.isfinite(lqr.measures["upright_error_final_rad"])
    assert np.isnan(broken.measures["upright_error_final_rad"])
    assert broken.outcomes == {"controller error": 1}
    assert "broken" in result.to_markdown()


def _not_one(problem):
    return "lqr"


def test_a_factory_that_returns_no_controller_is_a_type_error_not_a_row():
    from mpcbox.errors import InvalidTypeError

    with pytest.raises(InvalidTypeError, match="'_not_one' returned str, not an mpcbox"):
        compare(
            "pendulum_swingup",
            ["lqr", _not_one],
            Scenario(duration=0.05, noise_scale=0.0),
            seeds=1,
            workers=1,
            progress=False,
        )


def test_cli_unknown_names(capsys):
    assert main(["compare", "humanoid_balanse"]) == 2
    err = capsys.readouterr().err
    assert "unknown task 'humanoid_balanse'" in err and "'humanoid_balance'" in err
    assert main(["compare", "humanoid_balance", "--controllers", "lqr,nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown controller 'nope'" in err and "'lqr'" in err
    assert main(["frobnicate"]) == 2
    assert "'compare'" in capsys.readouterr().err
    assert main(["list"]) == 0
    listing = capsys.readouterr().out
    assert "humanoid_balance: lqr" in listing and "humanoid_two_feet: lqr, ilqr, qp" in listing


def test_cli_end_to_end(tmp_path, capsys):
    out = tmp_path / "res"
    argv = ["compare", "humanoid_balance", "--controllers", "lqr", "--seeds", "2"]
    argv += ["--duration", "0.4", "--noise", "1,3", "--push", "20", "--push-time", "0.1"]
    argv += ["--largest-push", "--push-tolerance", "200", "--leg", "left"]
    argv += ["--workers", "1", "--no-progress", "--out", str(out)]
    assert main(argv) == 0
    stdout = capsys.readouterr().out
    assert "largest push forward (N)" in stdout and "largest push backward (N)" in stdout
    assert "| noise x3 push 20N@0.1s | lqr | 2 |" in stdout
    assert (out / "results.md").read_text().strip() in stdout
    assert (out / "results.csv").is_file()
    assert (out / "survival_vs_noise.png").is_file()
    assert (out / "compute_time.png").is_file()


def test_task_script_entry_point(tmp_path, capsys):
    argv = ["--duration", "0.3", "--workers", "1", "--no-progress", "--no-plots"]
    argv += ["--controllers", "lqr,ilqr"]
    argv += ["--out", str(tmp_path), "--balance-cost", "500", "--push-time", "0.1"]
    assert run_task_script("humanoid_balance", argv, seeds=1, push=10.0) == 0
    stdout = capsys.readouterr().out
    assert "balance_cost=500.0" in stdout
    assert "| noise x1 push 10N@0.1s | lqr | 1 | 100% |" in stdout
    # A push that would start after the 0.3 s run is refused, not reported as survived.
    late = [a for a in argv if a not in ("--push-time", "0.1")]
    assert run_task_script("humanoid_balance", late, seeds=1, push=10.0) == 2
    with pytest.raises(UnknownNameError, match="seeds"):
        run_task_script("humanoid_balance", [], seedz=1)


def test_rows_stream_as_runs_finish_and_a_rerun_loads_the_finished_ones(tmp_path):
    """Each finished run is in runs.jsonl and runs.csv before the next one starts; a re-run
    with the same checkpoint streams the finished runs (loaded, same timings) and then runs
    only the new seed."""
    import json

    from mpcbox.comparison.stream import RunStream

    out = tmp_path / "out"
    scenario = Scenario(duration=0.1, noise_scale=0.0)
    kwargs = dict(scenarios=scenario, executor="serial", checkpoint=out / "runs", progress=False)
    stream, seen = RunStream(out, [scenario]), []

    def hook(done):
        stream(done)
        lines = (out / "runs.jsonl").read_text().splitlines()
        with (out / "runs.csv").open() as f:
            rows = list(csv.DictReader(f))
        seen.append((done.job.seed, len(lines), len(rows), rows[-1]["seed"]))

    first = compare("pendulum_swingup", ["lqr"], seeds=3, on_done=hook, **kwargs)
    assert seen == [(0, 1, 1, "0"), (1, 2, 2, "1"), (2, 3, 3, "2")]
    rows = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert [r["cost"] for r in rows] == [r.metrics.cost for r in first.runs]
    assert all(r["where"] for r in rows)

    stream, seen = RunStream(out, [scenario]), []
    second = compare("pendulum_swingup", ["lqr"], seeds=4, on_done=hook, **kwargs)
    assert [s[0] for s in seen] == [0, 1, 2, 3] and seen[-1][1:3] == (4, 4)
    for x, y in zip(first.runs, second.runs[:3]):
        assert x.metrics.compute_mean_ms == y.metrics.compute_mean_ms  # loaded, not re-run
    with pytest.raises(TypeError, match="on_done"):
        compare("pendulum_swingup", ["lqr"], seeds=1, on_done=3, **kwargs)


def _children(pid: int) -> set[int]:
    from pathlib import Path

    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        out |= {int(c) for c in (task / "children").read_text().split()}
    return out


@pytest.mark.skipif(not __import__("pathlib").Path("/proc/self/task").exists(), reason="Linux")
def test_worker_processes_do_not_outlive_a_killed_comparison():
    """Killed by a signal, the parent left its workers running their jobs for minutes."""
    import os
    import signal
    import subprocess
    import sys
    import time

    script = (
        "from mpcbox.comparison.runner import compare\n"
        "from mpcbox.comparison.scenario import Scenario\n"
        "compare('humanoid_balance', ['lqr'], [Scenario(duration=600.0, noise_scale=1.0)],"
        " seeds=[0, 1], workers=2, progress=False)\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", script])
    try:
        deadline = time.monotonic() + 60.0
        workers: set[int] = set()
        while time.monotonic() < deadline and len(workers) < 2:
            time.sleep(0.2)
            # The pool's workers (the spawn context also starts a resource tracker).
            workers = {c for c in _children(parent.pid) if b"spawn_main" in _cmdline(c)}
        assert len(workers) == 2, "the workers did not start"
        time.sleep(2.0)  # into their 600 s jobs
        parent.send_signal(signal.SIGKILL)
        parent.wait(10.0)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(_alive(w) for w in workers):
            time.sleep(0.2)
        left = [w for w in workers if _alive(w)]
        for w in left:
            os.kill(w, signal.SIGKILL)
        assert not left, f"workers {left} outlived their comparison"
    finally:
        if parent.poll() is None:
            parent.kill()


def _cmdline(pid: int) -> bytes:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read()
    except OSError:
        return b""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def test_cli_largest_push_can_ask_for_rest(tmp_path, capsys):
    """``--push-rest-speed``: a push counts only when the body ends slower than that; no
    balancing humanoid is still to 1e-12 m/s 3 s after a push, so the limit drops to 0."""
    out = tmp_path / "res"
    argv = ["compare", "humanoid_balance", "--controllers", "lqr", "--seeds", "1"]
    argv += ["--duration", "0.2", "--largest-push", "--push-tolerance", "20"]
    argv += ["--workers", "1", "--no-progress", "--no-plots", "--out", str(out)]
    rows = {}
    for extra in ([], ["--push-rest-speed", "1e-12"]):
        assert main([*argv, *extra]) == 0
        capsys.readouterr()
        with open(out / "results.csv") as f:
            rows[bool(extra)] = next(csv.DictReader(f))
    key = next(k for k in rows[False] if "push" in k and "forward" in k)
    assert float(rows[False][key]) > 0.0
    assert float(rows[True][key]) == 0.0


def test_cli_push_scan_step_walks_the_force_grid_before_bisecting(tmp_path, capsys):
    """``--push-scan-step S`` tries S, 2S, ... up to the first failure and bisects only
    inside that bracket: with a tolerance wider than S no bisection step is taken, so each
    limit is a positive multiple of S (plain bisection over [0, max_force] lands elsewhere)."""
    out = tmp_path / "res"
    argv = ["compare", "humanoid_balance", "--controllers", "lqr", "--seeds", "1"]
    argv += ["--duration", "0.2", "--largest-push", "--push-tolerance", "30"]
    argv += ["--push-scan-step", "25", "--workers", "1", "--no-progress", "--no-plots"]
    assert main([*argv, "--out", str(out)]) == 0
    capsys.readouterr()
    with open(out / "results.csv") as f:
        row = next(csv.DictReader(f))
    limits = [
        float(v) for k, v in row.items() if "push" in k and ("forward" in k or "backward" in k)
    ]
    assert len(limits) == 2, row
    for limit in limits:
        assert limit >= 25.0 and limit % 25.0 == 0.0, limits


class _StallsEverySolve(Controller):
    """Holds zero control; every call is a solve that kept its warm start."""

    name = "stalling"

    def __init__(self, problem) -> None:
        self.nu, self.stalled = problem.nu, 0

    def reset(self) -> None:
        self.stalled = 0

    def __call__(self, state, time):
        self.stalled += 1
        self.last_call = "solve"
        return np.zeros(self.nu)

    @property
    def stats(self):
        return {"fallbacks": 0.0, "stalled": float(self.stalled)}


def test_stalls_get_a_column_only_when_a_controller_stalled():
    def stalling(problem):
        return _StallsEverySolve(problem)

    stalling.name = "stalling"
    kw = dict(seeds=1, workers=1, progress=False)
    result = compare(
        "pendulum_swingup", ["lqr", stalling], Scenario(duration=0.05, noise_scale=0.0), **kw
    )
    lqr, stalled = result.rows()
    solves = sum(r.metrics.solve_ticks for r in result.runs if r.controller == "stalling")
    assert solves >= 5 and stalled.stalls == solves and stalled.stall_rate == 1.0
    assert lqr.stalls == 0
    header, *rows = result.to_markdown().splitlines()
    assert header.rstrip(" |").endswith("stalled")
    assert rows[-1].rstrip(" |").endswith(f"{solves} (100%)")
    assert result.to_csv().splitlines()[0].endswith("fallbacks,fallback_rate,stalls,stall_rate")
    plain = compare("pendulum_swingup", ["lqr"], Scenario(duration=0.05, noise_scale=0.0), **kw)
    assert "stalled" not in plain.to_markdown() and "stalls" not in plain.to_csv()


def test_lqr_matrices_of_the_wrong_shape_are_refused_before_any_run():
    """They failed in every run and filled the row with controller errors (a fuzz run)."""
    from mpcbox.errors import ShapeError

    with pytest.raises(ShapeError, match=r"R must have shape \(1, 1\)"):
        compare(
            "pendulum_swingup",
            ["lqr"],
            Scenario(duration=0.05, noise_scale=0.0),
            seeds=1,
            controller_options={"lqr": {"R": 0.0}},
            progress=False,
        )
