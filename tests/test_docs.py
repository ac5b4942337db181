"""The documentation: its Python code runs, and the site builds with --strict, warning-free.

Each ``docs/tutorials/*.md`` (and ``docs/extending.md``) has its fenced ``python`` blocks run
in order in one namespace, from the repository root, with ``MPCBOX_DOCS_FAST=1`` (the
tutorials shorten their simulations) and ``MPCBOX_DOCS_IMG`` pointing at a temporary folder
for the figures. Blocks fenced as ``py`` are shown, not run.

The site is built once, verbosely; any WARNING line fails, and so does reStructuredText
markup (Sphinx roles, ``.. math::``) or unconverted TeX left in the rendered API pages.

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
#: Pages whose python blocks run: the tutorials and the guide to extending mpcbox.
PAGES = [*TUTORIALS, ROOT / "docs" / "extending.md"]
FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.MULTILINE | re.DOTALL)

#: Modules a tutorial needs; it is skipped, naming the module, when one cannot be imported.
REQUIRES: dict[str, tuple[str, ...]] = {
    "02_ilqr_swingup.md": ("mpcbox.controllers.ilqr.controller",),
    "03_qp_mpc_push.md": ("mpcbox.controllers.qp_mpc.controller",),
    "04_sampling_mpc.md": ("mpcbox.controllers.sampling",),
    "07_your_robot.md": ("dm_control",),
    "08_arm_reach.md": ("mujoco_warp", "matplotlib"),
}


def code_blocks(path: Path) -> list[str]:
    """The fenced ``python`` blocks of a markdown file, in order."""
    return FENCE.findall(path.read_text())


def run_tutorial(path: Path) -> None:
    """Execute a tutorial's blocks in one namespace; errors name the failing block."""
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for i, block in enumerate(code_blocks(path), start=1):
        # dont_inherit: the blocks run as a reader's script would, without this file's
        # `from __future__ import annotations` (which dataclasses in a block would trip on).
        code = compile(block, f"{path.name}[block {i}]", "exec", dont_inherit=True)
        exec(code, namespace)


def _missing(name: str) -> str | None:
    for module in REQUIRES.get(name, ()):
        try:
            importlib.import_module(module)
        except ImportError as exc:
            return f"{name} needs {module}, which does not import yet: {exc}"
    return None


@pytest.mark.parametrize("path", PAGES, ids=[p.name for p in PAGES])
def test_page_runs(path, tmp_path, monkeypatch):
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
    for number in range(1, 8):
        assert any(n.startswith(f"0{number}_") for n in names), f"tutorial {number} is missing"


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> tuple[Path, str, int]:
    """The site built once with ``mkdocs build --strict`` (verbose): folder, log, exit status."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip("mkdocs is not installed (pip install mpcbox[docs])")
    for module in ("mkdocstrings", "latex2mathml"):
        pytest.importorskip(module, reason=f"{module} is not installed (pip install mpcbox[docs])")
    out = tmp_path_factory.mktemp("site")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    return out, result.stdout + result.stderr, result.returncode


def test_mkdocs_build_strict_without_warnings(site):
    out, log, returncode = site
    warnings = [line for line in log.splitlines() if re.match(r"\s*(WARNING|ERROR)\b", line)]
    assert not warnings, "mkdocs build --strict warned:\n" + "\n".join(warnings)
    assert returncode == 0, log
    assert (out / "index.html").is_file()
    assert (out / "api" / "compare" / "index.html").is_file()
    assert (out / "extending" / "index.html").is_file()


#: reStructuredText markup that must not reach the rendered API pages.
RAW_MARKUP = re.compile(
    r":(?:py:)?(?:math|meth|func|class|attr|mod|data|exc|obj|const):|\.\. math::|\\\(|\\\["
)


def test_api_pages_have_no_raw_markup(site):
    out, log, returncode = site
    assert returncode == 0, log
    pages = sorted((out / "api").glob("*/index.html"))
    assert pages
    for page in pages:
        text = page.read_text()
        raw = [m.group(0) for m in RAW_MARKUP.finditer(text)]
        assert not raw, f"{page.relative_to(out)} shows raw markup: {sorted(set(raw))}"


def test_maths_is_mathml(site):
    out, log, returncode = site
    assert returncode == 0, log
    for page in out.rglob("*.html"):
        text = page.read_text()
        assert 'class="arithmatex"' not in text, f"{page.relative_to(out)} has unconverted TeX"
        assert "mathjax" not in text.lower(), f"{page.relative_to(out)} loads MathJax"
    assert "<math" in (out / "api" / "controllers" / "index.html").read_text()
    assert "<math" in (out / "tutorials" / "01_lqr_balance" / "index.html").read_text()


def _hook(name: str):
    """A module of ``docs/hooks`` (imported by path, as mkdocs and griffe do)."""
    spec = importlib.util.spec_from_file_location(
        f"docs_hook_{name}", ROOT / "docs/hooks" / f"{name}.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_maths_hook_converts_and_warns(caplog):
    pytest.importorskip("latex2mathml")
    maths = _hook("maths")
    page = type("Page", (), {"file": type("File", (), {"src_uri": "api/x.md"})()})()
    html = (
        '<p>a <span class="arithmatex">\\(x_t &lt; \\arg\\min_n J_n\\)</span></p>'
        '<div class="arithmatex">\\[\\tfrac12 x^T H x\\]</div>'
    )
    out = maths.on_page_content(html, page=page)
    assert "arithmatex" not in out and out.count("<math") == 2
    assert 'display="block"' in out and "<mo>&#x0003C;</mo>" in out  # the unescaped <
    with caplog.at_level("WARNING", logger="mkdocs"):
        out = maths.on_page_content('<span class="arithmatex">\\(\\nosuch x\\)</span>', page=page)
    assert "arithmatex" in out  # left as TeX
    assert "api/x.md" in caplog.text and "\\nosuch x" in caplog.text


def test_sphinx_roles_become_markdown():
    pytest.importorskip("griffe")
    roles = _hook("sphinx_roles")
    text = "Solve\n\n.. math::\n\n    a = b\n    + c\n\nthen :math:`x^2` with :meth:`~a.B.c`.\n"
    rewritten = roles.math_blocks(text)
    assert "\\[a = b + c\\]" in rewritten and ".. math::" not in rewritten
    assert roles.math_blocks(".. math:: y = 1\nnext") == "\\[y = 1\\]\n\nnext"


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
