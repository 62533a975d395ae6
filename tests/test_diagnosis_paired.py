"""The paired tests of the diagnosis (:mod:`tcamlab.diagnosis.paired`) on cases small enough
to work out by hand, and their place in the diagnosis result (``paired_tests``, in
diagnosis.json).

Data: hand-made candidates (held-out mean squared residual per fold, rows per fold); no
rig, no fit.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from tcamlab.diagnosis.paired import best_candidate, candidate_name, paired_tests
from tcamlab.diagnosis.result import CandidateResult, DiagnosisResult, stand_ins_text


def _cand(effect, fold_mse, ci=(0.0, 0.1)):
    """A candidate with held-out mean squared residual ``fold_mse`` per fold [noise sd²]."""
    return SimpleNamespace(
        effect=effect,
        folds=[{"rmse_after_noise": float(np.sqrt(m))} for m in fold_mse],
        shrinkage_ci95=list(ci),
    )


def _settings(rows, n_boot=400, seed=0):
    """Fold k withholds one run of ``rows[k]`` rows."""
    return {
        "seed": seed,
        "n_boot": n_boot,
        "fold_details": [{"held_out": [{"run": k, "rows": [10, 10 + r - 1]}]} for k, r in enumerate(rows)],
    }


def _result(best, others, rows, **settings):
    return SimpleNamespace(
        effect=best.effect, combination=None, ranking=[best, *others], settings=_settings(rows, **settings)
    )


def test_a_constant_difference_per_row_has_a_point_interval_and_bootstrap_p_zero():
    # every fold: the other candidate's mean squared residual 0.5 above the best's, so every
    # resample gives 0.5: interval [0.5, 0.5], no resample with it not worse
    best = _cand("a", [1.0, 2.0, 0.5], ci=(0.6, 0.7))
    other = _cand("b", [1.5, 2.5, 1.0], ci=(0.1, 0.2))
    (t,) = paired_tests(_result(best, [other], rows=[3, 5, 2]))
    assert t["candidate"] == "b" and t["best"] == "a"
    assert t["diff"] == pytest.approx(0.5)
    assert t["ci95"] == pytest.approx([0.5, 0.5])
    assert t["p_boot"] == 0.0 and t["n_boot"] == 400 and t["seed"] == 0
    # worse on 3 of 3 folds: one-sided sign test p = 0.5^3
    assert t["worse_folds"] == 3 and t["folds"] == 3 and t["p_sign"] == pytest.approx(1 / 8)
    assert t["intervals_overlap"] is False and t["clearly_worse"] is True


def test_folds_are_weighted_by_their_withheld_rows():
    # differences per fold 1, 0, 3 [noise sd²] on 1, 1 and 2 rows: pooled (1 + 0 + 6) / 4 = 1.75
    # (the unweighted mean would be 4/3)
    best = _cand("a", [1.0, 1.0, 1.0], ci=(0.5, 0.6))
    other = _cand("b", [2.0, 1.0, 4.0], ci=(0.1, 0.2))
    (t,) = paired_tests(_result(best, [other], rows=[1, 1, 2], n_boot=2700, seed=5))
    assert t["diff"] == pytest.approx(1.75)
    # a resample is <= 0 only when it draws the tied fold three times: p = (1/3)^3 = 1/27
    assert t["p_boot"] == pytest.approx(1 / 27, abs=0.015)
    # resamples lie between 0 (tied fold only) and 6 / 2 = 3 (the two-row fold only)
    # and 1/27 > 2.5 % of them are 0, so the interval's lower end is 0
    lo, hi = t["ci95"]
    assert lo == 0.0 and 1.75 < hi <= 3.0
    # worse on 2 of 3 folds (the tie is not worse): P(X >= 2 | 3, 1/2) = 4/8
    assert t["worse_folds"] == 2 and t["p_sign"] == pytest.approx(0.5)
    # the interval reaches 0: not clearly worse even without overlapping shrinkage intervals
    assert t["intervals_overlap"] is False and t["clearly_worse"] is False


def test_overlapping_shrinkage_intervals_are_never_clearly_worse():
    best = _cand("a", [1.0, 1.0, 1.0], ci=(0.5, 0.6))
    other = _cand("b", [2.0, 2.0, 2.0], ci=(0.55, 0.7))
    (t,) = paired_tests(_result(best, [other], rows=[2, 2, 2]))
    assert t["ci95"] == pytest.approx([1.0, 1.0]) and t["intervals_overlap"] is True
    assert t["clearly_worse"] is False


def test_a_pair_is_tested_against_the_others_by_its_joint_name():
    pair = {
        "effects": ["a", "b"],
        "folds": [{"rmse_after_noise": 1.0}] * 2,
        "shrinkage_ci95": [0.8, 0.9],
    }
    a, c = _cand("a", [2.0, 2.0]), _cand("c", [3.0, 1.0])
    res = SimpleNamespace(effect="a", combination=pair, ranking=[a, c], settings=_settings([1, 3]))
    assert best_candidate(res) is pair and candidate_name(pair) == "a + b"
    tests = {t["candidate"]: t for t in paired_tests(res)}
    # both single effects are tested against the pair, the named effect too
    assert set(tests) == {"a", "c"} and tests["a"]["best"] == "a + b"
    assert tests["a"]["diff"] == pytest.approx(1.0)
    # c: (2 x 1 + 0 x 3) / 4 = 0.5, worse on 1 of 2 folds: p = 3/4
    assert tests["c"]["diff"] == pytest.approx(0.5) and tests["c"]["p_sign"] == pytest.approx(0.75)


def test_no_named_candidate_or_no_fold_scores_gives_no_tests():
    a = _cand("a", [1.0, 1.0])
    assert (
        paired_tests(SimpleNamespace(effect=None, combination=None, ranking=[a], settings=_settings([1, 1])))
        == []
    )
    no_folds = SimpleNamespace(effect="a", combination=None, ranking=[a], settings={"seed": 0, "n_boot": 10})
    assert paired_tests(no_folds) == []
    # a candidate scored on another number of folds is left out, not compared fold by fold
    short = _cand("b", [2.0])
    assert paired_tests(_result(a, [short], rows=[1, 1])) == []


def _diagnosis(ranking, effect, settings, **fields):
    """A DiagnosisResult with only what the paired tests and the verdict's words read."""
    values = {
        "kind": "static",
        "experiment": {},
        "verdict": "attributed",
        "effect": effect,
        "ranking": ranking,
        "aliased_with": [],
        "separate_by": {},
        "noise_floor": {},
        "baseline": {},
        "regimes": [],
        "runs": [],
        "gap": {},
        "reason": "",
        "settings": settings,
    }
    return DiagnosisResult(**{**values, **fields})


