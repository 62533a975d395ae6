"""Regressions found on real files: each test failed on the code before its fix."""

from __future__ import annotations

import json
import shlex
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from tcamlab.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _recorded_commands() -> list[str]:
    """Every tcamlab command recorded in the bundled data (experiment and truth files)."""
    found = set()
    for path in sorted((ROOT / "experiments").glob("*.toml")):
        synthetic = tomllib.loads(path.read_text()).get("synthetic") or {}
        if synthetic.get("command"):
            found.add(synthetic["command"])
    for path in sorted((ROOT / "truth").glob("*.json")):
        found.add(json.loads(path.read_text())["command"])
    return sorted(found)


@pytest.mark.slow
@pytest.mark.parametrize("command", _recorded_commands())
def test_recorded_command_runs_and_remakes_the_shipped_files(tmp_path, monkeypatch, command):
    """The command in each SYNTHETIC banner runs as written and makes the shipped bytes."""
    words = shlex.split(command)
    assert words[0] == "tcamlab"
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, words[1:])
    assert res.exit_code == 0, res.output
    made = sorted(p for p in tmp_path.rglob("*") if p.is_file())
    assert made
    for path in made:
        rel = path.relative_to(tmp_path)
        assert path.read_bytes() == (ROOT / rel).read_bytes(), rel


# --- fit-spring: a negative S is refused, a preload is named as one ----------------------


def _segment(path: Path, header: str, xs, fs) -> Path:
    path.write_text(header + "\n" + "".join(f"{x:.5f},{f:.4f}\n" for x, f in zip(xs, fs)))
    return path


def _release(tmp_path: Path, sign: float = 1.0) -> Path:
    """A rheometer release segment: 17 N at the start, falling to 0 over 0.13 mm."""
    import numpy as np

    x = np.linspace(0.0, 0.13, 40)
    f = 17.0 - 129470.0 * x * 1e-3 + np.random.default_rng(0).normal(0.0, 0.05, x.size)
    return _segment(tmp_path / "release.csv", "Gap (mm),Normal force (N)", sign * x, sign * f)


def test_fit_spring_refuses_a_negative_spring_constant(tmp_path):
    path = _release(tmp_path, sign=-1.0)  # the force column's sign as exported
    res = runner.invoke(
        app,
        [
            "fit-spring",
            str(path),
            "--column",
            "displacement_mm=Gap (mm)",
            "--column",
            "force_N=Normal force (N)",
        ],
    )
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.output
    assert "release.csv" in lines[0] and "negative" in lines[0]
    assert 'force_N = { from = "Normal force (N)", scale = -1 }' in lines[0]
    assert "release" in lines[0] and "starts under load" in lines[0]


def test_fit_spring_names_a_preload_not_a_tare_error(tmp_path):
    import numpy as np

    x = np.linspace(0.0, 0.13, 40)
    f = 17.0 + 129470.0 * x * 1e-3 + np.random.default_rng(1).normal(0.0, 0.05, x.size)
    path = _segment(tmp_path / "preloaded.csv", "displacement_mm,force_N", x, f)
    res = runner.invoke(app, ["fit-spring", str(path)])
    assert res.exit_code == 0, res.output
    assert "preloaded starts under load" in res.output and "preload" in res.output
    assert "check the tare" not in res.output


# --- one missing-value option on every command that reads runs ---------------------------

READS_RUNS = [["validate", "static"], "report", "fit-spring", "check", "calibrate", "diagnose"]


@pytest.mark.parametrize("command", READS_RUNS)
def test_every_command_that_reads_runs_takes_drop_na(command):
    words = command if isinstance(command, list) else [command]
    res = runner.invoke(app, [*words, "--help"])
    assert res.exit_code == 0, res.output
    assert "--drop-na" in res.output


