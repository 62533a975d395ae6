"""Tests of tcamlab.metrics: hand values, NaN handling, thresholds, properties."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from tcamlab.errors import ConfigError, InputError
from tcamlab.metrics import (
    METRIC_UNITS_NOTE,
    MIN_REST_ROWS,
    ThresholdCheck,
    check_thresholds,
    error_metrics,
    estimate_zero,
    pooled_metrics,
    quantity_unit,
)

# --------------------------------------------------------------------------
# error_metrics
# --------------------------------------------------------------------------


def test_hand_values():
    m = error_metrics([0, 1, 2, 3], [0, 1, 2, 4])
    # e = [0, 0, 0, 1]: SS_res = 1, n = 4
    assert m["rmse"] == pytest.approx(0.5, rel=1e-15)  # sqrt(1/4)
    assert m["mae"] == pytest.approx(0.25, rel=1e-15)
    assert m["max_abs"] == 1.0
    assert m["bias"] == pytest.approx(0.25, rel=1e-15)
    assert m["nrmse"] == pytest.approx(0.5 / 3, rel=1e-15)  # range 3
    # SS_tot = 2.25 + 0.25 + 0.25 + 2.25 = 5
    assert m["r2"] == pytest.approx(1 - 1 / 5, rel=1e-15)
    assert m["n"] == 4
    assert m["n_nan"] == 0


def test_bias_sign_is_predicted_minus_measured():
    assert error_metrics([1.0, 1.0, 2.0], [0.0, 0.0, 1.0])["bias"] == pytest.approx(-1.0)


def test_perfect_prediction():
    m = error_metrics([1.0, 2.0, 5.0], [1.0, 2.0, 5.0])
    assert m["rmse"] == 0.0 and m["mae"] == 0.0 and m["max_abs"] == 0.0 and m["bias"] == 0.0
    assert m["r2"] == 1.0 and m["nrmse"] == 0.0


def test_nan_pairs_ignored_and_counted():
    m = error_metrics([0, 1, np.nan, 2, 3, 7.0], [0, 1, 2, 2, 4, np.nan])
    ref = error_metrics([0, 1, 2, 3], [0, 1, 2, 4])
    assert m["n"] == 4 and m["n_nan"] == 2
    for key in ("rmse", "mae", "max_abs", "bias", "nrmse", "r2"):
        assert m[key] == pytest.approx(ref[key], rel=1e-15)


def test_constant_measured_gives_nan_nrmse_and_r2():
    m = error_metrics([0.1, 0.1, 0.1], [0.1, 0.2, 0.0])
    assert math.isnan(m["nrmse"]) and math.isnan(m["r2"])
    assert m["rmse"] == pytest.approx(math.sqrt(0.02 / 3))


def test_all_nan_gives_nan_metrics():
    m = error_metrics([np.nan, 1.0], [1.0, np.nan])
    assert m["n"] == 0 and m["n_nan"] == 2
    assert all(math.isnan(m[k]) for k in ("rmse", "mae", "max_abs", "bias", "nrmse", "r2"))


def test_shape_mismatch_and_inf_raise():
    with pytest.raises(InputError, match="shape"):
        error_metrics([1, 2, 3], [1, 2])
    with pytest.raises(InputError, match="inf"):
        error_metrics([1, 2, np.inf], [1, 2, 3])


def test_pooled_is_concatenation():
    a = ([0.0, 1.0], [0.0, 1.0])
    b = ([2.0, 3.0], [2.0, 4.0])
    assert pooled_metrics([a, b]) == error_metrics([0, 1, 2, 3], [0, 1, 2, 4])
    with pytest.raises(InputError):
        pooled_metrics([])


def test_units_note_mentions_units():
    assert "unit" in METRIC_UNITS_NOTE and "mm" in METRIC_UNITS_NOTE


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(
    st.integers(min_value=1, max_value=40).flatmap(
        lambda n: st.tuples(hnp.arrays(float, n, elements=finite), hnp.arrays(float, n, elements=finite))
    )
)
def test_metric_inequalities(pair):
    measured, predicted = pair
    m = error_metrics(measured, predicted)
    for key in ("rmse", "mae", "max_abs", "bias"):
        assert math.isfinite(m[key])
    tol = 1e-9 * (1.0 + m["max_abs"])
    assert m["mae"] >= 0.0
    assert m["rmse"] >= m["mae"] - tol
    assert m["rmse"] >= abs(m["bias"]) - tol
    assert m["max_abs"] >= m["rmse"] - tol
    if np.ptp(measured) > 1e-100:  # a subnormal range overflows nrmse and r2 honestly
        assert math.isfinite(m["nrmse"]) and m["nrmse"] >= 0.0
        assert math.isfinite(m["r2"]) and m["r2"] <= 1.0 + 1e-12
    assert m["n"] == len(measured)


# --------------------------------------------------------------------------
# thresholds
# --------------------------------------------------------------------------


@pytest.fixture
def metrics_by_quantity():
    return {
        "displacement_mm": {"rmse": 0.4, "mae": 0.3, "max_abs": 1.2, "bias": -0.2, "nrmse": 0.05, "r2": 0.97},
        "force_N": {"rmse": 0.02, "mae": 0.01, "max_abs": 0.05, "bias": 0.0, "nrmse": 0.12, "r2": 0.85},
        "gauge_per_mm": {"rmse": 9.0, "mae": 9.0, "max_abs": 9.0, "bias": 9.0, "nrmse": 0.01, "r2": 0.99},
    }


def _by(checks, key, quantity):
    (c,) = [c for c in checks if c.key == key and c.quantity == quantity]
    return c


def test_unit_suffix_selects_quantities(metrics_by_quantity):
    checks = check_thresholds(metrics_by_quantity, {"rmse_mm": 0.5, "rmse_N": 0.01})
    assert [(c.key, c.quantity) for c in checks] == [("rmse_mm", "displacement_mm"), ("rmse_N", "force_N")]
    assert _by(checks, "rmse_mm", "displacement_mm").passed is True
    assert _by(checks, "rmse_N", "force_N").passed is False
    assert _by(checks, "rmse_N", "force_N").value == 0.02
    assert _by(checks, "rmse_N", "force_N").limit == 0.01


def test_mm_does_not_match_per_mm(metrics_by_quantity):
    assert quantity_unit("gauge_per_mm") == "per_mm"
    assert quantity_unit("displacement_mm") == "mm"
    assert quantity_unit("temperature_C") is None
    checks = check_thresholds(metrics_by_quantity, {"max_abs_per_mm": 10.0})
    assert [(c.quantity, c.passed) for c in checks] == [("gauge_per_mm", True)]


def test_bare_key_applies_to_all(metrics_by_quantity):
    checks = check_thresholds(metrics_by_quantity, {"nrmse": 0.1})
    assert [c.quantity for c in checks] == list(metrics_by_quantity)
    assert [c.passed for c in checks] == [True, False, True]


def test_r2_min_is_a_lower_bound(metrics_by_quantity):
    checks = check_thresholds(metrics_by_quantity, {"r2_min": 0.9})
    assert [c.passed for c in checks] == [True, False, True]
    assert checks[0].comparison == ">=" and checks[0].metric == "r2"
    # boundary: equal passes for both kinds
    eq = check_thresholds({"x_mm": {"r2": 0.9, "rmse": 0.5}}, {"r2_min": 0.9, "rmse_mm": 0.5})
    assert all(c.passed for c in eq)


def test_bias_uses_absolute_value(metrics_by_quantity):
    checks = check_thresholds(metrics_by_quantity, {"bias_mm": 0.1})
    assert checks[0].value == -0.2 and checks[0].passed is False
    assert check_thresholds(metrics_by_quantity, {"bias_mm": 0.25})[0].passed is True


def test_nan_or_missing_metric_fails():
    checks = check_thresholds({"a_mm": {"r2": float("nan")}, "b_mm": {}}, {"r2_min": 0.0, "rmse_mm": 1.0})
    assert [c.passed for c in checks] == [False, False, False, False]


@pytest.mark.parametrize("key", ["rms_mm", "rmse_cm", "r2", "r2_mm", "max", "rmse_", "", "RMSE_mm"])
def test_unknown_key_raises_config_error(key):
    with pytest.raises(ConfigError) as info:
        check_thresholds({"displacement_mm": {"rmse": 1.0}}, {key: 1.0})
    assert repr(key) in info.value.message
    assert "r2_min" in info.value.hint and "rmse_mm" in info.value.hint


def test_r2_hint_suggests_r2_min():
    with pytest.raises(ConfigError, match="write r2_min"):
        check_thresholds({}, {"r2": 0.9})


def test_non_numeric_limit_raises():
    with pytest.raises(ConfigError, match="rmse_mm"):
        check_thresholds({}, {"rmse_mm": "small"})


def test_threshold_check_helpers():
    c = ThresholdCheck("rmse_mm", "displacement_mm", 0.42, 0.5, True)
    assert c.describe() == "displacement_mm rmse 0.42 mm <= 0.5 mm: pass"
    assert ThresholdCheck("x", "q", float("nan"), 1.0, False).to_dict()["value"] is None


# --------------------------------------------------------------------------
# nuisance zeros
# --------------------------------------------------------------------------


def test_zero_from_rest_rows_by_hand():
    """Mean of measured - predicted over the rest rows; SE = sd / sqrt(k); Student-t interval."""
    from scipy import stats

    resid = np.array([0.1, 0.3, 0.2, 0.4, 0.0, 0.2, 0.1, 0.3, 0.2, 0.2, 5.0, 7.0])
    predicted = np.linspace(0.0, 1.0, resid.size)
    z = estimate_zero(predicted + resid, predicted, np.arange(10))
    assert z.source == "rest rows" and z.rows == 10
    assert z.value == pytest.approx(0.2, rel=1e-12)  # the two moving rows are left out
    se = np.std(resid[:10], ddof=1) / math.sqrt(10)
    assert z.stderr == pytest.approx(se, rel=1e-12)
    half = stats.t.ppf(0.975, 9) * se
    assert z.ci95 == pytest.approx((0.2 - half, 0.2 + half), rel=1e-12)


def test_with_too_few_rest_rows_the_logged_zero_stands():
    """Fewer than MIN_REST_ROWS rows at rest: no zero is fitted over the run (that would take
    the model's mean error away); the logged zero stands, with the noise sd as its sd."""
    from tcamlab.signals import second_difference_sigma

    resid = np.array([0.0, 2.0, 3.0, np.nan, 6.0])
    z = estimate_zero(resid, np.zeros(5), np.arange(MIN_REST_ROWS - 1)[:3])
    assert z.source == "logged zero" and z.rows == 1 and z.value == 0.0  # the first row
    assert z.stderr == pytest.approx(second_difference_sigma([0.0, 2.0, 3.0, 6.0]))
    assert z.ci95 == pytest.approx((-1.96 * z.stderr, 1.96 * z.stderr), rel=1e-3)
    shifted = estimate_zero(resid + 1.5, np.zeros(5))  # a log not zeroed on its first row
    assert shifted.value == pytest.approx(1.5) and shifted.source == "logged zero"
    tare = estimate_zero(resid + 1.5, np.zeros(5), np.arange(4), first_row=False)
    assert tare.value == 0.0 and tare.rows == 4  # a load cell stands as logged
    assert tare.stderr == pytest.approx(second_difference_sigma([0.0, 2.0, 3.0, 6.0]) / 2)
    whole = estimate_zero(resid, np.zeros(5), np.arange(3), rule="whole-run")
    assert whole.source == "whole run" and whole.rows == 4  # the NaN pair is left out
    assert whole.value == pytest.approx(11.0 / 4)
    empty = estimate_zero([np.nan, np.nan], [0.0, 0.0])
    assert empty.rows == 0 and math.isnan(empty.value)
    json.dumps(empty.to_dict(), allow_nan=False)
    with pytest.raises(ValueError, match="whole-run"):
        estimate_zero(resid, np.zeros(5), rule="wholerun")


def test_zero_interval_covers_the_true_zero_95_percent_of_the_time():
    rng = np.random.default_rng(20261123)
    hits = 0
    for _ in range(400):
        truth = rng.normal(0.0, 1.0)
        measured = truth + rng.normal(0.0, 0.5, 40)
        lo, hi = estimate_zero(measured, np.zeros(40), np.arange(15)).ci95
        hits += lo <= truth <= hi
    assert 0.92 <= hits / 400 <= 0.98


def test_opposite_direction_and_opposite_sign_by_hand():
    """A measurement that falls where the model rises is flagged whatever its fit; a poor fit in
    the right direction is not. A parameter of the opposite sign to a stated value is flagged
    without a stated sd; a stated 0 has no sign to keep."""
    from tcamlab.metrics import opposite_direction_warning, opposite_sign_warning

    p = np.linspace(0, 1, 50)
    w = opposite_direction_warning("displacement_mm", -0.3 * p + 0.01 * np.sin(40 * p), p)
    assert w.check == "opposite-direction" and w.values["correlation"] < -0.99
    assert opposite_direction_warning("displacement_mm", 0.2 * p + 0.3 * np.sin(9 * p), p) is None
    assert opposite_direction_warning("displacement_mm", np.zeros(50), p) is None
    w = opposite_sign_warning("rho", -6.5e-5, 8.1e-5, "1/K", "calibrated")
    assert w.check == "parameter-far-from-stated" and "opposite sign to the stated 8.1e-05 1/K" in w.message
    assert opposite_sign_warning("rho", 6.5e-5, 8.1e-5, "1/K", "calibrated") is None
    assert opposite_sign_warning("beta", -1.0, 0.0, "-", "calibrated") is None


def test_a_resistance_in_kohm_or_mohm_read_as_ohm_is_implausible():
    """A 30 ohm sensor logged in kohm reads 0.03 "ohm" (only R/R0 enters, so every figure
    stays the same and nothing said so); in mohm it reads 30,000. Curvature's R1 and R2 too."""
    from tcamlab.metrics import implausible_value_warnings

    r = np.full(20, 30.0)
    assert implausible_value_warnings("run1", {"resistance": r, "r1": r, "r2": r}) == []
    low = implausible_value_warnings("run1", {"resistance": r / 1e3})
    assert [w.check for w in low] == ["implausible-value"] and 'unit = "kohm"' in low[0].message
    high = implausible_value_warnings("run1", {"r2": r * 1e4})
    assert high[0].quantity == "r2" and 'unit = "mohm"' in high[0].message
