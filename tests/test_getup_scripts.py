"""The get-up scripts of ``problems/``: the humanoid's runs, the G1's names a missing robot."""

from __future__ import annotations

import json

import pytest


def test_humanoid_getup_script_runs_the_task_and_reports_why_it_missed(
    tmp_path, capsys, problem_script
):
    argv = ["--controllers", "mppi", "--duration", "0.3", "--no-progress", "--no-plots"]
    argv += ["--set", "mppi.num_samples=8", "--set", "mppi.backend=cpu", "--out", str(tmp_path)]
    assert problem_script("humanoid_getup").main(argv) == 0
    stdout = capsys.readouterr().out
    assert "| 1 | 0% | 1 goal missed |" in stdout  # 0.3 s is too short to get up
    (run,) = json.loads((tmp_path / "runs.json").read_text())
    assert run["controller"] == "mppi" and run["outcome"] == "goal missed"
    assert run["failure"].startswith("not standing for the last 0.5 s")


def test_g1_getup_script_names_the_missing_robot(tmp_path, monkeypatch, capsys, problem_script):
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))  # an empty copy: nothing downloads
    out = tmp_path / "out"
    assert problem_script("g1_getup").main(["--controllers", "mppi", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "unitree_g1" in err and "MENAGERIE_ROOT" in err
    with pytest.raises(SystemExit):
        problem_script("g1_getup").main(["--controllers"])  # argparse: an option without its value
