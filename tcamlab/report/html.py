"""Self-contained HTML rendering (inline CSS and SVG, no external resources).

Templates live in ``tcamlab/report/templates``; autoescaping is on for every
template except the stylesheet, so user strings are always escaped.  The only
markup inserted unescaped is the SVG produced by matplotlib.
"""

from __future__ import annotations

import re
from typing import Any

from markupsafe import Markup

from .document import Document, IndexDocument, Section, Table, safe_href
from .figures import figure_to_svg

_ENV = None


def _autoescape(name: str | None) -> bool:
    # The stylesheet is included raw inside <style>; escaping quotes there
    # would break it.  Everything else (and string templates) is escaped.
    return not (name or "").endswith(".css")


_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def _finalize(value: Any) -> Any:
    # Control characters are not allowed in HTML text; drop them from user strings.
    if isinstance(value, str) and not isinstance(value, Markup):
        return _CONTROL.sub("", value)
    return value


def _env():
    global _ENV
    if _ENV is None:
        import jinja2

        _ENV = jinja2.Environment(
            loader=jinja2.PackageLoader("tcamlab.report", "templates"),
            autoescape=_autoescape,
            undefined=jinja2.StrictUndefined,
            trim_blocks=True,
            lstrip_blocks=True,
            keep_trailing_newline=True,
            finalize=_finalize,
        )
    return _ENV


_NUMBER = re.compile(r"[-+−]?(\d+\.?\d*|\.\d+)(e[-+]\d+)?( [^\s\d]{1,4})?")
"""A number, optionally with a short unit: kept on one line (never broken at "e-")."""


def _cell_class(cell) -> str:
    """The td's classes: its status, and ``num`` for a number (kept on one line)."""
    classes = [f"status-{cell.status}"] if cell.status else []
    return " ".join(classes + (["num"] if _NUMBER.fullmatch(cell.text) else []))


class _Counter:
    def __init__(self) -> None:
        self.tables = 0
        self.figures = 0


def _table_view(table: Table, counter: _Counter) -> dict[str, Any]:
    counter.tables += 1
    rows = [
        [{"text": c.text, "href": safe_href(c.href), "cls": _cell_class(c)} for c in row]
        for row in table.formatted_rows()
    ]
    return {
        "id": f"table-{counter.tables}",
        "number": counter.tables,
        "caption": table.caption,
        "columns": list(table.columns),
        "rows": rows,
    }


def _section_view(section: Section, path: tuple[int, ...], counter: _Counter) -> dict[str, Any]:
    figures = []
    for fig in section.figures:
        counter.figures += 1
        n = counter.figures
        figures.append(
            {
                "id": f"figure-{n}",
                "number": n,
                "caption": fig.caption,
                "alt": fig.alt or fig.caption,
                "svg": Markup(figure_to_svg(fig.figure, index=n)),
            }
        )
    tables = [_table_view(t, counter) for t in section.tables]
    return {
        "id": "sec-" + "-".join(str(i) for i in path),
        "number": ".".join(str(i) for i in path),
        "level": min(len(path) + 1, 6),
        "heading": section.heading,
        "notes": [str(n) for n in section.notes],
        "warnings": [str(w) for w in section.warnings],
        "paragraphs": [str(p) for p in section.paragraphs],
        "tables": tables,
        "figures": figures,
        "subsections": [
            _section_view(sub, path + (i,), counter) for i, sub in enumerate(section.subsections, start=1)
        ],
    }


def _metadata_view(metadata) -> list[tuple[str, str]]:
    return [(str(k), str(v)) for k, v in metadata.items()]


def render_html(doc: Document) -> str:
    """Render one report as a complete, self-contained HTML page."""
    counter = _Counter()
    sections = [_section_view(s, (i,), counter) for i, s in enumerate(doc.sections, start=1)]
    return (
        _env()
        .get_template("report.html")
        .render(
            title=doc.title,
            subtitle=doc.subtitle,
            banner=doc.synthetic_banner,
            sections=sections,
            metadata=_metadata_view(doc.metadata),
        )
    )


def render_index_html(index: IndexDocument) -> str:
    """Render an index page linking many reports."""
    metric_names = index.metric_names() or (["Error"] if any(e.error for e in index.entries) else [])
    entries = []
    for e in index.entries:
        entries.append(
            {
                "name": e.name,
                "title": e.title,
                "kind": e.kind,
                "status": e.status,
                "status_label": e.status_label,
                "warnings": list(e.warnings),
                "link": safe_href(e.link),
                "error": e.error,
                "metrics": [str(e.metrics[m]) if m in e.metrics else None for m in metric_names],
            }
        )
    return (
        _env()
        .get_template("index.html")
        .render(
            title=index.title,
            metric_names=metric_names,
            entries=entries,
            counts=index.status_counts(),
            banner=index.synthetic_banner,
            metadata=_metadata_view(index.metadata),
        )
    )
