"""The calibration report: calibration.html / .pdf and figures beside calibration.json.

Data: the bundled synthetic dynamic experiment (tcamlab simulate, seed 1), copied to a
temporary folder because calibrate writes NAME.calibrated.toml beside the file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pytest
from typer.testing import CliRunner

import tcamlab.calibration
from tcamlab.calibration.fit import PROFILE_TOL, Z95
from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.errors import TcamlabError
from tcamlab.pipeline import CALIBRATION_FILES, calibrate_experiment
from tcamlab.report.calibration_report import calibration_document

ROOT = Path(__file__).resolve().parent.parent
pypdf = pytest.importorskip("pypdf")


def _copy_lab(dest: Path) -> Path:
    shutil.copytree(ROOT / "experiments", dest / "experiments")
    shutil.copytree(ROOT / "raw", dest / "raw")
    return dest / "experiments" / "dynamic.toml"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    base = tmp_path_factory.mktemp("calreport")
    path = _copy_lab(base)
    outcome = calibrate_experiment([path], out_dir=base / "rep")
    return base, path, outcome


@pytest.fixture
def fake_calibrate(written, monkeypatch):
    """Skip the fit in tests of the writing: calibrate returns the module's result."""
    result = written[2].result

    def fake(exps, params=None, *, drop_na=False):
        # the inputs name the experiment given, as a real calibration's do (its output
        # folder belongs to that file: pipeline.output_folder)
        inputs = [{**i, "path": str(exps[0].path)} if i["role"] == "experiment" else i for i in result.inputs]
        return dataclasses.replace(result, inputs=inputs)

    monkeypatch.setattr(tcamlab.calibration, "calibrate", fake)
    return result


class _Page(HTMLParser):
    """Tables as lists of rows of cell texts, figures as (caption, has svg)."""

    def __init__(self):
        super().__init__()
        self.tables, self.figures = [], []
        self._cell = self._caption = None
        self._svg = False

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = ""
        elif tag == "figure":
            self._svg, self._caption = False, None
        elif tag == "svg":
            self._svg = True
        elif tag == "figcaption":
            self._caption = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append(self._cell.strip())
            self._cell = None
        elif tag == "figcaption":
            self.figures.append((" ".join(self._caption.split()), self._svg))
            self._caption = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        if self._caption is not None:
            self._caption += data


def _number(text: str) -> float:
    return float(text.replace("\u2212", "-"))


def _page(written) -> _Page:
    base, _, _ = written
    page = _Page()
    page.feed((base / "rep" / "dynamic" / "calibration.html").read_text())
    return page


def test_files_written_beside_the_json(written):
    base, _, outcome = written
    folder = base / "rep" / "dynamic"
    names = {f.name for f in outcome.files if f.parent == folder}
    assert set(CALIBRATION_FILES) <= names
    assert (folder / "calibration.pdf").read_bytes().startswith(b"%PDF-")
    pngs = sorted(folder.glob("calibration-fig*.png"))
    svgs = sorted(folder.glob("calibration-fig*.svg"))
    assert len(pngs) == len(svgs) == 4  # overlay, residuals, profiles, correlation
    assert all(p.read_bytes().startswith(b"\x89PNG\r\n\x1a\n") for p in pngs)
    assert all(b"<svg" in s.read_bytes()[:400] for s in svgs)
    html = (folder / "calibration.html").read_bytes()
    assert all(s.read_bytes() in html for s in svgs)  # the figures the report shows
    assert not list(folder.glob(".*.tmp"))


def test_html_parameter_table_has_the_calibrated_values(written):
    _, _, outcome = written
    page = _page(written)
    table = next(t for t in page.tables if t and t[0][:2] == ["symbol", "parameter"])
    head, rows = table[0], {r[0]: r for r in table[1:]}
    # the dynamic kind also calibrates the sample's rho and G_t slope (displacement alone ties
    # C_th to them); their rows print in scaled lab units, so the numbers are checked on the
    # three rig parameters, whose lab units are SI
    assert set(rows) == {"C_th", "lambda", "b", "rho", "G_t slope"}
    for p in outcome.result.parameters:
        row = dict(zip(head, rows[p.symbol]))
        assert row["identified"] == p.identification
        if p.stated_sd is None:
            continue
        # printed in lab units (J/K, W/K, N s/m are their own lab units) to within a tenth
        # of the posterior sd, and the profile interval around it
        assert abs(_number(row["calibrated"]) - p.value) < 0.1 * p.posterior_sd
        lo, hi = (_number(x) for x in row["profile 95 %"].split(" to "))
        assert lo == pytest.approx(p.profile_95[0], abs=0.1 * p.posterior_sd)
        assert hi == pytest.approx(p.profile_95[1], abs=0.1 * p.posterior_sd)
        assert _number(row["stated"]) == pytest.approx(p.stated)
        assert _number(row["stated sd"]) == pytest.approx(p.stated_sd)
        shift = _number(row["shift [stated sds]"])
        assert shift == pytest.approx(p.shift_in_stated_sds, abs=0.006)


