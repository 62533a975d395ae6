"""MkDocs hook: the API reference shows a docstring's Sphinx cross-reference roles
(:func:`name`, :class:`~pkg.Name`) as plain code, ``name`` and ``Name``, the way a reader
of the source reads them."""

from __future__ import annotations

import re

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|attr|mod|data|exc|obj|const):<code>(~?)([^<]*)</code>")


def _short(match: re.Match) -> str:
    tilde, target = match.groups()
    # a leading "~" asks for the last component only, as Sphinx shows it
    return f"<code>{target.rsplit('.', 1)[-1] if tilde else target}</code>"


def on_page_content(html: str, page, config, files) -> str:
    if not page.file.src_uri.startswith("api/"):
        return html
    return ROLE.sub(_short, html)
