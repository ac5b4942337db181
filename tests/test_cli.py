"""The command line: user errors exit with status 2 and one clear line, never a traceback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import mpcbox
from mpcbox.cli import main
from mpcbox.registry import task_class


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys) -> None:
    code, out, _ = run(capsys, "--version")
    assert code == 0 and out.strip() == f"mpcbox {mpcbox.__version__}"


def test_options_lists_a_controllers_config_with_defaults(capsys) -> None:
    code, out, _ = run(capsys, "options", "ilqr")
    assert code == 0
    assert "ILQRConfig" in out and "horizon = 50" in out


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["compare", "pendulum_swingup", "--set", "ilqr.bogus=1"], "bogus"),
        (["compare", "pendulum_swingup", "--set", "mppi.num_samples=8"], "--set"),
        (["compare", "pendulum_swingup", "--seed", "-1"], "--seed"),
        (["compare", "pendulum_swingup", "--push", "nan"], "--push"),
        (["compare", "pendulum_swingup", "--duration", "0"], "--duration"),
        (["compare", "pendulum_swingup", "--push-tolerance", "1e-20"], "--push-tolerance"),
        (["compare", "pendulum_swingup", "--push-scan-step", "-5"], "--push-scan-step"),
        (["compare", "pendulum_swingup", "--push-rest-speed", "0"], "--push-rest-speed"),
        (["compare", "pendulum_swingup", "--lookahead", "auto"], "--lookahead needs --realtime"),
        (["compare", "pendulum_swingup", "--realtime", "--lookahead", "-1"], "--lookahead"),
        (["compare", "pendulum_swingup", "--realtime", "--lookahead", "soon"], "'auto'"),
        (["compare", "pendulum_swingup", "--delay", "0.03"], "--delay needs --realtime"),
        (["compare", "pendulum_swingup", "--realtime", "--delay", "-1"], "--delay"),
        (["compare", "pendulum_swingup", "--speed", "2"], "--speed needs --realtime"),
        (["compare", "pendulum_swingup", "--realtime", "--speed", "0"], "--speed must be > 0"),
        (
            ["compare", "pendulum_swingup", "--realtime", "--delay", "0.03", "--speed", "2"],
            "--speed has no effect with --delay",
        ),
        (
            ["compare", "pendulum_swingup", "--realtime", "--largest-push"],
            "--largest-push searches in lock-step",
        ),
        (["compare", "pendulum_swingup", "--noise", "x"], "--noise"),
        (["compare", "pendulum_swingup", "--controllers", "nope"], "nope"),
        (["compare", "no_such_task"], "no_such_task"),
        # Checked before any run (each run used to fail, the table came first or rc was 0):
        (["compare", "pendulum_swingup", "--set", "ilqr.horizon=-3"], "horizon"),
        (["compare", "pendulum_swingup", "--push", "3", "--push-body", "nope"], "--push-body"),
        (["compare", "quadruped_stand", "--model", str(Path(__file__))], "model: MuJoCo could"),
        (["options", "no_such_controller"], "no_such_controller"),
        (["frobnicate"], "frobnicate"),
        # From a fuzz of the command line (each ran, failed every run, or read oddly):
        (["compare", "pendulum_swingup", "--controllers", "ilqr,ilqr"], "'ilqr' twice"),
        (["compare", "pendulum_swingup", "--duration", "1e-9"], "one simulation step"),
        (["compare", "pendulum_swingup", "--noise", ""], "--noise"),
        (["compare", "pendulum_swingup", "--push-body", "nope"], "--push-body"),
        (
            ["compare", "pendulum_swingup", "--controllers", "ilqr", "--set", "mppi.horizon=1"],
            "'mppi' is not among the chosen controllers (ilqr)",
        ),
        (["simulate", "pendulum_swingup"], "--controller is required"),
        (
            ["simulate", "pendulum_swingup", "--controller", "lqr", "--controllers", "ilqr"],
            "one --controller",
        ),
        (["list", "extra"], "no arguments"),
        # From a fuzz with robots nobody here wrote (stop 51):
        (["options"], "needs a controller name, one of: lqr"),
        (
            ["simulate", "pendulum_swingup", "--controller", "lqr,ilqr"],
            "--controller takes one name, got 'lqr,ilqr'",
        ),
        (["inspect", "nope", "--json", "/proc/no/such.json"], "--json: '/proc/no' is not"),
        (
            ["compare", "pendulum_swingup", "--controllers", "lqr", "--set", "lqr.R=0"],
            "R must have shape (1, 1)",
        ),
    ],
)
def test_user_errors_exit_2_with_one_line(capsys, tmp_path, argv, needle) -> None:
    out_flag = ["--out", str(tmp_path / "out")] if argv[0] in ("compare", "simulate") else []
    code, out, err = run(capsys, *argv, *out_flag)
    assert code == 2
    assert err.startswith("error:") and needle in err, err
    assert "Traceback" not in err
    assert "|" not in out  # no table: nothing ran
    assert not (tmp_path / "out").exists()  # --out is made only once every argument passed


def test_unwritable_out_fails_before_anything_runs(capsys, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code, out, err = run(
        capsys, "compare", "pendulum_swingup", "--out", str(blocker / "sub"), "--duration", "60"
    )
    assert code == 2 and "--out" in err
    assert "|" not in out  # no table: nothing ran


def test_simulate_runs_one_controller_once(capsys, tmp_path: Path) -> None:
    code, out, err = run(
        capsys,
        "simulate",
        "pendulum_swingup",
        "--controller",
        "lqr",
        "--duration",
        "0.2",
        "--no-plots",
        "--no-progress",
        "--out",
        str(tmp_path),
    )
    assert code == 0, err
    assert "| lqr |" in out.replace("|lqr|", "| lqr |") or "lqr" in out
    assert (tmp_path / "results.csv").read_text().count("\n") == 2  # header and one row


def _simulate_args(tmp_path: Path, *extra: str) -> list[str]:
    return [
        "simulate",
        "pendulum_swingup",
        "--controller",
        "lqr",
        "--duration",
        "0.3",
        "--push",
        "2",
        "--push-time",
        "0.1",
        "--push-body",
        "pole",
        "--no-plots",
        "--no-progress",
        "--out",
        str(tmp_path / "out"),
        *extra,
    ]


def test_simulate_saves_a_trajectory_that_replays_to_the_same_state(capsys, tmp_path) -> None:
    saved = tmp_path / "traj" / "run"
    code, out, err = run(capsys, *_simulate_args(tmp_path, "--save-trajectory", str(saved)))
    assert code == 0, err
    assert saved.with_suffix(".csv").exists() and saved.with_suffix(".json").exists()
    code, out, err = run(capsys, "replay", str(saved.with_suffix(".csv")))
    assert code == 0, err
    assert "final-state error 0 " in out and "same" in out
    # A changed control (within the +-2 N m range) makes the replay differ: status 1.
    lines = saved.with_suffix(".csv").read_text().splitlines()
    cells = lines[1].split(",")
    ctrl_column = lines[0].split(",").index("ctrl_0")
    cells[ctrl_column] = "1.0" if abs(float(cells[ctrl_column]) - 1.0) > 0.5 else "-1.0"
    saved.with_suffix(".csv").write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]))
    code, out, _ = run(capsys, "replay", str(saved))
    assert code == 1 and "DIFFERENT" in out


def test_compare_out_keeps_per_seed_rows_spread_settings_and_trajectories(capsys, tmp_path):
    import csv
    import json

    from mpcbox.sim.simulation import Metrics

    out_dir = tmp_path / "out"
    argv = ["compare", "pendulum_swingup", "--controllers", "lqr", "--seeds", "3"]
    argv += ["--duration", "0.3", "--workers", "1", "--no-plots", "--no-progress"]
    code, _, err = run(capsys, *argv, "--out", str(out_dir))
    assert code == 0, err
    rows = list(csv.DictReader((out_dir / "runs.csv").open()))
    assert [r["seed"] for r in rows] == ["0", "1", "2"]
    plain = [f for f in Metrics._fields if f != "measures"]
    assert set(plain) <= set(rows[0]) and {"scenario", "controller", "outcome"} <= set(rows[0])
    groups = json.loads((out_dir / "groups.json").read_text())
    cost = [float(r["cost"]) for r in rows]
    assert groups[0]["runs"] == 3
    assert groups[0]["cost_mean"] == pytest.approx(np.mean(cost))
    assert groups[0]["cost_std"] == pytest.approx(np.std(cost, ddof=1))
    assert groups[0]["cost_min"] == min(cost) and groups[0]["cost_max"] == max(cost)
    record = json.loads((out_dir / "run.json").read_text())
    assert record["command"].startswith("mpcbox compare pendulum_swingup")
    assert record["versions"]["mujoco"] and record["versions"]["numpy"]
    assert record["controllers"]["lqr"]["config_class"] == "LQRConfig"
    assert record["scenarios"][0]["duration"] == 0.3 and record["date"]
    assert len(list((out_dir / "trajectories").glob("*.csv"))) == 1  # the traced first seed


def test_cpu_reduced_settings_are_marked_next_to_their_row() -> None:
    from mpcbox.cli.outputs import REDUCED_MARK, cpu_reductions, mark_reduced

    cls = task_class("humanoid_balance")
    tuned = cls.controller_configs["mppi"]
    small = {"num_samples": tuned.num_samples // 8, "horizon": tuned.horizon / 2, "backend": "x"}
    reductions = cpu_reductions(cls, {"mppi": small}, {"mppi": {"horizon": 0.1}})
    assert reductions == {"mppi": {"num_samples": (tuned.num_samples, small["num_samples"])}}
    table = "| scenario | controller |\n|---|---|\n| s | lqr |\n| s | mppi |"
    marked = mark_reduced(table, reductions).splitlines()
    assert marked[2] == "| s | lqr |" and marked[3] == f"| s | mppi{REDUCED_MARK} |"
    assert f"num_samples {tuned.num_samples} -> {small['num_samples']}" in marked[-1]
    assert mark_reduced(table, {}) == table


def test_push_body_defaults_to_the_tasks_root() -> None:
    """A G1 has no body called ``torso`` (its root is ``pelvis``): ``--push`` without
    ``--push-body`` pushed a body that did not exist."""
    import argparse
    import types

    import mujoco

    from mpcbox.cli.compare import default_push_body

    free = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="base"><freejoint/><geom size=".1"/></body>'
        "</worldbody></mujoco>"
    )
    cases = [
        (types.SimpleNamespace(root="pelvis", model=free), None, "pelvis"),
        (types.SimpleNamespace(model=free), None, "base"),
        (types.SimpleNamespace(root="pelvis", model=free), "torso_link", "torso_link"),
    ]
    for problem, given, expected in cases:
        args = argparse.Namespace(push_body=given)
        default_push_body(args, problem)
        assert args.push_body == expected


@pytest.mark.skipif(Path("/dev/nvidia0").exists(), reason="with a GPU the quick runs use it")
def test_quick_cpu_runs_shrink_only_the_gpu_sized_sampling_configs() -> None:
    """The humanoid's 1024-2048 samples become 16 over 0.15 s; the cart-pole's CPU-sized
    128 over 1 s stay (cut to 0.15 s, its plan never swung the pole up: `mpcbox simulate
    cartpole_swingup --controller ps` ended hanging, 3.14 rad from upright)."""
    from mpcbox.cli import quick_sampling_options

    assert quick_sampling_options("humanoid_stand")["mppi"] == {"num_samples": 16, "horizon": 0.15}
    assert quick_sampling_options("cartpole_swingup") == {}
    assert set(quick_sampling_options()) == {"ps", "mppi", "cem"}


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--video", "run.avi"], ".mp4 or .gif"),
        (["--save-trajectory", "{out}/run"], "--save-trajectory"),
    ],
)
def test_simulate_output_errors_exit_2_before_running(capsys, tmp_path, extra, needle) -> None:
    extra = [e.format(out=tmp_path / "out") for e in extra]
    code, out, err = run(capsys, *_simulate_args(tmp_path, *extra))
    assert code == 2 and err.startswith("error:") and needle in err, err
    assert "|" not in out


def test_replay_errors_exit_2_with_one_line(capsys, tmp_path) -> None:
    code, _, err = run(capsys, "replay", str(tmp_path / "missing.csv"))
    assert code == 2 and err.startswith("error:") and "missing" in err
    assert "Traceback" not in err
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    (tmp_path / "bad.csv").write_text("time\n0\n")
    code, _, err = run(capsys, "replay", str(bad))
    assert code == 2 and err.startswith("error:") and "bad" in err
    video, viewer = ["--video", str(tmp_path / "v.gif")], ["--viewer", "live"]
    code, _, err = run(capsys, "replay", str(bad), *video, *viewer)
    assert code == 2 and "give one" in err


def test_compare_realtime_reports_kept_up(capsys, tmp_path):
    import json

    argv = ["compare", "pendulum_swingup", "--controllers", "lqr", "--seeds", "2"]
    argv += ["--duration", "0.3", "--workers", "1", "--no-plots", "--no-progress"]
    code, out, err = run(capsys, *argv, "--realtime", "--out", str(tmp_path))
    assert code == 0, err
    table = [line for line in out.splitlines() if line.startswith("| scenario")]
    assert table and "kept up" in table[0] and "real time" in out, out
    groups = json.loads((tmp_path / "groups.json").read_text())
    assert 0.0 <= groups[0]["kept_up_mean"] <= 1.0


def test_compare_realtime_with_a_simulated_delay_and_lookahead(capsys, tmp_path):
    import json

    argv = ["compare", "pendulum_swingup", "--controllers", "lqr", "--seeds", "1"]
    argv += ["--duration", "0.3", "--workers", "1", "--no-plots", "--no-progress"]
    argv += ["--realtime", "--delay", "0.03", "--lookahead", "auto", "--out", str(tmp_path)]
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    assert "delay 0.03 s" in out and "lookahead auto" in out, out
    groups = json.loads((tmp_path / "groups.json").read_text())
    assert groups[0]["kept_up_mean"] == 0.0  # a 30 ms state age against LQR's 10 ms step


def test_set_values_are_python_literals_or_json_words() -> None:
    from mpcbox.cli.compare import parse_sets

    sets = parse_sets(
        ["qp.relinearize=true", "qp.warm_start=False", "qp.time_limit=null", "mppi.n=64"]
    )
    assert sets == {
        "qp": {"relinearize": True, "warm_start": False, "time_limit": None},
        "mppi": {"n": 64},
    }
    assert parse_sets(["cem.name=trueish"]) == {"cem": {"name": "trueish"}}


def test_compare_takes_a_bare_menagerie_name_as_the_scripts_do(tmp_path, monkeypatch, capsys):
    # The bare name is looked up in Menagerie (it was read as a missing MJCF file), and the
    # error lists Menagerie's robots.
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path / "menagerie"))
    code = main(["compare", "quadruped_stand", "--model", "no_such_robot", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "unknown Menagerie robot 'no_such_robot'" in err
    assert "'anybotics_anymal_b'" in err and "no MJCF file" not in err


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["simulate", "--help"], "mpcbox simulate TASK --controller NAME"),
        (["simulate", "-h"], "mpcbox simulate TASK --controller NAME"),
        (["options", "--help"], "usage: mpcbox options CONTROLLER"),
        (["list", "--help"], "usage: mpcbox list"),
    ],
)
def test_help_of_simulate_and_options(capsys, argv, needle) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 0 and needle in out and not err


def test_simulate_help_lists_its_own_options_not_compares(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["simulate", "pendulum_swingup", "--help"])
    out = capsys.readouterr().out
    assert info.value.code == 0
    assert "One run of one controller" in out and "--controllers" not in out


def test_a_realtime_run_takes_the_tasks_lookahead_unless_told() -> None:
    """The G1 get-up plans one median tick ahead in real time by default (its class
    attribute, read without building the robot); --lookahead none or a value overrides it,
    and other tasks plan from the observed state."""
    from argparse import Namespace

    from mpcbox.cli.compare import realtime_lookahead

    def ahead(task, realtime=True, lookahead=None):
        return realtime_lookahead(Namespace(realtime=realtime, lookahead=lookahead), task)

    assert ahead("g1_getup") == "auto"
    assert ahead("g1_getup", lookahead="none") is None
    assert ahead("g1_getup", lookahead="0.02") == 0.02
    assert ahead("g1_getup", realtime=False) is None
    assert ahead("humanoid_getup") is None and ahead("pendulum_swingup") is None


def test_inspect_refuses_a_hold_of_a_billion_seconds(capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        run(capsys, "inspect", "nope", "--hold", "1e9")
    assert exit_info.value.code == 2
    assert "--hold must be a number of seconds in [0, 3600]" in capsys.readouterr().err


def test_name_list_task_options_are_comma_separated_flags() -> None:
    """A fuzz run could not point g1_getup at another humanoid: its feet (a tuple of names)
    and its keyframe had no flags."""
    from mpcbox.cli.compare_parser import build_parser

    parser = build_parser("humanoid_getup")
    args = parser.parse_args(["--feet", "left_sole, right_sole"])
    assert args.feet == ("left_sole", "right_sole")
    assert parser.parse_args([]).feet == ("foot_left", "foot_right")
    with pytest.raises(SystemExit):
        parser.parse_args(["--feet", "left,,right"])
    args = build_parser("g1_getup").parse_args(["--keyframe", "home", "--feet", "a,b"])
    assert args.keyframe == "home" and args.feet == ("a", "b")
