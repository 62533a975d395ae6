"""Reports a reviewer can trust: a three-way status, sanity warnings, honest provenance,
one number format, PDF tables without words cut mid-token, the index and its banner."""

from __future__ import annotations

import io
import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.metrics import (
    STATUS_FAILED,
    STATUS_NO_LIMITS,
    STATUS_PASSED,
    ZeroEstimate,
    check_thresholds,
    domain_warning,
    flat_prediction_warning,
    reference_warning,
    threshold_status,
    zero_offset_warning,
)
from tcamlab.numbers import fmt, fmt_percent, fmt_r2, with_unit
from tcamlab.report import Cell, Document, IndexDocument, IndexEntry, Section, Table
from tcamlab.report.html import render_index_html
from tcamlab.report.pdf import render_combined_pdf, render_pdf
from tcamlab.validation import validate

pypdf = pytest.importorskip("pypdf")

ROOT = Path(__file__).resolve().parent.parent
runner = CliRunner()


def _pdf_text(data: bytes, pages=None) -> str:
    reader = pypdf.PdfReader(io.BytesIO(data))
    chosen = reader.pages if pages is None else [reader.pages[i] for i in pages]
    return "\n".join(p.extract_text() for p in chosen)


class _Cells(HTMLParser):
    """Text of every td/th, the class of each td, and all text in order."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.cells, self.classes, self.text, self._in = [], [], [], False

    def handle_starttag(self, tag, attrs):
        if tag in ("td", "th"):
            self._in = True
            self.cells.append("")
            if tag == "td":
                self.classes.append(dict(attrs).get("class"))

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self._in = False

    def handle_data(self, data):
        self.text.append(data)
        if self._in:
            self.cells[-1] += data


def _parse(html: str) -> _Cells:
    p = _Cells()
    p.feed(html)
    return p


# -- status ------------------------------------------------------------------------------


def test_three_statuses_and_nothing_checked_is_not_a_pass():
    metrics = {"displacement_mm": {"rmse": 0.2, "r2": 0.9}}
    assert threshold_status([]) == STATUS_NO_LIMITS
    assert threshold_status(check_thresholds(metrics, {"rmse_mm": 0.5})) == STATUS_PASSED
    assert threshold_status(check_thresholds(metrics, {"rmse_mm": 0.1})) == STATUS_FAILED
    # a threshold that matches no quantity checks nothing
    assert threshold_status(check_thresholds(metrics, {"rmse_N": 0.1})) == STATUS_NO_LIMITS


def without_thresholds(text: str) -> str:
    """An experiment file's text without its [thresholds] table (and the comment above it)."""
    return re.sub(r"\n(#[^\n]*\n)?\[thresholds\]\n([^\[\n][^\n]*\n?)*", "", text)


@pytest.fixture(scope="module")
def unlimited(tmp_path_factory) -> Path:
    """A copy of the bundled experiments without their [thresholds] (status: no limits set)."""
    root = tmp_path_factory.mktemp("unlimited")
    shutil.copytree(ROOT / "raw", root / "raw")
    (root / "experiments").mkdir()
    for path in (ROOT / "experiments").glob("*.toml"):
        (root / "experiments" / path.name).write_text(without_thresholds(path.read_text()))
    return root / "experiments"


def test_without_thresholds_removes_the_table_only():
    text = 'kind = "static"\n\n# limits\n[thresholds]\nrmse_mm = 0.02\nr2_min = 0.99\n\n[rig]\nload_g = 50\n'
    assert without_thresholds(text) == 'kind = "static"\n\n[rig]\nload_g = 50\n'


@pytest.fixture(scope="module")
def static_result(unlimited):
    return validate(load_experiment(unlimited / "static.toml"))


def test_metrics_json_says_no_limits_and_passed_null(static_result):
    doc = static_result.to_dict()
    assert static_result.checks == []
    assert doc["status"] == "no limits set" and doc["passed"] is None
    assert static_result.failed is False


def test_validate_without_thresholds_exits_0_and_says_no_limits(tmp_path, unlimited):
    exp = unlimited / "static.toml"
    out = runner.invoke(app, ["validate", "static", str(exp), "--out", str(tmp_path), "--format", "html"])
    assert out.exit_code == 0, out.output
    assert "status: no limits set" in out.output
    doc = json.loads((tmp_path / "static" / "metrics.json").read_text())
    assert doc["passed"] is None and doc["status"] == "no limits set"
    html = (tmp_path / "static" / "report.html").read_text()
    first = html.split('id="sec-2"')[0]  # the first section: status and sanity checks
    assert "NO LIMITS SET" in first and "Sanity checks" in first


