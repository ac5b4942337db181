"""The command line: user errors exit with status 2 and one clear line, never a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

import mpcbox
from mpcbox.cli import main


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
        (["compare", "pendulum_swingup", "--noise", "x"], "--noise"),
        (["compare", "pendulum_swingup", "--controllers", "nope"], "nope"),
        (["compare", "no_such_task"], "no_such_task"),
        (["options", "no_such_controller"], "no_such_controller"),
        (["frobnicate"], "frobnicate"),
    ],
)
def test_user_errors_exit_2_with_one_line(capsys, tmp_path, argv, needle) -> None:
    code, _, err = run(capsys, *argv, *(["--out", str(tmp_path)] if argv[0] == "compare" else []))
    assert code == 2
    assert err.startswith("error:") and needle in err, err
    assert "Traceback" not in err


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
