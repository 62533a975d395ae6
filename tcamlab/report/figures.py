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


def _freeze_layout(fig: Figure) -> None:
    """Run the figure's layout engine once, then keep that layout.

    Constrained layout can move axes by a few ulps on every draw, which
    would make repeated renders of the same figure differ.  The first time a
    figure is rendered here its layout is computed and then frozen.
    """
    if getattr(fig, "_tcamlab_layout_frozen", False):
        return
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
