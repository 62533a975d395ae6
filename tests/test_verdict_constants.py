"""Every threshold, quantile and weighting of the verdict, the noise floor and the bands against
a hand-computed value.

Each test feeds a small hand-made input (candidate scores, bootstrap samples, shifts and
covariances) to the function that uses the constant, at and beside its threshold, and compares
with the documented level through scipy's own quantiles, so that a small change of a constant,
of a formula or of a comparison fails.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import special, stats

from tcamlab import band
from tcamlab.calibration.problem import Spec
from tcamlab.diagnosis import noise, verdict
from tcamlab.diagnosis.candidates import CI_LEVEL, ci, effect_parameters
from tcamlab.diagnosis.noise import (
    GAP_LEVEL,
    MEDIAN_EFFICIENCY,
    POOL_CONSISTENCY_LEVEL,
    SECOND_DIFF_EFFICIENCY,
    BaselineFit,
    check_gap,
    gap_limit,
    pool_noise_estimates,
    second_difference_sigma,
)
from tcamlab.diagnosis.recalibration import (
    ALIAS_CORRELATION,
    PLAUSIBLE_LEVEL,
    RECALIBRATION,
    Recalibration,
)
from tcamlab.diagnosis.result import CandidateResult
from tcamlab.diagnosis.verdict import (
    JOINT_LEVEL,
    MIN_FRACTION_CLOSED,
    MIN_PARTIAL_FRACTION,
    PAIR_POOL,
    SWITCHED_OFF,
    WHOLE_FRACTION,
    beats,
    closes_the_rest,
    leaves_a_gap,
    moved_jointly,
    named_parameters,
    pair_verdict,
    qualifies,
    restores_combination,
    stands_in,
    switched_off,
)
from tcamlab.kinds import CalibrationParam

Z_975 = stats.norm.ppf(0.975)  # the documented "95 %" two-sided


def cand(effect="E", fraction=0.8, lower=0.1, term=1.0, after=1.0, **kw) -> CandidateResult:
    return CandidateResult(
        effect=effect,
        heldout_rmse_before=3.0,
        heldout_rmse_after=after,
        unit="noise",
        heldout_rmse_before_noise=3.0,
        heldout_rmse_after_noise=after,
        shrinkage=0.5,
        shrinkage_ci95=[lower, 0.9],
        fraction_closed=fraction,
        aic=0.0,
        bic=0.0,
        parameters={},
        by_quantity={},
        folds=[],
        term_rms=term,
        **kw,
    )


# bootstrap over 101 folds, each bootstrap sample one fold: a name's samples are its fold values
K = 101
BOOT = np.arange(K).reshape(K, 1)
S = np.arange(K, dtype=float)  # 2.5 % quantile 2.5, 97.5 % quantile 97.5 (linear interpolation)


# ---------------------------------------------------------------------------- intervals
def test_ci_is_the_central_95_percent_of_the_samples():
    assert ci(S) == pytest.approx([2.5, 97.5], abs=1e-12)
    assert ci(np.append(S, [np.nan, np.inf])) == pytest.approx([2.5, 97.5], abs=1e-12)
    assert CI_LEVEL == 0.95


def test_beats_needs_the_interval_of_the_difference_strictly_above_0():
    for eps, expected in ((-1e-6, False), (1e-6, True)):
        after = {"ref": S - 2.5 + eps, "name": np.zeros(K)}
        assert beats(after, "name", "ref", BOOT, 1.0) is expected
    # equal held-out errors: an interval [0, 0] is not above 0
    assert not beats({"ref": S, "name": S.copy()}, "name", "ref", BOOT, 1.0)


def test_effect_parameter_interval_is_z_975_stderrs():
    p = SimpleNamespace(field="lag", unit="s", scale=2.0, lower=-np.inf, upper=np.inf)
    eff = SimpleNamespace(params=[p])
    fit = SimpleNamespace(u=np.zeros(2), values=[0.3], box=None)
    cov = np.diag([1.0, 1.0, 0.04])
    out = effect_parameters(eff, fit, cov)["lag"]
    assert out["stderr"] == pytest.approx(0.4, rel=1e-12)
    assert out["ci95"] == pytest.approx([0.3 - Z_975 * 0.4, 0.3 + Z_975 * 0.4], rel=1e-12)


# ---------------------------------------------------------------------------- qualifying
def test_qualifies_at_and_beside_half_the_gap():
    assert qualifies(cand(fraction=0.5))
    assert not qualifies(cand(fraction=0.5 * (1 - 1e-9)))
    assert not qualifies(cand(fraction=float("nan")))
    assert MIN_FRACTION_CLOSED == 0.5


def test_qualifies_needs_the_shrinkage_interval_strictly_above_0():
    assert not qualifies(cand(lower=0.0))
    assert qualifies(cand(lower=1e-12))


def test_switched_off_below_a_hundredth_of_the_noise():
    assert not switched_off(cand(term=0.01))
    assert switched_off(cand(term=0.01 * (1 - 1e-9)))
    assert not qualifies(cand(term=0.01 * (1 - 1e-9)))
    assert qualifies(cand(term=float("nan")))  # recalibration alone has no term
    assert SWITCHED_OFF == 0.01


def test_closes_the_rest_at_half_of_what_recalibration_leaves():
    recal = cand(RECALIBRATION, after=2.0)
    # (4 - 2.25) / (4 - 0.5) = 0.5 exactly
    assert closes_the_rest(cand(after=1.5), recal, floor2=0.5)
    assert not closes_the_rest(cand(after=1.5 * (1 + 1e-9)), recal, floor2=0.5)
    # default noise floor 1: (4 - 2.4) / 3 = 0.53 closes, but not above a floor of 0.5 (0.46)
    assert closes_the_rest(cand(after=math.sqrt(2.4)), recal)
    assert not closes_the_rest(cand(after=math.sqrt(2.4)), recal, floor2=0.5)
    assert not closes_the_rest(cand(after=0.1), recal, floor2=4.0)  # nothing left
    assert closes_the_rest(cand(after=2.9), None)


# ---------------------------------------------------------------------------- the verdict
def _winners(eps):
    """Recalibration and two effects that both beat it; the runner-up's held-out error exceeds
    the best's by a bootstrap whose 2.5 % quantile is ``eps``."""
    after = {
        RECALIBRATION: 200.0 + 2 * S,
        "E1": S.copy(),
        "E2": S + (S - 2.5 + eps),
    }
    ranking = [cand(RECALIBRATION, after=2.0), cand("E1"), cand("E2")]
    return verdict.verdict(ranking, True, after, BOOT, 1.0, 3.0, 1.2)


