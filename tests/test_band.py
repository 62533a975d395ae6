"""The band for measured points (tcamlab.band and the dynamic kind's use of it).

Synthetic data: the virtual rig (tcamlab.rig.simulate, generator named in each
experiment file) with lies (parameter_error=1, noisy_zero=True), seeds stated
in each test.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import optimize, stats

from tcamlab import band
from tcamlab.calibration import calibrate, calibrated_text
from tcamlab.config import CalibratedJoint, load_experiment
from tcamlab.kinds import dynamic as kd
from tcamlab.rig import simulate
from tcamlab.validation import validate

TEMPLATES = Path(__file__).resolve().parent.parent / "tcamlab" / "templates"
Z = stats.norm.ppf(0.975)


# --- pure functions ----------------------------------------------------------------------


def test_mixture_interval_of_one_component_is_the_normal_interval():
    lo, hi = band.mixture_interval(np.array([[1.0, -2.0, 0.0]]), np.array([0.5, 2.0, 1e-6]))
    assert lo == pytest.approx([1 - Z * 0.5, -2 - Z * 2.0, -Z * 1e-6], rel=1e-3)
    assert hi == pytest.approx([1 + Z * 0.5, -2 + Z * 2.0, Z * 1e-6], rel=1e-3)


def test_mixture_interval_solves_the_mixture_cdf():
    rng = np.random.default_rng(5)
    centres = np.concatenate([rng.normal(0, 1, 300), rng.normal(6, 0.5, 100)])[:, None]
    s = 0.7
    lo, hi = band.mixture_interval(centres, s)

    def cdf(y):
        return float(np.mean(stats.norm.cdf((y - centres[:, 0]) / s)))

    want_lo = optimize.brentq(lambda y: cdf(y) - 0.025, -20, 20)
    want_hi = optimize.brentq(lambda y: cdf(y) - 0.975, -20, 20)
    assert lo[0] == pytest.approx(want_lo, abs=1e-3 * s)
    assert hi[0] == pytest.approx(want_hi, abs=1e-3 * s)
    # wider than the parameter part alone and than the noise alone
    plo, phi = band.parameter_interval(centres)
    assert lo[0] < plo[0] and hi[0] > phi[0]


def test_calibrated_draws_keep_the_correlations_in_log_coordinates():
    joint = CalibratedJoint(
        keys=("rig.thermal_mass_J_per_K", "rig.heat_loss_W_per_K"),
        fields=(("rig", "thermal_mass"), ("rig", "heat_loss")),
        log=(True, True),
        sd=(0.05, 0.2),
        correlation=((1.0, -0.8), (-0.8, 1.0)),
    )
    dist = band.from_calibration(joint, {("rig", "thermal_mass"): 0.02, ("rig", "heat_loss"): 0.001})
    assert dist.calibrated and band.band_label(dist.calibrated) == "95% prediction band"
    d = dist.draw(40_000, np.random.default_rng(1))
    a, b = np.log(d[("rig", "thermal_mass")]), np.log(d[("rig", "heat_loss")])
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(-0.8, abs=0.01)
    assert a.std() == pytest.approx(0.05, rel=0.02) and b.std() == pytest.approx(0.2, rel=0.02)
    # the centre is the calibrated value (the median of a log-normal)
    assert np.median(d[("rig", "heat_loss")]) == pytest.approx(0.001, rel=0.01)


def test_profile_sds_give_split_normal_marginals_with_the_laplace_correlation():
    joint = CalibratedJoint(
        keys=("rig.thermal_mass_J_per_K", "rig.heat_loss_W_per_K"),
        fields=(("rig", "thermal_mass"), ("rig", "heat_loss")),
        log=(True, True),
        sd=(0.05, 0.2),
        correlation=((1.0, 0.5), (0.5, 1.0)),
        sd_below=(0.05, 0.4),
        sd_above=(0.05, 0.1),
    )
    dist = band.from_calibration(joint, {("rig", "thermal_mass"): 0.02, ("rig", "heat_loss"): 0.001})
    assert "profile-likelihood" in dist.description
    d = dist.draw(100_000, np.random.default_rng(3))
    u = np.log(d[("rig", "heat_loss")] / 0.001)
    # the profile interval's ends are the 2.5 % and 97.5 % quantiles
    assert np.quantile(u, [0.025, 0.5, 0.975]) == pytest.approx([-Z * 0.4, 0.0, Z * 0.1], abs=0.01)
    v = np.log(d[("rig", "thermal_mass")] / 0.02)
    assert stats.spearmanr(u, v)[0] == pytest.approx(6 / np.pi * np.arcsin(0.5 / 2), abs=0.01)


def test_stated_draws_are_independent_with_the_stated_mean_and_sd():
    dist = band.from_stated({("rig", "heat_loss"): (0.00893, 0.01615), ("rig", "damping"): (0.84, 0.12)})
    assert not dist.calibrated
    assert band.band_label(False) == "95% stated-uncertainty band (parameters not calibrated)"
    d = dist.draw(200_000, np.random.default_rng(2))
    lam, b = d[("rig", "heat_loss")], d[("rig", "damping")]
    assert lam.min() > 0  # log-normal although the sd exceeds the value
    assert lam.mean() == pytest.approx(0.00893, rel=0.03) and lam.std() == pytest.approx(0.01615, rel=0.1)
    assert b.mean() == pytest.approx(0.84, rel=0.002) and b.std() == pytest.approx(0.12, rel=0.01)
    assert abs(np.corrcoef(np.log(lam), np.log(b))[0, 1]) < 0.01
    assert band.from_stated({("rig", "damping"): (0.84, 0.0)}) is None


def test_band_grid_decimates_a_long_log_and_keeps_every_input_change():
    t = np.arange(200_000) * 1e-3
    v = np.where((t % 7.0) < 1.0, 10.0, 0.0)  # a pulse every 7 s
    idx, decimated = band.band_grid(t, v, 1000)
    assert decimated and idx[0] == 0 and idx[-1] == t.size - 1
    assert 1000 <= idx.size <= 1000 + 2 * 29
    # the input held on the grid (zero-order hold) is the log's at every row
    held = v[idx][np.searchsorted(idx, np.arange(t.size), side="right") - 1]
    assert np.array_equal(held, v)
    short, dec = band.band_grid(t[:500], v[:500], 1000)
    assert not dec and np.array_equal(short, np.arange(500))


def test_long_logs_get_fewer_draws_within_the_budget():
    assert band.draws_for(10.0, 1000) == 1000
    assert band.draws_for(1000.0, 1000) == int(band.DRAW_SECONDS / 1000.0)
    assert band.draws_for(1e6, 1000) == band.MIN_DRAWS
    assert band.draws_for(1e6, 30) == 30


def test_rest_zero_and_its_sd():
    r = np.r_[np.full(49, 2e-6), np.full(100, 5e-5)]
    rest = np.arange(r.size) < 49
    zero, sd, n = band.rest_zero(r, rest, sigma=7e-6)
    assert (zero, n) == (pytest.approx(2e-6), 49) and sd == pytest.approx(1e-6)
    assert band.rest_zero(r, rest, 7e-6, zero_sd=3e-6)[1] == 3e-6
    assert band.rest_zero(r, np.zeros(r.size, bool), 7e-6) == (0.0, 7e-6, 0)


def test_informative_rows_compare_the_parameter_part_with_the_noise_part():
    s = 1.0
    half = np.array([0.0, 0.4 * Z, 0.5 * Z, 3.0])
    assert band.informative_rows(half, s).tolist() == [False, False, True, True]
    assert band.coverage(np.array([0, 1, 5.0]), np.zeros(3), np.full(3, 2.0)) == pytest.approx(2 / 3)
    assert band.coverage(np.zeros(3), np.zeros(3), np.ones(3), np.zeros(3, bool)) is None


# --- the dynamic kind ------------------------------------------------------------------


def _with_runs(text: str, names) -> str:
    runs = "runs = [" + ", ".join(f'"../raw/{n}.csv"' for n in names) + "]"
    return re.sub(r"runs = \[.*?\]", runs, text, count=1, flags=re.S)


def _lying_rig(tmp_path, seed):
    res = simulate(
        "dynamic",
        TEMPLATES / "dynamic.toml",
        seed=seed,
        out_dir=tmp_path,
        n_runs=5,
        parameter_error=1.0,
        noisy_zero=True,
    )
    return res.experiment_path


def _calibrated_withheld(path: Path, train_names, seconds: float | None = None) -> Path:
    """Calibrate on ``train_names`` (optionally their first ``seconds``); the calibrated file for runs 4-5."""
    text = path.read_text()
    if seconds is not None:
        for n in train_names:
            df = pd.read_csv(path.parent.parent / "raw" / f"{n}.csv")
            df[df["time_s"] < seconds].to_csv(path.parent.parent / "raw" / f"short_{n}.csv", index=False)
        train_names = [f"short_{n}" for n in train_names]
    train = path.with_name("train.toml")
    train.write_text(_with_runs(text, train_names))
    cal_text = calibrated_text(load_experiment(train), calibrate(train))
    held = path.with_name("withheld.calibrated.toml")
    held.write_text(_with_runs(cal_text, ["dynamic_run4", "dynamic_run5"]))
    return held


@pytest.fixture(scope="module")
def withheld(tmp_path_factory):
    """Seeds 31-33: calibrated on runs 1-3, validated on the withheld runs 4-5."""
    out = {}
    for seed in (31, 32, 33):
        path = _lying_rig(tmp_path_factory.mktemp(f"band{seed}"), seed)
        held = _calibrated_withheld(path, ["dynamic_run1", "dynamic_run2", "dynamic_run3"])
        out[seed] = (path, held, validate(load_experiment(held), mc_draws=400, seed=seed))
    return out


def test_calibrated_file_carries_the_joint_posterior(withheld):
    _, held, _ = next(iter(withheld.values()))
    exp = load_experiment(held)
    # the dynamic kind calibrates the rig's C_th, lambda, b and the sample's rho and G_t slope
    assert exp.calibration.fields == (
        ("rig", "thermal_mass"),
        ("rig", "heat_loss"),
        ("rig", "damping"),
        ("sample", "radial_cte"),
        ("sample", "shear_modulus_slope"),
    )
    # C_th, lambda, b in log coordinates; rho and the G_t slope linear (0 is a legitimate value)
    assert exp.calibration.log == (True, True, True, False, False)
    c = np.asarray(exp.calibration.correlation)
    # displacement alone ties C_th to rho (only their ratio is pinned): a strong correlation
    assert np.allclose(c, c.T) and abs(c[0, 3]) > 0.9
    # the marginal sd in [rig.uncertainty] is the log sd times the value (delta method)
    assert exp.rig.uncertainty["thermal_mass"] == pytest.approx(
        exp.calibration.sd[0] * exp.rig.thermal_mass, rel=1e-4
    )


def test_prediction_band_covers_95_percent_of_withheld_runs(withheld):
    for seed, (_, _, res) in withheld.items():
        info = res.extras["prediction_band"]
        assert info["label"] == "95% prediction band" and info["calibrated"] and info["nominal"] == 0.95
        runs = info["runs"].values()
        rows = sum(r["rows"] for r in runs)
        covered = sum(r["coverage"] * r["rows"] for r in runs) / rows
        assert 0.90 <= covered <= 0.98, (seed, covered)
        # after calibration on three full runs the band is mostly the noise-and-zero band; where
        # the parameter part exceeds half the noise part (informative rows: rho and the G_t
        # slope are drawn in linear coordinates, so the C_th/rho ridge is not a straight line
        # there), those rows are covered too, and the report says how many there are
        for r in runs:
            assert r["informative_rows"] < 0.3 * r["rows"], (seed, r["informative_rows"])
            if r["informative_rows"]:
                assert 0.90 <= r["coverage_informative"] <= 1.0, (seed, r["coverage_informative"])
            else:
                assert r["coverage_informative"] is None
        assert all(("informative rows" in n) for n in res.notes if "prediction band covers" in n)
        # the band is not zero-width before the pulse
        p = res.predictions[0]
        assert np.all(
            p.band["upper"][:40] - p.band["lower"][:40]
            > 2 * Z * 0.9 * info["runs"][p.name]["noise_sd_mm"] * 1e-3
        )


def test_band_is_centred_on_the_runs_zero(withheld):
    """The withheld runs are zeroed on one noisy reading: without the zero the band would miss."""
    for _, _, res in withheld.values():
        for p in res.predictions:
            s = res.extras["prediction_band"]["runs"][p.name]
            t = p.data["time"].to_numpy()
            mid = (p.band["lower"] + p.band["upper"]) / 2
            rest = (t > 0) & (t < 0.5)
            # the logged rest rows' mean (minus a zero validation may have subtracted already)
            want = np.mean(p.data["displacement"].to_numpy()[rest])
            assert np.median(mid[rest]) == pytest.approx(want, abs=0.1 * s["noise_sd_mm"] * 1e-3)
            assert abs(s["zero_mm"]) > 0  # a noisy zero, not the exact tare


def test_a_zero_validation_already_subtracted_is_not_applied_twice():
    """Validation may estimate each run's zero and subtract it (``RunPrediction.zeros``):
    the band is then centred on the model and takes the estimate's standard error."""
    from types import SimpleNamespace

    from tcamlab.validation import RunPrediction

    exp = load_experiment(Path(__file__).resolve().parent.parent / "experiments" / "dynamic.toml")
    res = validate(exp, mc_draws=0, **({"zeros": False} if "zeros" in validate.__code__.co_varnames else {}))
    p = res.predictions[0]
    logged = p.data["displacement"].to_numpy()
    zero = float(np.mean(logged[1:50]))
    moved = RunPrediction(p.name, p.data.assign(displacement=logged - zero), p.predicted)
    moved.zeros = {"displacement": SimpleNamespace(value=zero, stderr=2e-6, rows=49)}
    dist = kd.parameter_distribution(exp)
    b, info = kd.run_band(exp, moved, dist, draws=100, seed=0, call=lambda fn, *a, **k: fn(*a, **k))
    assert info["zero_mm"] == pytest.approx(zero * 1e3) and info["zero_sd_mm"] == pytest.approx(2e-3)
    assert info["rest_rows"] == 49 and info["rows"] == len(logged) - 1  # row 0 was the zeroing row
    assert np.allclose((b["lower"][:40] + b["upper"][:40]) / 2, 0.0, atol=1e-9)
    own, own_info = kd.run_band(exp, p, dist, draws=100, seed=0, call=lambda fn, *a, **k: fn(*a, **k))
    assert own_info["zero_mm"] == pytest.approx(zero * 1e3) and own_info["rest_rows"] == 49
    assert np.allclose((own["lower"][:40] + own["upper"][:40]) / 2, zero, atol=1e-9)


