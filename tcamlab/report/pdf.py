"""PDF rendering with reportlab platypus (pure Python, no system libraries).

Output is reproducible: reportlab's ``invariant`` mode fixes the document ID
and dates (``SOURCE_DATE_EPOCH`` is hidden from it, so the variable changes
nothing), the info dictionary is fixed, fonts are the DejaVu TTFs shipped
with matplotlib (so Greek letters and units render; Helvetica is the
fallback), and figures are embedded as deterministic PNGs.

Each page has a footer with the report title and "Page N of M"; the document
is laid out twice to learn M.  Headings get PDF outline (bookmark) entries.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape as _xml_escape

from .document import (
    MISSING,
    Cell,
    Document,
    Figure,
    IndexDocument,
    Section,
    Table,
    safe_href,
)
from .figures import figure_size_in, figure_to_png

PNG_DPI = 150

_STATUS_COLOURS = {
    # status: (background, text)
    "pass": ("#e3f4e5", "#18632a"),
    "fail": ("#fbe4e4", "#a1191d"),
    "warn": ("#fff4d6", "#7a5300"),
    "error": ("#f4e1f7", "#6e1780"),
}

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def esc(text: object) -> str:
    """Escape a plain user string for reportlab Paragraph markup."""
    s = _CONTROL.sub("", str(text))
    s = _xml_escape(s)
    return s.replace("\r\n", "\n").replace("\n", "<br/>")


def _attr(text: str) -> str:
    return _xml_escape(_CONTROL.sub("", text), {'"': "&quot;"})


# --------------------------------------------------------------------------
# fonts and styles


@dataclass(frozen=True)
class _Fonts:
    regular: str
    bold: str
    italic: str
    mono: str


_FONTS: _Fonts | None = None


def _fonts() -> _Fonts:
    global _FONTS
    if _FONTS is not None:
        return _FONTS
    try:
        import matplotlib
        from reportlab.lib.fonts import addMapping
        from reportlab.pdfbase import pdfmetrics
        from reportlab.pdfbase.ttfonts import TTFont

        base = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
        files = {
            "TcamSans": "DejaVuSans.ttf",
            "TcamSans-Bold": "DejaVuSans-Bold.ttf",
            "TcamSans-Oblique": "DejaVuSans-Oblique.ttf",
            "TcamSans-BoldOblique": "DejaVuSans-BoldOblique.ttf",
            "TcamMono": "DejaVuSansMono.ttf",
        }
        registered = set(pdfmetrics.getRegisteredFontNames())
        for name, file in files.items():
            if name not in registered:
                pdfmetrics.registerFont(TTFont(name, str(base / file)))
        addMapping("TcamSans", 0, 0, "TcamSans")
        addMapping("TcamSans", 1, 0, "TcamSans-Bold")
        addMapping("TcamSans", 0, 1, "TcamSans-Oblique")
        addMapping("TcamSans", 1, 1, "TcamSans-BoldOblique")
        addMapping("TcamMono", 0, 0, "TcamMono")
        addMapping("TcamMono", 1, 0, "TcamMono")
        addMapping("TcamMono", 0, 1, "TcamMono")
        addMapping("TcamMono", 1, 1, "TcamMono")
        _FONTS = _Fonts("TcamSans", "TcamSans-Bold", "TcamSans-Oblique", "TcamMono")
    except Exception:  # fonts missing or unreadable: fall back to base-14
        _FONTS = _Fonts("Helvetica", "Helvetica-Bold", "Helvetica-Oblique", "Courier")
    return _FONTS


class _Styles:
    def __init__(self) -> None:
        from reportlab.lib import colors
        from reportlab.lib.styles import ParagraphStyle

        f = _fonts()
        self.fonts = f
        body = ParagraphStyle("body", fontName=f.regular, fontSize=9.5, leading=13, spaceAfter=5)
        self.body = body
        self.title = ParagraphStyle(
            "title", parent=body, fontName=f.bold, fontSize=20, leading=24, spaceAfter=4
        )
        self.subtitle = ParagraphStyle(
            "subtitle",
            parent=body,
            fontSize=11.5,
            leading=15,
            textColor=colors.HexColor("#5b6670"),
            spaceAfter=8,
        )
        self.headings = [
            ParagraphStyle(
                f"h{i}",
                parent=body,
                fontName=f.bold,
                fontSize=size,
                leading=size * 1.25,
                spaceBefore=before,
                spaceAfter=4,
                keepWithNext=1,
            )
            for i, (size, before) in enumerate([(15, 14), (12.5, 10), (11, 8), (10, 6)], start=1)
        ]
        self.caption = ParagraphStyle(
            "caption",
            parent=body,
            fontSize=8.5,
            leading=11,
            textColor=colors.HexColor("#3d4750"),
            spaceAfter=8,
        )
        self.table_caption = ParagraphStyle("tcaption", parent=self.caption, spaceAfter=3, keepWithNext=1)
        self.note = ParagraphStyle("note", parent=body, textColor=colors.HexColor("#4d3800"), spaceAfter=0)
        self.banner = ParagraphStyle(
            "banner",
            parent=body,
            fontName=f.bold,
            fontSize=10.5,
            leading=14,
            textColor=colors.HexColor("#7c2d12"),
            spaceAfter=0,
        )
        self._cell_cache: dict[tuple[float, str | None, bool], Any] = {}

    def cell(self, size: float, status: str | None = None, header: bool = False, mono: bool = False):
        from reportlab.lib import colors
        from reportlab.lib.styles import ParagraphStyle

        key = (size, status, header, mono)
        style = self._cell_cache.get(key)
        if style is None:
            font = self.fonts.mono if mono else self.fonts.regular
            if header or status:
                font = self.fonts.bold if not mono else font
            colour = colors.HexColor(_STATUS_COLOURS[status][1]) if status else colors.black
            style = ParagraphStyle(
                f"cell{len(self._cell_cache)}",
                fontName=font,
                fontSize=size,
                leading=size * 1.22,
                textColor=colour,
                spaceAfter=0,
                spaceBefore=0,
                embeddedHyphenation=1,
                splitLongWords=0,
            )
            self._cell_cache[key] = style
        return style


# --------------------------------------------------------------------------
# flowable builders


class _Ctx:
    """Per-build state: styles, numbering, outline keys, cached PNGs."""

    def __init__(self, width: float, height: float, pngs: dict[int, bytes]):
        self.styles = _Styles()
        self.width = width
        self.height = height
        self.pngs = pngs
        self.tables = 0
        self.figures = 0
        self.keys = 0

    def reset_numbers(self) -> None:
        self.tables = 0
        self.figures = 0

    def png(self, fig: Any) -> bytes:
        data = self.pngs.get(id(fig))
        if data is None:
            data = figure_to_png(fig, dpi=PNG_DPI)
            self.pngs[id(fig)] = data
        return data

    def key(self) -> str:
        self.keys += 1
        return f"tcam-{self.keys}"


def _outlined(flowable: Any, title: str, level: int, ctx: _Ctx) -> Any:
    flowable._tcam_outline = (ctx.key(), " ".join(str(title).split()) or "-", level)
    return flowable


def _label(text: str):
    from reportlab.platypus import Flowable

    class _RunningLabel(Flowable):
        """Zero-size flowable that sets the footer label from here on."""

        def wrap(self, availWidth, availHeight):
            return 0, 0

        def draw(self):
            self.canv._doctemplate._tcam_label = text

    return _RunningLabel()


def _boxed(paragraph: Any, ctx: _Ctx, background: str, border: str, left_bar_only: bool) -> Any:
    from reportlab.lib import colors
    from reportlab.platypus import Table as RLTable
    from reportlab.platypus import TableStyle

    box = RLTable([[paragraph]], colWidths=[ctx.width], hAlign="LEFT")
    cmds = [
        ("BACKGROUND", (0, 0), (-1, -1), colors.HexColor(background)),
        ("LEFTPADDING", (0, 0), (-1, -1), 8),
        ("RIGHTPADDING", (0, 0), (-1, -1), 8),
        ("TOPPADDING", (0, 0), (-1, -1), 5),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 6),
    ]
    if left_bar_only:
        cmds.append(("LINEBEFORE", (0, 0), (0, -1), 3, colors.HexColor(border)))
    else:
        cmds.append(("BOX", (0, 0), (-1, -1), 1.5, colors.HexColor(border)))
    box.setStyle(TableStyle(cmds))
    box.spaceBefore = 3
    box.spaceAfter = 6
    return box


_BREAK_AFTER_HYPHEN = re.compile(r"(?<=[^\W\d_]-)(?=[^\W\d_])")

MIN_CELL_FONT = 5.0
"""Smallest table font [pt]: a table whose words do not fit shrinks to this before anything else."""


def _pieces(text: str) -> list[str]:
    """The unbreakable pieces of a cell: words split at spaces, and after a hyphen between
    letters (reportlab's ``embeddedHyphenation``); never inside a token such as a file name
    or a number (``-7.769e-04`` stays whole: its column is made wide enough)."""
    return [p for w in text.split() for p in _BREAK_AFTER_HYPHEN.split(w)] or [""]


def _col_widths(
    header: Sequence[str], rows: Sequence[Sequence[Cell]], width: float, size: float, fonts: Sequence[str]
) -> list[float] | None:
    """Column widths at font ``size`` from measured text, each at least its widest unbreakable
    piece; None when those pieces alone do not fit ``width``.

    ``fonts`` is (header font, font per column, status-cell font per column): cells are
    measured in the font they are drawn in (bold for headers and status cells), so no word is
    cut mid-token.
    """
    from reportlab.pdfbase.pdfmetrics import stringWidth

    bold, col_fonts, status_fonts = fonts
    pad = 8.0 + 1.5  # left + right padding, plus slack
    natural: list[float] = []
    minimal: list[float] = []
    for j, head in enumerate(header):
        word_min = max(stringWidth(w, bold, size) for w in _pieces(head))
        widest = max(stringWidth(line, bold, size) for line in head.split("\n"))
        for row in rows:
            font = status_fonts[j] if row[j].status else col_fonts[j]
            text = row[j].text
            widest = max(widest, max(stringWidth(line[:80], font, size) for line in text.split("\n")))
            word_min = max(word_min, max(stringWidth(w, font, size) for w in _pieces(text)))
        natural.append(max(min(widest, 260.0), word_min) + pad)
        minimal.append(word_min + pad)
    if sum(natural) <= width:
        return natural
    if sum(minimal) > width:
        return None
    spare = width - sum(minimal)
    extra = [n - m for n, m in zip(natural, minimal)]
    total = sum(extra) or 1.0
    return [m + spare * e / total for m, e in zip(minimal, extra)]


def _fit_table(header, rows, ctx: _Ctx, mono: set[int], size: float) -> tuple[float, list[float]]:
    """The largest font size from ``size`` down to :data:`MIN_CELL_FONT` at which every
    unbreakable piece fits its column, and the widths; at the smallest size, the minimal widths
    scaled to the page (only a single piece wider than the page is then cut)."""
    f = ctx.styles.fonts
    col_fonts = [f.mono if j in mono else f.regular for j in range(len(header))]
    fonts = (f.bold, col_fonts, [f.mono if j in mono else f.bold for j in range(len(header))])
    while True:
        widths = _col_widths(header, rows, ctx.width, size, fonts)
        if widths is not None:
            return size, widths
        if size - 0.5 < MIN_CELL_FONT:
            break
        size -= 0.5
    from reportlab.pdfbase.pdfmetrics import stringWidth

    minimal = [
        max(
            stringWidth(w, col_fonts[j], size)
            for r in [[Cell(h) for h in header], *rows]
            for w in _pieces(r[j].text)
        )
        + 9.5
        for j in range(len(header))
    ]
    return size, _squeezed(minimal, ctx.width, stringWidth("0.000", f.regular, size) + 9.5)


def _squeezed(minimal: list[float], width: float, floor: float) -> list[float]:
    """Column widths [pt] summing to ``width`` when the ``minimal`` ones do not fit: every column
    keeps at least ``floor`` (a column narrower than its cell padding cannot be drawn at all:
    one cell holding a 20-digit figure squeezed a table's other seven to 4 pt), the rest of the
    width shared in proportion to what each column asks beyond it (its long pieces are cut)."""
    floor = min(floor, width / len(minimal))
    extra = [max(m - floor, 0.0) for m in minimal]
    spare = width - floor * len(minimal)
    total = sum(extra) or 1.0
    return [floor + spare * e / total for e in extra]


def _cell_markup(cell: Cell) -> str:
    text = esc(cell.text)
    href = safe_href(cell.href)
    if href and not href.startswith("#"):
        return f'<a href="{_attr(href)}" color="#0b5cad">{text}</a>'
    return text


def _grid_table(
    header: Sequence[str], rows: Sequence[Sequence[Cell]], ctx: _Ctx, mono_cols: Iterable[int] = ()
) -> Any:
    from reportlab.lib import colors
    from reportlab.platypus import Paragraph, TableStyle
    from reportlab.platypus import Table as RLTable

    st = ctx.styles
    ncols = len(header)
    mono = set(mono_cols)
    size, widths = _fit_table(header, rows, ctx, mono, 8.5 if ncols <= 6 else 7.5 if ncols <= 10 else 6.5)
    data = [[Paragraph(esc(h), st.cell(size, header=True)) for h in header]]
    cmds: list[tuple] = [
        ("GRID", (0, 0), (-1, -1), 0.5, colors.HexColor("#9aa5b1")),
        ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#e6ebf0")),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("LEFTPADDING", (0, 0), (-1, -1), 4),
        ("RIGHTPADDING", (0, 0), (-1, -1), 4),
        ("TOPPADDING", (0, 0), (-1, -1), 2.5),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 3),
    ]
    for i, row in enumerate(rows, start=1):
        line = []
        for j, cell in enumerate(row):
            line.append(Paragraph(_cell_markup(cell), st.cell(size, cell.status, mono=j in mono)))
            if cell.status:
                cmds.append(("BACKGROUND", (j, i), (j, i), colors.HexColor(_STATUS_COLOURS[cell.status][0])))
        data.append(line)
    table = RLTable(data, colWidths=widths, repeatRows=1, hAlign="LEFT")
    table.setStyle(TableStyle(cmds))
    table.spaceBefore = 2
    table.spaceAfter = 10
    return table


def _table_flowables(table: Table, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Paragraph

    ctx.tables += 1
    st = ctx.styles
    caption = f"<b>Table {ctx.tables}.</b>"
    if table.caption:
        caption += " " + esc(table.caption)
    out: list[Any] = [Paragraph(caption, st.table_caption)]
    if not table.columns:
        out.append(Paragraph("(empty table)", st.body))
        return out
    out.append(_grid_table(table.columns, table.formatted_rows(), ctx))
    return out


def _figure_flowables(fig: Figure, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Image, Paragraph

    ctx.figures += 1
    data = ctx.png(fig.figure)
    w_in, h_in = figure_size_in(fig.figure)
    width = ctx.width
    height = width * h_in / w_in if w_in > 0 else width * 0.56
    max_h = ctx.height * 0.8
    if height > max_h:
        width, height = width * max_h / height, max_h
    image = Image(io.BytesIO(data), width=width, height=height)
    image.hAlign = "CENTER"
    caption = f"<b>Figure {ctx.figures}.</b>"
    if fig.caption:
        caption += " " + esc(fig.caption)
    # keepWithNext instead of a KeepTogether: reportlab groups a heading only with a plain
    # flowable after it (a KeepTogether is a container it skips), which left headings orphaned.
    image.keepWithNext = 1
    return [image, Paragraph(caption, ctx.styles.caption)]


def _section_flowables(section: Section, path: tuple[int, ...], level: int, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Paragraph

    st = ctx.styles
    number = ".".join(str(i) for i in path)
    style = st.headings[min(len(path), len(st.headings)) - 1]
    heading = Paragraph(f"{number}&nbsp;&nbsp;{esc(section.heading)}", style)
    out: list[Any] = [_outlined(heading, f"{number} {section.heading}", level, ctx)]
    for w in section.warnings:
        out.append(
            _boxed(
                Paragraph(f"<b>Warning:</b> {esc(w)}", st.note), ctx, "#fdebe3", "#c2410c", left_bar_only=True
            )
        )
    for note in section.notes:
        out.append(
            _boxed(
                Paragraph(f"<b>Note:</b> {esc(note)}", st.note), ctx, "#fff4d6", "#d69e00", left_bar_only=True
            )
        )
    for para in section.paragraphs:
        out.append(Paragraph(esc(para), st.body))
    for table in section.tables:
        out.extend(_table_flowables(table, ctx))
    for fig in section.figures:
        out.extend(_figure_flowables(fig, ctx))
    for i, sub in enumerate(section.subsections, start=1):
        out.extend(_section_flowables(sub, path + (i,), level + 1, ctx))
    return out


def _metadata_flowables(metadata, level: int, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Paragraph

    if not metadata:
        return []
    heading = Paragraph("Provenance", ctx.styles.headings[0])
    rows = [[Cell(str(k)), Cell(str(v))] for k, v in metadata.items()]
    return [
        _outlined(heading, "Provenance", level, ctx),
        _grid_table(["Key", "Value"], rows, ctx, mono_cols=(1,)),
    ]


def _document_flowables(doc: Document, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Paragraph

    st = ctx.styles
    ctx.reset_numbers()
    out: list[Any] = [_label(doc.title)]
    out.append(_outlined(Paragraph(esc(doc.title), st.title), doc.title, 0, ctx))
    if doc.subtitle:
        out.append(Paragraph(esc(doc.subtitle), st.subtitle))
    if doc.synthetic_banner:
        out.append(_banner(doc.synthetic_banner, ctx))
    for i, section in enumerate(doc.sections, start=1):
        out.extend(_section_flowables(section, (i,), 1, ctx))
    out.extend(_metadata_flowables(doc.metadata, 1, ctx))
    return out


def _index_flowables(index: IndexDocument, ctx: _Ctx) -> list[Any]:
    from reportlab.platypus import Paragraph

    st = ctx.styles
    out: list[Any] = [_label(index.title)]
    out.append(_outlined(Paragraph(esc(index.title), st.title), index.title, 0, ctx))
    if index.synthetic_banner:
        out.append(_banner(index.synthetic_banner, ctx))
    out.append(Paragraph(esc(index.summary()), st.subtitle))
    metric_names = index.metric_names() or (["Error"] if any(e.error for e in index.entries) else [])
    header = ["Experiment", "Kind", "Status", "Warnings", *metric_names]
    rows = []
    for e in index.entries:
        if e.error:  # the one-line error in place of the metrics
            metrics = [Cell(e.error, "fail")] + [Cell("") for _ in metric_names[1:]]
        else:
            metrics = [Cell(str(e.metrics[m])) if m in e.metrics else Cell(MISSING) for m in metric_names]
        rows.append(
            [
                Cell(f"{e.name}\n{e.title}"),
                Cell(e.kind),
                _index_status(e.status, e.status_label),
                Cell(str(len(e.warnings)), "warn" if e.warnings else None),
                *metrics,
            ]
        )
    out.append(_grid_table(header, rows, ctx))
    out.extend(_metadata_flowables(index.metadata, 1, ctx))
    return out


def _index_status(status: str, label: str) -> Cell:
    # Cell statuses are pass/fail/warn; an "error" entry is shown like a failure, "no limits" neutral.
    return Cell(label, {"pass": "pass", "fail": "fail", "error": "fail"}.get(status))


def _banner(text: str, ctx: _Ctx) -> Any:
    from reportlab.platypus import Paragraph

    return _boxed(Paragraph(esc(text), ctx.styles.banner), ctx, "#fff1e6", "#c2410c", left_bar_only=False)


# --------------------------------------------------------------------------
# building


def _keep_class():
    from reportlab.platypus import KeepTogether
    from reportlab.platypus.doctemplate import FrameBreak

    class _KeepWithNext(KeepTogether):
        """keepWithNext group that lets an oversized last item (a long table) split.

        reportlab's default moves a heading + caption + long table to a new
        page even when the table would have to split anyway, leaving a
        mostly blank page.  Here, when the group cannot fit on any page, it
        starts in place as long as the lead-in plus ~5 lines of the last item
        fit; otherwise it starts on a new frame.
        """

        MIN_TAIL = 72.0
        IN_PLACE_SHARE = 0.5
        """A table that would fit on a page of its own still starts in place when at least
        this share of the page is left: moved whole, it left the benchmark report's first
        page three-quarters blank."""

        def split(self, aW, aH):
            from reportlab.platypus import Table

            if getattr(self, "_wrapInfo", None) != (aW, aH):
                self.wrap(aW, aH)
            frame = getattr(self, "_frame", None)
            if frame is None or len(self._content) < 2:
                return KeepTogether.split(self, aW, aH)
            last = self._content[-1]
            fits_a_page = self._H <= frame._height
            if fits_a_page and not (isinstance(last, Table) and aH >= self.IN_PLACE_SHARE * frame._height):
                return KeepTogether.split(self, aW, aH)
            _, last_h = last.wrapOn(self.canv, aW, 0x7FFFFFFF)
            lead = self._H - last_h - last.getSpaceBefore() - last.getSpaceAfter()
            content = list(self._content)
            if lead + self.MIN_TAIL <= aH:
                return content
            return [FrameBreak()] + content

    return _KeepWithNext


# --------------------------------------------------------------------------


def _build(make_flowables: Callable[[_Ctx], list[Any]], title: str, subject: str) -> bytes:
    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.platypus import BaseDocTemplate, Frame, PageTemplate

    fonts = _fonts()
    pngs: dict[int, bytes] = {}

    class _Doc(BaseDocTemplate):
        def afterFlowable(self, flowable):
            info = getattr(flowable, "_tcam_outline", None)
            if info:
                key, text, level = info
                self.canv.bookmarkPage(key)
                if not getattr(self, "_tcam_outline_shown", False):
                    self.canv.showOutline()
                    self._tcam_outline_shown = True
                self.canv.addOutlineEntry(text, key, level=level, closed=level >= 1)

    def run(total: int | None) -> tuple[bytes, int]:
        buf = io.BytesIO()
        doc = _Doc(
            buf,
            pagesize=A4,
            leftMargin=18 * mm,
            rightMargin=18 * mm,
            topMargin=16 * mm,
            bottomMargin=18 * mm,
            invariant=1,
            title=title,
            author="tcamlab",
            creator="tcamlab",
            producer="tcamlab",
            subject=subject,
            keywords=[],
            lang="en",
            displayDocTitle=1,
            keepTogetherClass=_keep_class(),
        )
        doc._tcam_label = title

        def footer(canv, d):
            canv.saveState()
            canv.setFont(fonts.regular, 7.5)
            canv.setFillColor(colors.HexColor("#5b6670"))
            y = 10 * mm
            label = " ".join(str(getattr(d, "_tcam_label", "")).split())
            if len(label) > 90:
                label = label[:89] + "\u2026"
            canv.drawString(d.leftMargin, y, label)
            page = f"Page {d.page}" + (f" of {total}" if total else "")
            canv.drawRightString(d.pagesize[0] - d.rightMargin, y, page)
            canv.setStrokeColor(colors.HexColor("#d5dbe1"))
            canv.setLineWidth(0.5)
            canv.line(d.leftMargin, y + 9, d.pagesize[0] - d.rightMargin, y + 9)
            canv.restoreState()

        frame = Frame(doc.leftMargin, doc.bottomMargin, doc.width, doc.height, id="body")
        doc.addPageTemplates([PageTemplate(id="page", frames=[frame], onPageEnd=footer)])
        ctx = _Ctx(doc.width, doc.height, pngs)
        flowables = make_flowables(ctx)
        doc.build(flowables)
        return buf.getvalue(), doc.page

    with _without_source_date_epoch():
        _, pages = run(None)
        data, pages2 = run(pages)
        if pages2 != pages:  # footer text cannot change layout, but be safe
            data, _ = run(pages2)
    return data


@contextlib.contextmanager
def _without_source_date_epoch():
    """Hide ``SOURCE_DATE_EPOCH`` from reportlab while a PDF is built.

    reportlab stamps CreationDate/ModDate from ``SOURCE_DATE_EPOCH`` even in
    invariant mode. tcamlab's outputs embed no date at all (they depend only
    on the inputs), so the variable must not change a single byte; with it
    hidden, invariant mode uses its fixed date (2000-01-01).
    """
    saved = os.environ.pop("SOURCE_DATE_EPOCH", None)
    try:
        yield
    finally:
        if saved is not None:
            os.environ["SOURCE_DATE_EPOCH"] = saved


def render_pdf(doc: Document) -> bytes:
    """Render one report as PDF bytes (reproducible)."""
    return _build(lambda ctx: _document_flowables(doc, ctx), doc.title, doc.subtitle)


def render_combined_pdf(docs: Sequence[Document], index: IndexDocument | None = None) -> bytes:
    """One PDF: the index table first (if given), then each report on a new page.

    Every report (and the index) is a top-level outline entry with its
    sections nested below.
    """
    from reportlab.platypus import PageBreak

    def make(ctx: _Ctx) -> list[Any]:
        out: list[Any] = []
        if index is not None:
            out.extend(_index_flowables(index, ctx))
        for doc in docs:
            if out:
                out.append(PageBreak())
            out.extend(_document_flowables(doc, ctx))
        if not out:
            from reportlab.platypus import Paragraph

            out.append(Paragraph("No reports.", ctx.styles.body))
        return out

    title = index.title if index is not None else "tcamlab reports"
    return _build(make, title, f"{len(docs)} reports")