def test_check_honours_drop_na_which_its_hint_names(tmp_path):
    lines = (ROOT / "raw" / "static_run1.csv").read_text().splitlines()
    lines[5] = lines[5].rsplit(",", 1)[0] + ","
    (tmp_path / "r1.csv").write_text("\n".join(lines) + "\n")
    text = (ROOT / "experiments" / "static.toml").read_text()
    text = text.replace('"../raw/static_run1.csv"', '"r1.csv"').replace('"../raw/', f'"{ROOT}/raw/')
    (tmp_path / "s.toml").write_text(text)
    res = runner.invoke(app, ["check", str(tmp_path / "s.toml")])
    assert res.exit_code == 2 and "blank or NaN cell" in res.output and "--drop-na" in res.output
    res = runner.invoke(app, ["check", str(tmp_path / "s.toml"), "--drop-na"])
    assert res.exit_code == 0, res.output


# --- did-you-mean stays within a dimension ------------------------------------------------

_RIG = '[sample]\npreset = "thesis-tca"\n[rig]\nload_g = 50\nambient_C = 20\n'


def _check(tmp_path: Path, csv: str, columns: str = "") -> str:
    (tmp_path / "run.csv").write_text(csv)
    (tmp_path / "e.toml").write_text(f'kind = "static"\ntitle = "t"\nruns = ["run.csv"]\n{columns}{_RIG}')
    res = runner.invoke(app, ["check", str(tmp_path / "e.toml")])
    assert res.exit_code == 2 and "Traceback" not in res.output
    return res.output


def test_a_column_of_another_dimension_is_never_proposed(tmp_path):
    rows = "".join(f"{i},{0.1 * i},{25 + i}\n" for i in range(6))
    out = _check(tmp_path, "time_s,displacement_rad,temperature_C\n" + rows)
    assert "'displacement_mm' not found" in out
    assert 'from = "displacement_rad"' not in out and "the file has 'displacement_rad'" not in out
    out = _check(tmp_path, "time_s,Displacement (rad),temperature_C\n" + rows)
    assert 'from = "Displacement (rad)"' not in out
    out = _check(tmp_path, "time_s,displacement_um,temperature_C\n" + rows)  # same dimension: proposed
    # with the unit its header names: read as mm it would be 1000 x off
    assert 'displacement_mm = { from = "displacement_um", unit = "um" }' in out


def test_a_headerless_file_is_never_told_to_reuse_a_mapped_column(tmp_path):
    rows = "".join(f"{i},{0.1 * i}\n" for i in range(6))
    cols = "[columns]\nheader_row = 0\ntime_s = { from = 1 }\ndisplacement_mm = { from = 2 }\n"
    out = _check(tmp_path, rows, cols)
    assert "temperature_C needs a column number" in out and "from = 1" not in out
    rows3 = "".join(f"{i},{0.1 * i},{25 + i}\n" for i in range(6))
    out = _check(tmp_path, rows3, cols)
    assert "temperature_C = { from = 3 }" in out


def test_mm_in_capitals_is_never_answered_with_another_unit(tmp_path):
    rows = "".join(f"{i},{0.1 * i},{25 + i}\n" for i in range(6))
    cols = '[columns]\ndisplacement_mm = { from = "displacement_mm", unit = "MM" }\n'
    out = _check(tmp_path, "time_s,displacement_mm,temperature_C\n" + rows, cols)
    assert "unknown unit 'MM'" in out and "did you mean 'm'" not in out
    assert "case-sensitive" in out and "length units: m, cm, mm" in out


# --- init checks a strain column's sign against the data ---------------------------------


def _strain_log(tmp_path: Path, sign: float, header: str = "Contraction strain (%)") -> Path:
    rows = "".join(f"{25 + 1.25 * i:.2f},{sign * 0.028 * i:.4f}\n" for i in range(100))
    path = tmp_path / "strain.csv"
    path.write_text(f"Temperature (C),{header}\n" + rows)
    return path


@pytest.mark.parametrize(
    ("sign", "scale"), [(-1.0, "scale = coil_length_mm / 100"), (1.0, "scale = -coil_length_mm / 100")]
)
def test_init_checks_a_strain_sign_against_the_data(tmp_path, sign, scale):
    """Signed (negative = shorter) gets +L/100, contraction counted positive -L/100; either way
    init says which convention it assumed."""
    csv = _strain_log(tmp_path, sign)
    res = runner.invoke(app, ["init", "static", "--csv", str(csv), "--out", str(tmp_path / "e.toml")])
    assert res.exit_code == 0, res.output
    text = (tmp_path / "e.toml").read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("displacement_mm"))
    assert scale in line and "as the temperature rises" in line
    assert "sign of displacement_mm" in res.output
    assert "positive when the sample gets longer" in res.output


