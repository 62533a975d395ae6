"""Reports of long logs stay small and faithful; legends stay readable; figures export.

The long logs are SYNTHETIC, made by ``bench/bench_large_log.py``'s ``make_log`` (the thesis
dynamic model tiled plus laser noise, seed 12); the five-run experiment by the virtual rig
(``simulate_experiment``, seed 3).
"""

from __future__ import annotations

import importlib.util
import io
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tcamlab.io.csvfast import fixed_csv_bytes
from tcamlab.pipeline import simulate_experiment, validate_experiment
from tcamlab.report.figures import (
    LEGEND_MAX_ENTRIES,
    LEGEND_MIN_FONT_PT,
    MIN_MARKER_PT,
    compact_figure,
    envelope,
    figure_to_svg,
    group_legend_entries,
    new_figure,
)

ROOT = Path(__file__).resolve().parent.parent


def _make_log():
    spec = importlib.util.spec_from_file_location("bench_large_log", ROOT / "bench" / "bench_large_log.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.make_log


def _brute_envelope(x, y, columns):
    x0, x1 = x.min(), x.max()
    col = np.minimum(((x - x0) * (columns / (x1 - x0))).astype(int), columns - 1)
    lo = np.array([y[col == c].min() if np.any(col == c) else np.nan for c in range(columns)])
    hi = np.array([y[col == c].max() if np.any(col == c) else np.nan for c in range(columns)])
    return lo, hi


@pytest.mark.parametrize("shuffle", [False, True])
def test_envelope_equals_the_data_min_max_per_column(shuffle):
    rng = np.random.default_rng(4)
    x = np.sort(rng.uniform(0, 10, 20_000))
    x[5000:6000] = np.linspace(2.0, 2.001, 1000)  # a dense stretch and an empty bin or two
    x = np.sort(x)
    x = np.r_[x[x < 4.0], x[x > 4.2]]  # a gap: empty columns
    y = np.sin(x) + rng.normal(0, 0.1, x.size)
    if shuffle:  # residuals against temperature come unsorted
        order = rng.permutation(x.size)
        x, y = x[order], y[order]
    centres, lo, hi = envelope(x, y, 300)
    want_lo, want_hi = _brute_envelope(x, y, 300)
    np.testing.assert_array_equal(lo, want_lo)
    np.testing.assert_array_equal(hi, want_hi)
    assert np.isnan(lo).sum() >= 5  # the gap stays a gap
    assert centres[0] > x.min() and centres[-1] < x.max()


def test_envelope_drops_non_finite_points():
    x = np.arange(1000.0)
    y = np.ones(1000)
    y[10] = np.nan
    y[20] = 7.0
    _, lo, hi = envelope(x, y, 10)
    assert hi[0] == 7.0 and np.nanmin(lo) == 1.0 and not np.isnan(hi).any()


def test_compact_figure_keeps_short_series_and_envelopes_long_ones():
    rng = np.random.default_rng(5)
    fig, ax = new_figure()
    t = np.linspace(0, 100, 300_000)
    y = np.sin(t) + rng.normal(0, 0.05, t.size)
    ax.plot(t, y, ".", ms=1.5, label="long measured")
    ax.plot(t[:50], y[:50], ".", ms=1.0, label="short measured")
    compact_figure(fig)
    lines = ax.get_lines()
    assert len(lines) == 1 and len(lines[0].get_xdata()) == 50
    # a "." marker is drawn at half its size: at least 2 pt wide, not a 1-pixel dot
    assert lines[0].get_markersize() * 0.5 >= MIN_MARKER_PT == 2.0
    (coll,) = [c for c in ax.collections if c.get_gid() == "envelope"]
    ys = coll.get_paths()[0].vertices[:, 1]
    assert ys.min() == pytest.approx(y.min()) and ys.max() == pytest.approx(y.max())
    assert len(figure_to_svg(fig)) < 400_000  # 300,000 points as markers: tens of MB


def test_legend_grouping_keeps_at_most_six_entries():
    labels = [f"run{i} {w}" for i in range(1, 6) for w in ("measured", "model")] + ["95% band"]
    handles, out = group_legend_entries(list(range(len(labels))), labels)
    assert len(out) <= LEGEND_MAX_ENTRIES
    assert out[0].startswith("measured: run1 … run5 (5 runs")
    assert handles[0] == (0, 2, 4, 6, 8)
    assert out[-1] == "95% band"
    many = [f"r{i} kind{i}" for i in range(12)]  # nothing groups: merged at the end
    h, out = group_legend_entries(list(range(12)), many)
    assert len(out) == LEGEND_MAX_ENTRIES and out[-1] == "7 more series" and len(h[-1]) == 7
    # long run names keep only the ends, so the entry fits beside the axes
    long = [f"selfsensing_run{i} {w}" for i in (1, 2, 3) for w in ("laser", "model", "EKF")]
    _, out = group_legend_entries(list(range(9)), long)
    assert out[0] == "laser: selfsensing_run1 … selfsensing_run3 (3 runs, colours left to right)"


@pytest.fixture(scope="module")
def five_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("five")
    sim = simulate_experiment("dynamic", "dynamic", seed=3, out_dir=tmp, runs=5)
    return validate_experiment(sim.experiment_path, tmp / "reports", formats="html,png,svg", mc_draws=30)


def test_every_validation_figure_has_a_readable_legend(five_runs):
    figures = [f.figure for s in five_runs.result.document.sections for f in s.figures]
    assert len(figures) >= 2
    legends = [ax.get_legend() for fig in figures for ax in fig.axes if ax.get_legend() is not None]
    assert legends  # the dynamic figure has 11 entries before grouping
    for legend in legends:
        assert len(legend.get_texts()) <= LEGEND_MAX_ENTRIES
        assert min(t.get_fontsize() for t in legend.get_texts()) >= LEGEND_MIN_FONT_PT
    texts = [t.get_text() for lg in legends for t in lg.get_texts()]
    assert any("5 runs" in t for t in texts)


def test_figures_exported_as_png_and_svg(five_runs):
    folder = five_runs.out_dir / "figures"
    pngs, svgs = sorted(folder.glob("fig*.png")), sorted(folder.glob("fig*.svg"))
    n = sum(len(s.figures) for s in five_runs.result.document.sections)
    assert len(pngs) == len(svgs) == n >= 2
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import xml.etree.ElementTree as ET

    for s in svgs:
        root = ET.parse(s).getroot()
        assert root.tag == "{http://www.w3.org/2000/svg}svg"


@pytest.fixture(scope="module")
def long_reports(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("long")
    make_log = _make_log()
    out = {}
    for rows in (100_000, 1_000_000):
        toml = make_log(rows, tmp)
        out[rows] = validate_experiment(toml, tmp / f"r{rows}", formats="html", mc_draws=20)
    return out


def test_report_size_does_not_grow_with_the_log(long_reports):
    small = (long_reports[100_000].out_dir / "report.html").stat().st_size
    large = (long_reports[1_000_000].out_dir / "report.html").stat().st_size
    assert large < 2_000_000  # a full-resolution figure of 1M rows was over 200 MB
    assert large < 1.15 * small  # 10x the rows, about the same size


def test_band_decimation_is_stated_in_the_report(long_reports):
    res = long_reports[1_000_000]
    grid = res.result.extras["prediction_band"]["runs"]["run1"]["grid_points"]
    assert 5000 <= grid < 10_000
    html = (res.out_dir / "report.html").read_text()
    assert f"computed on a decimated grid of {grid} rows and interpolated" in html


def test_long_predictions_csv_reads_back(long_reports):
    res = long_reports[1_000_000]
    back = pd.read_csv(res.out_dir / "predictions.csv")
    want = res.result.to_pandas()
    assert list(back.columns) == list(want.columns) and len(back) == len(want) == 1_000_000
    for c in want.columns[1:]:
        top = np.nanmax(np.abs(want[c]))
        np.testing.assert_allclose(back[c], want[c], rtol=0, atol=max(top, 1e-300) * 1e-8)


def test_fixed_csv_quotes_labels_and_leaves_nan_empty():
    df = pd.DataFrame({"run": ["a,b", "a,b", "c"], "x": [1.5, np.nan, -0.000125], "n": [1, 2, 3]})
    text = fixed_csv_bytes(df, label="run").decode()
    assert text == 'run,x,n\n"a,b",1.5,1\n"a,b",,2\nc,-0.000125,3\n'
    back = pd.read_csv(io.StringIO(text))
    assert back["x"].isna().sum() == 1 and re.fullmatch(r"a,b", back["run"][0])


def test_band_grid_of_a_long_log_keeps_the_model_in_its_domain():
    """10,000 s at 1 kHz: on 5000 evenly spaced rows (2 s apart) the Monte Carlo left the
    model's domain for every draw, the nominal one included; the grid now keeps <= 0.2 s."""
    from tcamlab import band
    from tcamlab.config import load_experiment
    from tcamlab.models import dynamic

    exp = load_experiment(ROOT / "experiments" / "dynamic.toml")
    t = np.arange(10_000_000) / 1000.0
    v = np.where((t % 20.0 >= 0.5) & (t % 20.0 < 1.5), 10.0, 0.0)
    idx, decimated = band.band_grid(t, v)
    assert decimated and np.diff(t[idx]).max() <= band.MAX_GRID_STEP_S + 1e-9
    draws = {"heat_loss": exp.rig.heat_loss * np.array([0.5, 1.0, 2.0])}
    mc = dynamic.monte_carlo(t[idx], v[idx], exp.sample, exp.rig, draws=draws)
    assert mc.valid.all()
    assert mc.displacement.min() == pytest.approx(-0.42e-3, rel=0.2)  # a full 1 s pulse's stroke
