"""The diagnosis report a reviewer can trust: residuals before and after the best candidate
against the physical input, every run, small regimes not drawn, "clearly worse" only with the
paired test shown, units on every printed RMSE, parameters in lab units, standalone figures.

Data: virtual-rig experiments (synthetic; ``tcamlab.rig.simulate``, seeds below), and
hand-made result stand-ins where only the report's arithmetic is tested.
"""

from __future__ import annotations

import io
import re
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from tcamlab import rig
from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.diagnosis import diagnose
from tcamlab.diagnosis.paired import paired_tests
from tcamlab.numbers import lab_unit, rmse_unit
from tcamlab.report.diagnosis_figures import (
    MAX_LEGEND_ENTRIES,
    MIN_REGIME_POINTS,
    regime_figure,
    residual_figure,
)
from tcamlab.report.diagnosis_report import (
    diagnosis_document,
    diagnosis_lines,
    next_experiment_section,
    verdict_text,
)
from tcamlab.report.diagnosis_tests import paired_lines, paired_sentence, paired_table
from tcamlab.report.html import render_html
from tcamlab.report.pdf import render_pdf

pypdf = pytest.importorskip("pypdf")

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "tcamlab" / "templates"
runner = CliRunner()


@pytest.fixture(scope="module")
def glass(tmp_path_factory):
    """Static heat-cool test with a glass transition at 10x noise (virtual rig, seed 3)."""
    out = tmp_path_factory.mktemp("glass")
    sim = rig.simulate(
        "static",
        TEMPLATES / "static.toml",
        seed=3,
        out_dir=out,
        effects={"glass-transition": 10.0},
        n_runs=5,
        oven="heat-cool",
    )
    exp = load_experiment(sim.experiment_path)
    return diagnose(exp, n_boot=300), exp


def _residual_axes(fig):
    return [ax for ax in fig.figure.axes if "measured - predicted" in ax.get_ylabel() or ax.get_title()]


def test_residuals_before_and_after_every_run_against_temperature(glass):
    result, _ = glass
    fig = residual_figure(result, "displacement")
    before, after = fig.figure.axes
    assert before.get_xlabel() == after.get_xlabel() == "temperature [degC]"
    assert before.get_ylabel() == "displacement: measured - predicted [mm]"
    assert "before: thesis model" in before.get_title() and "glass-transition" in after.get_title()
    runs = result._series["runs"]
    for ax, which in ((before, "baseline"), (after, "best")):
        lines = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
        assert len(lines) == len(runs) == 5  # every run, not runs 1 and 2
        for ln, run in zip(lines, runs):
            expected = (run["measured"]["displacement"] - run[which]["displacement"]) * 1e3
            np.testing.assert_allclose(ln.get_ydata(), expected)
            np.testing.assert_allclose(ln.get_xdata(), run["x"])
            assert ln.get_markersize() >= 3  # a short log: visible markers
    # at the scale of the noise: the y range is a few noise sds, not the 0-50 mm stroke
    sigma_mm = result.noise_floor["by_quantity"]["displacement"]["sigma"]
    assert np.ptp(before.get_ylim()) < 40 * sigma_mm
    rms = [float(re.search(r"RMSE ([0-9.e-]+) mm", ax.get_title()).group(1)) for ax in (before, after)]
    assert rms[1] < 0.3 * rms[0]
    legend = fig.figure.legends[0]
    assert len(legend.get_texts()) <= MAX_LEGEND_ENTRIES
    assert legend.get_texts()[0].get_fontsize() >= 8


def _fake(labels: dict, z, runs=None, kind="static"):
    return SimpleNamespace(
        kind=kind,
        _series={
            "labels": labels,
            "z": np.asarray(z, float),
            "regime_groups": list(labels),
            "runs": runs or [],
        },
    )


def test_small_regimes_are_not_drawn_and_a_one_box_plot_is_not_made():
    n = 60
    phase = np.array(["heating"] * n, dtype=object)
    band = np.array(["<25 degC"] + ["25-50 degC"] * 29 + ["50-75 degC"] * 30, dtype=object)
    res = _fake({"phase": phase, "temperature band": band}, np.linspace(-1, 1, n))
    assert regime_figure(res, "phase") is None  # a heating-only test: one box says nothing
    fig = regime_figure(res, "temperature band")
    ax = fig.figure.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["25-50 degC", "50-75 degC"]
    assert "<25 degC (n = 1)" in fig.caption and str(MIN_REGIME_POINTS) in fig.caption