def test_attributed_only_when_every_other_candidate_is_clearly_worse():
    v, effect, aliased, reason = _winners(1e-6)
    assert (v, effect, aliased) == ("attributed", "E1", [])
    assert "clearly worse" in reason
    v, effect, aliased, _ = _winners(-1e-6)
    assert (v, effect, aliased) == ("aliased", "E1", ["E2"])


def test_an_effect_that_leaves_a_gap_of_its_own_is_not_named():
    after = {RECALIBRATION: 200.0 + 2 * S, "E1": S.copy()}
    recal = cand(RECALIBRATION, fraction=0.5, after=2.0)

    def judged(fraction, left):
        return verdict.verdict(
            [cand("E1", fraction=fraction, after=left), recal], True, after, BOOT, 1.0, 3.0, 1.2
        )

    v, effect, aliased, reason = judged(0.79, 1.5)
    assert (v, effect, aliased) == ("unexplained", None, [])
    assert (
        "E1 closes 79% of the gap" in reason and "1.50 x the noise floor" in reason and "limit 1.20" in reason
    )
    # at 90 % closed, or leaving no more than the no-gap limit, it is the explanation
    assert judged(0.9, 1.5)[:2] == ("attributed", "E1")
    assert judged(0.9 * (1 - 1e-9), 1.5)[0] == "unexplained"
    assert judged(0.79, 1.2)[:2] == ("attributed", "E1")
    assert judged(0.79, 1.2 * (1 + 1e-9))[0] == "unexplained"
    assert WHOLE_FRACTION == 0.9
    # nor is it an alias of an effect that explains the whole gap
    after["E2"] = S.copy()
    ranking = [cand("E1"), cand("E2", fraction=0.8, after=1.5), recal]
    assert verdict.verdict(ranking, True, after, BOOT, 1.0, 3.0, 1.2)[:3] == ("attributed", "E1", [])
    ranking[1] = cand("E2", fraction=0.8, after=1.2)
    assert verdict.verdict(ranking, True, after, BOOT, 1.0, 3.0, 1.2)[:3] == ("aliased", "E1", ["E2"])
    assert leaves_a_gap(cand(fraction=0.5, after=1.3), 1.2)
    assert not leaves_a_gap(cand(fraction=0.5, after=1.3), 1.3)