# --- a straight fiber is outside the models' scope: one message, every key ----------------


def test_a_straight_fiber_gets_one_message_naming_its_scope_and_every_key(tmp_path):
    text = (ROOT / "experiments" / "static.toml").read_text().replace('"../raw/', f'"{ROOT}/raw/')
    text = text.replace("twists = 150.0", "twists = 0").replace(
        "coil_length_mm = 20.0", "coil_length_mm = 95.0"
    )
    text = text.replace("coil_diameter_mm = 0.36", "coil_diameter_mm = 0.17")
    (tmp_path / "straight.toml").write_text(text)
    res = runner.invoke(app, ["check", str(tmp_path / "straight.toml")])
    assert res.exit_code == 2
    problems = [ln for ln in res.output.splitlines() if ln.startswith("problem:")]
    assert len(problems) == 1, res.output
    line = problems[0]
    assert "not a coiled sample" in line and "outside their scope" in line
    for key in ("twists = 0", "coil_length_mm = 95", "fiber_length_mm = 95", "coil_diameter_mm = 0.17"):
        assert key in line
    assert "check the unit in the key name" not in line


# --- the [columns] mapping and every dropped row reach metrics.json and the report ---------


def test_join_drops_and_the_mapping_are_recorded_and_shown(tmp_path):
    from tests.test_io import two_clock_lab

    exp = two_clock_lab(tmp_path, 2.0)  # the laser's first 20 rows precede the logger's
    rig = 'preset = "thesis-tca"\n[rig]\nload_g = 50\nambient_C = 20\n'
    exp.write_text(exp.read_text().replace('preset = "thesis-tca"\n', rig))
    res = runner.invoke(app, ["validate", str(exp), "--out", str(tmp_path / "out"), "--format", "html"])
    assert res.exit_code in (0, 1), res.output
    metrics = json.loads(next((tmp_path / "out").rglob("metrics.json")).read_text())
    (inp,) = metrics["inputs"]
    assert inp["dropped_rows"] == 20
    assert inp["dropped"] == {"outside the joined file's time span": 20}
    mapped = {"from": "Position (mm)", "unit": "mm", "scale": 1.0, "offset": 0.0}
    assert inp["columns"]["displacement_mm"] == mapped
    assert inp["columns"]["temperature_C"]["file"].endswith("tc.csv")
    html = next((tmp_path / "out").rglob("*.html")).read_text()
    assert "20 (20 outside the joined file&#39;s time span)" in html
    assert "Position (mm)" in html and "[columns] mapping" in html


# --- no library warning reaches the console ------------------------------------------------


def test_report_and_spring_plot_raise_no_library_warning(tmp_path, monkeypatch):
    """A guard: every warning turned into an error while the bundled report and a plot are made."""
    import warnings

    monkeypatch.chdir(ROOT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = runner.invoke(app, ["report", "--out", str(tmp_path / "r")])
        assert res.exit_code in (0, 1), res.output
        assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
        plot = tmp_path / "s.png"
        res = runner.invoke(app, ["fit-spring", str(ROOT / "raw" / "sensing_run1.csv"), "--plot", str(plot)])
        assert res.exit_code == 0 and res.exception is None, res.output


def test_a_run_named_in_cjk_draws_without_a_missing_glyph_warning(tmp_path):
    """Run names come from file names; a glyph the report font lacks is drawn as its code point."""
    import warnings

    csv = tmp_path / "試験1.csv"
    csv.write_bytes((ROOT / "raw" / "sensing_run1.csv").read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for suffix in (".png", ".svg", ".pdf"):
            res = runner.invoke(app, ["fit-spring", str(csv), "--plot", str(tmp_path / f"p{suffix}")])
            assert res.exit_code == 0 and res.exception is None, (suffix, res.exception)
    assert (tmp_path / "p.svg").stat().st_size > 0


def test_drawable_keeps_what_the_font_has():
    from tcamlab.report.figures import drawable

    assert drawable("run 1 µm ± °C") == "run 1 µm ± °C"
    assert drawable("試験1") == "U+8A66U+9A131"