def test_index_shows_no_limits_neutral_and_the_synthetic_banner():
    index = IndexDocument(
        "reports",
        [
            IndexEntry("a", "A", "static", "no-limits", {"RMSE": "0.1 mm"}, link="a/report.html"),
            IndexEntry("b", "B", "static", "pass", {"RMSE": "0.2 mm"}, warnings=["x"]),
        ],
        synthetic_banner="SYNTHETIC DATA: 2 of 2 experiments",
    )
    p = _parse(render_index_html(index))
    assert "no limits set" in p.cells and "passed" in p.cells
    assert "status-no-limits" in p.classes and p.classes.count("status-pass") == 1
    assert "status-warn" in p.classes  # b has a warning
    text = "".join(p.text)
    assert "SYNTHETIC DATA: 2 of 2" in text and "1 no limits set" in text
    pdf = render_combined_pdf([], index)
    assert "SYNTHETIC DATA" in _pdf_text(pdf, [0])


# -- sanity checks -------------------------------------------------------------------------


def test_flat_prediction_against_a_varying_measurement():
    t = np.linspace(0, 1, 200)
    measured = 0.04 * np.sin(6 * t)  # [mm]
    w = flat_prediction_warning("displacement_mm", "mm", measured, np.full_like(t, 1e-8) + 1e-10 * t)
    assert w is not None and w.check == "flat-prediction"
    assert w.values["measured_range"] == pytest.approx(np.ptp(measured))
    assert "mm" in w.message
    assert flat_prediction_warning("displacement_mm", "mm", measured, 0.5 * measured) is None
    dead = flat_prediction_warning("force_N", "N", np.zeros_like(t), measured)
    assert dead is not None and "constant" in dead.message


def test_zero_offset_needs_both_standard_errors_and_noise_sds():
    # noise sd 1 over 100 rows: SE 0.1. A zero of 0.5 is 5 SE but half a noise sd: no warning
    assert (
        zero_offset_warning("r", "force_N", "N", ZeroEstimate(0.5, 0.1, (0.3, 0.7), 100, "rest rows")) is None
    )
    w = zero_offset_warning("r", "force_N", "N", ZeroEstimate(-3.5, 0.1, (-3.7, -3.3), 100, "rest rows"))
    assert w is not None and w.values["noise_sd"] == pytest.approx(1.0)
    assert "-3.5 N" in w.message


def test_a_threshold_that_applies_to_nothing_warns():
    from tcamlab.metrics import unused_threshold_warnings

    metrics = {"displacement_mm": {"rmse": 0.2, "r2": 0.9}}
    checks = check_thresholds(metrics, {"rmse_N": 0.1, "r2_min": 0.5})
    ws = unused_threshold_warnings({"rmse_N": 0.1, "r2_min": 0.5}, checks, list(metrics))
    assert [w.values["key"] for w in ws] == ["rmse_N"]


def test_reference_and_domain_warnings():
    rest = 45.0 + 0.003 * np.random.default_rng(1).standard_normal(50)
    w = reference_warning("run1", "R0", 30.0, "preset: assumed", rest)
    assert w is not None and w.values["relative"] == pytest.approx(-1 / 3, rel=1e-3)
    assert reference_warning("run1", "R0", 45.001, "experiment file", rest) is None
    assert domain_warning("run1", "displacement_mm", 0, 10) is None
    assert "3 of 10 rows" in domain_warning("run1", "displacement_mm", 3, 10).message


@pytest.fixture(scope="module")
def sensor45(tmp_path_factory):
    """A case found by users: the bundled sensing data with every resistance x1.5 (a 45 ohm
    sensor) and no initial_resistance_ohm, so the thesis-tcs preset's 30 ohm is taken."""
    root = tmp_path_factory.mktemp("sensor45")
    (root / "experiments").mkdir()
    (root / "raw").mkdir()
    for i in (1, 2, 3):
        df = pd.read_csv(ROOT / "raw" / f"sensing_run{i}.csv", comment="#")
        df["resistance_ohm"] *= 1.5
        df.to_csv(root / "raw" / f"sensing_run{i}.csv", index=False)
    text = without_thresholds((ROOT / "experiments" / "sensing.toml").read_text())
    assert "initial_resistance_ohm = 30.0" in text
    (root / "experiments" / "s45.toml").write_text(text.replace("initial_resistance_ohm = 30.0\n", ""))
    return root / "experiments" / "s45.toml"


