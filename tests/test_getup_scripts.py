"""The get-up scripts of ``problems/``: the humanoid's runs, the G1's names a missing robot."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, PROBLEMS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_humanoid_getup_script_runs_the_task_and_reports_why_it_missed(tmp_path, capsys):
    argv = ["--controllers", "mppi", "--duration", "0.3", "--no-progress", "--no-plots"]
    argv += ["--set", "mppi.num_samples=8", "--set", "mppi.backend=cpu", "--out", str(tmp_path)]
    assert _script("humanoid_getup").main(argv) == 0
    stdout = capsys.readouterr().out
    assert "| 1 | 0% | 1 goal missed |" in stdout  # 0.3 s is too short to get up
    (run,) = json.loads((tmp_path / "runs.json").read_text())
    assert run["controller"] == "mppi" and run["outcome"] == "goal missed"
    assert run["failure"].startswith("not standing for the last 0.5 s")


def test_g1_getup_script_names_the_missing_robot(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))  # an empty copy: nothing downloads
    out = tmp_path / "out"
    assert _script("g1_getup").main(["--controllers", "mppi", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "unitree_g1" in err and "MENAGERIE_ROOT" in err
    with pytest.raises(SystemExit):
        _script("g1_getup").main(["--controllers"])  # argparse: an option without its value
