"""Long logs: fits on the reduced representation (tcamlab.reduction) agree with fits on every row.

The logs are bench/bench_large_log.py's ``make_log`` (SYNTHETIC: the thesis dynamic model
tiled at 1 kHz plus laser noise, seed 12) and ``make_static_log`` (SYNTHETIC: the thesis
static model on a heat-cool cycle, a 1 kHz laser joined with a 25 Hz thermal camera whose
temperature is held between frames or interpolated, noise on both, seed 12). The reduction is
switched on below its usual length (:data:`tcamlab.reduction.MIN_ROWS` lowered) so that the
fit on every row, the reference, runs in a test's time.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tcamlab import reduction

_PATH = Path(__file__).resolve().parents[1] / "bench" / "bench_large_log.py"
_spec = importlib.util.spec_from_file_location("bench_large_log", _PATH)
big = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(big)

AGREE = 0.1
"""Largest difference between the reduced and the every-row fit, in widths of the
every-row fit's interval."""


def test_a_line_has_exact_moments_and_blocks_respect_the_spread():
    """An exponential decay (tau 3 s at 1 kHz, amplitude 1000 noise floors): every block's
    largest second difference times L^2/8 stays within SPREAD, the curve's fast start gets
    short blocks and its flat tail long ones, and the two-row moments of a straight line are
    its exact moments."""
    t = np.arange(20_000) / 1000.0
    p = 1000.0 * np.exp(-t / 3.0)
    data = pd.DataFrame({"time": t, "voltage": np.zeros_like(t)})
    red = reduction.reduce_run(data, ["voltage"], {"x": p}, {"x": p}, {"x": 1.0})
    d2 = np.abs(np.diff(p, 2))
    for a, n in zip(red.starts, red.counts):
        if n > 2:
            assert d2[a : a + n - 2].max() * n * n <= 8 * reduction.SPREAD + 1e-12
    assert red.counts[0] < 200 and red.counts[-1] > 1000
    line = 2.0 + 0.5 * t
    m0, m1 = red.moments(line, t)
    c0, c1 = red.coarse_moments(line[red.grid])
    np.testing.assert_allclose(c0, m0, rtol=1e-10)
    np.testing.assert_allclose(c1, m1, rtol=1e-8, atol=1e-9)
    # a fold edge splits a block; a mask cutting a block is refused
    cut = reduction.reduce_run(data, ["voltage"], {"x": p}, {"x": p}, {"x": 1.0}, breaks=[12_345])
    assert 12_345 in cut.starts
    mask = np.zeros(t.size, bool)
    mask[12_345:] = True
    assert cut.blocks_in(mask).sum() == np.count_nonzero(cut.starts >= 12_345)
    mask[12_346] = False
    assert cut.blocks_in(mask) is None


def test_short_runs_are_not_reduced(monkeypatch):
    """Below MIN_ROWS, and with the switch set, a run is fitted on every row."""
    assert reduction.enabled(reduction.MIN_ROWS) and not reduction.enabled(reduction.MIN_ROWS - 1)
    monkeypatch.setenv(reduction.ENV, "1")
    assert not reduction.enabled(10**9)


@pytest.fixture(scope="module")
def long_log(tmp_path_factory):
    return big.make_log(20_000, tmp_path_factory.mktemp("longlog"))


def _both(monkeypatch, fn):
    """``fn()`` with the reduction on (a 20,000-row run counts as long), then off."""
    monkeypatch.setattr(reduction, "MIN_ROWS", 5_000)
    reduced = fn()
    monkeypatch.setenv(reduction.ENV, "1")
    return reduced, fn()


@pytest.mark.slow
def test_calibration_on_the_reduced_log_agrees_with_every_row(monkeypatch, long_log):
    from tcamlab.calibration import calibrate
    from tcamlab.calibration.problem import CalibrationProblem
    from tcamlab.config import load_experiment

    exp = load_experiment(long_log)
    monkeypatch.setattr(reduction, "MIN_ROWS", 5_000)
    prob = CalibrationProblem([exp], [exp.read_runs()])
    assert prob.n_resid < prob.size / 20  # the fit sees a few moments per block, not 20,000 rows
    red, full = _both(monkeypatch, lambda: calibrate(long_log))
    assert red.n_points == full.n_points == 20_000
    assert red.chi2 == pytest.approx(full.chi2, rel=1e-3)  # both of every row
    for a, b in zip(red.parameters, full.parameters):
        width = b.profile_95[1] - b.profile_95[0]
        assert abs(a.value - b.value) <= AGREE * width, a.name
        for x, y in zip(a.profile_95 + a.laplace_95, b.profile_95 + b.laplace_95):
            assert abs(x - y) <= AGREE * width, a.name
        assert a.identification == b.identification