def test_html_has_profile_correlation_overlay_and_residual_figures(written):
    page = _page(written)
    captions = [c for c, svg in page.figures if svg]
    assert len(captions) == len(page.figures) == 4
    assert any("profile likelihood" in c for c in captions)
    assert any("Posterior correlation" in c for c in captions)
    assert any("measured displacement" in c and "every run" in c for c in captions)
    assert any("residuals" in c and "against time" in c for c in captions)


def test_html_provenance_has_relative_paths_and_hashes(written):
    base, path, _ = written
    html = (base / "rep" / "dynamic" / "calibration.html").read_text()
    assert str(base) not in html  # no absolute path
    for run in load_experiment(path).runs:
        digest = hashlib.sha256(run.read_bytes()).hexdigest()
        assert f"run ../raw/{run.name}: {digest}" in html
    assert "Command: tcamlab calibrate" in html
    assert "Tool: tcamlab " in html


def _pdf_text(path: Path) -> str:
    reader = pypdf.PdfReader(str(path))
    return "\n".join(page.extract_text() for page in reader.pages)


def _document_words(doc) -> set[str]:
    """Every word of the document's tables and paragraphs (what the PDF must keep whole)."""
    words = set()
    for section in doc.sections:
        texts = list(section.paragraphs) + [c for t in section.tables for c in t.columns]
        texts += [c.text for t in section.tables for row in t.formatted_rows() for c in row]
        for text in texts:
            words.update(w for w in re.split(r"[\s(),;:]+", text) if len(w) >= 3)
    return words


def test_pdf_keeps_every_word_whole_and_names_the_symbols(written):
    base, path, outcome = written
    text = _pdf_text(base / "rep" / "dynamic" / "calibration.pdf")
    tokens = set(re.split(r"[\s(),;:]+", text))
    for symbol in ("C_th", "lambda", "b"):
        assert symbol in tokens
    doc = calibration_document(outcome.result, [load_experiment(path)])
    words = _document_words(doc)
    assert any(len(w) == 64 for w in words)  # the SHA-256s are among them
    broken = sorted(w for w in words if w not in tokens)
    assert not broken, broken[:10]


def test_result_carries_signed_profile_points_and_curves(written):
    _, path, outcome = written
    res = outcome.result
    for p in res.parameters:
        values = [v for v, _ in p.profile_points]
        zs = [z for _, z in p.profile_points]
        assert values == sorted(values)
        assert (p.value, 0.0) in p.profile_points
        # signed root: negative below the MAP, positive above, reaching 1.96 at the bounds
        assert all((z < 0) == (v < p.value) for v, z in p.profile_points if z != 0)
        assert min(zs) < -Z95 + 0.05 and max(zs) > Z95 - 0.05
        # the interval's bounds are points of the profile where |z| = 1.96
        for bound in p.profile_95:
            (z,) = [z for v, z in p.profile_points if v == pytest.approx(bound, rel=1e-12)]
            # the search stops within PROFILE_TOL of the target (its documented precision)
            assert abs(z) == pytest.approx(Z95, abs=PROFILE_TOL)
    exp = load_experiment(path)
    assert [c.run for c in res.curves] == [r.name for r in exp.runs]
    for c, z in zip(res.curves, res.zeros):
        assert c.x == "time" and c.zero["displacement"] == pytest.approx(z.value)
        resid = c.measured["displacement"] - c.calibrated["displacement"]
        assert abs(resid.mean()) < 1e-12  # the fitted zero is in the calibrated curve
    doc = res.to_dict()
    assert "curves" not in doc
    assert len(doc["parameters"][0]["profile_points"]) >= 3
    run_hashes = [i["sha256"] for i in doc["inputs"] if i["role"] == "run"]
    assert run_hashes == [hashlib.sha256(r.read_bytes()).hexdigest() for r in exp.runs]


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()} if folder.exists() else {}