def test_no_gap_is_none():
    assert verdict.verdict([cand()], False, {}, BOOT, 1.0, 1.1, 1.2)[0] == "none"


def _recal(shift_r0, reading_sd=1e-3, r0_prior=0.3, s_prior=0.8, lo_edge=None):
    stated = 1.0
    value = stated + shift_r0
    lo = value - 1e-5 if lo_edge is None else lo_edge
    params = {
        "R0": {
            "value": value,
            "stated": stated,
            "ci95": [lo, value + 1e-5],
            "reading": [value, reading_sd],
            "shift_in_prior_sds": r0_prior,
        },
        "S": {"value": 2.0, "stated": 2.0, "ci95": [1.9, 2.1], "shift_in_prior_sds": s_prior},
    }
    return cand(RECALIBRATION, recalibrated=params)


def test_a_parameter_read_directly_is_named_beyond_its_readings_95_percent():
    sd = 1e-3
    # beside the documented quantile 1.95996 (the code's 1.96 lies between the two)
    assert named_parameters(_recal(1.9599 * sd, sd)) == ["S"]  # within: the largest prior shift
    assert named_parameters(_recal(1.9601 * sd, sd)) == ["R0"]
    assert Z_975 == pytest.approx(1.96, abs=1e-4)


def test_an_interval_ending_at_the_stated_value_covers_it():
    # R0's interval excludes the stated value by a hair, then starts at it
    assert named_parameters(_recal(0.01, lo_edge=1.0 + 1e-12)) == ["R0"]
    assert named_parameters(_recal(0.01, lo_edge=1.0)) == ["S"]


def _joint(scale, cov=None):
    q = stats.chi2.ppf(0.95, 2)
    u = np.full(2, math.sqrt(q / 2) * scale)
    return cand(RECALIBRATION, shift_u=u, shift_cov=np.eye(2) if cov is None else cov)


def test_moved_jointly_beyond_the_95_percent_chi2_quantile():
    assert moved_jointly(_joint(1 + 1e-7))
    assert not moved_jointly(_joint(1 - 1e-7))
    assert JOINT_LEVEL == 0.95


def test_restores_combination_inside_z_975_sds():
    recal = cand(RECALIBRATION, shift_u=np.array([1.0, 0.0]), shift_cov=np.eye(2))
    var = 0.25  # the effect's fit: sd 0.5 along w = (1, 0)
    for scale, expected in ((1 - 1e-9, True), (1 + 1e-9, False)):
        c = cand(shift_u=np.array([Z_975 * 0.5 * scale, 3.0]), shift_cov=np.diag([var, 9.0]))
        assert restores_combination(c, recal) is expected


def test_stands_in_by_the_combination_when_no_single_interval_moved():
    covering = {"A": {"ci95": [0.0, 2.0], "stated": 1.0}, "B": {"ci95": [0.0, 2.0], "stated": 1.0}}
    q = stats.chi2.ppf(0.95, 2)
    recal = cand(
        RECALIBRATION,
        recalibrated=covering,
        shift_u=np.full(2, math.sqrt(q / 2) * 1.001),
        shift_cov=np.eye(2),
    )
    # along w = recal's shift (unit vector e), c's sd is 0.1 (covariance 0.01 I): inside z 0.1
    e = recal.shift_u / np.linalg.norm(recal.shift_u)
    inside = cand(shift_u=e * 0.99 * Z_975 * 0.1, shift_cov=np.eye(2) * 0.01)
    assert stands_in(inside, recal, ["A", "B"])
    weak = cand(RECALIBRATION, recalibrated=covering, shift_u=np.full(2, math.sqrt(q / 2) * 0.999))
    weak.shift_cov = np.eye(2)
    assert not stands_in(inside, weak, ["A", "B"])


# ---------------------------------------------------------------------------- pairs
def _pair(fraction=0.5, lower=0.1):
    return cand("E1+E2", fraction=fraction, lower=lower, members=("E1", "E2"))


