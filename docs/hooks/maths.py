"""MkDocs hook: TeX formulas become MathML when the site is built, so no script renders them.

``pymdownx.arithmatex`` (``generic: true``) wraps inline maths as
``<span class="arithmatex">\\(...\\)</span>`` and display maths as
``<div class="arithmatex">\\[...\\]</div>``; this hook replaces both with the MathML that
``latex2mathml`` makes (``display="block"`` for the displays), which browsers render
natively, offline. A formula that latex2mathml rejects, or that keeps a TeX command it does
not know, is left as TeX with a warning naming the page and the formula (a failure under
``mkdocs build --strict``).
"""

from __future__ import annotations

import html
import logging
import re

from latex2mathml.converter import convert

log = logging.getLogger("mkdocs.hooks.maths")

INLINE = re.compile(r'<span class="arithmatex">\\\((?P<tex>.*?)\\\)</span>', re.DOTALL)
DISPLAY = re.compile(r'<div class="arithmatex">\\\[(?P<tex>.*?)\\\]</div>', re.DOTALL)
#: A TeX command that latex2mathml passed through as text.
UNKNOWN_COMMAND = re.compile(r">\\[A-Za-z]+")
#: Standard TeX operator names that latex2mathml does not know, spelled so that it does.
OPERATOR_NAMES = re.compile(r"\\(?P<name>arg)(?![A-Za-z])")


def to_mathml(tex: str, display: str) -> str:
    """MathML for one formula; raises ValueError when latex2mathml cannot render it."""
    try:
        tex = OPERATOR_NAMES.sub(r"\\operatorname{\g<name>}", tex.strip())
        mathml = convert(tex, display=display)
    except Exception as exc:  # latex2mathml raises its own exception types
        raise ValueError(f"{type(exc).__name__}: {exc}") from exc
    unknown = UNKNOWN_COMMAND.search(mathml)
    if unknown:
        raise ValueError(f"unknown command {unknown[0][1:]}")
    return mathml


def on_page_content(html_text: str, page, **kwargs) -> str:
    """Replace the page's arithmatex spans and divs with MathML."""

    def replace(match: re.Match[str], display: str) -> str:
        tex = html.unescape(match["tex"])
        try:
            return to_mathml(tex, display)
        except ValueError as exc:
            log.warning(
                "%s: cannot convert the formula %r to MathML (%s)", page.file.src_uri, tex, exc
            )
            return match[0]

    html_text = DISPLAY.sub(lambda m: replace(m, "block"), html_text)
    return INLINE.sub(lambda m: replace(m, "inline"), html_text)