@pytest.mark.slow
def test_preset_r0_far_from_the_rest_value_warns_and_is_credited_to_the_preset(sensor45, tmp_path):
    out = runner.invoke(app, ["validate", "sensing", str(sensor45), "--out", str(tmp_path)])
    assert out.exit_code == 0, out.output
    assert "WARNING: sensing_run1: R0 = 30 ohm (preset" in out.output
    doc = json.loads((tmp_path / "s45" / "metrics.json").read_text())
    checks = {w["check"] for w in doc["warnings"]}
    assert {"reference-far-from-rest", "r2-below-zero", "zero-offset"} <= checks
    r0 = next(w for w in doc["warnings"] if w["check"] == "reference-far-from-rest")
    assert r0["values"]["used_ohm"] == 30.0 and r0["values"]["rest_ohm"] == pytest.approx(45.0, rel=1e-3)
    src = doc["extras"]["spring_constant"]["sensing_run1"]["initial_resistance_source"]
    assert src.startswith("preset") and "experiment file" not in src
    html = (tmp_path / "s45" / "report.html").read_text()
    first = html.split('id="sec-2"')[0]
    assert "R0 = 30 ohm" in first and "R² below 0" in first
    assert first.count('class="warning"') == len(doc["warnings"]) and "Status: no limits set; " in first
    # the parameter table names the preset, not the file
    p = _parse(html)
    i = p.cells.index("initial_resistance")
    assert any(c.startswith("preset thesis-tcs") for c in p.cells[i : i + 4])
    strict = runner.invoke(
        app, ["validate", "sensing", str(sensor45), "--out", str(tmp_path / "s"), "--strict"]
    )
    assert strict.exit_code == 1


def test_bundled_experiments_raise_no_warning(static_result):
    assert static_result.warnings == []


# -- numbers -------------------------------------------------------------------------------


def test_number_policy():
    assert fmt_r2(0.99998) == "0.99998" and fmt_r2(0.99891) == "0.9989"
    assert fmt_r2(-81.20651) == "-81.2065"
    assert fmt_percent(-0.001) == "0%" and fmt_percent(0.125) == "12%"
    assert fmt(-0.0) == "0" and fmt(0.00609) == "0.00609" and fmt(8.614e-05) == "8.614e-05"
    assert with_unit(0.01234, "mm") == "0.01234 mm"


def test_a_table_column_uses_one_notation():
    table = Table(["run", "zero"], [["a", 1e-4], ["b", 9.4e-4], ["c", 0.00108], ["d", None]])
    assert [r[1].text for r in table.formatted_rows()] == ["0.0001", "0.00094", "0.00108", "\u2013"]
    wide = Table(["x"], [[2.5e-7], [0.5]])
    assert [r[0].text for r in wide.formatted_rows()] == ["2.5e-07", "5e-01"]


def test_validate_text_output_has_units_on_every_rmse(tmp_path):
    exp = ROOT / "experiments" / "static.toml"
    out = runner.invoke(app, ["validate", "static", str(exp), "--out", str(tmp_path), "--format", "html"])
    rmse = re.findall(r"RMSE (\S+) (\S+),", out.output)
    assert rmse and all(unit == "mm" for _, unit in rmse)


# -- PDF layout ------------------------------------------------------------------------------


def test_pdf_tables_never_cut_a_word_mid_token():
    words = ["youngs-modulus-temperature", "shear_modulus_slope", "passed", "Name", "no limits set"]
    rows = [
        [w, "x" * 3, 1.5, w.upper(), Cell("passed", "pass"), "a", "b", "c", "d", "e", "f", "g"] for w in words
    ]
    table = Table([f"column {i}" for i in range(12)], rows, caption="many columns")
    pdf = render_pdf(Document("t", sections=[Section("s", tables=[table])]))
    text = _pdf_text(pdf)
    for w in ("shear_modulus_slope", "passed", "Name", "SHEAR_MODULUS_SLOPE"):
        assert w in text, w
    # a hyphenated name may break only after a hyphen: joined there, every one is whole
    joined = text.replace("-\n", "-")
    assert joined.count("youngs-modulus-temperature") == 1
    assert joined.count("YOUNGS-MODULUS-TEMPERATURE") == 1


