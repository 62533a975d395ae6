"""Figures of a gap diagnosis: residuals before and after the best candidate, by regime.

Residuals (measured - predicted) are drawn against the physical input of the kind
(temperature, time, cable pull; for sensing the measured force, where slack, hysteresis
and stiffening show), in the quantity's unit, at the scale of the noise: a full-scale
overlay (0-50 mm) cannot show a 0.01 mm fix. Every run is drawn with visible markers;
legends hold at most :data:`MAX_LEGEND_ENTRIES` entries.
"""

from __future__ import annotations

import numpy as np

from tcamlab.numbers import fmt, rmse_unit
from tcamlab.units import display

from .document import Figure
from .figures import new_figure, report_style

__all__ = [
    "MIN_REGIME_POINTS",
    "MAX_LEGEND_ENTRIES",
    "DENSE_POINTS",
    "best_name",
    "residual_figure",
    "regime_figure",
    "drawable_regimes",
    "forest_figure",
]

MIN_REGIME_POINTS = 10
"""A regime with fewer residuals is not drawn (a box of one re-zeroed row says nothing)."""

MAX_LEGEND_ENTRIES = 6
"""Most entries of a legend (runs beyond five share one entry, coloured in order)."""

DENSE_POINTS = 3000
"""Above this many points a panel's markers are smaller and rasterised (the SVG stays small)."""

_RUN_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd"]


def best_name(result) -> str | None:
    """Name of the candidate whose all-runs fit the result's series hold as ``best``."""
    combo = getattr(result, "combination", None)
    if combo is not None:
        return " + ".join(combo["effects"])
    if result.verdict == "miscalibrated":
        via = (getattr(result, "recalibration", None) or {}).get("via_effect")
        return f"{via} (the parameter's own error)" if via else "recalibration"
    if result.effect is not None and result.verdict != "unexplained":
        return result.effect
    return result.ranking[0].effect if result.ranking else None


def _zeroed(result) -> tuple:
    """The quantities whose per-run zero the diagnosis profiled out."""
    gap = getattr(result, "gap", None)
    return tuple(gap.get("nuisance_zeros", ())) if gap is not None else ()


def _x(result, run: dict):
    """The physical input a run's residuals are drawn against, and its label."""
    if result.kind == "sensing" and "force" in run["measured"]:
        return np.asarray(run["measured"]["force"], float), "measured force [N]"
    return np.asarray(run["x"], float), run["xlabel"]


def _run_colours(n: int) -> list:
    if n <= len(_RUN_COLOURS):
        return _RUN_COLOURS[:n]
    from matplotlib import colormaps

    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.9, n)]


def _residuals(result, q: str, which: str) -> list[np.ndarray] | None:
    """Measured - predicted of every run [residual unit], or None when not available."""
    unit, fac = display(q)
    fac *= rmse_unit(unit)[1]
    out = []
    for run in result._series.get("runs", []):
        pred = run.get(which)
        if pred is None:
            return None
        if q not in run["measured"]:  # a run that does not log it: no points, same x
            out.append(np.full(len(run["x"]), np.nan))
            continue
        out.append((np.asarray(run["measured"][q], float) - np.asarray(pred[q], float)) * fac)
    return out


def _panel(ax, result, res, colours, title, sigma, unit):
    xs = [_x(result, r)[0] for r in result._series["runs"]]
    n_points = sum(r.size for r in res)
    dense = n_points > DENSE_POINTS
    ax.axhspan(-sigma, sigma, color="0.88", zorder=0, lw=0)
    ax.axhline(0.0, color="0.3", lw=0.8)
    many = len(res) > len(_RUN_COLOURS)
    for i, (x, r, c) in enumerate(zip(xs, res, colours)):
        if not np.isfinite(r).any():  # a run that does not log this quantity: no legend entry
            continue
        label = None if many else f"run {i + 1}"
        if many and i == 0:
            label = f"runs 1-{len(res)} (dark to light)"
        ax.plot(
            x,
            r,
            "o",
            ms=1.6 if dense else 3.2,
            mew=0,
            alpha=0.7 if dense else 0.9,
            color=c,
            label=label,
            rasterized=dense,
        )
    all_r = np.concatenate(res)
    ok = np.isfinite(all_r)
    rms = float(np.sqrt(np.mean(all_r[ok] ** 2))) if ok.any() else float("nan")
    ax.set_title(f"{title}\nRMSE {fmt(rms)} {unit}", fontsize=9)


