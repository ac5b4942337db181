"""The package's layering: imports point down, never up, and form no circle.

Layers, lowest first: the base modules (errors, validation, config, registry), ``core``,
``controllers``, ``sim``, then ``comparison``, ``tasks`` and ``gates``, then ``cli``. Every import
counts, including those inside functions (a lazy import is still a dependency).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mpcbox"
MAX_LINES = 500

LAYERS: dict[str, int] = {
    "mpcbox": 0,
    "mpcbox.errors": 0,
    "mpcbox.validation": 0,
    "mpcbox.config": 0,
    "mpcbox.registry": 0,
    "mpcbox.core": 1,
    "mpcbox.controllers": 2,
    "mpcbox.sim": 3,
    "mpcbox.comparison": 4,
    "mpcbox.tasks": 4,
    "mpcbox.gates": 4,
    "mpcbox.cli": 5,
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def layer(name: str) -> int:
    best = None
    for prefix in LAYERS:
        if (name == prefix or name.startswith(prefix + ".")) and (
            best is None or len(prefix) > len(best)
        ):
            best = prefix
    assert best is not None, f"module {name} has no layer in LAYERS"
    return LAYERS[best]


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The mpcbox modules that ``name`` imports, resolved to modules that exist."""
    tree = ast.parse(path.read_text(), str(path))
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                sub = f"{module}.{alias.name}"
                targets.append(sub if sub in known else module)
        for target in targets:
            if target == "mpcbox" or target.startswith("mpcbox."):
                while target not in known and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target != name:
                    out.add(target)
    return out


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports(name, path, known) for name, path in mods.items()}


def test_no_module_imports_from_a_layer_above() -> None:
    upward = [
        f"{src} (layer {layer(src)}) imports {dst} (layer {layer(dst)})"
        for src, targets in graph().items()
        for dst in sorted(targets)
        if layer(dst) > layer(src)
    ]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_imports_form_no_circle() -> None:
    edges = graph()
    # A package's __init__ may re-export its own submodules: that edge is not a circle
    # unless the submodule imports the package back, which the search below still sees.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    assert not cycles, f"import circles: {cycles}"


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: module_name(p))
def test_module_is_small(path: Path) -> None:
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_LINES, f"{path} has {lines} lines (limit {MAX_LINES})"


def test_layer_checker_sees_an_upward_import(tmp_path: Path) -> None:
    """The resolver catches ``from mpcbox.sim...`` written inside a core module."""
    fake = tmp_path / "mpcbox" / "core"
    fake.mkdir(parents=True)
    src = fake / "bad.py"
    src.write_text("def f():\n    from mpcbox.sim.simulation import simulate\n")
    found = imports("mpcbox.core.bad", src, {"mpcbox.sim.simulation", "mpcbox.core.bad"})
    assert found == {"mpcbox.sim.simulation"}
    assert layer("mpcbox.sim.simulation") > layer("mpcbox.core.bad")