def test_many_runs_share_legend_entries():
    x = np.linspace(25, 150, 40)
    runs = [
        {
            "x": x,
            "xlabel": "temperature [degC]",
            "measured": {"displacement": x * 1e-4},
            "baseline": {"displacement": x * 1e-4 - 1e-5 * k},
            "best": None,
        }
        for k in range(9)
    ]
    res = _fake({}, [], runs)
    res.ranking, res.verdict, res.effect, res.combination = [], "none", None, None
    res.noise_floor = {"by_quantity": {"displacement": {"sigma": 1e-5}}}
    fig = residual_figure(res, "displacement")
    assert len(fig.figure.axes) == 1  # no best candidate: no "after" panel
    assert len([ln for ln in fig.figure.axes[0].get_lines() if ln.get_marker() == "o"]) == 9
    assert len(fig.figure.legends[0].get_texts()) <= MAX_LEGEND_ENTRIES


def _cand(effect, folds_mse, ci):
    return SimpleNamespace(
        effect=effect,
        folds=[{"rmse_after_noise": float(np.sqrt(m))} for m in folds_mse],
        shrinkage_ci95=list(ci),
    )


def _result(best, others, rows=(100, 100, 100, 100, 200), n_boot=500):
    """A result stand-in with its paired tests stored, as the diagnosis stores them."""
    res = SimpleNamespace(
        effect=best.effect,
        combination=None,
        ranking=[best, *others],
        settings={
            "seed": 0,
            "n_boot": n_boot,
            "fold_details": [{"held_out": [{"run": i, "rows": [0, r - 1]}]} for i, r in enumerate(rows)],
        },
    )
    res.paired_tests = paired_tests(res)
    return res


def test_paired_sentence_prints_the_stored_tests():
    best = _cand("a", [1.0, 1.1, 0.9, 1.0, 1.2], (0.5, 0.6))
    worse = _cand("b", [2.0, 2.1, 1.9, 2.2, 2.0], (0.2, 0.3))
    tied = _cand("c", [1.2, 0.9, 1.1, 0.8, 1.1], (0.45, 0.58))
    text = paired_sentence(_result(best, [worse, tied]))
    assert "Not every other candidate is clearly worse" in text and "cannot tell it from c" in text
    assert "Every other candidate is clearly worse" not in text
    # only b: clearly worse, with the statistic and p shown; b's pooled difference is
    # (1 x 300 + 1.2 x 100 + 0.8 x 200) / 600 = 0.967 noise sd²
    text = paired_sentence(_result(best, [worse]))
    assert text.startswith("Every other candidate is clearly worse")
    assert "b, 0.967 noise sd²" in text
    assert "p < 0.002" in text and "worse on 5 of 5 folds" in text and "seed 0" in text


def test_the_report_prints_what_is_stored_and_computes_nothing():
    # tests stored by hand, not what the folds would give: the report prints these
    stored = [
        {
            "candidate": "b",
            "best": "a",
            "diff": 0.25,
            "ci95": [0.125, 0.5],
            "p_boot": 0.004,
            "n_boot": 250,
            "seed": 7,
            "worse_folds": 4,
            "folds": 5,
            "p_sign": 0.1875,
            "intervals_overlap": True,
            "clearly_worse": False,
        }
    ]
    res = SimpleNamespace(settings={}, ranking=[], effect="a", combination=None, paired_tests=stored)
    text = paired_sentence(res)
    assert "Not every other candidate is clearly worse" in text and "250 resamples, seed 7" in text
    assert "b is worse by the paired test (closest: b, 0.25 noise sd² (95 % 0.125 to 0.5" in text
    assert "p = 0.004" in text and "worse on 4 of 5 folds" in text
    table = paired_table(res)
    assert table.caption.startswith("Paired tests against a ")
    assert table.rows == [["b", "0.25", "0.125 to 0.5", "p = 0.004", "4 of 5", "0.19", "yes", "no"]]
    assert paired_lines(res)[1].endswith(
        "sign test p = 0.19) - NOT clearly worse: worse by the paired test, but its shrinkage "
        "interval overlaps the best's"
    )
    tied = [{**stored[0], "ci95": [-0.1, 0.5]}]
    assert paired_lines(SimpleNamespace(paired_tests=tied))[1].endswith(
        "NOT clearly worse: the interval includes 0"
    )
    # the same from the diagnosis.json mapping
    as_json = {"paired_tests": stored}
    assert paired_sentence(as_json) == text and paired_table(as_json).rows == table.rows
    # nothing stored: no table and no claim
    assert paired_table({"paired_tests": []}) is None
    assert "no candidate is called clearly worse" in paired_sentence(SimpleNamespace(paired_tests=None))