def _page_images(page) -> int:
    xobjects = (page.get("/Resources") or {}).get("/XObject")
    return 0 if not xobjects else len(xobjects.get_object())


def test_pdf_heading_never_left_alone_at_a_page_bottom():
    """Filler pushes a heading followed by a figure to every position near the page bottom:
    the heading's page must always hold the figure too."""
    from tcamlab.report import Figure
    from tcamlab.report.figures import new_figure

    fig, ax = new_figure(6.4, 3.2)
    ax.plot([0, 1], [0, 1])
    for n in range(30, 62, 3):
        filler = Section("Filler", paragraphs=[f"line {i}" for i in range(n)])
        target = Section("Target heading", figures=[Figure(fig, "the figure")])
        reader = pypdf.PdfReader(io.BytesIO(render_pdf(Document("t", sections=[filler, target]))))
        page = next(p for p in reader.pages if "Target heading" in p.extract_text())
        assert _page_images(page) == 1, n


def test_pdf_a_long_token_gets_a_column_wide_enough():
    """A SHA-256 (64 characters, one token) is never cut nor drawn past its column."""
    sha = "8a7b587918ddba2cf3a7763c916fda97de6fdb5507cb5e5a440e1bd3f44e2dd7"
    doc = Document("t", sections=[], metadata={"tool": "tcamlab", "sha256 curvature.toml": sha})
    assert sha in _pdf_text(render_pdf(doc)).replace("\n", " ").split(" ")


def test_metrics_json_and_report_record_relative_paths_version_and_hashes(tmp_path):
    lab = tmp_path / "lab"
    shutil.copytree(ROOT / "experiments", lab / "experiments", ignore=shutil.ignore_patterns("templates"))
    shutil.copytree(ROOT / "raw", lab / "raw")
    out = runner.invoke(
        app, ["validate", "static", str(lab / "experiments/static.toml"), "--out", str(tmp_path / "r")]
    )
    assert out.exit_code == 0, out.output
    folder = tmp_path / "r" / "static"
    text = (folder / "metrics.json").read_text()
    doc = json.loads(text)
    assert str(tmp_path) not in text and doc["tool"].startswith("tcamlab ")
    assert doc["inputs"][0]["path"] == "../raw/static_run1.csv" and len(doc["inputs"][0]["sha256"]) == 64
    assert len(doc["experiment_file"]["sha256"]) == 64
    for name in ("report.html", "metrics.json", "predictions.csv"):
        assert str(tmp_path) not in (folder / name).read_text()
    assert str(tmp_path) not in _pdf_text((folder / "report.pdf").read_bytes())


def test_residuals_one_panel_per_quantity_against_the_physical_input():
    from tcamlab.report.validation_report import validation_document

    res = validate(load_experiment(ROOT / "experiments" / "sensing.toml"), mc_draws=0)
    figs = [f for s in validation_document(res).sections for f in s.figures]
    axes = figs[-1].figure.axes
    assert [a.get_ylabel() for a in axes] == ["displacement residual [mm]", "force residual [N]"]
    assert axes[-1].get_xlabel() == "time [s]"


@pytest.mark.slow
def test_report_index_is_headline_only_and_strict_exits_1_on_warnings(sensor45, tmp_path, unlimited):
    """Two kinds with different quantities still give 7 columns (no per-quantity columns full
    of dashes); the synthetic banner is on the index and the combined PDF's first page."""
    exps = [str(unlimited / "static.toml"), str(sensor45)]
    out = runner.invoke(app, ["report", *exps, "--out", str(tmp_path / "r"), "--mc-draws", "0"])
    assert out.exit_code == 0, out.output
    assert "no limits set static" in out.output and "  WARNING: sensing_run1: R0 = 30 ohm" in out.output
    html = (tmp_path / "r" / "index.html").read_text()
    p = _parse(html)
    header = p.cells[:7]
    assert header == ["Experiment", "Kind", "Status", "Warnings", "Quantity", "RMSE", "R²"]
    assert len(re.findall(r"<th[ >]", html)) == 7 + 2  # the index table, then the provenance table
    assert "SYNTHETIC DATA: 2 of 2 experiments" in "".join(p.text)
    assert "0.005913 mm" in p.cells and "no limits set" in p.cells
    # the sensing force RMSE in mN, as the diagnosis prints it (not 0.002 N)
    rmse = [c for c in p.cells if "mN" in c]
    assert len(rmse) == 1 and not re.search(r"\d N\b", rmse[0])
    assert "SYNTHETIC DATA" in _pdf_text((tmp_path / "r" / "reports.pdf").read_bytes(), [0])
    strict = runner.invoke(
        app, ["report", *exps, "--out", str(tmp_path / "s"), "--mc-draws", "0", "--strict"]
    )
    assert strict.exit_code == 1