def test_pair_qualifies_at_half_the_gap_and_clearly_better_than_each_member():
    after = {"E1": 10 + S, "E2": 10 + S, RECALIBRATION: 10 + S, "E1+E2": S.copy()}
    order = {"E1": 0, "E2": 1}
    assert pair_verdict([_pair(0.5)], after, BOOT, 1.0, order)[:3] == ("attributed", "E1", [])
    assert pair_verdict([_pair(0.5 * (1 - 1e-9))], after, BOOT, 1.0, order) is None
    assert pair_verdict([_pair(lower=0.0)], after, BOOT, 1.0, order) is None
    # a member not clearly worse (its interval's lower end just below 0): not both needed
    after["E2"] = S + (S - 2.5 - 1e-6)
    assert pair_verdict([_pair(0.5)], after, BOOT, 1.0, order) is None
    after["E2"] = S + (S - 2.5 + 1e-6)
    assert pair_verdict([_pair(0.5)], after, BOOT, 1.0, order) is not None
    after["E2"] = S.copy()  # as good as the pair: an interval [0, 0] is not above 0
    assert pair_verdict([_pair(0.5)], after, BOOT, 1.0, order) is None


def test_a_pair_that_leaves_a_gap_of_its_own_is_not_named():
    after = {"E1": 10 + S, "E2": 10 + S, RECALIBRATION: 10 + S, "E1+E2": S.copy()}
    order = {"E1": 0, "E2": 1}
    pair = cand("E1+E2", fraction=0.6, after=1.5, members=("E1", "E2"))
    assert pair_verdict([pair], after, BOOT, 1.0, order) is not None  # no limit given
    assert pair_verdict([pair], after, BOOT, 1.0, order, 1.5)[:2] == ("attributed", "E1")
    assert pair_verdict([pair], after, BOOT, 1.0, order, 1.4) is None


def test_pair_pool_takes_the_best_four_closing_at_least_5_percent():
    fractions = [0.9, 0.05, 0.05 * (1 - 1e-9), 0.3, 0.2, 0.1]
    ranking = [cand(f"E{k}", fraction=f) for k, f in enumerate(fractions)]
    assert verdict._pair_pool(ranking) == ["E0", "E1", "E3", "E4"]
    assert (MIN_PARTIAL_FRACTION, PAIR_POOL) == (0.05, 4)


# ---------------------------------------------------------------------------- recalibration
def _param(field, positive=True):
    return CalibrationParam(field, "sample", field, "-", 0.1, "a test", positive)


def _rec(p=2):
    rec = Recalibration.__new__(Recalibration)
    rec.specs = [Spec(f"x{k}", _param(f"x{k}"), (0,), 2.0, True, 0.2, True, f"x{k}", 1.0) for k in range(p)]
    rec.p = p
    rec.cal = SimpleNamespace(prior_residuals=lambda u: np.asarray(u, float))
    return rec


def test_recalibrated_parameters_aliased_from_a_correlation_of_0_9():
    rec = _rec()
    fit = SimpleNamespace(u=np.log([2.2, 1.8]))
    for r, aliased in ((0.9, True), (0.9 * (1 - 1e-9), False), (-0.9, True)):
        cov = np.array([[0.25, r * 0.25], [r * 0.25, 0.25]])  # sds 0.5: the correlation is r
        out = rec.parameters(fit, cov, Z_975)
        assert bool(out["x0"]["aliased_with"]) is aliased
    assert out["x0"]["aliased_with"]["x1"] == pytest.approx(-0.9, rel=1e-12)
    x0 = out["x0"]
    assert x0["ci95"] == pytest.approx([2.2 * math.exp(-Z_975 * 0.5), 2.2 * math.exp(Z_975 * 0.5)])
    assert x0["shift_in_prior_sds"] == pytest.approx(math.log(1.1) / 0.1, rel=1e-12)
    assert x0["shift_in_stated_sds"] == pytest.approx(1.0, rel=1e-12)
    assert ALIAS_CORRELATION == 0.9


def test_recalibration_plausible_within_the_99_9_percent_prior_chi2():
    rec = _rec(2)
    q = stats.chi2.ppf(0.999, 2)
    assert rec.plausible(np.full(2, math.sqrt(q / 2) * (1 - 1e-9)))
    assert not rec.plausible(np.full(2, math.sqrt(q / 2) * (1 + 1e-9)))
    assert PLAUSIBLE_LEVEL == 0.999


