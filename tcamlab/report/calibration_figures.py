"""Figures of the calibration report: overlays, residuals, profiles, correlation.

Every figure is a :class:`matplotlib.figure.Figure` on an Agg canvas (through
:func:`tcamlab.report.figures.new_figure`'s style), drawn with mathtext off so
run names (file names, user text) are shown as they are. Values are shown in
lab units (:mod:`tcamlab.units`); legends have at most four entries, drawn once
per figure. Logs longer than :data:`MAX_ROWS` rows per run are drawn as the lowest
and highest point of each bin (:func:`envelope`; model curves every k-th row), said
in the caption, so a report stays small and no outlier is lost.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tcamlab.report.figures import legend_label, report_style
from tcamlab.units import display, parameter_unit

__all__ = [
    "MAX_ROWS",
    "RASTER",
    "DISPLAY_UNITS",
    "quantity_display",
    "parameter_display",
    "pretty_symbol",
    "stride",
    "envelope",
    "overlay_figure",
    "residual_figure",
    "profile_figure",
    "correlation_figure",
]

MAX_ROWS = 2000
"""Most rows per run drawn in an overlay or residual panel."""

RASTER = 500
"""Point layers with more markers than this are embedded as images in SVG (small files)."""

DISPLAY_UNITS = {"force": ("mN", 1e3)}
"""Quantities shown in a smaller unit than their log column (load-cell zeros are mN)."""

COLOURS = {"measured": "0.45", "stated": "#d95f02", "calibrated": "#1b6fb3", "band": "0.85"}

_GREEK = {"lambda": "\u03bb", "rho": "\u03c1", "tau": "\u03c4"}

_NAMES = {
    "time": "time",
    "temperature": "temperature",
    "displacement": "displacement",
    "force": "force",
    "cable": "cable pull",
    "resistance": "resistance",
    "kappa1": "curvature \u03ba1",
    "kappa2": "curvature \u03ba2",
}


def quantity_display(q: str) -> tuple[str, float]:
    """(lab unit, factor from SI) a quantity is drawn and tabulated in."""
    return DISPLAY_UNITS.get(q) or display(q)


def _label(q: str) -> str:
    unit, _ = quantity_display(q)
    return f"{_NAMES.get(q, q)} [{unit}]" if unit else _NAMES.get(q, q)


def pretty_symbol(symbol: str) -> str:
    """A parameter symbol for a figure: Greek letters as such (``lambda`` -> λ)."""
    return " ".join(_GREEK.get(w, w) for w in symbol.split(" "))


_SUPERSCRIPT = str.maketrans(
    "-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079"
)


def parameter_display(p) -> tuple[str, float]:
    """(unit label, factor from SI) of a parameter estimate in lab units.

    Values far from 1 (below 1e-3 or from 1e4) get a power of ten in the unit,
    ``×10⁻⁵ 1/K``, so a table row or an axis reads ``8.21`` rather than ``8.21e-05``.
    """
    unit, factor = parameter_unit(p.field)
    v = abs(p.value * factor)
    if v == 0 or 1e-3 <= v < 1e4 or not math.isfinite(v):
        return unit, factor
    exp = math.floor(math.log10(v))
    return f"\u00d710{str(exp).translate(_SUPERSCRIPT)} {unit}", factor / 10.0**exp


def _marker(n: int) -> float:
    """Marker size [pt]: larger for short logs, so a dozen points stay visible."""
    return 4.0 if n < 100 else 3.0 if n < 500 else 2.2


def stride(n: int) -> int:
    """Every how many rows a model curve of ``n`` rows is drawn (1 up to :data:`MAX_ROWS`)."""
    return max(1, math.ceil(n / MAX_ROWS))


def envelope(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points of a long log drawn faithfully: up to :data:`MAX_ROWS` rows as they are,
    beyond that the lowest and the highest point of each bin of ``2 * stride(n)``
    consecutive rows (so no outlier disappears)."""
    n = len(y)
    if n <= MAX_ROWS:
        return x, y
    k = 2 * stride(n)
    m = (n // k) * k
    idx = np.arange(m).reshape(-1, k)
    rows = np.concatenate(
        [
            idx[np.arange(len(idx)), np.argmin(y[:m].reshape(-1, k), axis=1)],
            idx[np.arange(len(idx)), np.argmax(y[:m].reshape(-1, k), axis=1)],
        ]
    )
    if m < n:
        rows = np.concatenate([rows, [m + int(np.argmin(y[m:])), m + int(np.argmax(y[m:]))]])
    rows = np.unique(rows)
    return x[rows], y[rows]


def _figure(w: float, h: float, nrows: int, ncols: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    with report_style(**{"text.parse_math": False}):
        fig = Figure(figsize=(w, h), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _hide_unused(axes, n: int) -> None:
    """Hide the panels of a grid beyond the first ``n``; the x label moves up to the panel above."""
    nrows, ncols = axes.shape
    for k in range(n, nrows * ncols):
        axes.flat[k].set_visible(False)
        if k - ncols >= 0:
            axes.flat[k - ncols].xaxis.set_tick_params(labelbottom=True)


def _bottom_labels(axes, n: int, label: str) -> None:
    """The x label under the lowest visible panel of each column; unused panels hidden."""
    _hide_unused(axes, n)
    nrows, ncols = axes.shape
    for col in range(ncols):
        rows = [r for r in range(nrows) if r * ncols + col < n]
        if rows:
            axes[rows[-1], col].set_xlabel(label)


def _legend(fig, handles, labels) -> None:
    fig.legend(handles, labels, loc="outside upper center", ncol=len(labels), fontsize=8.5)


def overlay_figure(curves: Sequence, q: str):
    """Measured points and the model at the stated and calibrated values, one panel per run.

    Parameters
    ----------
    curves : sequence of RunCurves
        Runs of one experiment.
    q : str
        Internal quantity.
    """
    n = len(curves)
    ncols = min(n, 3)
    nrows = math.ceil(n / ncols)
    fig, axes = _figure(6.6, 0.9 + 2.0 * nrows, nrows, ncols)
    _, f = quantity_display(q)
    xunit, xf = quantity_display(curves[0].x)
    handles = []
    with report_style(**{"text.parse_math": False}):
        for ax, c in zip(axes.flat, curves):
            k = stride(len(c.measured[q]))
            x = c.inputs[c.x][::k] * xf
            px, py = envelope(c.inputs[c.x] * xf, c.measured[q] * f)
            m = ax.plot(
                px,
                py,
                "o",
                ms=_marker(px.size),
                color=COLOURS["measured"],
                alpha=0.8,
                rasterized=px.size > RASTER,
            )
            s = ax.plot(x, c.stated[q][::k] * f, "--", lw=1.3, color=COLOURS["stated"])
            a = ax.plot(x, c.calibrated[q][::k] * f, "-", lw=1.3, color=COLOURS["calibrated"])
            ax.set_title(legend_label(c.run), fontsize=8.5)
            handles = [m[0], s[0], a[0]]
        _bottom_labels(axes, n, _label(curves[0].x))
        for ax in axes[:, 0]:
            ax.set_ylabel(_label(q))
        zeroed = any(q in c.zero for c in curves)
        calibrated = "model, calibrated (+ fitted zero)" if zeroed else "model, calibrated"
        _legend(fig, handles, ["measured", "model, stated values", calibrated])
    return fig


def _band(ax, x, sigma: float) -> object:
    lo, hi = (float(np.min(x)), float(np.max(x))) if len(x) else (0.0, 1.0)
    return ax.fill_between([lo, hi], -2 * sigma, 2 * sigma, color=COLOURS["band"], lw=0, zorder=0)


def residual_figure(curves: Sequence, quantities: Sequence[str], sigma: dict):
    """Residuals (measured - predicted) against the physical input, before and after.

    One row of panels per quantity: left at the stated values (logged zero),
    right at the calibrated values (fitted zero); the grey band is +-2 noise sd.

    Parameters
    ----------
    curves : sequence of RunCurves
        Runs of one experiment.
    quantities : sequence of str
        Quantities fitted.
    sigma : dict of str to float
        Noise floor of each quantity [SI].
    """
    nq = len(quantities)
    fig, axes = _figure(6.6, 0.7 + 2.1 * nq, nq, 2)
    xunit, xf = quantity_display(curves[0].x)
    handles = []
    with report_style(**{"text.parse_math": False}):
        for row, q in zip(axes, quantities):
            _, f = quantity_display(q)
            for ax, which in zip(row, ("stated", "calibrated")):
                colour = COLOURS[which]
                x_all = []
                for c in (c for c in curves if q in c.measured):  # a run may not log q
                    x, r = envelope(c.inputs[c.x] * xf, (c.measured[q] - getattr(c, which)[q]) * f)
                    pts = ax.plot(
                        x,
                        r,
                        "o",
                        ms=_marker(x.size) * 0.8,
                        color=colour,
                        alpha=0.6,
                        rasterized=x.size > RASTER,
                    )
                    x_all.append(x)
                band = _band(ax, np.concatenate(x_all), sigma[q] * f)
                ax.axhline(0.0, color="0.2", lw=0.7)
                handles.append(pts[0])
            row[0].set_ylabel(f"{_NAMES.get(q, q)} residual\n[{quantity_display(q)[0]}]")
        axes[0, 0].set_title("stated values", fontsize=9)
        zeroed = any(c.zero for c in curves)
        axes[0, 1].set_title("calibrated values" + (", fitted zeros" if zeroed else ""), fontsize=9)
        for ax in axes[-1, :]:
            ax.set_xlabel(_label(curves[0].x))
        _legend(
            fig,
            [handles[0], handles[1], band],
            ["at stated values", "at calibrated values", "\u00b12 noise sd"],
        )
    return fig


def _laplace_z(p, x_si: np.ndarray) -> np.ndarray:
    """The signed root of the Laplace (quadratic) approximation at values ``x_si``."""
    if p.positive:
        return (np.log(x_si) - math.log(p.value)) / p.posterior_sd_rel
    return (x_si - p.value) / p.posterior_sd


def _profile_panel(ax, p, label: str) -> list:
    from matplotlib.ticker import MaxNLocator

    from tcamlab.calibration.fit import Z95

    unit, f = parameter_display(p)
    pts = np.array(p.profile_points, float).reshape(-1, 2)
    lo, hi = p.profile_95
    a, b = min(pts[:, 0].min(), lo), max(pts[:, 0].max(), hi)
    # a margin of about 1.2 sd beyond the 95 % bounds: the curve's shape past them shows
    x_si = np.linspace(a - 0.3 * (p.value - a), b + 0.3 * (b - p.value), 200)
    ax.axvspan(lo * f, hi * f, color="#dbe8f5", lw=0, zorder=0)
    lap = ax.plot(x_si * f, _laplace_z(p, x_si), ":", color="0.35", lw=1.2)
    prof = ax.plot(pts[:, 0] * f, pts[:, 1], "o-", color=COLOURS["calibrated"], ms=3.5, lw=1.3)
    line = ax.axhline(Z95, color="#b2182b", lw=0.9, ls="--")
    ax.axhline(-Z95, color="#b2182b", lw=0.9, ls="--")
    handles = [prof[0], lap[0], line]
    left, right = x_si[0] * f, x_si[-1] * f
    if left <= p.stated * f <= right:
        handles.append(ax.axvline(p.stated * f, color=COLOURS["stated"], lw=1.1, ls="-."))
    else:
        arrow = "←" if p.stated * f < left else "→"
        ax.text(
            0.03 if arrow == "←" else 0.97,
            0.04,
            f"{arrow} stated {p.stated * f:.4g}",
            transform=ax.transAxes,
            ha="left" if arrow == "←" else "right",
            fontsize=7.5,
            color=COLOURS["stated"],
        )
    if right > left:  # a degenerate profile (one point) keeps matplotlib's own limits
        ax.set_xlim(left, right)
    ax.set_ylim(-3.2, 3.2)
    ax.set_xlabel(f"{pretty_symbol(label)} [{unit}]")
    ax.ticklabel_format(axis="x", useOffset=False, style="plain")
    ax.xaxis.set_major_locator(MaxNLocator(nbins=3))
    return handles


def profile_figure(parameters: Sequence, labels: Sequence[str] | None = None):
    """Signed root of the profile likelihood against each parameter, one panel each.

    The shaded span is the 95 % profile interval, the dashed lines z = +-1.96, the
    dotted line the Laplace approximation, the dash-dotted line the stated value.
    ``labels`` name the panels (default the symbols).
    """
    n = len(parameters)
    ncols = 1 if n == 1 else 2 if n in (2, 4) else 3
    nrows = math.ceil(n / ncols)
    fig, axes = _figure(6.6, 0.9 + 2.3 * nrows, nrows, ncols)
    _hide_unused(axes, n)
    best: list = []
    with report_style(**{"text.parse_math": False}):
        for ax, p, label in zip(axes.flat, parameters, labels or [p.symbol for p in parameters]):
            handles = _profile_panel(ax, p, label)
            best = handles if len(handles) > len(best) else best
        for ax in axes[:, 0]:
            ax.set_ylabel("signed root z")
        labels = ["profile", "Laplace approximation", "z = \u00b11.96 (95 %)", "stated value"]
        _legend(fig, best, labels[: len(best)])
    return fig


def _corr_text(r: float) -> str:
    """``+0.53`` / ``−0.10``; ``0.00`` unsigned."""
    text = f"{r:+.2f}"
    return "0.00" if float(text) == 0 else text.replace("-", "\u2212")


def correlation_figure(symbols: Sequence[str], matrix):
    """The posterior correlation matrix as an annotated heatmap (fitted coordinates)."""
    m = np.asarray(matrix, float)
    n = len(symbols)
    # wide and short: the PDF scales every figure to the text width
    fig, axes = _figure(6.6, 1.3 + 0.45 * n, 1, 1)
    ax = axes[0, 0]
    labels = [pretty_symbol(s) for s in symbols]
    with report_style(**{"text.parse_math": False}):
        im = ax.imshow(m, cmap="RdBu_r", vmin=-1, vmax=1)
        for i in range(n):
            for j in range(n):
                ax.text(
                    j,
                    i,
                    _corr_text(m[i, j]),
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="white" if abs(m[i, j]) > 0.6 else "black",
                )
        tilted = n > 3 or max(len(s) for s in labels) > 8
        ax.set_xticks(range(n), labels, rotation=35 if tilted else 0, ha="right" if tilted else "center")
        ax.set_yticks(range(n), labels)
        ax.grid(False)
        ax.tick_params(length=0)
        fig.colorbar(im, ax=ax, shrink=0.85, label="correlation")
    return fig