# -- a calibrated or identified parameter far outside its stated uncertainty ------------------


def _beside(tmp_path, name: str, *, c_th: float) -> Path:
    """``dynamic.toml`` (bundled, synthetic) and ``dynamic.calibrated.toml`` with C_th = c_th."""
    # without the bundled limits: a warning alone leaves the status "no limits set", exit 0
    text = without_thresholds((ROOT / "experiments" / "dynamic.toml").read_text())
    text = text.replace('"../raw/', f'"{ROOT}/raw/')
    (tmp_path / "dynamic.toml").write_text(text)
    assert "thermal_mass_J_per_K = 0.0266\n" in text
    cal = text.replace("thermal_mass_J_per_K = 0.0266\n", f"thermal_mass_J_per_K = {c_th}\n", 1)
    cal += (
        '\n[calibration]\nparameters = ["rig.thermal_mass_J_per_K"]\ncoordinates = ["log"]\n'
        "sd = [0.01]\ncorrelation = [[1.0]]\n"
    )
    path = tmp_path / name
    path.write_text(cal)
    return path


@pytest.mark.slow
def test_calibrated_parameter_far_from_stated_warns_and_strict_exits_1(tmp_path):
    # stated 0.0266 +- 0.00845 J/K in dynamic.toml; calibrated 0.0604 = +4.0 stated sds
    path = _beside(tmp_path, "dynamic.calibrated.toml", c_th=0.0604)
    out = runner.invoke(app, ["validate", str(path), "--out", str(tmp_path / "o")])
    assert out.exit_code == 0, out.output
    line = next(ln for ln in out.output.splitlines() if "stated sds" in ln)
    assert line.startswith("WARNING: rig.thermal_mass_J_per_K = 0.0604 J/K")
    assert "+4.0 stated sds from the stated 0.0266 J/K (sd 0.00845 J/K" in line
    doc = json.loads((tmp_path / "o" / "dynamic.calibrated" / "metrics.json").read_text())
    w = next(w for w in doc["warnings"] if w["check"] == "parameter-far-from-stated")
    assert w["values"]["shift_in_stated_sds"] == pytest.approx(4.0, abs=0.01)
    html = (tmp_path / "o" / "dynamic.calibrated" / "report.html").read_text()
    assert "+4.0 stated sds" in html.split('id="sec-2"')[0]  # in the first section
    strict = runner.invoke(app, ["validate", str(path), "--out", str(tmp_path / "s"), "--strict"])
    assert strict.exit_code == 1


def test_calibrated_parameter_within_three_stated_sds_does_not_warn(tmp_path):
    path = _beside(tmp_path, "dynamic.calibrated.toml", c_th=0.0266 + 2.9 * 0.00845)
    result = validate(load_experiment(path), mc_draws=0)
    assert not [w for w in result.warnings if w.check == "parameter-far-from-stated"]


def test_identified_spring_constant_far_from_the_stated_one_warns(tmp_path):
    # the bundled sensing data were made with S = 4.7 N/m; the file states 3.0 +- 0.1 N/m
    text = (ROOT / "experiments" / "sensing.toml").read_text().replace('"../raw/', f'"{ROOT}/raw/')
    text = text.replace("[rig]\n", "[rig]\nspring_constant_N_per_m = 3.0\n", 1)
    text += "\n[rig.uncertainty]\nspring_constant_N_per_m = 0.1\n"
    path = tmp_path / "s3.toml"
    path.write_text(text)
    result = validate(load_experiment(path), mc_draws=0)
    w = next(w for w in result.warnings if w.check == "parameter-far-from-stated")
    assert w.values["value"] == pytest.approx(4.69, abs=0.03)
    assert w.values["shift_in_stated_sds"] == pytest.approx((w.values["value"] - 3.0) / 0.1)
    assert "identified from the logs" in w.message