def test_overlapping_shrinkage_intervals_never_read_clearly_worse(glass):
    result, exp = glass
    tests = result.paired_tests
    assert tests, "the glass case has other candidates"
    assert result.to_dict()["paired_tests"] == tests  # in diagnosis.json
    text = verdict_text(result)
    # shrinkage 82-86 % for glass-transition against 80-84 % for the rest: the intervals overlap
    assert any(t["intervals_overlap"] for t in tests)
    assert "Every other candidate is clearly worse" not in text
    # the statistic behind any claim is printed: difference, interval, p
    assert re.search(r"noise sd² \(95 % [-0-9.e]+ to [-0-9.e]+, p [<=] [0-9.e-]+", text)
    doc = diagnosis_document(result, exp)
    html = render_html(doc)
    assert "bootstrap p" in html and "sign test p" in html
    pdf = " ".join(
        " ".join(p.extract_text() for p in pypdf.PdfReader(io.BytesIO(render_pdf(doc))).pages).split()
    )
    assert "Paired tests against" in pdf and "bootstrap p" in pdf


class _Text(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.text = []

    def handle_data(self, data):
        self.text.append(data)


def test_html_has_no_full_scale_overlay_and_no_negative_zero(glass):
    result, exp = glass
    html = render_html(diagnosis_document(result, exp))
    p = _Text()
    p.feed(html)
    text = " ".join(p.text)
    assert "measured, thesis model and best candidate" not in text  # the old full-scale overlays
    assert "against temperature, every run" in text
    assert "-0%" not in text and "-0 %" not in text and not re.search(r"[-+]0\.00\b", text)
    assert not re.search(r"\] -(\s|$)", text)  # no "[...] -" parameter cells


def test_lab_units_of_parameters_and_rmse():
    assert lab_unit("m") == ("mm", 1e3) and lab_unit("m/s") == ("um/s", 1e6) and lab_unit("-") == ("", 1.0)
    assert (
        rmse_unit("N") == ("mN", 1e3) and rmse_unit("1/mm") == ("1/m", 1e3) and rmse_unit("mm") == ("mm", 1.0)
    )


@pytest.mark.slow
def test_diagnose_text_units_and_standalone_figures(tmp_path):
    sim = rig.simulate(
        "curvature",
        TEMPLATES / "curvature.toml",
        seed=7,
        out_dir=tmp_path,
        effects={"camera-placement": 10.0},
        n_runs=5,
    )
    out = tmp_path / "out"
    res = runner.invoke(app, ["diagnose", str(sim.experiment_path), "--out", str(out)])
    assert res.exit_code == 0, res.output
    rmse_lines = [ln for ln in res.output.splitlines() if "held-out RMSE " in ln and "->" in ln]
    assert rmse_lines and all(re.search(r"-> [-0-9.e]+ (1/m|mm|mN|ohm|x noise sd) ", ln) for ln in rmse_lines)
    assert "-0%" not in res.output and not re.search(r"\] -(\s|$)", res.output)
    folder = out / sim.experiment_path.stem
    pngs, svgs = sorted(folder.glob("diagnosis-fig*.png")), sorted(folder.glob("diagnosis-fig*.svg"))
    html = (folder / "diagnosis.html").read_text()
    assert "held-out RMSE before [1/m]" in html  # curvature RMSE in 1/m, not 0.0005 1/mm
    n_figures = len(re.findall(r"<figure\b", html))
    assert n_figures >= 3 and len(pngs) == len(svgs) == n_figures
    for png in pngs:
        assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    for svg in svgs:
        assert re.match(r"\s*<svg\b[^>]*xmlns=\"http://www.w3.org/2000/svg\"", svg.read_text())


def test_text_lines_print_parameters_in_lab_units():
    cand = {
        "effect": "initial-slack",
        "unit": "noise",
        "heldout_rmse_before": 3.0,
        "heldout_rmse_after": 1.0,
        "shrinkage": -0.001,
        "by_quantity": {
            "displacement": {"heldout_rmse_before": 0.24, "heldout_rmse_after": 0.068, "unit": "mm"},
            "force": {"heldout_rmse_before": 0.00318, "heldout_rmse_after": 0.00203, "unit": "N"},
        },
        "parameters": {
            "slack": {"value": 1.91e-4, "ci95": [1.8e-4, 2.0e-4], "unit": "m"},
            "relaxation": {"value": 0.01, "ci95": [0.0, 0.02], "unit": "-"},
        },
    }
    fake = SimpleNamespace(
        reason="something",
        to_dict=lambda: {"verdict": "unexplained", "effect": None, "recalibration": None, "ranking": [cand]},
    )
    lines = diagnosis_lines(fake)
    line = lines[-1]
    assert "slack = 0.191 mm (95 % 0.18 to 0.2)" in line
    assert "force 3.18 -> 2.03 mN" in line and "displacement 0.24 -> 0.068 mm" in line
    assert "(0% shrinkage)" in line  # never -0%
    assert "relaxation = 0.01 (95 %" in line and "] -" not in line
    # a verdict with aliased candidates prints the experiments that tell them apart
    doc = {**fake.to_dict(), "separate_by": {"initial-slack": "pre-tension the thread"}}
    lines = diagnosis_lines(SimpleNamespace(reason="something", to_dict=lambda: doc))
    assert "  to tell apart, initial-slack: pre-tension the thread" in lines


def test_diagnosis_json_records_no_absolute_path(glass):
    result, exp = glass
    # the virtual rig wrote the experiment under pytest's tmp folder, outside the working one
    assert exp.path.is_absolute()
    assert result.to_dict()["experiment"]["path"] == f".../{exp.path.name}"


def test_diagnosis_provenance_has_tool_version_and_input_hashes(glass):
    import hashlib

    from tcamlab import __version__
    from tcamlab.report.diagnosis_report import diagnosis_document

    result, exp = glass
    info = result.to_dict()["experiment"]
    assert info["tool"] == f"tcamlab {__version__}"
    roles = [e["role"] for e in info["inputs"]]
    assert roles[0] == "experiment" and roles.count("run") == info["n_runs"]
    for e in info["inputs"]:
        assert not e["path"].startswith("/")
        on_disk = (exp.path.parent / e["path"]).read_bytes()
        assert e["sha256"] == hashlib.sha256(on_disk).hexdigest()
    doc = diagnosis_document(result, exp)
    assert doc.metadata["tool"] == f"tcamlab {__version__}"
    assert doc.metadata[f"sha256 {info['inputs'][1]['path']}"] == info["inputs"][1]["sha256"]
    # a synthetic experiment's banner says what made it and that withheld options are left out
    assert "withheld options" in doc.synthetic_banner and "seed" in doc.synthetic_banner


def test_verdict_text_of_a_parameter_found_as_its_own_error():
    from tcamlab.report.diagnosis_report import verdict_text

    entry = {
        "symbol": "d1",
        "value": 8.1e-3,
        "ci95": [7.8e-3, 8.4e-3],
        "unit": "m",
        "stated": 9e-3,
        "shift_in_stated_sds": -3.0,
        "shift_in_prior_sds": -3.0,
    }
    result = SimpleNamespace(
        gap={"rmse_over_noise": 3.2, "limit": 1.2, "level": 0.99},
        verdict="miscalibrated",
        ranking=[],
        effect=None,
        recalibration={
            "named": ["sensor_offset"],
            "parameters": {"sensor_offset": entry},
            "fraction_closed": 0.99,
            "via_effect": "sensor-offset-error",
        },
        aliased_with=[],
        separate_by={},
    )
    text = verdict_text(result)
    assert "a wrong parameter, not missing physics" in text
    assert "(sensor-offset-error)" in text and "-3.0 stated sds" in text
    assert "does not move it that far" in text


def test_verdict_text_of_miscalibrated_names_the_stand_ins_and_how_to_separate_them():
    # a miscalibrated verdict with effects that fit as well must say so in the report, with
    # the experiments under separate_by; without stand-ins it says nothing of them
    entry = {
        "symbol": "rho",
        "value": 1.02e-3,
        "ci95": [0.9e-3, 1.1e-3],
        "unit": "m",
        "stated": 1.0e-3,
        "shift_in_stated_sds": 0.2,
        "shift_in_prior_sds": 0.2,
    }
    recalibration = {
        "named": ["resistivity"],
        "parameters": {"resistivity": entry},
        "fraction_closed": 0.9,
        "stand_ins": {"youngs-modulus-temperature": ["resistivity"], "glass-transition": []},
    }
    result = _miscalibrated(
        recalibration,
        aliased_with=["youngs-modulus-temperature", "glass-transition"],
        separate_by={"recalibration": "a second load", "glass-transition": "a slower oven ramp"},
    )
    text = verdict_text(result)
    # each with the parameter whose shift it takes over (none listed: the combination the data fix)
    assert (
        "youngs-modulus-temperature (with resistivity at its stated value) and glass-transition "
        "(with the combination of parameters the data fix at its stated value) fit the withheld "
        "runs as well" in text
    )
    assert "recalibration: a second load; glass-transition: a slower oven ramp." in text
    assert "withheld runs as well" not in verdict_text(_miscalibrated(recalibration, [], {}))
    # the words are the result's: the report prints them as stored
    stored = SimpleNamespace(**{**vars(result), "stand_ins_words": "x (with y at its stated value)"})
    assert "But x (with y at its stated value) fit the withheld runs as well" in verdict_text(stored)


def _miscalibrated(recalibration, aliased_with, separate_by):
    """A ``miscalibrated`` diagnosis result with only what its verdict text reads."""
    from tcamlab.diagnosis.result import DiagnosisResult

    return DiagnosisResult(
        kind="static",
        experiment={},
        verdict="miscalibrated",
        effect=None,
        ranking=[],
        aliased_with=aliased_with,
        separate_by=separate_by,
        noise_floor={},
        baseline={},
        regimes=[],
        runs=[],
        gap={"rmse_over_noise": 1.9, "limit": 1.2, "level": 0.99},
        reason="",
        settings={},
        recalibration=recalibration,
    )


def test_a_parameter_at_a_bound_of_its_fit_is_printed_without_an_interval():
    params = {
        "lag_tau": {"value": 3.6e-6, "ci95": [3.6e-6, 3.6e-6], "unit": "s", "at_bound": True},
        "drift": {"value": 2e-6, "ci95": [1e-6, 3e-6], "unit": "m", "at_bound": False},
    }
    cand = {
        "effect": "oven-thermal-lag",
        "unit": "m",
        "heldout_rmse_before": 1e-5,
        "heldout_rmse_after": 6e-6,
    }
    doc = {
        "verdict": "unexplained",
        "effect": None,
        "ranking": [{**cand, "shrinkage": 0.4, "parameters": params}],
    }
    text = diagnosis_lines(SimpleNamespace(reason="something", to_dict=lambda: doc))[-1]
    assert "lag_tau = 3.6e-06 s (at a bound of its fitted range, so no interval)" in text
    assert "3.6e-06 to 3.6e-06" not in text and "(95 % " in text


def _design() -> dict:
    """A design's JSON (:meth:`tcamlab.design.DesignResult.to_dict`), made by hand."""
    protocol = {"table": {}, "log_bayes_factor": 3.0, "pairs": {}, "max_difference": {}}
    return {
        "schema_version": 1,
        "status": "ambiguous",
        "message": "Run the slow oven ramp next: it tells glass-transition from recalibration.",
        "best": "slow oven ramp",
        "out_of_reach": {"displacement-drift": {"drift": {"fitted": 1e-12, "smallest": 1e-9, "unit": "m/s"}}},
        "candidates": [
            {
                **protocol,
                "name": "slow oven ramp",
                "separation": 12.5,
                "separation_refit": 9.25,
                "beyond_repeat": 9.5,
                "at_fit": {"glass-transition": 30.0, "displacement-drift": 0.1},
                "decisive": True,
                "runs": 3,
                "minutes": 45.0,
                "per_hour": 16.7,
                "feasible": True,
                "limit": "",
            },
            {
                **protocol,
                "name": "second load",
                "separation": 4.5,
                "separation_refit": None,  # NaN in the design, null in its JSON
                "runs": 2,
                "minutes": 30.0,
                "per_hour": 9.0,
                "feasible": False,
                "limit": "load above the thread's rating",
            },
        ],
    }


def test_next_experiment_section_lists_the_protocols_with_the_best_marked():
    sec = next_experiment_section(_design())
    assert sec.heading == "Next experiment"
    assert sec.paragraphs == [_design()["message"]]
    (table,) = sec.tables
    assert table.columns == [
        "protocol",
        "separation J",
        "J beyond the repeat",
        "weakest effect at its fit",
        "decides",
        "runs",
        "minutes",
        "feasible",
    ]
    rows = [[c.text for c in row] for row in table.formatted_rows()]
    # the drift is out of the menu's reach: the weakest effect within it is the glass transition
    assert rows[0] == ["slow oven ramp (best)", "9.25", "9.5", "30", "yes", "3", "45", "yes"]
    dash = "\u2013"
    assert rows[1] == ["second load", dash, dash, dash, "no", "2", "30", "load above the thread's rating"]
    # a clear diagnosis: ranked by the information the protocols add
    clear = {**_design(), "status": "clear"}
    clear["candidates"] = [{**c, "information_gain": 2.5} for c in clear["candidates"]]
    (table,) = next_experiment_section(clear).tables
    assert table.columns[1] == "information gain [nats]"
    assert [c.text for c in table.formatted_rows()[0]][:2] == ["slow oven ramp (best)", "2.5"]
    # nothing to separate: the message alone, no empty table
    none = next_experiment_section({"status": "none", "message": "Nothing to separate.", "candidates": []})
    assert none.paragraphs == ["Nothing to separate."] and list(none.tables) == []
    assert next_experiment_section(None) is None and next_experiment_section({}) is None


def test_a_hypothesis_without_a_statistic_at_its_fit_shows_a_dash():
    # a hypothesis with no solution near its fit under a protocol: NaN in the design, null in
    # its JSON; the weakest effect is then unknown, not the smallest of the others
    design = _design()
    design["candidates"][0]["at_fit"] = {"glass-transition": 30.0, "youngs-modulus-temperature": None}
    (table,) = next_experiment_section(design).tables
    row = [c.text for c in table.formatted_rows()[0]]
    assert row[:5] == ["slow oven ramp (best)", "9.25", "9.5", "\u2013", "yes"]


def test_diagnosis_report_renders_the_next_experiment_only_when_present(glass):
    result, exp = glass
    assert [s.heading for s in diagnosis_document(result, exp).sections] == ["Sim-to-real gap diagnosis"]
    doc = diagnosis_document(result, exp, next_experiment=_design())
    assert [s.heading for s in doc.sections] == ["Sim-to-real gap diagnosis", "Next experiment"]
    html = render_html(doc)
    assert "Next experiment" in html and "slow oven ramp (best)" in html and "9.25" in html
    pdf = " ".join(
        " ".join(p.extract_text() for p in pypdf.PdfReader(io.BytesIO(render_pdf(doc))).pages).split()
    )
    assert "Next experiment" in pdf and "slow oven ramp (best)" in pdf
    # stored on the result (as diagnosis.json's next_experiment), the report finds it there
    stored = SimpleNamespace(**{**vars(result), "next_experiment": _design()})
    assert diagnosis_document(stored, exp).sections[-1].heading == "Next experiment"


def test_the_reason_keeps_what_the_verdict_said_after_the_paired_tests():
    """ "it leaves 1.95 x the noise floor ..." came after "every other candidate is clearly
    worse" and was cut from the printed reason and the report."""
    from tcamlab.report.diagnosis_report import _reason

    best = _cand("a", [1.0, 1.1, 0.9, 1.0, 1.2], (0.5, 0.6))
    tail = "; it leaves 1.95 x the noise floor on withheld data, above the no-gap limit 1.03"
    for others, words in (
        ([_cand("b", [2.0, 2.1, 1.9, 2.2, 2.0], (0.2, 0.3))], "; every other candidate is clearly worse by"),
        ([_cand("c", [1.2, 0.9, 1.1, 0.8, 1.1], (0.45, 0.58))], "; paired tests against it on the withheld"),
    ):
        res = _result(best, others)
        res.reason = "a closes 97% of the gap, and every other candidate is clearly worse" + tail
        text = _reason(res)
        assert text.startswith("a closes 97% of the gap" + tail + words), text
        res.reason = "a closes 97% of the gap, and every other candidate is clearly worse"
        assert tail not in _reason(res) and _reason(res).endswith(":")