def _panels(ncols: int):
    """A figure of ``ncols`` panels side by side sharing the y axis (Agg canvas, no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure as MplFigure

    with report_style():
        fig = MplFigure(figsize=(6.6 if ncols == 2 else 4.4, 3.4), layout="constrained")
        FigureCanvasAgg(fig)
        axes = list(fig.subplots(1, ncols, sharey=True, squeeze=False)[0])
    return fig, axes


def residual_figure(result, q: str) -> Figure | None:
    """Residuals of quantity ``q`` before (thesis model) and after the best candidate, every run.

    Both panels share the y axis; the grey band is +-1 noise sd. None when the result
    carries no series.
    """
    before = _residuals(result, q, "baseline")
    if not before:
        return None
    after = _residuals(result, q, "best")
    name = best_name(result)
    unit, fac = display(q)
    r_unit, r_fac = rmse_unit(unit)
    sigma = float(result.noise_floor["by_quantity"][q]["sigma"]) * r_fac
    ncols = 2 if after is not None else 1
    fig, axes = _panels(ncols)
    colours = _run_colours(len(before))
    _panel(axes[0], result, before, colours, "before: thesis model", sigma, r_unit)
    if after is not None:
        label = f"after: {name}" + (" (not needed: no gap)" if result.verdict == "none" else "")
        _panel(axes[1], result, after, colours, label, sigma, r_unit)
    xlabel = _x(result, result._series["runs"][0])[1]
    for ax in axes:
        ax.set_xlabel(xlabel)
    axes[0].set_ylabel(f"{q}: measured - predicted [{r_unit}]")
    handles, labels = axes[0].get_legend_handles_labels()
    from matplotlib.patches import Patch

    handles.append(Patch(color="0.88", label=f"±1 noise sd ({fmt(sigma)} {r_unit})"))
    fig.legend(
        handles=handles[:MAX_LEGEND_ENTRIES],
        loc="outside lower center",
        ncol=min(len(handles), 6),
        fontsize=8,
    )
    caption = (
        f"{q} residuals (measured - predicted, {r_unit}) against {xlabel.split(' [')[0]}, every run that logs it: "
        "the thesis model"
        + (
            f" (left) and with {name} fitted on all runs (right; held-out scores in the table)"
            if after
            else ""
        )
        + ("; each run's zero profiled out" if q in _zeroed(result) else "")
        + "; grey band ±1 noise sd."
    )
    return Figure(fig, caption, alt=caption)


def drawable_regimes(result, group: str) -> tuple[list[str], list[tuple[str, int]]]:
    """The regimes of ``group`` with at least :data:`MIN_REGIME_POINTS` residuals, and
    (name, n) of those left out."""
    labels = result._series["labels"][group]
    names = list(dict.fromkeys(lab for lab in labels if lab))
    counts = {n: int(np.sum(labels == n)) for n in names}
    keep = [n for n in names if counts[n] >= MIN_REGIME_POINTS]
    return keep, [(n, counts[n]) for n in names if counts[n] < MIN_REGIME_POINTS]


def regime_figure(result, group: str) -> Figure | None:
    """Box plot of the baseline residuals (noise-floor multiples) per regime of ``group``;
    None when fewer than two regimes have :data:`MIN_REGIME_POINTS` points (a one-box plot,
    e.g. "by phase" of a heating-only test, says nothing)."""
    keep, dropped = drawable_regimes(result, group)
    if len(keep) < 2:
        return None
    s = result._series
    labels = s["labels"][group]
    fig, ax = new_figure(5.4, 3.0)
    ax.boxplot([s["z"][labels == name] for name in keep], showfliers=False)
    ax.set_xticks(range(1, len(keep) + 1), keep, rotation=20, ha="right")
    ax.axhspan(-1, 1, color="0.88", zorder=0, lw=0)
    ax.axhline(0, color="0.3", lw=0.8)
    ax.set_ylabel("residual / noise sd [-]")
    ax.set_title(f"thesis model residuals by {group}", fontsize=9)
    caption = f"Baseline residuals by {group}, in noise-floor multiples (grey band ±1)"
    if dropped:
        caption += "; not drawn (fewer than {} points): {}".format(
            MIN_REGIME_POINTS, ", ".join(f"{n} (n = {c})" for n, c in dropped)
        )
    return Figure(fig, caption + ".", alt=caption)


FOREST_FLOOR = -100.0
"""Shrinkages below this [%] (a failed fit) are drawn at the axis edge with their value
written, so one failure does not squeeze every other interval into a dot."""


def forest_figure(result) -> Figure | None:
    """Held-out RMSE shrinkage [%] with its 95 % bootstrap interval per candidate, best first
    (the named candidate in red); None without candidates."""
    cands = list(result.ranking)
    if not cands:
        return None
    fig, ax = new_figure(6.0, 0.9 + 0.32 * len(cands))
    y = np.arange(len(cands))[::-1]
    for yi, c in zip(y, cands):
        s, (lo, hi) = 100.0 * c.shrinkage, (100.0 * v for v in c.shrinkage_ci95)
        color = "#d62728" if c.effect == result.effect else "#1f77b4"
        if not np.isfinite(s) or s < FOREST_FLOOR:
            ax.plot([FOREST_FLOOR], [yi], "<", color=color, ms=6)
            ax.annotate(
                f" {fmt(s, 3)}% (off scale)", (FOREST_FLOOR, yi), va="center", fontsize=8, color=color
            )
            continue
        lo, hi = max(lo, FOREST_FLOOR), max(hi, FOREST_FLOOR)
        ax.errorbar(
            [s], [yi], xerr=[[max(0.0, s - lo)], [max(0.0, hi - s)]], fmt="o", color=color, capsize=3, ms=5
        )
    ax.axvline(0, color="0.3", lw=0.8)
    if any(not c.shrinkage * 100.0 >= FOREST_FLOOR for c in cands):
        ax.set_xlim(left=FOREST_FLOOR - 5.0)
    ax.set_yticks(y, [c.effect for c in cands])
    ax.set_xlabel("held-out RMSE shrinkage [%] (95 % bootstrap interval)")
    caption = "Held-out RMSE shrinkage per candidate (95 % bootstrap interval over withheld folds)"
    return Figure(fig, caption, alt=caption)
