"""Deterministic matplotlib figures for reports.

matplotlib is imported lazily so that importing this module stays cheap.
Figures are made with :class:`matplotlib.figure.Figure` and an Agg canvas
(never pyplot), so no GUI backend or global figure registry is involved.

Plot inside :func:`report_style` if you want the artists themselves (line
widths, font sizes, colours) to ignore any user ``matplotlibrc``::

    with report_style():
        fig, ax = new_figure()
        ax.plot(x, y)
"""

from __future__ import annotations

import contextlib
import io
import re
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Fixed rcParams applied when figures are created and saved.
STYLE: dict[str, Any] = {
    "font.family": "sans-serif",
    "font.sans-serif": ["DejaVu Sans"],
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.6,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.prop_cycle": None,  # filled in lazily (needs matplotlib's cycler)
    "lines.linewidth": 1.4,
    "lines.markersize": 4.0,
    "legend.fontsize": 8.0,
    "legend.frameon": False,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "figure.dpi": 100.0,
    "figure.facecolor": "white",
    "axes.facecolor": "white",
    "savefig.facecolor": "white",
    "savefig.edgecolor": "white",
    "savefig.bbox": None,
    "savefig.pad_inches": 0.1,
    "svg.fonttype": "path",
    "svg.image_inline": True,
    "path.simplify": True,
    "text.usetex": False,
}

_PALETTE = [
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#ff7f0e",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
]


def _rc(extra: dict[str, Any] | None = None) -> dict[str, Any]:
    from cycler import cycler

    rc = dict(STYLE)
    rc["axes.prop_cycle"] = cycler(color=_PALETTE)
    if extra:
        rc.update(extra)
    return rc


@contextlib.contextmanager
def report_style(**extra: Any) -> Iterator[None]:
    """Context manager applying the fixed report rcParams (plus *extra*)."""
    import matplotlib

    with matplotlib.rc_context(_rc(extra)):
        yield