# ---------------------------------------------------------------------------- noise floor
def test_second_difference_sigma_is_its_sum_over_6_n_minus_2():
    r = np.array([0.0, 1.0, -1.0, 2.0, 0.5])
    d = [-3.0, 5.0, -4.5]
    assert second_difference_sigma(r) == pytest.approx(math.sqrt(sum(x * x for x in d) / 18), rel=1e-12)


def _second_diff_efficiency():
    """dof per point of the mean squared second difference of white noise: 2 E^2 / var with
    the autocovariances of the filter (1, -2, 1)."""
    f = np.array([1.0, -2.0, 1.0])
    c = [float(np.sum(f[: 3 - k] * f[k:])) for k in range(3)]  # 6, -4, 1
    return 2 * c[0] ** 2 / (2 * (c[0] ** 2 + 2 * c[1] ** 2 + 2 * c[2] ** 2))


def test_second_difference_efficiency_is_36_over_70():
    assert _second_diff_efficiency() == pytest.approx(36 / 70, rel=1e-12)
    assert SECOND_DIFF_EFFICIENCY == pytest.approx(_second_diff_efficiency(), rel=1e-12)


def test_gap_limit_of_one_quantity_is_the_99_percent_f_quantile():
    assert gap_limit(200, 60.0) == pytest.approx(math.sqrt(stats.f.ppf(0.99, 200, 60.0)), rel=1e-12)
    assert GAP_LEVEL == 0.99


def test_gap_limit_pooled_and_with_a_held_zero():
    # a noise sd known exactly (nu huge): point-weighted pooling of chi2_40/40 and chi2_60/60
    # is chi2_100/100 (40000 seeded draws: to about 0.3 %)
    exact = math.sqrt(stats.chi2.ppf(0.99, 100) / 100)
    assert gap_limit([40, 60], [1e12, 1e12]) == pytest.approx(exact, rel=3e-3)
    # a zero of 5 rows held in half the points adds 0.5 chi2_1 / 5 to chi2_10 / 10: chi2_11 / 10
    exact = math.sqrt(stats.chi2.ppf(0.99, 11) / 10)
    assert gap_limit(10, 1e12, reference=[(0.5, 5)]) == pytest.approx(exact, rel=1e-2)


def test_pooled_noise_weights_and_the_99_percent_consistency_interval():
    run_vars = np.array([0.9, 1.0, 1.0, 1.2])  # median 1
    n, m, median_dof = 4, 20, 30.0
    nu_a = _second_diff_efficiency() * (m - 2) * n
    nu_b = (n - 1) * m
    lo, hi = stats.f.ppf([0.005, 0.995], nu_b, median_dof)
    assert pool_noise_estimates(run_vars, hi * (1 + 1e-9), m, median_dof) is None
    assert pool_noise_estimates(run_vars, lo * (1 - 1e-9), m, median_dof) is None
    assert pool_noise_estimates(run_vars, lo * (1 + 1e-9), m, median_dof) is not None
    b = 1.3
    var, dof = pool_noise_estimates(run_vars, b, m, median_dof)
    ta, tb, tab = 1 / nu_a, 1 / nu_b, 1 / (n * m)
    w = (tb - tab) / (ta + tb - 2 * tab)
    assert var == pytest.approx(w * run_vars.mean() + (1 - w) * b, rel=1e-12)
    assert dof == pytest.approx(1 / (w * w * ta + (1 - w) ** 2 * tb + 2 * w * (1 - w) * tab), rel=1e-12)
    assert POOL_CONSISTENCY_LEVEL == 0.99


def test_median_of_three_or_more_runs_keeps_2_over_pi_of_the_dof():
    eff = _second_diff_efficiency()
    for runs, factor in ((2, 1.0), (3, 2 / math.pi)):
        problem = SimpleNamespace(frames=[np.zeros(12)] * runs, logs=lambda i, q: True)
        sigma, dof, _ = noise._quantity_noise(problem, "x", [1.0, 2.0, 3.0][:runs], {}, None)
        assert sigma == pytest.approx(float(np.median([1.0, 2.0, 3.0][:runs])))
        assert dof == pytest.approx(eff * 10 * runs * factor, rel=1e-12)
    assert MEDIAN_EFFICIENCY == pytest.approx(2 / math.pi, rel=1e-12)