def test_uncalibrated_file_gets_a_stated_uncertainty_band_labelled_as_such(withheld):
    path, _, _ = next(iter(withheld.values()))
    stated = path.with_name("withheld.toml")
    stated.write_text(_with_runs(path.read_text(), ["dynamic_run4", "dynamic_run5"]))
    res = validate(load_experiment(stated), mc_draws=200)
    info = res.extras["prediction_band"]
    assert info["label"] == "95% stated-uncertainty band (parameters not calibrated)"
    assert not info["calibrated"]
    assert "independently" in info["distribution"]
    assert all(
        "stated-uncertainty band (parameters not calibrated) covers" in n for n in res.notes if "covers" in n
    )
    section = kd.extras_section(res)
    assert section.heading.startswith("95% stated-uncertainty band")
    assert any("not a prediction band" in t for t in section.paragraphs)
    caption = kd.figures(res)[0].caption
    assert (
        "stated-uncertainty band (parameters not calibrated)" in caption
        and "not a prediction band" in caption
    )
    legend = [t.get_text() for t in kd.figures(res)[0].figure.axes[0].get_legend().get_texts()]
    assert legend.count(info["label"]) == 1


def test_prediction_band_in_the_legend(withheld):
    _, _, res = next(iter(withheld.values()))
    fig = kd.figures(res)[0]
    legend = [t.get_text() for t in fig.figure.axes[0].get_legend().get_texts()]
    assert legend.count("95% prediction band") == 1
    assert "for measured points" in fig.caption