def new_figure(width_in: float = 6.4, height_in: float = 3.6) -> tuple[Figure, Axes]:
    """A new figure with one axes, attached to an Agg canvas (no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    with report_style():
        fig = Figure(figsize=(width_in, height_in), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
    return fig, ax


_XML_HEAD = re.compile(r"^\s*<\?xml[^>]*\?>\s*", re.S)
_DOCTYPE = re.compile(r"^\s*<!DOCTYPE[^>]*>\s*", re.S)
_METADATA = re.compile(r"\s*<metadata>.*?</metadata>", re.S)
_ID = re.compile(r'\bid="([^"]+)"')
_HREF = re.compile(r'\b((?:xlink:)?href)="#([^"]+)"')
_URL = re.compile(r"url\(#([^)]+)\)")


_HASHED = re.compile(r"^([A-Za-z]+)[0-9a-f]{10}$")


def _prefix_ids(svg: str, prefix: str) -> str:
    """Prefix every id (and reference to it) with *prefix*.

    matplotlib's hashed ids (clip paths, markers, hatches) are derived from
    float coordinates and can change between two saves of the same figure,
    so they are renumbered in order of first appearance.
    """
    ids = _ID.findall(svg)
    known = set(ids)
    renamed: dict[str, str] = {}
    counters: dict[str, int] = {}
    for token in re.findall(r'(?:id="|href="#|url\(#)([^")]+)', svg):
        if token in known and token not in renamed:
            m = _HASHED.match(token)
            if m:
                kind = m.group(1)
                counters[kind] = counters.get(kind, 0) + 1
                renamed[token] = f"{kind}-h{counters[kind]}"
            else:
                renamed[token] = token

    def ref(name: str) -> str:
        return prefix + renamed.get(name, name) if name in known else name

    svg = _ID.sub(lambda m: f'id="{ref(m.group(1))}"', svg)
    svg = _HREF.sub(lambda m: f'{m.group(1)}="#{ref(m.group(2))}"', svg)
    svg = _URL.sub(lambda m: f"url(#{ref(m.group(1))})", svg)
    return svg


_CHARMAP: list[frozenset[int]] = []


def drawable(text: str) -> str:
    """``text`` with each character the report font lacks written as its code point
    (a run file named in CJK: ``試験1`` -> ``U+8A66U+9A131``), so no glyph goes missing
    (matplotlib would warn and draw an empty box)."""
    if text.isascii():
        return text
    if not _CHARMAP:
        from matplotlib import font_manager, ft2font

        path = font_manager.findfont(font_manager.FontProperties(family=STYLE["font.sans-serif"]))
        _CHARMAP.append(frozenset(ft2font.FT2Font(path).get_charmap()))
    known = _CHARMAP[0]
    return "".join(c if c.isascii() or ord(c) in known else f"U+{ord(c):04X}" for c in text)


def replace_missing_glyphs(fig: Figure) -> None:
    """Every text of ``fig`` made :func:`drawable`."""
    from matplotlib.text import Text

    for t in fig.findobj(Text):
        text = t.get_text()
        if isinstance(text, str) and drawable(text) != text:
            t.set_text(drawable(text))


def _freeze_layout(fig: Figure) -> None:
    """Run the figure's layout engine once, then keep that layout.

    Constrained layout can move axes by a few ulps on every draw, which
    would make repeated renders of the same figure differ.  The first time a
    figure is rendered here it is made compact (:func:`compact_figure`), its
    layout is computed and then frozen.
    """
    if getattr(fig, "_tcamlab_layout_frozen", False):
        return
    replace_missing_glyphs(fig)
    compact_figure(fig)
    engine = fig.get_layout_engine()
    if engine is not None and type(engine).__name__ != "PlaceHolderLayoutEngine":
        with report_style():
            fig.draw_without_rendering()
        fig.set_layout_engine("none")
    fig._tcamlab_layout_frozen = True


def figure_to_svg(fig: Figure, index: int = 0) -> str:
    """Render *fig* as an SVG fragment ready to inline in HTML.

    The output is deterministic (fixed hash salt, no date, no metadata
    block, no XML header/doctype).  Every ``id`` is prefixed with
    ``svg{index}-`` (and references rewritten), so several figures can be
    inlined in one page as long as each gets a distinct *index*.
    """
    _freeze_layout(fig)
    buf = io.StringIO()
    with report_style(**{"svg.hashsalt": f"tcamlab-{index}"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    svg = buf.getvalue()
    svg = _XML_HEAD.sub("", svg, count=1)
    svg = _DOCTYPE.sub("", svg, count=1)
    svg = _METADATA.sub("", svg, count=1)
    return _prefix_ids(svg, f"svg{index}-").strip() + "\n"


def figure_to_png(fig: Figure, dpi: int = 150) -> bytes:
    """Render *fig* as PNG bytes (deterministic: no software/date chunks)."""
    _freeze_layout(fig)
    buf = io.BytesIO()
    with report_style():
        fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return buf.getvalue()


def figure_size_in(fig: Figure) -> tuple[float, float]:
    """(width, height) of *fig* in inches."""
    w, h = fig.get_size_inches()
    return float(w), float(h)


def legend_label(name: str) -> str:
    """A run name (a file stem, so user text) made safe as a matplotlib legend label.

    matplotlib hides artists whose label starts with '_' from the legend; a
    leading space keeps such runs visible. Mathtext ('$...$') is switched off
    where report figures are drawn.
    """
    return " " + name if name.startswith("_") else name


BAND_MAX_POINTS = 2000
"""Most columns a shaded band is drawn with; a longer band is drawn as its min/max envelope."""


def draw_band(ax, x, lower, upper, *, label: str | None = None, color=None, alpha: float = 0.18):
    """Shade a band between ``lower`` and ``upper`` (a legend entry when ``label`` is given).

    A band longer than :data:`BAND_MAX_POINTS` is drawn as the envelope of
    consecutive blocks (lowest lower, highest upper per block), so a long log
    stays a small figure and never looks narrower than it is.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    x, lower, upper : array_like
        Abscissa and the band's bounds, in plot units.
    label : str, optional
        Legend text, e.g. ``"95% prediction band"``.
    color : optional
        Fill colour (default: the axes' next colour).
    alpha : float
        Fill opacity.

    Returns
    -------
    matplotlib.collections.PolyCollection
    """
    import numpy as np

    x, lo, hi = (np.asarray(a, float) for a in (x, lower, upper))
    if x.size > BAND_MAX_POINTS:
        edges = np.linspace(0, x.size, BAND_MAX_POINTS + 1).astype(int)[:-1]
        x = x[edges]
        lo, hi = np.minimum.reduceat(lo, edges), np.maximum.reduceat(hi, edges)
    kw = {"alpha": alpha, "linewidth": 0}
    if color is not None:
        kw["color"] = color
    if label is not None:
        kw["label"] = label
    return ax.fill_between(x, lo, hi, **kw)


ENVELOPE_COLUMNS_PER_INCH = 200
"""Columns per inch of axes width a long series is reduced to (its min and max in each)
[1/in]: 1.3 columns per pixel of a 150 dpi PNG, finer than a screen shows."""

ENVELOPE_MIN_POINTS_PER_COLUMN = 4
"""A series is drawn as its envelope only when it has more points than this many per
column [-]; a shorter one keeps every point (its markers stay visible)."""

DENSE_POINTS_ALPHA = 0.4
"""Opacity of the envelope that replaces a dense point series [-]."""

LEGEND_MAX_ENTRIES = 6
"""Most entries in a legend; more are grouped by what they show (one entry per group) [-]."""

LEGEND_MIN_FONT_PT = 8.0
"""Smallest legend font at the saved size [pt] (figures are saved at their own size)."""

MIN_MARKER_PT = 2.0
"""Smallest drawn diameter of a marker [pt] (matplotlib's '.' is half its markersize)."""


def envelope(x, y, columns: int):
    """Min and max of ``y`` in each of ``columns`` equal-width bins of ``x``.

    Non-finite points are left out; an empty bin gives NaN (a gap when drawn).

    Parameters
    ----------
    x, y : array_like
        Abscissa and ordinate, in plot units, any order.
    columns : int
        Number of bins across the finite range of ``x``.

    Returns
    -------
    (ndarray, ndarray, ndarray)
        Bin centres, the lowest and the highest ``y`` of each bin, shape (columns,).
    """
    import numpy as np

    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.all():
        x, y = x[ok], y[ok]
    lo = np.full(columns, np.nan)
    hi = np.full(columns, np.nan)
    if x.size == 0:
        return np.zeros(columns), lo, hi
    x0, x1 = float(x.min()), float(x.max())
    span = x1 - x0 if x1 > x0 else 1.0
    col = np.minimum(((x - x0) * (columns / span)).astype(np.int64), columns - 1)
    if np.any(col[1:] < col[:-1]):
        order = np.argsort(col, kind="stable")  # unsorted x (e.g. residuals against temperature)
        col, y = col[order], y[order]
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    used = col[starts]
    lo[used] = np.minimum.reduceat(y, starts)
    hi[used] = np.maximum.reduceat(y, starts)
    centres = x0 + (np.arange(columns) + 0.5) * (span / columns)
    return centres, lo, hi


def _line_colour(line):
    if line.get_linestyle() in ("None", "", " "):
        return line.get_markerfacecolor()
    return line.get_color()


def _envelope_line(ax, line, columns: int) -> None:
    """Replace a long Line2D by its per-column min/max envelope in the same colour and
    layer (an edge of the line's width keeps a flat stretch visible)."""
    xc, lo, hi = envelope(line.get_xdata(orig=True), line.get_ydata(orig=True), columns)
    dense_points = line.get_linestyle() in ("None", "", " ")
    width = 0.6 if dense_points else line.get_linewidth()
    colour = _line_colour(line)
    ax.fill_between(
        xc,
        lo,
        hi,
        step="mid",
        facecolor=colour,
        edgecolor=colour,
        linewidth=width,
        # the points' envelope lighter, so that a model line drawn over it stays distinct
        alpha=DENSE_POINTS_ALPHA if dense_points else line.get_alpha(),
        zorder=line.get_zorder(),
        gid="envelope",
    )
    line.remove()


def _is_points(line) -> bool:
    """A series drawn as markers only (measured points)."""
    return line.get_linestyle() in ("None", "", " ") and line.get_marker() not in ("None", "", None)


def compact_figure(fig: Figure) -> None:
    """Make ``fig`` compact and readable whatever the length of its series.

    * a line or point series with more than :data:`ENVELOPE_MIN_POINTS_PER_COLUMN`
      points per column (:data:`ENVELOPE_COLUMNS_PER_INCH` columns per inch of axes
      width) is replaced by its min/max envelope per column (:func:`envelope`), so
      the figure's size does not grow with the log while every extreme stays drawn;
    * markers of the remaining point series are at least :data:`MIN_MARKER_PT` wide;
    * every legend is rebuilt with at most :data:`LEGEND_MAX_ENTRIES` entries
      (:func:`group_legend_entries`) at no less than :data:`LEGEND_MIN_FONT_PT`.

    Called once per figure before it is first rendered (:func:`figure_to_svg`,
    :func:`figure_to_png`); a second call changes nothing.
    """
    if getattr(fig, "_tcamlab_compact", False):
        return
    for ax in fig.axes:
        linear = ax.get_xscale() == "linear" and ax.get_yscale() == "linear"
        columns = max(100, int(ax.get_position().width * fig.get_figwidth() * ENVELOPE_COLUMNS_PER_INCH))
        has_points = any(_is_points(line) for line in ax.get_lines())
        for line in list(ax.get_lines()):
            if has_points and not _is_points(line) and line.get_zorder() == 2:
                line.set_zorder(2.2)  # a model line over the measured points, not hidden by them
            n = len(line.get_xdata(orig=True))
            if linear and n > ENVELOPE_MIN_POINTS_PER_COLUMN * columns:
                _envelope_line(ax, line, columns)
            elif _is_points(line):
                scale = 0.5 if line.get_marker() in (".", ",") else 1.0
                line.set_markersize(max(line.get_markersize(), MIN_MARKER_PT / scale))
        legend = ax.get_legend()
        if legend is not None:
            _rebuild_legend(ax, legend)
    fig._tcamlab_compact = True


def group_legend_entries(handles, labels, max_entries: int = LEGEND_MAX_ENTRIES):
    """At most ``max_entries`` legend entries, grouping runs.

    An entry's label is read as ``"RUN what"`` (first word: the run). With more
    entries than allowed, entries showing the same ``what`` become one entry whose
    handle is the tuple of theirs (drawn side by side, colours left to right) and
    whose label names the runs (up to four in 32 characters; else the first and the last); entries without a ``what`` group as
    runs. Groups beyond the limit are merged into one last entry.

    Returns
    -------
    (list, list)
        Handles (an artist or a tuple of artists) and labels.
    """
    if len(labels) <= max_entries:
        return list(handles), list(labels)
    groups: dict[str, list] = {}
    for h, lab in zip(handles, labels):
        run, _, what = lab.strip().partition(" ")
        groups.setdefault(what, []).append((h, run, lab))
    out_h, out_l = [], []
    for what, members in groups.items():
        if len(members) == 1:
            out_h.append(members[0][0])
            out_l.append(members[0][2])
            continue
        runs = [m[1] for m in members]
        listed = ", ".join(runs)
        # a long list (many runs, or long run names) keeps only its ends, so the legend fits
        span = f"{runs[0]} … {runs[-1]}" if len(runs) > 4 or len(listed) > 32 else listed
        out_h.append(tuple(m[0] for m in members))
        out_l.append(f"{what or 'runs'}: {span} ({len(runs)} runs, colours left to right)")
    if len(out_l) > max_entries:
        rest_h = tuple(h for hs in out_h[max_entries - 1 :] for h in (hs if isinstance(hs, tuple) else (hs,)))
        out_h = out_h[: max_entries - 1] + [rest_h]
        out_l = out_l[: max_entries - 1] + [f"{len(rest_h)} more series"]
    return out_h, out_l


def _rebuild_legend(ax, legend) -> None:
    """Redraw an axes' legend grouped (:func:`group_legend_entries`), font >= 8 pt, same place."""
    from matplotlib.legend_handler import HandlerTuple

    labels = [t.get_text() for t in legend.get_texts()]
    for h in legend.legend_handles:
        if hasattr(h, "set_markersize") and h.get_marker() not in ("None", "", None):
            scale = 0.5 if h.get_marker() in (".", ",") else 1.0
            h.set_markersize(max(h.get_markersize(), 1.5 * MIN_MARKER_PT / scale))
    if len(labels) <= LEGEND_MAX_ENTRIES:
        # few enough: keep the legend where and as it is drawn, only the font made readable
        for t in legend.get_texts():
            t.set_fontsize(max(t.get_fontsize(), LEGEND_MIN_FONT_PT))
        return
    # run names are user text: keep mathtext off where the figure was drawn with it off
    parse_math = all(t.get_parse_math() for t in legend.get_texts())
    handles, labels = group_legend_entries(list(legend.legend_handles), labels)
    size = max(legend.get_texts()[0].get_fontsize() if labels else 0.0, LEGEND_MIN_FONT_PT)
    grouped = any(isinstance(h, tuple) for h in handles)
    ncols = min(getattr(legend, "_ncols", 1), len(labels)) or 1
    with report_style():
        ax.legend(
            handles,
            labels,
            loc=legend._loc,
            bbox_to_anchor=legend._bbox_to_anchor,
            ncols=1 if grouped else ncols,
            fontsize=size,
            frameon=legend.get_frame_on(),
            handler_map={tuple: HandlerTuple(ndivide=None)},
            handlelength=4.0 if grouped else None,
        )
    for t in ax.get_legend().get_texts():
        t.set_parse_math(parse_math)