def _gap(scale):
    """Three runs of 10 zeroed rows whose RMSE over N - R = 27 is ``scale`` x the limit."""
    nu = 40.0
    limit = math.sqrt(stats.f.ppf(0.99, 27, nu))
    rng = np.random.default_rng(2)
    z = [rng.normal(size=10) for _ in range(3)]
    z = [v - v.mean() for v in z]
    norm = math.sqrt(sum(float(v @ v) for v in z) / 27)
    z = [v / norm * limit * scale for v in z]
    problem = SimpleNamespace(
        spring_nuisance=False,
        quantities=["x"],
        frames=[np.zeros(10)] * 3,
        zeroed={"x"},
        run_to_run={},
        norm_resid=lambda i, mods, spring: z[i],
        logs=lambda i, q: True,
        n_entries=lambda i, mask=None: 10,
        sigma={"x": 1.0},
        rig=SimpleNamespace(spring_constant=None),
        k=SimpleNamespace(needs_training=False),
    )
    base = BaselineFit(None, [{"x": np.zeros(10)}] * 3, [{"x": v} for v in z])
    floor = SimpleNamespace(by_quantity={"x": SimpleNamespace(dof=nu)})
    base, _, gap = check_gap(problem, base, floor)
    return base, gap, limit


def test_gap_is_significant_beyond_the_f_limit_over_n_minus_the_zeros():
    base, gap, limit = _gap(1 + 1e-6)
    assert gap.limit == pytest.approx(limit, rel=1e-12)
    assert gap.rmse_over_noise == pytest.approx(limit * (1 + 1e-6), rel=1e-9)
    assert gap.significant
    assert base.floor2 == pytest.approx(27 / 30, rel=1e-12)
    assert not _gap(1 - 1e-6)[1].significant


# ---------------------------------------------------------------------------- bands
def test_band_of_one_draw_is_z_975_sds_wide():
    lo, hi = band.mixture_interval(np.array([[1.0, -2.0]]), np.array([0.5, 2.0]))
    assert lo == pytest.approx([1.0 - Z_975 * 0.5, -2.0 - Z_975 * 2.0], rel=1e-9)
    assert hi == pytest.approx([1.0 + Z_975 * 0.5, -2.0 + Z_975 * 2.0], rel=1e-9)
    assert band.NOMINAL == 0.95


def test_band_of_a_mixture_has_2_5_percent_either_side():
    centres = np.array([[0.0], [1.0], [3.0]])
    s = 0.7
    lo, hi = band.mixture_interval(centres, s)

    def cdf(x):
        return float(np.mean(special.ndtr((x - centres[:, 0]) / s)))

    assert cdf(lo[0]) == pytest.approx(0.025, abs=1e-7)
    assert cdf(hi[0]) == pytest.approx(0.975, abs=1e-7)


def test_parameter_interval_and_coverage():
    lo, hi = band.parameter_interval(S.reshape(K, 1))
    assert (lo[0], hi[0]) == pytest.approx((2.5, 97.5), abs=1e-12)
    assert band.coverage(np.array([0.0, 1.0, 2.0]), np.zeros(3), np.ones(3)) == pytest.approx(2 / 3)


def test_informative_rows_at_half_the_noise_half_width():
    s = np.array([2.0, 2.0, 3.0])
    edge = 0.5 * Z_975 * s
    rows = band.informative_rows(edge * np.array([1 + 1e-9, 1 - 1e-9, 1 + 1e-9]), s)
    assert rows.tolist() == [True, False, True]
    assert band.INFORMATIVE_RATIO == 0.5


def test_rest_zero_sd_is_sigma_over_sqrt_n():
    r = np.array([1.0, 2.0, 3.0, 6.0, 9.0])
    rest = np.array([True, True, True, True, False])
    assert band.rest_zero(r, rest, 0.8) == pytest.approx((3.0, 0.4, 4))
    assert band.rest_zero(r, np.zeros(5, bool), 0.8) == pytest.approx((0.0, 0.8, 0))


def test_stated_band_is_log_normal_with_the_stated_mean_and_sd():
    d = band.from_stated({("sample", "thermal_mass"): (2.0, 0.6), ("rig", "offset"): (-1.0, 0.3)})
    mu, s2 = d.mean[0], d.covariance[0, 0]
    assert math.exp(mu + s2 / 2) == pytest.approx(2.0, rel=1e-12)
    assert math.sqrt((math.exp(s2) - 1) * math.exp(2 * mu + s2)) == pytest.approx(0.6, rel=1e-12)
    assert (d.mean[1], d.covariance[1, 1]) == pytest.approx((-1.0, 0.09))
    assert d.log == (True, False)
