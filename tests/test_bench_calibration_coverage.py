"""Scoring functions of bench/bench_calibration_coverage.py (interval containment, binomial CI,
pinned-closer, per-kind summary); the benchmark itself is run by .ci/run, not here."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "bench" / "bench_calibration_coverage.py"
_spec = importlib.util.spec_from_file_location("bench_calibration_coverage", _PATH)
cov = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cov)


def test_contains_is_closed_and_order_free():
    assert cov.contains((1.0, 2.0), 1.0) and cov.contains((1.0, 2.0), 2.0)
    assert cov.contains((2.0, 1.0), 1.5)  # a reversed interval still counts
    assert not cov.contains((1.0, 2.0), 2.0000001)
    assert not cov.contains((1.0, 2.0), 0.999)


def test_contains_rejects_missing_and_non_finite():
    assert not cov.contains(None, 1.0)
    assert not cov.contains((math.nan, 2.0), 1.0)
    assert not cov.contains((0.0, math.inf), 1.0)
    assert not cov.contains((0.0, 2.0), math.nan)


def test_binomial_ci_exact_values():
    # Clopper-Pearson: 0 of 10 -> upper 1 - 0.025**(1/10); 10 of 10 -> lower 0.025**(1/10).
    lo, hi = cov.binomial_ci(0, 10)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025**0.1, rel=1e-9)
    lo, hi = cov.binomial_ci(10, 10)
    assert lo == pytest.approx(0.025**0.1, rel=1e-9) and hi == 1.0
    # 90 of 100: the textbook exact interval 0.8238-0.9510 (a Wald interval would give 0.841-0.959).
    lo, hi = cov.binomial_ci(90, 100)
    assert lo == pytest.approx(0.82378, abs=2e-5) and hi == pytest.approx(0.95099, abs=2e-5)
    assert all(math.isnan(x) for x in cov.binomial_ci(0, 0))


def test_closer_than_stated_is_strict():
    assert cov.closer_than_stated(value=1.1, stated=2.0, true=1.0)
    assert not cov.closer_than_stated(value=2.5, stated=2.0, true=1.0)
    assert not cov.closer_than_stated(value=0.0, stated=2.0, true=1.0)  # a tie is not closer
    assert cov.closer_than_stated(value=-0.5, stated=3.0, true=-1.0)


def test_standardized_error_log_space_for_positive():
    # value e^0.2 times the truth, 10 % relative sd -> z = 2.
    assert cov.standardized_error(math.exp(0.2), 1.0, 0.1, 0.1, True) == pytest.approx(2.0)
    assert cov.standardized_error(1.3, 1.0, 0.1, 0.1, False) == pytest.approx(3.0)


def _param(name, in_profile, in_laplace, pinned, drawn, closer, z=0.0):
    return {
        "name": name,
        "symbol": name.upper(),
        "in_profile": in_profile,
        "in_laplace": in_laplace,
        "pinned": pinned,
        "drawn": drawn,
        "closer": closer,
        "profile_open": [False, False],
        "z": z,
    }


def test_summarise_kind_pools_and_skips_failed_cases():
    cases = [
        {
            "failed": False,
            "seconds": 2.0,
            "error": "",
            "parameters": [
                _param("a", True, True, True, True, True, 1.0),
                _param("b", False, True, True, False, True, 3.0),
            ],
        },
        {
            "failed": False,
            "seconds": 4.0,
            "error": "",
            "parameters": [
                _param("a", True, False, True, True, False, -1.0),
                _param("b", True, True, False, True, False),
            ],
        },
        {
            "failed": True,
            "seconds": 100.0,
            "error": "boom",
            "parameters": [_param("a", False, False, True, True, False)],
        },
    ]
    s = cov.summarise_kind(cases)
    assert s["cases"] == 3 and s["failed"]["k"] == 1
    assert (s["profile"]["k"], s["profile"]["n"]) == (3, 4)
    assert (s["laplace"]["k"], s["laplace"]["n"]) == (3, 4)
    # pinned and drawn: a in both ok cases (closer once); b's pinned case was not drawn.
    assert (s["pinned_closer"]["k"], s["pinned_closer"]["n"]) == (1, 2)
    assert s["seconds_median"] == 3.0
    assert s["parameters"]["a"]["z_rms"] == pytest.approx(1.0)
    assert s["parameters"]["b"]["profile"]["fraction"] == 0.5
    assert s["errors"] == ["boom"]
    assert cov.verdict(s) == "FAIL"  # 75 % coverage


def test_predicted_closer_is_the_atan_law_of_the_relative_sds():
    # posterior 10 % of value, prior 20 % of stated: ratio 0.5 -> (2/pi) atan(2) = 0.7048
    rec = {"posterior_sd": 0.1, "value": 1.0, "prior_sd": 0.4, "stated": 2.0}
    assert cov.predicted_closer(rec) == pytest.approx(2 / math.pi * math.atan(2.0), rel=1e-12)
    assert cov.predicted_closer(rec) == pytest.approx(0.7048, abs=1e-4)
    # the pinned threshold's ratio tan(0.05 pi) is exactly the 90 % the target asks for
    edge = {"posterior_sd": math.tan(0.05 * math.pi), "value": 1.0, "prior_sd": 1.0, "stated": 1.0}
    assert cov.predicted_closer(edge) == pytest.approx(0.90, abs=1e-12)
    assert math.isnan(cov.predicted_closer({"posterior_sd": 0.1}))


def test_summary_compares_closer_with_its_prediction_over_all_drawn_cases():
    def rec(closer, drawn, pinned=False):
        p = _param("a", True, True, pinned, drawn, closer)
        p.update(posterior_sd=0.5, value=1.0, prior_sd=1.0, stated=1.0)  # predicted 0.7048
        return p

    cases = [
        {"failed": False, "seconds": 1.0, "error": "", "parameters": [rec(c, d)]}
        for c, d in ((True, True), (False, True), (True, True), (True, False))
    ]
    a = cov.summarise_kind(cases)["parameters"]["a"]
    assert (a["closer_drawn"]["k"], a["closer_drawn"]["n"]) == (2, 3)  # the undrawn case left out
    assert a["closer_predicted"] == pytest.approx(0.7048, abs=1e-4)
    assert a["pinned_closer"]["n"] == 0
