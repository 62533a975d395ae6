"""Tests of the withheld-effect benchmark (tcamlab.benchmark)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tcamlab import benchmark
from tcamlab.benchmark import make_tasks, run_benchmark, score

pytest.importorskip("tcamlab.rig")


def _check_outputs(out, res):
    data = json.loads((out / "benchmark.json").read_text())
    assert data["scores"]["accuracy_by_strength"]
    assert (out / "benchmark.md").read_text().startswith("# Withheld-effect benchmark")
    assert (out / "benchmark.html").exists() and (out / "benchmark.pdf").exists()
    assert not res.scores["errors"], res.scores["errors"]


@pytest.mark.slow
def test_quick_benchmark_tiny_subset(tmp_path):
    res = run_benchmark(
        tmp_path,
        quick=True,
        seeds=1,
        kinds=("dynamic",),
        effects=["response-delay"],
        workers=1,
        families=("effect-only", "null"),
    )
    assert len(res.results) == 2  # one effect case + one null case
    _check_outputs(tmp_path, res)
    single = [r for r in res.results if r["case"] == "single"][0]
    assert single["effects"] == {"response-delay": 3.0}
    assert single["ranking"][0] == "response-delay"
    assert single["truth_values"]["response-delay"]["delay"] != 0
    assert "| strength |" in (tmp_path / "benchmark.md").read_text()


@pytest.mark.slow
def test_dask_path_with_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=1, processes=False, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        res = run_benchmark(
            tmp_path,
            quick=True,
            seeds=1,
            kinds=("curvature",),
            effects=["sensor-offset-error"],
            scheduler=cluster.scheduler_address,
            families=("effect-only", "null"),
        )
    assert res.settings["executor"] == "dask"
    assert len(res.results) == 2
    _check_outputs(tmp_path, res)


def test_task_lists():
    quick = make_tasks(quick=True)
    full = make_tasks(seeds=10)
    assert {t["case"] for t in quick} == {"single", "null"}
    assert all(next(iter(t["effects"].values())) == 3.0 for t in quick if t["case"] == "single")
    assert {t["case"] for t in full} == {"single", "null", "pair"}
    singles = [t for t in full if t["case"] == "single"]
    assert {next(iter(t["effects"].values())) for t in singles} == set(benchmark.STRENGTHS)
    assert len({t["seed"] for t in singles}) == 10


def test_scoring_rules():
    def single(truth, verdict, effect, ranking, s=3.0):
        return {
            "case": "single",
            "kind": "static",
            "effects": {truth: s},
            "seed": 1,
            "verdict": verdict,
            "effect": effect,
            "aliased_with": [],
            "ranking": ranking,
            "shrinkage": {e: 0.6 for e in ranking},
            "fitted": {},
            "truth_values": {},
            "fraction_closed": {e: 0.9 for e in ranking},
            "heldout_rmse_before_noise": 4.0,
            "seconds": 1.0,
        }

    results = [
        single("a", "attributed", "a", ["a", "b", "c"]),
        single("a", "aliased", "b", ["b", "a", "c"]),
        single("a", "unexplained", None, ["a", "b"]),
        {
            "case": "null",
            "kind": "static",
            "effects": {},
            "seed": 2,
            "verdict": "attributed",
            "effect": "b",
            "aliased_with": [],
            "ranking": ["b"],
            "seconds": 1.0,
        },
        {
            "case": "pair",
            "kind": "static",
            "effects": {"a": 5.0, "b": 5.0},
            "seed": 3,
            "verdict": "attributed",
            "effect": "c",
            "aliased_with": [],
            "ranking": ["c"],
            "seconds": 1.0,
        },
    ]
    s = score(results)
    acc = s["accuracy_by_strength"]["3.0"]
    assert acc["top1"] == pytest.approx(1 / 3) and acc["top3"] == pytest.approx(2 / 3)
    assert s["null"]["rate"] == 1.0
    assert s["pairs"][0]["outcome"].startswith("confident third")
    assert s["confusion"]["static"]["a"] == {"a": 1, "b": 1, "unexplained": 1}
    # one right attribution: shrinkage 0.6 of an attainable 1 - 1/4 = 0.75
    cell = s["shrinkage_by_strength"]["3.0"]
    assert cell["n"] == 1 and cell["median_shrinkage"] == pytest.approx(0.6)
    assert cell["median_share_of_attainable"] == pytest.approx(0.8)
    assert cell["noise_ceiling"] == pytest.approx(1 - 1 / math.sqrt(10), rel=1e-12)
    assert s["median_fraction_closed_when_right"] == pytest.approx(0.9)


# --- the families of a lab that lies ------------------------------------------------------


def test_family_task_lists():
    quick = make_tasks(quick=True, families=benchmark.FAMILIES)
    for fam in ("calibration-only", "realistic", "off-library", "null-noisy-zero", "null-quiet"):
        cases = [t for t in quick if t["case"] == fam]
        assert {t["kind"] for t in cases} == set(benchmark.BENCHMARK_KINDS), fam
        assert all(t["stated"] == benchmark.STATED_UNCERTAINTY[t["kind"]] for t in cases)
    realistic = [t for t in quick if t["case"] == "realistic"]
    assert all(t["parameter_error"] == 1.0 and t["noisy_zero"] and t["effects"] for t in realistic)
    assert all(t["noisy_zero"] and not t["effects"] for t in quick if t["case"] == "null-noisy-zero")
    quiet = [t for t in quick if t["case"] == "null-quiet"]
    assert all(t["noisy_zero"] and not t["effects"] and t["noise_scale"] == 0.2 for t in quiet)
    assert not any("noise_scale" in t for t in quick if t["case"] == "null-noisy-zero")
    full = make_tasks(seeds=10, families=("realistic", "off-library"))
    assert {next(iter(t["offlibrary"].values())) for t in full if t["case"] == "off-library"} == {3.0, 10.0}
    assert len({t["nearest"] for t in full if t["case"] == "off-library"}) == 14
    with pytest.raises(Exception, match="unknown benchmark family"):
        make_tasks(families=("nope",))


def test_calibration_offsets_are_one_to_three_stated_sds():
    for kind in benchmark.BENCHMARK_KINDS:
        st = benchmark.STATED_UNCERTAINTY[kind]
        seen = set()
        for seed in range(7000, 7030):
            offsets = benchmark.calibration_offsets(kind, seed)
            assert 1 <= len(offsets) <= 2 and set(offsets) <= set(st["rig"]) | set(st["sample"])
            assert all(1.0 <= abs(d) <= 3.0 for d in offsets.values())
            seen |= {d > 0 for d in offsets.values()}
        assert seen == {True, False}, kind  # both signs occur


def test_calibration_only_case_is_really_off_and_states_its_uncertainty(tmp_path):
    from tcamlab.config import load_experiment
    from tcamlab.rig import simulate

    task = next(t for t in make_tasks(quick=True, families=("calibration-only",)) if t["kind"] == "dynamic")
    sim = simulate(
        "dynamic",
        benchmark.stated_template("dynamic"),
        seed=task["seed"],
        out_dir=tmp_path,
        parameter_offsets=task["parameter_offsets"],
    )
    tp = json.loads(sim.truth_path.read_text())["true_parameters"]
    for f, d in task["parameter_offsets"].items():
        assert tp[f]["offset_sd"] == pytest.approx(d, rel=1e-9)
        assert tp[f]["true"] == pytest.approx(tp[f]["stated"] + d * tp[f]["sd"], rel=1e-12)
    for f in set(tp) - set(task["parameter_offsets"]):
        assert tp[f]["true"] == tp[f]["stated"]
    exp = load_experiment(sim.experiment_path)
    st = benchmark.STATED_UNCERTAINTY["dynamic"]
    assert exp.sample_uncertainty == pytest.approx(st["sample"])
    assert {k: exp.rig.uncertainty[k] for k in st["rig"]} == pytest.approx(st["rig"])


def test_calibration_only_truth_outside_the_model_is_drawn_on_the_other_side():
    # G(T) slope 1.24 stated sds up makes G_t' of (2.13) <= 0 inside the oven's 130 K rise
    task = {
        "case": "calibration-only",
        "kind": "static",
        "effects": {},
        "seed": 7003,
        "parameter_offsets": {"shear_modulus_slope": 1.24},
        "stated": benchmark.stated_uncertainty("static"),
        "n_boot": 50,
    }
    r = benchmark.run_task(task)
    assert "error" not in r, r.get("error")
    assert r["offsets_flipped"] is True
    assert r["parameter_offsets"] == {"shear_modulus_slope": -1.24}
    assert r["parameter_offsets_sd"]["shear_modulus_slope"] == pytest.approx(-1.24, rel=1e-9)


def test_null_noisy_zero_case_has_noisy_zeros(tmp_path):
    from tcamlab.rig import simulate

    sim = simulate(
        "dynamic",
        benchmark.stated_template("dynamic"),
        seed=5500,
        out_dir=tmp_path,
        noisy_zero=True,
        n_runs=12,
    )
    zeros = [r["zero_error"]["displacement"] for r in json.loads(sim.truth_path.read_text())["runs"]]
    # one reading of a 5 um laser (10 um ADC step): the zeros scatter by microns, not the 64-reading tare
    assert 2e-6 < float(np.std(zeros)) < 12e-6


def _row(case, verdict, effect=None, **kw):
    return {
        "case": case,
        "kind": "dynamic",
        "effects": {},
        "seed": 1,
        "verdict": verdict,
        "effect": effect,
        "aliased_with": [],
        "ranking": [effect] if effect else [],
        "seconds": 2.0,
        **kw,
    }


def test_family_scoring_on_hand_made_rows():
    rows = [
        _row(
            "calibration-only",
            "miscalibrated",
            recalibrated=["thermal_mass"],
            parameter_offsets_sd={"thermal_mass": 1.5, "damping": 0.0},
        ),
        _row(
            "calibration-only",
            "miscalibrated",
            recalibrated=["damping"],
            parameter_offsets_sd={"thermal_mass": 1.5, "damping": 0.0},
        ),
        _row(
            "calibration-only", "attributed", "convective-heat-loss", parameter_offsets_sd={"heat_loss": 2.0}
        ),
        _row("calibration-only", "none", parameter_offsets_sd={"heat_loss": -2.0}),
        _row("realistic", "attributed", "response-delay", effects={"response-delay": 3.0}),
        _row("realistic", "miscalibrated", None, effects={"response-delay": 3.0}),
        _row("realistic", "aliased", "response-delay", effects={"response-delay": 10.0}),
        _row(
            "off-library",
            "attributed",
            "response-delay",
            offlibrary={"sensor-lag": 3.0},
            nearest="response-delay",
        ),
        _row("off-library", "unexplained", None, offlibrary={"sensor-lag": 3.0}, nearest="response-delay"),
        _row(
            "off-library",
            "attributed",
            "convective-heat-loss",
            offlibrary={"sensor-lag": 10.0},
            nearest="response-delay",
        ),
        _row("null-noisy-zero", "none"),
        _row("null-noisy-zero", "none"),
        _row("null-noisy-zero", "unexplained"),
        _row("null-noisy-zero", "attributed", "response-delay"),
    ]
    f = score(rows)["families"]
    cal = f["calibration-only"]
    assert cal["n"] == 4 and cal["attributed_rate"] == pytest.approx(0.25)
    # the damping row names a parameter the rig did not move (offset 0)
    assert cal["miscalibrated_naming_a_moved_parameter"] == 1 and cal["miscalibrated_right_rate"] == 0.25
    assert f["realistic"]["3.0"]["top1"] == pytest.approx(0.5) and f["realistic"]["10.0"]["top1"] == 1.0
    assert f["off-library"]["3.0"]["top1"] == pytest.approx(0.5) and f["off-library"]["10.0"]["top1"] == 0.0
    nn = f["null-noisy-zero"]
    assert (nn["n"], nn["false_attributions"], nn["none"]) == (4, 1, 2)
    assert nn["false_rate"] == 0.25 and nn["none_rate"] == 0.5
    conf = score(rows)["confusion_by_family"]
    assert conf["off-library"]["dynamic"]["sensor-lag (response-delay)"] == {
        "response-delay": 1,
        "unexplained": 1,
        "convective-heat-loss": 1,
    }


def test_shrinkage_against_the_noise_ceiling():
    row = {
        "case": "single",
        "kind": "static",
        "effects": {"a": 10.0},
        "seed": 1,
        "verdict": "attributed",
        "effect": "a",
        "aliased_with": [],
        "ranking": ["a"],
        "shrinkage": {"a": 0.81},
        "fraction_closed": {"a": 0.9},
        "heldout_rmse_before_noise": 10.0,
        "seconds": 1.0,
    }
    cell = score([row])["shrinkage_by_strength"]["10.0"]
    assert cell["median_share_of_ceiling"] == pytest.approx(0.81 / (1 - 1 / math.sqrt(101)))


def test_full_run_estimate_from_per_case_times():
    secs = {"effect-only": {"static": 4.0}, "calibration-only": {"static": 10.0}}
    plan = benchmark.plan_full_run(secs, seeds=10, kinds=("static",), cores=2)
    n = plan["cases"]
    assert plan["seconds"]["calibration-only"] == pytest.approx(n["calibration-only"] * 10.0 / 2)
    # families without a timing of their own are costed at the kind's median (7 s)
    assert plan["seconds"]["off-library"] == pytest.approx(n["off-library"] * 7.0 / 2)
    assert plan["total_seconds"] == pytest.approx(sum(plan["seconds"].values()))


def test_named_or_aliased_counts_honest_aliasing_but_top1_does_not():
    from tcamlab.benchmark import _acc, named_or_aliased

    base = {"case": "single", "kind": "static", "effects": {"glass-transition": 3.0}, "ranking": []}
    named = {**base, "verdict": "attributed", "effect": "glass-transition", "aliased_with": []}
    honest = {**base, "verdict": "miscalibrated", "effect": None, "aliased_with": ["glass-transition"]}
    other = {
        **base,
        "verdict": "miscalibrated",
        "effect": None,
        "aliased_with": ["youngs-modulus-temperature"],
    }
    wrong = {
        **base,
        "verdict": "attributed",
        "effect": "displacement-drift",
        "aliased_with": ["glass-transition"],
    }
    assert [named_or_aliased(r) for r in (named, honest, other, wrong)] == [True, True, False, False]
    acc = _acc([named, honest, other, wrong])
    assert acc["top1"] == 0.25 and acc["named_or_aliased"] == 0.5


def test_a_truth_the_rig_cannot_run_is_skipped_not_scored(monkeypatch):
    """A drawn truth the rig cannot simulate on either side of the stated value (the model has
    no solution) is listed as skipped and left out of the rates; an error inside the
    diagnosis still counts as a miss."""
    import tcamlab.rig
    from tcamlab.benchmark import family_tasks, run_task, score
    from tcamlab.errors import ModelDomainError

    def no_solution(*a, **k):
        raise ModelDomainError("temperature rise 130.3 K makes the shear modulus G_t' non-positive")

    monkeypatch.setattr(tcamlab.rig, "simulate", no_solution)
    task = next(t for t in family_tasks("static", ("calibration-only",), seeds=10) if t["seed"] == 7003)
    r = run_task({**task, "n_boot": 10})
    assert r["error_stage"] == "simulate" and r["error"].startswith("ModelDomainError")
    ok = {**task, "verdict": "miscalibrated", "effect": None, "aliased_with": [], "recalibrated": [],
          "ranking": [], "seconds": 1.0, "parameter_offsets_sd": {"radial_cte": 2.0}}  # fmt: skip
    broken = {**task, "error": "ValueError: inside the diagnosis", "error_stage": "diagnose", "seconds": 1.0}
    s = score([r, ok, broken])
    assert len(s["skipped"]) == 1 and s["skipped"][0]["task"]["seed"] == 7003
    c = s["families"]["calibration-only"]
    assert c["n"] == 2 and c["verdicts"] == {"miscalibrated": 1, "error": 1}


def test_miscalibrated_naming_the_parameter_an_effect_is_counts_as_right():
    # sensor-offset-error *is* an error of the calibrated d1 (Effect.generalises): naming
    # d1 recalibrated is the right diagnosis; naming another parameter is not
    from tcamlab.benchmark import _acc, names_its_parameter, right, right_candidate

    base = {
        "case": "single",
        "kind": "curvature",
        "effects": {"sensor-offset-error": 3.0},
        "ranking": ["recalibration", "camera-placement"],
        "aliased_with": [],
        "effect": None,
        "verdict": "miscalibrated",
    }
    d1 = {**base, "recalibrated": ["sensor_offset"]}
    e = {**base, "recalibrated": ["youngs_modulus"]}
    # an effect that is no parameter's error (camera placement) is not rescued by recalibration
    cam = {**base, "effects": {"camera-placement": 3.0}, "recalibrated": ["sensor_offset"]}
    attributed = {**base, "verdict": "attributed", "effect": "sensor-offset-error", "recalibrated": []}
    assert [names_its_parameter(r) for r in (d1, e, cam, attributed)] == [True, False, False, False]
    assert [right(r) for r in (d1, e, cam, attributed)] == [True, False, False, True]
    assert right_candidate(d1) == "recalibration" and right_candidate(attributed) == "sensor-offset-error"
    assert _acc([d1, e, cam, attributed])["top1"] == 0.5
    # a null case is never right by a parameter
    null = {**base, "effects": {}, "recalibrated": ["sensor_offset"]}
    assert not names_its_parameter(null)


def test_two_condition_tasks_run_only_the_kinds_that_have_a_second_condition():
    from tcamlab.errors import ConfigError

    tasks = benchmark.make_tasks(quick=True, conditions=2, families=("effect-only", "calibration-only"))
    assert {t["kind"] for t in tasks} == {"static", "dynamic"}
    assert all(t["conditions"] == 2 for t in tasks)
    assert all("conditions" not in t for t in benchmark.make_tasks(quick=True))
    with pytest.raises(ConfigError, match="no second condition"):
        benchmark.make_tasks(quick=True, conditions=2, kinds=("sensing",))


def test_calibration_only_counts_a_named_partner_apart_from_the_strict_figure():
    base = {"case": "calibration-only", "kind": "curvature", "effects": {}, "verdict": "miscalibrated"}
    moved = {"parameter_offsets_sd": {"youngs_modulus": -2.8, "sensor_offset": 0.0}}
    strict = {**base, **moved, "recalibrated": ["youngs_modulus"], "recalibrated_aliases": []}
    partner = {
        **base,
        **moved,
        "recalibrated": ["spring_constant"],
        "recalibrated_aliases": ["youngs_modulus"],
    }
    other = {**base, **moved, "recalibrated": ["spring_constant"], "recalibrated_aliases": []}
    c = benchmark._calibration_only([strict, partner, other])
    assert c["miscalibrated_naming_a_moved_parameter"] == 1
    assert c["miscalibrated_right_rate"] == pytest.approx(1 / 3)
    assert c["miscalibrated_right_or_partner_rate"] == pytest.approx(2 / 3)


def test_top1_where_the_effect_beats_recalibration_on_withheld_runs():
    from tcamlab.benchmark import SEPARABLE_RATIO, _acc, _family_rows, separable

    base = {"case": "single", "kind": "static", "effects": {"glass-transition": 3.0}, "ranking": []}

    def case(verdict, effect, recal, true):
        return {
            **base,
            "verdict": verdict,
            "effect": effect,
            "aliased_with": [],
            "shrinkage": {"recalibration": recal, "glass-transition": true},
        }

    # held-out RMSE ratio recalibration / true effect: 0.5 / 0.4 = 1.25 (separable), 1.0 (not)
    won_right = case("attributed", "glass-transition", 0.5, 0.6)
    won_missed = case("miscalibrated", None, 0.5, 0.6)
    tied = case("miscalibrated", None, 0.6, 0.6)
    just_under = case("miscalibrated", None, 1.0 - 0.4 * (SEPARABLE_RATIO - 0.001), 0.6)
    failed = {**won_right, "error": "ConvergenceError: x"}
    assert [separable(r) for r in (won_right, won_missed, tied, just_under, failed)] == [
        True,
        True,
        False,
        False,
        False,
    ]
    acc = _acc([won_right, won_missed, tied, just_under])
    assert acc["separable_n"] == 2 and acc["separable_top1"] == 0.5
    assert acc["top1"] == 0.25
    rows = _family_rows({"effect-only": {"3.0": acc}, "off-library": {"10.0": acc}})
    sep = [r for r in rows if "beats recalibration" in r[1]]
    assert sep[0][2:] == ["2", "0.5", "(proposed) >= 0.9"] and sep[1][-1] == "(proposed) >= 0.8"
    # the proposed targets by family and strength (README, "Proposed targets")
    rows = _family_rows({"effect-only": {"1.0": acc}, "realistic": {"3.0": acc}, "off-library": {"3.0": acc}})
    target = {(r[0], r[1]): r[-1] for r in rows}
    assert target[("effect-only", "top-1 at 1.0x")] == ">= 0.7"
    assert target[("effect-only", "named, or aliased with the verdict, at 1.0x")] == "-"
    beats = "top-1 at 1.0x where the effect beats recalibration on withheld runs"
    assert target[("effect-only", beats)] == "(proposed) >= 0.7"
    assert target[("realistic", "named, or aliased with the verdict, at 3.0x")] == "(proposed) >= 0.9"
    assert target[("off-library", "named, or aliased with the verdict, at 3.0x")] == "-"


def _another(kind):
    from pathlib import Path

    return Path(__file__).resolve().parents[1] / "bench" / "templates" / f"another_tca_{kind}.toml"


def test_another_sample_is_benchmarked_under_the_same_relative_stated_uncertainty():
    from tcamlab.benchmark import STATED_UNCERTAINTY, stated_template, stated_uncertainty

    assert stated_uncertainty("dynamic") is STATED_UNCERTAINTY["dynamic"]
    st = stated_uncertainty("static", _another("static"))
    # rho 7.0e-5 (bundled 8.1e-5, sd 8.1e-6), E 3.0 GPa (3.45, sd 0.1725), slope 0.9 MPa/K (1.11, 0.222)
    assert st["sample"]["radial_cte"] == pytest.approx(7.0e-6)
    assert st["sample"]["youngs_modulus"] == pytest.approx(0.15e9)
    assert st["sample"]["shear_modulus_slope"] == pytest.approx(0.18e6)
    dyn = stated_uncertainty("dynamic", _another("dynamic"))
    assert dyn["rig"]["thermal_mass"] == pytest.approx(0.00845 * 0.034 / 0.0266)
    exp = stated_template("dynamic", _another("dynamic"))
    assert exp.rig.thermal_mass == pytest.approx(0.034)
    assert exp.rig.uncertainty["thermal_mass"] == pytest.approx(dyn["rig"]["thermal_mass"])


def test_template_tasks_carry_their_file_and_other_kinds_keep_the_bundled_one():
    tasks = make_tasks(
        quick=True,
        seeds=1,
        kinds=("static", "sensing"),
        families=("null", "calibration-only"),
        templates={"static": _another("static")},
    )
    static = [t for t in tasks if t["kind"] == "static"]
    assert static and all(t["template"] == str(_another("static")) for t in static)
    assert all("template" not in t for t in tasks if t["kind"] == "sensing")
    cal = next(t for t in static if t["case"] == "calibration-only")
    assert cal["stated"]["sample"]["youngs_modulus"] == pytest.approx(0.15e9)


def test_template_option_errors_name_the_file(tmp_path):
    from tcamlab.errors import ConfigError
    from tcamlab.pipeline import benchmark_diagnosis
    from tcamlab.templates import template_path

    with pytest.raises(ConfigError, match="second --template of kind 'static'"):
        benchmark_diagnosis(tmp_path, templates=[_another("static"), template_path("static")])
    with pytest.raises(ConfigError, match="selfsensing.toml: kind 'selfsensing' has no diagnosis benchmark"):
        benchmark_diagnosis(tmp_path, templates=[template_path("selfsensing")])


def test_the_report_says_which_template_a_kind_was_benchmarked_on():
    from tcamlab.benchmark import _design_lines

    lines = _design_lines({"templates": {"static": str(_another("static"))}, "conditions": 1})
    assert lines[0].startswith("Sample and rig of the static cases: **another_tca_static.toml**")
    assert _design_lines({"conditions": 1}) == []


def test_the_benchmark_report_names_the_template_in_its_summary():
    from tcamlab.benchmark import BenchmarkResult, report_document, score

    res = BenchmarkResult(
        scores=score([]),
        results=[],
        settings={"templates": {"dynamic": str(_another("dynamic"))}, "conditions": 2, "n_tasks": 0},
    )
    summary = report_document(res).sections[0].paragraphs
    assert any(p.startswith("Sample and rig of the dynamic cases: another_tca_dynamic.toml") for p in summary)
    assert any(p.startswith("Design: two conditions.") for p in summary)


def test_off_library_top1_where_the_withheld_runs_point_to_the_nearest_effect():
    from tcamlab.benchmark import _acc, _family_rows, points_to_truth

    def case(verdict, effect, shrinkage):
        return {
            "case": "off-library",
            "kind": "curvature",
            "effects": {},
            "offlibrary": {"tilted-sensor": 3.0},
            "nearest": "sensor-offset-error",
            "ranking": [],
            "verdict": verdict,
            "effect": effect,
            "aliased_with": [],
            "shrinkage": shrinkage,
        }

    # the nearest effect beats recalibration but axial compression fits the withheld runs better:
    # the runs point elsewhere, whatever the verdict
    elsewhere = case(
        "attributed",
        "axial-compression",
        {"recalibration": 0.30, "sensor-offset-error": 0.45, "axial-compression": 0.50},
    )
    named = case("attributed", "sensor-offset-error", {"recalibration": 0.30, "sensor-offset-error": 0.50})
    missed = case("miscalibrated", None, {"recalibration": 0.30, "sensor-offset-error": 0.50, "x": 0.50})
    tied = case("miscalibrated", None, {"recalibration": 0.50, "sensor-offset-error": 0.50})
    assert [points_to_truth(r) for r in (elsewhere, named, missed, tied)] == [False, True, True, False]
    acc = _acc([elsewhere, named, missed, tied])
    assert (acc["points_n"], acc["points_right"]) == (2, 1)
    rows = _family_rows({"off-library": {"3.0": acc}, "effect-only": {"3.0": acc}})
    points = [r for r in rows if "point to the nearest" in r[1]]
    assert len(points) == 1 and points[0][0] == "off-library"
    assert points[0][2:] == ["2", "0.5 (1 of 2)", "(proposed) >= 0.8"]
