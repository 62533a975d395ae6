"""Plain data describing a report; no rendering happens here.

The pipeline builds a :class:`Document` (or an :class:`IndexDocument` for a
batch of reports) and hands it to :mod:`tcamlab.report.html` or
:mod:`tcamlab.report.pdf`.  Every user-supplied string (titles, notes, column
names, file names) is treated as plain text by both renderers and escaped, so
it may contain anything, including markup.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tcamlab.numbers import fmt, fmt_column

CELL_STATUSES = (None, "pass", "fail", "warn")
INDEX_STATUSES = ("pass", "fail", "no-limits", "error")
INDEX_STATUS_LABELS = {"pass": "passed", "fail": "FAILED", "no-limits": "no limits set", "error": "error"}
"""How each index status is shown: "no-limits" (no threshold checked) is neutral, never a pass."""
MISSING = "\u2013"  # en dash, shown for None cells

_SAFE_SCHEMES = ("http://", "https://", "mailto:")


def safe_href(href: str | None) -> str | None:
    """Return *href* if it is safe to put in a link, else ``None``.

    Relative references (``run-01/report.html``, ``#section``) and
    ``http``/``https``/``mailto`` URLs are allowed; anything with another
    scheme (``javascript:``, ``data:``, ``file:``...) is dropped.
    """
    if href is None:
        return None
    text = str(href).strip()
    if not text:
        return None
    lowered = "".join(text.split()).lower()
    if lowered.startswith(_SAFE_SCHEMES):
        return text
    # A scheme is "letters/digits/+-. followed by ':'" before any '/', '?', '#'.
    head = lowered.split("/", 1)[0].split("?", 1)[0].split("#", 1)[0]
    if ":" in head:
        return None
    return text


@dataclass(frozen=True)
class Cell:
    """A table cell with explicit text and an optional status or link.

    ``status`` is ``None``, ``"pass"``, ``"fail"`` or ``"warn"``; renderers
    colour the cell accordingly.  ``href`` makes the text a link (unsafe
    schemes such as ``javascript:`` are silently dropped when rendering).
    """

    text: str
    status: str | None = None
    href: str | None = None

    def __post_init__(self) -> None:
        if self.status not in CELL_STATUSES:
            raise ValueError(f"Cell status must be one of {CELL_STATUSES}, got {self.status!r}")
        if not isinstance(self.text, str):
            object.__setattr__(self, "text", str(self.text))


def _is_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    t = type(value)
    return t.__module__ == "numpy" and t.__name__ in ("bool_", "bool")


def _is_plain_float(value: Any) -> bool:
    if isinstance(value, (Cell, bool)) or value is None or _is_bool(value):
        return False
    return (
        isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral) and math.isfinite(value)
    )


def format_cell(value: object, number_format: str | None = None) -> Cell:
    """Turn one raw table value into a :class:`Cell`.

    ``None`` -> "–"; ``bool`` -> "pass"/"FAIL" with that status; integers
    verbatim; other real numbers through *number_format*, by default the
    policy of :func:`tcamlab.numbers.fmt`; ``Cell`` unchanged; anything else
    through ``str``.
    """
    if isinstance(value, Cell):
        return value
    if value is None:
        return Cell(MISSING)
    if _is_bool(value):
        return Cell("pass", "pass") if bool(value) else Cell("FAIL", "fail")
    if isinstance(value, numbers.Integral):
        return Cell(str(int(value)))
    if isinstance(value, numbers.Real):
        number = float(value)
        if math.isnan(number):
            return Cell("NaN")
        return Cell(fmt(number) if number_format is None else number_format.format(number))
    return Cell(str(value))


@dataclass
class Table:
    """A table with a header row.

    Each row must have exactly ``len(columns)`` cells.  Cells may be ``str``,
    ``int``, ``float``, ``None``, ``bool`` or :class:`Cell`; see
    :func:`format_cell` for how they are shown.
    """

    columns: list[str]
    rows: list[list[object]]
    caption: str = ""
    number_format: str | None = None

    def __post_init__(self) -> None:
        self.columns = [str(c) for c in self.columns]
        self.rows = [list(r) for r in self.rows]
        for i, row in enumerate(self.rows):
            if len(row) != len(self.columns):
                raise ValueError(
                    f"table {self.caption!r}: row {i} has {len(row)} cells, "
                    f"expected {len(self.columns)} (one per column)"
                )

    def formatted_rows(self) -> list[list[Cell]]:
        """Rows with every value converted to a :class:`Cell`; by default the float values of
        a column share one notation (:func:`tcamlab.numbers.fmt_column`)."""
        if self.number_format is not None or not self.rows:
            return [[format_cell(v, self.number_format) for v in row] for row in self.rows]
        columns = [fmt_column([row[j] for row in self.rows]) for j in range(len(self.columns))]
        return [
            [Cell(columns[j][i]) if _is_plain_float(v) else format_cell(v) for j, v in enumerate(row)]
            for i, row in enumerate(self.rows)
        ]


@dataclass
class Figure:
    """A matplotlib figure with a caption (and alt text for the HTML)."""

    figure: Any  # matplotlib.figure.Figure; not imported here to keep imports cheap
    caption: str
    alt: str = ""


@dataclass
class Section:
    """A headed section.

    Rendered in this order: heading, warnings (failed sanity checks, shown
    as such), notes (highlighted facts), paragraphs, tables, figures,
    subsections.
    """

    heading: str
    paragraphs: Sequence[str] = field(default_factory=list)
    tables: Sequence[Table] = field(default_factory=list)
    figures: Sequence[Figure] = field(default_factory=list)
    subsections: Sequence[Section] = field(default_factory=list)
    notes: Sequence[str] = field(default_factory=list)
    warnings: Sequence[str] = field(default_factory=list)


@dataclass
class Document:
    """One report.

    ``metadata`` (tool version, command line, input hashes...) is shown as a
    provenance table at the end, in insertion order.  ``synthetic_banner``,
    when set, is shown prominently at the top (use it whenever the data is
    synthetic).
    """

    title: str
    subtitle: str = ""
    sections: Sequence[Section] = field(default_factory=list)
    metadata: Mapping[str, str] = field(default_factory=dict)
    synthetic_banner: str | None = None


@dataclass
class IndexEntry:
    """One row of an index page: a report and its headline result."""

    name: str
    title: str
    kind: str
    status: str
    metrics: Mapping[str, str] = field(default_factory=dict)
    link: str | None = None
    error: str | None = None
    warnings: Sequence[str] = ()

    @property
    def status_label(self) -> str:
        """The status as shown (:data:`INDEX_STATUS_LABELS`)."""
        return INDEX_STATUS_LABELS[self.status]

    def __post_init__(self) -> None:
        if self.status not in INDEX_STATUSES:
            raise ValueError(
                f"IndexEntry {self.name!r}: status must be one of {INDEX_STATUSES}, got {self.status!r}"
            )


@dataclass
class IndexDocument:
    """An index of many reports.

    ``synthetic_banner``, when set, is shown at the top (set it whenever any
    report's data is synthetic).  Metric values are short strings; a value
    with several lines (one per quantity) is shown line by line in its cell.
    """

    title: str
    entries: Sequence[IndexEntry] = field(default_factory=list)
    metadata: Mapping[str, str] = field(default_factory=dict)
    synthetic_banner: str | None = None

    def metric_names(self) -> list[str]:
        """Union of the entries' metric keys, in first-seen order."""
        seen: dict[str, None] = {}
        for entry in self.entries:
            for key in entry.metrics:
                seen.setdefault(str(key), None)
        return list(seen)

    def status_counts(self) -> dict[str, int]:
        """Entries per status, and ``"warnings"``: entries with at least one warning."""
        counts = {s: 0 for s in INDEX_STATUSES}
        for entry in self.entries:
            counts[entry.status] += 1
        counts["warnings"] = sum(1 for e in self.entries if e.warnings)
        return counts

    def summary(self) -> str:
        """One line such as "2 passed, 0 failed, 2 no limits set, 0 error; 1 with warnings"."""
        counts = self.status_counts()
        parts = [f"{counts[s]} {INDEX_STATUS_LABELS[s].lower()}" for s in INDEX_STATUSES]
        return ", ".join(parts) + f"; {counts['warnings']} with warnings"