@pytest.mark.slow
def test_diagnosis_on_the_reduced_log_agrees_with_every_row(monkeypatch, long_log):
    from tcamlab.config import load_experiment
    from tcamlab.diagnosis import diagnose

    red, full = _both(monkeypatch, lambda: diagnose(load_experiment(long_log), n_boot=200).to_dict())
    assert red["verdict"] == full["verdict"] == "none"
    assert red["effect"] == full["effect"]
    ranked = {c["effect"]: c for c in full["ranking"]}
    assert {c["effect"] for c in red["ranking"]} == set(ranked)
    compared = 0
    for c in red["ranking"]:
        ref = ranked[c["effect"]]
        if c["effect"] == "recalibration":  # the folds' fits of a well-posed candidate agree too
            assert c["heldout_rmse_after_noise"] == pytest.approx(ref["heldout_rmse_after_noise"], abs=0.005)
        for name, p in (c.get("parameters") or {}).items():
            q = ref["parameters"][name]
            width = q["ci95"][1] - q["ci95"][0]
            assert abs(p["value"] - q["value"]) <= AGREE * width, name
            assert p["at_bound"] == q["at_bound"], name
            if q["at_bound"]:
                continue  # at a bound the Laplace interval is no interval (candidates.AT_BOUND)
            assert abs(p["ci95"][0] - q["ci95"][0]) <= AGREE * width, name
            assert abs(p["ci95"][1] - q["ci95"][1]) <= AGREE * width, name
            compared += 1
    assert compared >= 1


@pytest.fixture(scope="module")
def static_logs(tmp_path_factory):
    work = tmp_path_factory.mktemp("staticlog")
    return {cam: big.make_static_log(20_000, work, camera=cam) for cam in ("held", "interpolated")}


def test_a_noisy_input_cuts_no_block_and_its_line_replaces_it_on_the_grid():
    """A temperature with 0.5 degC noise on every row on a slow ramp (SYNTHETIC, seed 3): the
    blocks are hundreds of rows long (held-input blocks would be one row), the grid frame
    holds each block's least-squares line of the input, and the noise moments of a model
    linear in the input are its slope times the input's departure (the gram)."""
    rng = np.random.default_rng(3)
    t = np.arange(30_000) / 1000.0
    temp = 25.0 + 1.5 * t + rng.normal(0, 0.5, t.size)
    pred = -5.7e-6 * (temp - temp[0])  # a static response, [m]
    data = pd.DataFrame({"time": t, "temperature": temp})
    red = reduction.reduce_run(
        data, ["temperature"], {"x": pred}, {"x": pred}, {"x": 5e-6}, noisy=["temperature"]
    )
    assert red.counts.min() > 100 and red.counts.size < 300
    frame = red.on_lines(data, red.grid)
    level, slope = red.lines["temperature"]
    b = np.searchsorted(red.starts, red.grid[5]) - 1
    assert frame["temperature"].iloc[5] == pytest.approx(level[b] + slope[b] * (t[red.grid[5]] - red.tbar[b]))
    assert frame["temperature"].iloc[0] == temp[0]  # the first row keeps its logged value
    # the line of a noisy ramp is the ramp to within its noise over sqrt(rows)
    assert np.max(np.abs(level - (25.0 + 1.5 * red.tbar))) < 5 * 0.5 / np.sqrt(red.counts.min())
    # a model linear in the input: its noise moment is slope * |e| (noise_stated), exactly
    np.testing.assert_allclose(
        red.noise_stated["x"]["temperature"], -5.7e-6 * red.gram["temperature"]["temperature"], rtol=1e-9
    )
    assert red.size == red.counts.size + red.two.sum() + red.rough("temperature").sum()


