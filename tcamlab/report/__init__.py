"""Report rendering: HTML (self-contained), PDF (reportlab) and index pages.

The pipeline builds a :class:`Document` out of :class:`Section`,
:class:`Table` and :class:`Figure` objects, then calls :func:`render_html`
or :func:`render_pdf` and writes the result with :func:`atomic_write_text`
/ :func:`atomic_write_bytes`.  Renderers are imported lazily so that
``import tcamlab.report`` stays cheap.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .atomic import atomic_write_bytes, atomic_write_text
from .document import (
    Cell,
    Document,
    Figure,
    IndexDocument,
    IndexEntry,
    Section,
    Table,
    format_cell,
)

if TYPE_CHECKING:  # pragma: no cover
    from .figures import figure_to_png, figure_to_svg, new_figure, report_style
    from .html import render_html, render_index_html
    from .pdf import render_combined_pdf, render_pdf

__all__ = [
    "Cell",
    "Document",
    "Figure",
    "IndexDocument",
    "IndexEntry",
    "Section",
    "Table",
    "atomic_write_bytes",
    "atomic_write_text",
    "figure_to_png",
    "figure_to_svg",
    "format_cell",
    "new_figure",
    "render_combined_pdf",
    "render_html",
    "render_index_html",
    "render_pdf",
    "report_style",
]

_LAZY = {
    "figure_to_png": "figures",
    "figure_to_svg": "figures",
    "new_figure": "figures",
    "report_style": "figures",
    "render_html": "html",
    "render_index_html": "html",
    "render_pdf": "pdf",
    "render_combined_pdf": "pdf",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value
