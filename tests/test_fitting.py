"""Tests of tcamlab.fitting: closed forms, coverage, robustness, branches, runs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tcamlab.errors import InputError
from tcamlab.fitting import (
    SpringFit,
    SpringFitReport,
    fit_spring,
    fit_spring_runs,
    leave_one_out_spring,
    split_branches,
)

S_TRUE = 4.7  # N/m


def stepped_pull_test(rng, *, s=S_TRUE, unload=True, force_sd=2e-3, disp_sd=0.0):
    """2 mm steps to 50 mm, 5 s dwell per step at 10 Hz (50 samples), in SI."""
    levels = np.arange(0.0, 50.0 + 1e-9, 2.0) * 1e-3
    path = levels if not unload else np.concatenate([levels, levels[-2::-1]])
    x = np.repeat(path, 50)
    force = s * x + rng.normal(0.0, force_sd, x.size)
    x_logged = x + (rng.normal(0.0, disp_sd, x.size) if disp_sd else 0.0)
    return x_logged, force, int(levels.size * 50)


# --------------------------------------------------------------------------
# closed forms
# --------------------------------------------------------------------------


def test_exact_line_through_origin():
    x = np.linspace(0.001, 0.05, 20)
    fit = fit_spring(x, 2.5 * x)
    assert fit.spring_constant == pytest.approx(2.5, rel=1e-12)
    assert fit.stderr == pytest.approx(0.0, abs=1e-12)
    assert fit.ci95[0] == pytest.approx(2.5, rel=1e-12) and fit.ci95[1] == pytest.approx(2.5, rel=1e-12)
    assert fit.r2 == pytest.approx(1.0, abs=1e-12)
    assert fit.intercept == 0.0 and fit.intercept_stderr == 0.0
    assert fit.method == "ols-origin" and fit.n == 20 and fit.run == "pooled" and fit.branch_label == "all"
    np.testing.assert_allclose(fit.residuals, 0.0, atol=1e-14)


def test_hand_example_through_origin():
    x = np.array([1.0, 2.0, 3.0])
    f = np.array([2.0, 4.0, 7.0])
    fit = fit_spring(x, f)
    # S = sum(xF)/sum(x^2) = 31/14; residuals (-3, -6, 5)/14; SS_res = 70/196 = 5/14
    s = 31 / 14
    se = math.sqrt((5 / 14) / 2 / 14)  # dof n - 1 = 2
    t2 = math.sqrt(2 * 0.95**2 / (1 - 0.95**2))  # t_{0.975, 2}: t / sqrt(2 + t^2) = 0.95
    assert fit.spring_constant == pytest.approx(s, rel=1e-14)
    assert fit.stderr == pytest.approx(se, rel=1e-12)
    assert fit.ci95[0] == pytest.approx(s - t2 * se, rel=1e-10)
    assert fit.ci95[1] == pytest.approx(s + t2 * se, rel=1e-10)
    assert fit.r2 == pytest.approx(1 - (5 / 14) / 69, rel=1e-14)  # uncentred: sum F^2 = 69
    np.testing.assert_allclose(fit.residuals, np.array([-3.0, -6.0, 5.0]) / 14, atol=1e-14)


def test_hand_example_with_intercept():
    x = np.array([1.0, 2.0, 3.0])
    f = np.array([2.0, 4.0, 7.0])
    fit = fit_spring(x, f, intercept=True)
    # Sxx = 2, Sxy = 5 -> S = 5/2, c = 13/3 - 5 = -2/3; residuals (1, -2, 1)/6; SS_res = 1/6
    t1 = math.tan(math.pi * 0.475)  # t_{0.975, 1} (Cauchy)
    se = math.sqrt((1 / 6) / 1 / 2)
    assert fit.method == "ols-intercept"
    assert fit.spring_constant == pytest.approx(2.5, rel=1e-14)
    assert fit.intercept == pytest.approx(-2 / 3, rel=1e-14)
    assert fit.stderr == pytest.approx(se, rel=1e-12)
    assert fit.intercept_stderr == pytest.approx(math.sqrt((1 / 6) * (1 / 3 + 4 / 2)), rel=1e-12)
    assert fit.ci95[1] - fit.ci95[0] == pytest.approx(2 * t1 * se, rel=1e-10)
    assert fit.r2 == pytest.approx(1 - (1 / 6) / (114 / 9), rel=1e-14)  # centred
    assert fit.dof == 1


def test_intercept_recovers_slope_and_offset():
    x = np.linspace(0.0, 0.05, 30)
    fit = fit_spring(x, 3.2 * x + 0.15, intercept=True)
    assert fit.spring_constant == pytest.approx(3.2, rel=1e-12)
    assert fit.intercept == pytest.approx(0.15, rel=1e-12)
    assert fit.stderr == pytest.approx(0.0, abs=1e-10)
    # through the origin the offset biases S
    assert abs(fit_spring(x, 3.2 * x + 0.15).spring_constant - 3.2) > 1.0


@pytest.mark.parametrize("intercept", [False, True])
def test_ci_coverage(intercept):
    rng = np.random.default_rng(20240611 + intercept)
    x = np.linspace(0.002, 0.05, 12)
    hits = 0
    for _ in range(400):
        f = S_TRUE * x + 0.02 * intercept + rng.normal(0.0, 0.005, x.size)
        lo, hi = fit_spring(x, f, intercept=intercept).ci95
        hits += lo <= S_TRUE <= hi
    assert 0.92 <= hits / 400 <= 0.98


def test_robust_resists_gross_outliers():
    rng = np.random.default_rng(7)
    x = np.linspace(0.001, 0.05, 200)
    f = S_TRUE * x + rng.normal(0.0, 2e-3, x.size)
    bad = rng.choice(x.size, size=20, replace=False)
    f[bad] += rng.uniform(0.05, 0.2, bad.size)  # gross, one-sided
    ols = fit_spring(x, f)
    rob = fit_spring(x, f, robust=True)
    assert rob.method == "robust-origin"
    assert abs(rob.spring_constant / S_TRUE - 1) < 0.02
    assert abs(ols.spring_constant / S_TRUE - 1) > 0.02
    # soft_l1 bounds but does not remove the pull of one-sided outliers
    assert 0 < rob.stderr < ols.stderr
    rob_c = fit_spring(x, f + 0.01, robust=True, intercept=True)
    assert rob_c.method == "robust-intercept"
    assert abs(rob_c.spring_constant / S_TRUE - 1) < 0.02
    assert rob_c.intercept == pytest.approx(0.01, abs=3e-3)


def test_robust_on_clean_data_matches_ols():
    rng = np.random.default_rng(3)
    x = np.linspace(0.001, 0.05, 100)
    f = S_TRUE * x + rng.normal(0.0, 2e-3, x.size)
    ols, rob = fit_spring(x, f), fit_spring(x, f, robust=True)
    assert rob.spring_constant == pytest.approx(ols.spring_constant, abs=3 * ols.stderr)
    assert rob.stderr == pytest.approx(ols.stderr, rel=0.5)


def test_stepped_pull_test_recovers_s():
    rng = np.random.default_rng(11)
    x, f, _ = stepped_pull_test(rng, unload=False)
    fit = fit_spring(x, f)
    assert abs(fit.spring_constant / S_TRUE - 1) < 0.02
    assert fit.ci95[0] <= S_TRUE <= fit.ci95[1]


@settings(max_examples=50, deadline=None)
@given(
    st.floats(min_value=1e-3, max_value=1e3),
    st.floats(min_value=1e-3, max_value=1e3),
    st.booleans(),
)
def test_scaling_equivariance(kf, kx, intercept):
    rng = np.random.default_rng(5)
    x = np.linspace(0.001, 0.05, 15)
    f = S_TRUE * x + 0.01 + rng.normal(0.0, 2e-3, x.size)
    a = fit_spring(x, f, intercept=intercept)
    b = fit_spring(kx * x, kf * f, intercept=intercept)
    assert b.spring_constant == pytest.approx(a.spring_constant * kf / kx, rel=1e-9)
    assert b.stderr == pytest.approx(a.stderr * kf / kx, rel=1e-9)
    assert b.r2 == pytest.approx(a.r2, rel=1e-9, abs=1e-12)


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "x, f, match",
    [
        ([0.01, 0.02], [0.1, 0.2], "at least 3"),
        ([0.0, 0.0, 0.0], [0.1, 0.2, 0.3], "zero everywhere"),
        ([0.01, np.nan, 0.03], [0.1, 0.2, 0.3], "non-finite"),
        ([0.01, 0.02, 0.03], [0.1, np.inf, 0.3], "non-finite"),
        ([0.01, 0.02, 0.03], [0.1, 0.2], "force values"),
    ],
)
def test_invalid_input_raises(x, f, match):
    with pytest.raises(InputError, match=match) as info:
        fit_spring(x, f)
    assert info.value.hint
    assert "\n" not in str(info.value)


def test_constant_displacement_with_intercept_raises():
    with pytest.raises(InputError, match="constant"):
        fit_spring([0.01] * 4, [0.1, 0.2, 0.1, 0.2], intercept=True)
    # through the origin it is fine: S = mean(F) / x
    assert fit_spring([0.01] * 4, [0.1, 0.2, 0.1, 0.2]).spring_constant == pytest.approx(15.0)


# --------------------------------------------------------------------------
# SpringFit output
# --------------------------------------------------------------------------


def test_to_dict_is_json_safe_and_to_pandas_one_row():
    x = np.linspace(0.001, 0.05, 10)
    fit = fit_spring(x, 2.0 * x + 0.001 * np.sin(x * 1e3), run="r1")
    d = fit.to_dict()
    json.dumps(d, allow_nan=False)
    assert "residuals_N" not in d
    assert d["spring_constant_N_per_m"] == fit.spring_constant and d["run"] == "r1"
    assert all(isinstance(v, float) for v in d["ci95_N_per_m"])
    dr = fit.to_dict(include_residuals=True)
    assert len(dr["residuals_N"]) == 10 and isinstance(dr["residuals_N"], list)
    json.dumps(dr, allow_nan=False)
    df = fit.to_pandas()
    assert df.shape[0] == 1
    assert df.loc[0, "ci95_low_N_per_m"] == fit.ci95[0]
    # r2 of F = 0 through origin is undefined -> None in JSON
    zero = fit_spring(x, np.zeros_like(x))
    assert zero.to_dict()["r2"] is None
    json.dumps(zero.to_dict(), allow_nan=False)


def test_plots_do_not_touch_pyplot():
    import matplotlib
    from matplotlib.figure import Figure

    x = np.linspace(0.001, 0.05, 10)
    fit = fit_spring(x, 2.0 * x)
    before = list(matplotlib._pylab_helpers.Gcf.get_all_fig_managers())
    ax = fit.plot()
    assert isinstance(ax.figure, Figure)
    assert len(ax.lines) == 2
    ax2 = fit.plot_residuals()
    assert isinstance(ax2.figure, Figure) and ax2 is not ax
    # given axes are drawn on and returned
    fig = Figure()
    given_ax = fig.add_subplot()
    assert fit.plot(given_ax) is given_ax
    assert list(matplotlib._pylab_helpers.Gcf.get_all_fig_managers()) == before


# --------------------------------------------------------------------------
# branches
# --------------------------------------------------------------------------


def test_split_rise_then_fall_noisy():
    rng = np.random.default_rng(2)
    x = np.concatenate([np.linspace(0, 0.05, 300), np.linspace(0.05, 0.0, 200)[1:]])
    x_noisy = x + rng.normal(0.0, 5e-5, x.size)
    x_noisy[[50, 120, 350]] += 0.02  # spikes
    b = split_branches(x_noisy)
    assert set(b) == {"loading", "unloading"}
    assert not np.any(b["loading"] & b["unloading"]) and np.all(b["loading"] | b["unloading"])
    first_unloading = int(np.flatnonzero(b["unloading"])[0])
    assert abs(first_unloading - 300) <= 10
    assert b["loading"][:290].all() and b["unloading"][310:].all()


def test_split_stepped_with_dwell_ends_loading_after_top_dwell():
    rng = np.random.default_rng(4)
    x, _, n_up = stepped_pull_test(rng, disp_sd=5e-6)
    b = split_branches(x)
    assert int(b["loading"].sum()) == n_up
    assert b["loading"][:n_up].all() and b["unloading"][n_up:].all()


def test_split_rise_only_and_tiny_drop():
    x = np.linspace(0.0, 0.05, 100)
    assert list(split_branches(x)) == ["loading"]
    assert split_branches(x)["loading"].all()
    # drop after the maximum within the noise
    rng = np.random.default_rng(9)
    y = np.concatenate([x, np.full(50, 0.05)]) + rng.normal(0, 1e-5, 150)
    y[-20:] -= 2e-5
    assert list(split_branches(y)) == ["loading"]
    # fewer than 3 points after the max
    z = np.concatenate([x, [0.04, 0.03]])
    assert list(split_branches(z)) == ["loading"]


def test_split_uses_time_order():
    x = np.concatenate([np.linspace(0, 0.05, 50), np.linspace(0.05, 0, 50)[1:]])
    t = np.arange(x.size, dtype=float)
    perm = np.random.default_rng(0).permutation(x.size)
    b = split_branches(x[perm], t[perm])
    np.testing.assert_array_equal(b["loading"], (t[perm] <= 49))
    with pytest.raises(InputError):
        split_branches(x, t[:-1])


# --------------------------------------------------------------------------
# several runs
# --------------------------------------------------------------------------


def _runs(rng):
    a = stepped_pull_test(rng, disp_sd=5e-6)
    b = stepped_pull_test(rng, unload=False)
    c = stepped_pull_test(rng, s=S_TRUE * 1.01)
    return [("a", a[0], a[1]), ("b", b[0], b[1]), ("c", c[0], c[1])]


def test_fit_spring_runs_per_run_branch_and_pooled():
    rng = np.random.default_rng(12)
    runs = _runs(rng)
    rep = fit_spring_runs(runs)
    assert isinstance(rep, SpringFitReport) and isinstance(rep.pooled, SpringFit)
    labels = [(f.run, f.branch_label) for f in rep.fits]
    assert labels == [
        ("a", "all"), ("a", "loading"), ("a", "unloading"),
        ("b", "all"),
        ("c", "all"), ("c", "loading"), ("c", "unloading"),
    ]  # fmt: skip
    for fit in rep.fits:
        assert abs(fit.spring_constant / S_TRUE - 1) < 0.02, (fit.run, fit.branch_label)
    assert abs(rep.pooled.spring_constant / S_TRUE - 1) < 0.02
    assert rep.pooled.run == "pooled" and rep.pooled.n == sum(len(r[1]) for r in runs)
    # by default every run has its own F0 (the pooled fit changed from one line through the
    # origin to one S with a tare per run: the load cell's zero is a nuisance)
    assert [r["run"] for r in rep.pooled.run_intercepts] == ["a", "b", "c"]
    # through the origin, pooled is a single fit on the concatenated data
    origin = fit_spring_runs(runs, intercept=False)
    direct = fit_spring(np.concatenate([r[1] for r in runs]), np.concatenate([r[2] for r in runs]))
    assert origin.pooled.spring_constant == pytest.approx(direct.spring_constant, rel=1e-14)

    d = rep.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["spring_constant_N_per_m"] == rep.pooled.spring_constant
    assert len(d["runs"]) == 7
    df = rep.to_pandas()
    assert len(df) == 8 and df.iloc[-1]["run"] == "pooled"
    ax = rep.plot()
    assert ax.get_xlabel() == "displacement [mm]"

    flat = fit_spring_runs(runs, by_branch=False, robust=True, intercept=True)
    assert [f.branch_label for f in flat.fits] == ["all"] * 3
    assert flat.pooled.method == "robust-intercept"


def test_fit_spring_runs_errors():
    x = np.linspace(0.001, 0.05, 10)
    with pytest.raises(InputError, match="no runs"):
        fit_spring_runs([])
    with pytest.raises(InputError, match="twice"):
        fit_spring_runs([("a", x, x), ("a", x, x)])
    with pytest.raises(InputError, match=r"\[b/all\].*at least 3"):
        fit_spring_runs([("a", x, x), ("b", x[:2], x[:2])])


def test_leave_one_out():
    rng = np.random.default_rng(13)
    runs = _runs(rng)
    loo = leave_one_out_spring(runs, "c")
    direct = fit_spring(np.concatenate([runs[0][1], runs[1][1]]), np.concatenate([runs[0][2], runs[1][2]]))
    assert loo.spring_constant == pytest.approx(direct.spring_constant, rel=1e-14)
    assert loo.run == "pooled-without-c"
    assert leave_one_out_spring(runs, "a", robust=True, by_branch=True).method == "robust-origin"
    with pytest.raises(InputError, match="no run named") as info:
        leave_one_out_spring(runs, "zzz")
    assert "a, b, c" in info.value.hint
    with pytest.raises(InputError, match="at least two runs") as info:
        leave_one_out_spring(runs[:1], "a")
    assert "spring_constant_N_per_m" in info.value.hint and "[rig]" in info.value.hint


# --------------------------------------------------------------------------
# the load cell's zero F0
# --------------------------------------------------------------------------


def test_pooled_fit_has_one_intercept_per_run_by_hand():
    """S from the within-run (demeaned) sums, each F0 = mean F - S mean delta of its run,
    SE(S) = sqrt(SS_res / (n - 1 - runs) / Sxx_within)."""
    rng = np.random.default_rng(21)
    runs = []
    for name, f0 in (("a", -1e-3), ("b", 2e-3), ("c", 0.5e-3)):
        x = np.linspace(0.0, 0.05, 40 + len(runs) * 7)
        runs.append((name, x, S_TRUE * x + f0 + rng.normal(0.0, 1e-3, x.size)))
    pooled = fit_spring_runs(runs, by_branch=False).pooled
    sxy = sum(np.dot(x - x.mean(), f - f.mean()) for _, x, f in runs)
    sxx = sum(np.dot(x - x.mean(), x - x.mean()) for _, x, _ in runs)
    s = sxy / sxx
    f0 = [f.mean() - s * x.mean() for _, x, f in runs]
    ss = sum(np.sum((f - s * x - c) ** 2) for (_, x, f), c in zip(runs, f0))
    n = sum(x.size for _, x, _ in runs)
    assert pooled.spring_constant == pytest.approx(s, rel=1e-10)
    assert [r["intercept_N"] for r in pooled.run_intercepts] == pytest.approx(f0, rel=1e-8)
    assert pooled.intercept == pytest.approx(np.mean(f0), rel=1e-8)
    assert pooled.stderr == pytest.approx(math.sqrt(ss / (n - 4) / sxx), rel=1e-8)
    assert pooled.dof == n - 4 and pooled.r2_kind == "centred"
    # one common line would not do: the runs' tares differ by 3 mN
    assert fit_spring_runs(runs, intercept=False).pooled.r2_kind == "uncentred"


def test_significant_intercept_is_warned_and_labelled():
    x = np.repeat(np.linspace(0.0, 0.05, 26), 4)
    wiggle = np.tile([1e-3, -1e-3, 1e-3, -1e-3], 26)  # symmetric noise: F0 is exactly what is added
    clean = fit_spring_runs([("r", x, S_TRUE * x + wiggle)], by_branch=False)
    assert clean.warnings == [] and not clean.pooled.intercept_significant
    off = fit_spring_runs([("r", x, S_TRUE * x - 0.4e-3 + wiggle)], by_branch=False)
    assert off.pooled.intercept == pytest.approx(-0.4e-3, rel=1e-9)
    assert off.pooled.intercept_significant and "zero is off" in off.warnings[0]
    assert "-0.4 mN" in off.warnings[0]
    forced = fit_spring_runs([("r", x, S_TRUE * x - 0.4e-3 + wiggle)], intercept=False, by_branch=False)
    assert "biased" in forced.warnings[0] and "origin" in forced.warnings[0]
    d = off.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["pooled"]["intercept_significant"] is True and d["r2_kind"] == "centred"
    assert d["pooled"]["intercept_ci95_N"][1] < 0 and "standard error" in d["uncertainty"]
    assert forced.to_dict()["r2_kind"] == "uncentred" and forced.to_dict()["through_origin"] is True


@pytest.mark.parametrize("noisy_zero", [False, True])
def test_load_cell_offset_no_longer_biases_s(tmp_path, noisy_zero):
    """Pull tests from the virtual rig (synthetic: tcamlab.rig.simulate, the sensing template's
    S = 4.7 N/m, the load cell's -0.4 mN zero offset, or a tare redrawn per run with noisy_zero;
    seeds 1-8): the 95% CI of S contains 4.7 as a 95% interval should, the origin-forced fit's never."""
    from tcamlab import rig
    from tcamlab.pipeline import fit_spring_files
    from tcamlab.templates import template_path

    covered, z = 0, []
    for seed in range(1, 9):
        res = rig.simulate(
            "sensing",
            template_path("sensing"),
            seed=seed,
            out_dir=tmp_path / str(seed),
            noisy_zero=noisy_zero,
        )
        fit = fit_spring_files([res.experiment_path]).pooled
        covered += fit.ci95[0] <= S_TRUE <= fit.ci95[1]
        z.append((fit.spring_constant - S_TRUE) / fit.stderr)
        origin = fit_spring_files([res.experiment_path], intercept=False).pooled
        assert not origin.ci95[0] <= S_TRUE <= origin.ci95[1], seed
        assert abs(origin.spring_constant - S_TRUE) > 5 * origin.stderr
    assert covered >= 6  # of 8: P(fewer) < 1% for a true 95% interval
    assert np.max(np.abs(z)) < 4