@pytest.mark.slow
@pytest.mark.parametrize("camera", ["held", "interpolated"])
def test_calibration_with_a_noisy_temperature_agrees_with_every_row(monkeypatch, static_logs, camera):
    """The static log whose temperature comes from a thermal camera: reduced (a few moments
    per block), the calibrated values and their intervals agree with the every-row fit within
    a tenth of the interval's width, and the chi-square of every row with it."""
    from tcamlab.calibration import calibrate
    from tcamlab.calibration.problem import CalibrationProblem
    from tcamlab.config import load_experiment

    path = static_logs[camera]
    exp = load_experiment(path)
    monkeypatch.setattr(reduction, "MIN_ROWS", 5_000)
    prob = CalibrationProblem([exp], [exp.read_runs()])
    assert prob.reductions[(0, 0)] is not None and prob.n_resid < prob.size / 20
    red, full = _both(monkeypatch, lambda: calibrate(path))
    assert red.chi2 == pytest.approx(full.chi2, rel=1e-4)
    for a, b in zip(red.parameters, full.parameters):
        width = b.profile_95[1] - b.profile_95[0]
        assert abs(a.value - b.value) <= AGREE * width, a.name
        for x, y in zip(a.profile_95 + a.laplace_95, b.profile_95 + b.laplace_95):
            assert abs(x - y) <= AGREE * width, a.name
        assert a.identification == b.identification


@pytest.mark.slow
def test_diagnosis_with_a_noisy_temperature_agrees_with_every_row(monkeypatch, static_logs):
    """The diagnosis of the held-camera static log: same verdict and effect, every candidate's
    held-out score, and each parameter off its bound with its interval within a tenth of its
    width, the thermal lag's included (the models read the camera averaged over its frames,
    so a lag has no camera noise to smooth in either fit). The log has no lag and no effect:
    `none` (it was `attributed (oven-thermal-lag)` when the models read the camera's frames)."""
    from tcamlab.config import load_experiment
    from tcamlab.diagnosis import diagnose

    path = static_logs["held"]
    red, full = _both(monkeypatch, lambda: diagnose(load_experiment(path), n_boot=200).to_dict())
    assert red["verdict"] == full["verdict"] == "none"
    assert red["effect"] == full["effect"]
    ranked = {c["effect"]: c for c in full["ranking"]}
    assert {c["effect"] for c in red["ranking"]} == set(ranked)
    compared = 0
    for c in red["ranking"]:
        ref = ranked[c["effect"]]
        assert c["heldout_rmse_after_noise"] == pytest.approx(ref["heldout_rmse_after_noise"], abs=0.005)
        for name, p in (c.get("parameters") or {}).items():
            q = ref["parameters"][name]
            if p["at_bound"] or q["at_bound"]:
                continue  # at a bound the Laplace interval is no interval (candidates.AT_BOUND)
            width = q["ci95"][1] - q["ci95"][0]
            assert abs(p["value"] - q["value"]) <= AGREE * width, (c["effect"], name)
            assert abs(p["ci95"][0] - q["ci95"][0]) <= AGREE * width, (c["effect"], name)
            assert abs(p["ci95"][1] - q["ci95"][1]) <= AGREE * width, (c["effect"], name)
            compared += 1
    assert compared >= 1


@pytest.mark.slow
def test_a_real_thermal_lag_behind_the_camera_is_found_and_fitted_alike_on_blocks(monkeypatch, tmp_path):
    """The held-camera log whose actuator lags the camera's scene by 0.5 s (SYNTHETIC, seed 12):
    both fits attribute the thermal lag, and its time constant and interval agree within a
    tenth of the interval's width. On the grid the camera's block lines run straight between
    grid rows (a lag holding each grid row's value over the step before it led the input by
    half a step: 0.19 widths longer)."""
    from tcamlab.config import load_experiment
    from tcamlab.diagnosis import diagnose

    path = big.make_static_log(20_000, tmp_path, camera="held", lag_s=0.5)
    red, full = _both(monkeypatch, lambda: diagnose(load_experiment(path), n_boot=200).to_dict())
    assert red["verdict"] == full["verdict"] == "attributed"
    assert red["effect"] == full["effect"] == "oven-thermal-lag"
    a = next(c for c in red["ranking"] if c["effect"] == "oven-thermal-lag")["parameters"]
    b = next(c for c in full["ranking"] if c["effect"] == "oven-thermal-lag")["parameters"]
    for name in ("lag_tau", "lag_conductance_tc"):
        width = b[name]["ci95"][1] - b[name]["ci95"][0]
        assert abs(a[name]["value"] - b[name]["value"]) <= AGREE * width, name
        for x, y in zip(a[name]["ci95"], b[name]["ci95"]):
            assert abs(x - y) <= AGREE * width, name