def test_calibration_report_warns_on_a_parameter_beyond_three_stated_sds():
    from types import SimpleNamespace

    from tcamlab.report.calibration_report import stated_shift_warnings

    def p(value, sd):
        return SimpleNamespace(
            field="thermal_mass",
            where="rig",
            key="thermal_mass_J_per_K",
            symbol="C_th",
            unit="J/K",
            value=value,
            stated=0.0266,
            stated_sd=sd,
        )

    res = SimpleNamespace(parameters=[p(0.0604, 0.00845), p(0.03, 0.00845), p(0.09, None)])
    warnings = stated_shift_warnings(res)
    assert len(warnings) == 1  # within 3 sds, and without a stated sd: no warning
    assert "rig.thermal_mass_J_per_K (C_th) = 0.0604 J/K" in warnings[0] and "+4.0 stated sds" in warnings[0]


def test_synthetic_banner_says_what_its_command_leaves_out_and_where_the_rest_is():
    from types import SimpleNamespace

    from tcamlab.report.validation_report import synthetic_banner

    exp = SimpleNamespace(
        synthetic={"generator": "tcamlab simulate 0.1.0", "seed": 3, "command": "tcamlab simulate static"}
    )
    text = synthetic_banner(exp)
    assert text.startswith("SYNTHETIC DATA: made by tcamlab simulate 0.1.0 with seed 3")
    assert "leaves out any withheld options (--effect, --parameter-error, --noisy-zero)" in text
    assert "truth/NAME.truth.json" in text
    assert synthetic_banner(SimpleNamespace(synthetic=None)) is None


def test_percent_interval_keeps_distinct_ends_distinct():
    from tcamlab.numbers import fmt_percent_range

    # a null diagnosis's shrinkage interval (-0.15 % to -0.01 %) must not read "0% to 0%"
    assert fmt_percent_range(-0.0015, -0.0001) == "-0.1% to 0.0%"
    assert fmt_percent_range(0.48, 0.60) == "48% to 60%"
    assert fmt_percent_range(0.1234, 0.1236) == "12.3% to 12.4%"
    assert fmt_percent_range(0.12341, 0.12349) == "12.34% to 12.35%"
    assert fmt_percent_range(None, 0.1) == "\u2013 to 10%"
    from tcamlab.numbers import percent_decimals

    # the estimate takes its interval's decimals: 0.26 % beside 0.2 % to 0.3 %, not 0 %
    assert percent_decimals(0.002, 0.003) == 1 and percent_decimals(0.48, 0.60) == 0


def test_a_bias_that_is_rounding_of_a_whole_run_zero_shows_as_zero():
    from tcamlab.report.validation_report import _shown

    assert _shown({"rmse": 0.0114, "bias": -1.823e-17}, "bias") == 0.0
    # a real bias stays, however small against the RMSE threshold of 1e-9
    assert _shown({"rmse": 0.0114, "bias": -2.0e-6}, "bias") == -2.0e-6
    assert _shown({"rmse": 0.0114, "bias": 1e-20}, "rmse") == 0.0114


def test_a_small_shift_is_not_printed_as_zero():
    from tcamlab.numbers import shift_text

    assert shift_text({"shift_in_stated_sds": 1.44, "shift_in_prior_sds": 0.3}) == "+1.4 stated sds"
    assert shift_text({"shift_in_stated_sds": None, "shift_in_prior_sds": 0.034}) == "+0.03 prior sds"
    assert shift_text({"shift_in_stated_sds": None, "shift_in_prior_sds": -0.0004}) == "-0.0004 prior sds"
    assert shift_text({"shift_in_stated_sds": 0.0, "shift_in_prior_sds": 0.0}) == "+0.0 stated sds"


def test_a_parameter_read_at_rest_says_what_the_reading_was():
    from tcamlab.numbers import reading_text

    assert reading_text({"reading": [10.1, 0.0013]}, 1.0, "ohm") == "; read at rest 10.1 ohm (sd 0.0013)"
    assert reading_text({"reading": None}) == "" and reading_text({}) == ""


def test_an_interval_never_prints_its_two_ends_alike():
    from tcamlab.numbers import fmt_interval

    assert fmt_interval(10.1, 10.098, 10.102) == ("10.1", "10.098", "10.102")
    assert fmt_interval(0.03933, 0.03925, 0.03942) == ("0.03933", "0.03925", "0.03942")
    assert fmt_interval(9e-3, 9e-3, 9e-3) == ("0.009", "0.009", "0.009")  # equal ends stay equal
