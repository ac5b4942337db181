"""The documentation: every tutorial's Python code runs, and the site builds with --strict.

Each ``docs/tutorials/*.md`` has its fenced ``python`` blocks run in order in one namespace,
from the repository root, with ``MPCBOX_DOCS_FAST=1`` (the tutorials shorten their
simulations) and ``MPCBOX_DOCS_IMG`` pointing at a temporary folder for the figures.

Regenerate the committed figures (full-length runs into ``docs/tutorials/img``) with::

    python tests/test_docs.py [tutorial.md ...]
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.md"))
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)

#: Modules a tutorial needs; it is skipped, naming the module, when one cannot be imported.
REQUIRES: dict[str, tuple[str, ...]] = {
    "02_ilqr_swingup.md": ("mpcbox.controllers.ilqr.controller",),
    "03_qp_mpc_push.md": ("mpcbox.controllers.qp_mpc.controller",),
    "04_sampling_mpc.md": ("mpcbox.controllers.sampling",),
}


def code_blocks(path: Path) -> list[str]:
    """The fenced ``python`` blocks of a markdown file, in order."""
    return FENCE.findall(path.read_text())


def run_tutorial(path: Path) -> None:
    """Execute a tutorial's blocks in one namespace; errors name the failing block."""
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for i, block in enumerate(code_blocks(path), start=1):
        code = compile(block, f"{path.name}[block {i}]", "exec")
        exec(code, namespace)


def _missing(name: str) -> str | None:
    for module in REQUIRES.get(name, ()):
        try:
            importlib.import_module(module)
        except ImportError as exc:
            return f"{name} needs {module}, which does not import yet: {exc}"
    return None


@pytest.mark.parametrize("path", TUTORIALS, ids=[p.name for p in TUTORIALS])
def test_tutorial_runs(path, tmp_path, monkeypatch):
    reason = _missing(path.name)
    if reason:
        pytest.skip(reason)
    assert code_blocks(path), f"{path.name} has no python blocks"
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("MPCBOX_DOCS_FAST", "1")
    monkeypatch.setenv("MPCBOX_DOCS_IMG", str(tmp_path))
    run_tutorial(path)
    images = re.findall(r"\]\(img/([^)]+\.png)\)", path.read_text())
    for image in images:
        assert (tmp_path / image).is_file(), f"{path.name} shows img/{image} but does not write it"
        assert (ROOT / "docs" / "tutorials" / "img" / image).is_file(), (
            f"img/{image} is not committed; run python tests/test_docs.py {path.name}"
        )


def test_tutorials_exist():
    names = [p.name for p in TUTORIALS]
    for number in range(1, 7):
        assert any(n.startswith(f"0{number}_") for n in names), f"tutorial {number} is missing"


@pytest.mark.skipif(
    importlib.util.find_spec("mkdocs") is None,
    reason="mkdocs is not installed (pip install mpcbox[docs])",
)
def test_mkdocs_build_strict(tmp_path):
    pytest.importorskip("mkdocstrings")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "api" / "compare" / "index.html").is_file()


if __name__ == "__main__":
    os.chdir(ROOT)
    os.environ.pop("MPCBOX_DOCS_FAST", None)
    os.environ["MPCBOX_DOCS_IMG"] = str(ROOT / "docs" / "tutorials" / "img")
    chosen = [ROOT / "docs" / "tutorials" / a for a in sys.argv[1:]] or TUTORIALS
    for tutorial in chosen:
        t0 = time.perf_counter()
        reason = _missing(tutorial.name)
        if reason:
            print(f"skip {tutorial.name}: {reason}")
            continue
        run_tutorial(tutorial)
        print(f"{tutorial.name}: {time.perf_counter() - t0:.1f} s")