def _scores(effect, fold_mse, ci):
    """A CandidateResult with only its per-fold scores and shrinkage interval set."""
    c = _cand(effect, fold_mse, ci)
    nan = float("nan")
    return CandidateResult(
        effect, nan, nan, "mm", nan, nan, nan, c.shrinkage_ci95, nan, nan, nan, {}, {}, c.folds
    )


def test_the_diagnosis_result_stores_the_tests_and_writes_them_to_json():
    best = _scores("a", [1.0, 2.0, 0.5], ci=(0.6, 0.7))
    other = _scores("b", [1.5, 2.5, 1.0], ci=(0.1, 0.2))
    res = _diagnosis([best, other], "a", _settings([3, 5, 2]))
    assert [t["candidate"] for t in res.paired_tests] == ["b"]
    assert res.paired_tests[0]["diff"] == pytest.approx(0.5)
    doc = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert doc["paired_tests"][0]["ci95"] == pytest.approx([0.5, 0.5])
    assert doc["paired_tests"][0]["clearly_worse"] is True
    assert "next_experiment" not in doc  # only when the design was run
    # tests given (a result read back) are kept, not recomputed
    kept = _diagnosis([best, other], "a", _settings([3, 5, 2]), paired_tests=[{"candidate": "x"}])
    assert kept.paired_tests == [{"candidate": "x"}]


def test_the_stand_ins_of_a_miscalibrated_verdict_are_stored_in_words():
    rec = {"stand_ins": {"youngs-modulus-temperature": ["resistivity", "slack"], "glass-transition": []}}
    res = _diagnosis(
        [],
        None,
        {},
        verdict="miscalibrated",
        aliased_with=["youngs-modulus-temperature", "glass-transition", "oven-thermal-lag"],
        recalibration=rec,
    )
    assert res.stand_ins_words == (
        "youngs-modulus-temperature (with resistivity and slack at their stated values), "
        "glass-transition (with the combination of parameters the data fix at its stated value) "
        "and oven-thermal-lag"
    )
    assert res.to_dict()["stand_ins_words"] == res.stand_ins_words
    assert stand_ins_text({"e": ["p"]}) == "e (with p at its stated value)"
    # another verdict, or no stand-ins: no words
    assert _diagnosis([], None, {}, verdict="aliased", aliased_with=["x"]).stand_ins_words == ""
    assert _diagnosis([], None, {}, verdict="miscalibrated").stand_ins_words == ""