@pytest.mark.slow
def test_informative_rows_covered_on_withheld_runs_when_training_logs_are_short(tmp_path_factory):
    """Calibrated on the first 2 s of runs 1-3 (the cooling barely seen, so lambda is loose), the
    band on the full withheld runs is wider than the noise over most of the cooling. Pooled over
    seeds 41-44 (one set of true parameters per seed, so the pooled coverage varies from seed
    set to seed set by several percent), the informative rows are covered at 90-98 %."""
    inside = rows = 0
    for seed in (41, 42, 43, 44):
        path = _lying_rig(tmp_path_factory.mktemp(f"short{seed}"), seed)
        held = _calibrated_withheld(path, ["dynamic_run1", "dynamic_run2", "dynamic_run3"], seconds=2.0)
        res = validate(load_experiment(held), mc_draws=400, seed=seed)
        for r in res.extras["prediction_band"]["runs"].values():
            rows += r["informative_rows"]
            inside += (r["coverage_informative"] or 0.0) * r["informative_rows"]
    assert rows > 1000
    assert 0.90 <= inside / rows <= 0.98, (inside / rows, rows)


def test_long_log_band_on_a_decimated_grid_matches_the_full_band(monkeypatch, tmp_path):
    path = _lying_rig(tmp_path, 51)
    exp = load_experiment(path)
    full = validate(exp, mc_draws=200)
    monkeypatch.setattr(band, "MAX_GRID_POINTS", 150)
    dec = validate(exp, mc_draws=200)
    info = dec.extras["prediction_band"]["runs"]
    assert all(r["decimated"] and r["grid_points"] < 160 for r in info.values())
    assert any("decimated grid" in n for n in dec.notes)
    for a, b in zip(full.predictions, dec.predictions):
        width = np.median(a.band["upper"] - a.band["lower"])
        # interpolation error far below the band's width (the pulse edges are on the grid)
        assert np.quantile(np.abs(a.band["upper"] - b.band["upper"]), 0.95) < 0.1 * width
    covs = [r["coverage"] for r in info.values()]
    assert all(math.isfinite(c) for c in covs)