def test_no_output_overwritten_without_force(tmp_path, fake_calibrate):
    path = _copy_lab(tmp_path)
    runner = CliRunner()
    args = ["calibrate", str(path), "--out", str(tmp_path / "rep")]
    assert runner.invoke(app, args).exit_code == 0
    folder = tmp_path / "rep" / "dynamic"
    before = _snapshot(folder)
    calibrated = path.with_name("dynamic.calibrated.toml")
    calibrated.unlink()  # only the report files are left: still refused
    (folder / "calibration.html").write_text("edited by hand")
    r = runner.invoke(app, args)
    assert r.exit_code == 2 and "--force" in r.output and "Traceback" not in r.output
    assert (folder / "calibration.html").read_text() == "edited by hand"
    assert not calibrated.exists()
    r = runner.invoke(app, args + ["--force"])
    assert r.exit_code == 0, r.output
    assert _snapshot(folder) == before and calibrated.exists()


def test_a_failed_report_writes_nothing(tmp_path, fake_calibrate, monkeypatch):
    import tcamlab.report.pdf

    path = _copy_lab(tmp_path)

    def fail(doc):
        raise RuntimeError("renderer failed")

    monkeypatch.setattr(tcamlab.report.pdf, "render_pdf", fail)
    with pytest.raises(RuntimeError):
        calibrate_experiment([path], out_dir=tmp_path / "rep")
    assert not path.with_name("dynamic.calibrated.toml").exists()
    assert not (tmp_path / "rep").exists()


def test_a_failed_write_leaves_nothing(tmp_path, fake_calibrate, monkeypatch):
    import os
    import stat

    path = _copy_lab(tmp_path)
    calls = []
    real = os.fsync

    def full_disk(fd):
        if stat.S_ISREG(os.fstat(fd).st_mode):  # files, not the folder's fsync
            calls.append(fd)
        if len(calls) == 4:  # the toml, calibration.json, calibration.html, then the PDF
            raise OSError(28, "No space left on device")
        return real(fd)

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(TcamlabError, match="No space left"):
        calibrate_experiment([path], out_dir=tmp_path / "rep")
    assert not path.with_name("dynamic.calibrated.toml").exists()
    assert _snapshot(tmp_path / "rep" / "dynamic") == {}


def test_decimals_show_two_digits_of_the_sd(written):
    _, _, outcome = written
    page = _page(written)
    table = next(t for t in page.tables if t and t[0][:2] == ["symbol", "parameter"])
    checked = 0
    for row, p in zip(table[1:], outcome.result.parameters):
        if row[table[0].index("unit")] != p.unit:
            continue  # printed in scaled lab units (x10^-5 1/K, MPa/K)
        checked += 1
        text = row[table[0].index("calibrated")]
        decimals = len(text.split(".")[1]) if "." in text else 0
        assert decimals == max(0, 1 - math.floor(math.log10(p.posterior_sd)))
    assert checked == 3


def test_a_profile_bound_the_search_did_not_reach_is_flagged(written):
    from dataclasses import replace

    from tcamlab.report.calibration_report import parameter_rows, unsure_bounds

    _, path, outcome = written
    res = outcome.result
    p = res.parameters[0]
    assert unsure_bounds(p) == (False, False)
    # the search stopped at the upper bound with z = 0.5 (as on a strongly correlated static fit)
    hi = p.profile_95[1]
    pts = tuple((v, 0.5 if v == hi else z) for v, z in p.profile_points)
    bad = replace(res, parameters=[replace(p, profile_points=pts), *res.parameters[1:]])
    assert unsure_bounds(bad.parameters[0]) == (False, True)
    row = parameter_rows(bad)[0]
    assert row[8].endswith(" ?") and not row[8].split(" to ")[0].endswith("?")
    doc = calibration_document(bad, [load_experiment(path)])
    notes = [n for s in doc.sections for n in s.notes]
    assert any("upper profile bound of C_th is not a 95 % bound" in n and "+0.50" in n for n in notes)


def test_long_logs_are_drawn_as_envelopes_that_keep_every_outlier():
    import numpy as np

    from tcamlab.report.calibration_figures import MAX_ROWS, envelope

    # synthetic: numpy default_rng(3), 300 001 rows of unit noise with two spikes
    rng = np.random.default_rng(3)
    x = np.arange(300_001, dtype=float)
    y = rng.normal(size=x.size)
    y[1234], y[-1] = 40.0, -40.0
    px, py = envelope(x, y)
    assert px.size <= MAX_ROWS + 2
    assert 40.0 in py and -40.0 in py
    assert px[list(py).index(40.0)] == 1234.0
    assert np.all(np.diff(px) > 0)
    short = np.arange(10.0)
    assert envelope(short, short)[1] is short
