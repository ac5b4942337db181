"""Griffe extension: Sphinx roles and ``.. math::`` blocks in docstrings become Markdown.

mkdocstrings renders docstrings as Markdown, so the reStructuredText markup that the
docstrings use would show raw. Before a docstring is parsed this extension rewrites

* ``:math:`x``` into ``\\(x\\)``, which ``pymdownx.arithmatex`` keeps verbatim and
  ``docs/hooks/maths.py`` turns into MathML;
* ``.. math::`` directives (the formula on the same line or indented below) into a display
  block ``\\[ ... \\]`` at the directive's indentation;
* reference roles (``:meth:``, ``:func:``, ``:class:``, ``:attr:``, ``:mod:``, ``:data:``,
  ``:exc:``, ``:obj:``, ``:const:``) into an optional cross-reference: a link where the
  target is documented on this site, plain code otherwise. ``~target`` shows the last
  dotted component, ``title <target>`` shows the title, and a bare target shows as written.
  A target without a module path is looked up from the docstring's object outwards.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

REFERENCE_ROLES = ("meth", "func", "class", "attr", "mod", "data", "exc", "obj", "const")
ROLE = re.compile(r":(?:py:)?(?P<role>[a-z]+):`(?P<body>[^`]+)`")
MATH_DIRECTIVE = re.compile(r"^(?P<indent>[ \t]*)\.\. math::[ \t]*(?P<rest>.*)$")
EXPLICIT_TITLE = re.compile(r"^(?P<title>.+?)\s*<(?P<target>[^<>]+)>$")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def math_blocks(text: str) -> str:
    """Replace each ``.. math::`` directive by a ``\\[ ... \\]`` block (blank lines around)."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    while i < len(lines):
        match = MATH_DIRECTIVE.match(lines[i])
        if match is None:
            out.append(lines[i])
            i += 1
            continue
        indent = match["indent"]
        body = [match["rest"]] if match["rest"].strip() else []
        i += 1
        while i < len(lines) and (not lines[i].strip() or _indent(lines[i]) > len(indent)):
            if (
                not lines[i].strip()
                and body
                and (i + 1 >= len(lines) or _indent(lines[i + 1]) <= len(indent))
            ):
                break  # a blank line followed by a dedent ends the directive
            body.append(lines[i].strip())
            i += 1
        formula = " ".join(part for part in body if part)
        if out and out[-1].strip():
            out.append("")
        out.append(f"{indent}\\[{formula}\\]")
        if i < len(lines) and lines[i].strip():
            out.append("")
    return "\n".join(out)


def _walk(obj: griffe.Object) -> list[griffe.Object]:
    """``obj`` and every object defined under it (aliases left out)."""
    found = [obj]
    for member in obj.members.values():
        if not member.is_alias:
            found.extend(_walk(member))
    return found


def _identifier(target: str, obj: griffe.Object, paths: list[str]) -> str:
    """The documented path of ``target`` as seen from ``obj`` (``target`` if unknown).

    The first dotted component is looked up from ``obj`` outwards; a path through a
    re-export (``mpcbox.Problem.linearize``, which ``mpcbox`` imports lazily) falls back to
    the one object in ``paths`` whose path ends the same way.
    """
    head, _, tail = target.lstrip(".").partition(".")
    try:
        path = obj.resolve(head) + (f".{tail}" if tail else "")
        found = obj.modules_collection[path]
        return found.canonical_path if found.is_alias else found.path
    except Exception:  # an external, lazily exported or unknown name
        pass
    suffix = "." + (tail if head == obj.package.name and tail else target.lstrip("."))
    matches = [path for path in paths if path.endswith(suffix)]
    if len(matches) > 1 and "." not in suffix[1:]:  # a re-export names a module-level object
        matches = [path for path in matches if obj.modules_collection[path].parent.is_module]
    return matches[0] if len(matches) == 1 else target


def reference(body: str, obj: griffe.Object, paths: list[str]) -> str:
    """An optional autorefs cross-reference for the body of a reference role."""
    explicit = EXPLICIT_TITLE.match(body)
    if explicit:
        title, target = explicit["title"], explicit["target"]
    else:
        target = body
        title = None
    target = target.lstrip("!")
    short = target.startswith("~")
    target = target.lstrip("~").removesuffix("()")
    if title is None:
        title = target.rsplit(".", 1)[-1] if short else target
    return f'<autoref identifier="{_identifier(target, obj, paths)}" optional>`{title}`</autoref>'


def rewrite(text: str, obj: griffe.Object, paths: list[str]) -> str:
    """A docstring with its Sphinx markup replaced by Markdown."""

    def role(match: re.Match[str]) -> str:
        name, body = match["role"], match["body"]
        if name == "math":
            return f"\\({body}\\)"
        if name in REFERENCE_ROLES:
            return reference(body, obj, paths)
        return match[0]

    return ROLE.sub(role, math_blocks(text))


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring of a package once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        objects = _walk(pkg)
        paths = [obj.path for obj in objects]
        for obj in objects:
            if obj.docstring is not None:
                obj.docstring.value = rewrite(obj.docstring.value, obj, paths)
