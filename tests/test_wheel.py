"""The built wheel works on its own: scenes ship as package data, the CLI is installed.

Builds the wheel with ``pip wheel``, installs it without its dependencies into a folder of its
own (``pip install --target``; the dependencies are the test environment's, which CI installed
from ``pyproject.toml``), and from a directory outside the repository, with only that folder
on ``PYTHONPATH``, runs the README's first example and the installed ``mpcbox`` command.

This is the check for "a normal ``pip install .`` must give working tasks": with the scenes
outside the package every built-in task raised ``ModelNotFoundError``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIRST_EXAMPLE = re.compile(r"## A first example\s+```python\n(.*?)```", re.DOTALL)


def run(
    cmd: list[str], cwd: Path, timeout: float, path: Path | None = None
) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    env["MPLBACKEND"] = "Agg"
    if path is not None:
        env["PYTHONPATH"] = str(path)
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f"{' '.join(cmd)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
    return proc


@pytest.mark.slow
def test_wheel_runs_the_readme_example_outside_the_repository(tmp_path: Path) -> None:
    if os.environ.get("MPCBOX_SKIP_WHEEL_TEST"):
        pytest.skip("MPCBOX_SKIP_WHEEL_TEST is set")
    dist = tmp_path / "dist"
    run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(dist)],
        cwd=tmp_path,
        timeout=600,
    )
    wheels = list(dist.glob("mpcbox-*.whl"))
    assert len(wheels) == 1, wheels

    target = tmp_path / "installed"
    run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--target",
            str(target),
            str(wheels[0]),
        ],
        cwd=tmp_path,
        timeout=600,
    )

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    example = FIRST_EXAMPLE.search((ROOT / "README.md").read_text())
    assert example, "README.md has no '## A first example' python block"
    code = (
        example.group(1)
        + "\nassert result.survived, result.failure\nprint('ok', mpcbox.__file__)\n"
    )
    proc = run([sys.executable, "-c", code], cwd=outside, timeout=600, path=target)
    assert str(target) in proc.stdout, proc.stdout  # the installed copy ran, not the checkout

    proc = run(
        [str(target / "bin" / "mpcbox"), "compare", "pendulum_swingup", "--seeds", "1"],
        cwd=outside,
        timeout=600,
        path=target,
    )
    assert "pendulum_swingup" in proc.stdout or "|" in proc.stdout, proc.stdout
