"""Bad input through the CLI: every case is a one-line error naming the file and
row+column or key, what was expected and a hint, exit status 2, no traceback and no
partial report; `tcamlab report` lists the failure and still builds the other experiments.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from tcamlab.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
OUTPUTS = ("report.html", "report.pdf", "metrics.json", "predictions.csv")


def experiment(
    lab: Path,
    kind: str,
    name: str = "bad",
    runs: list[str] | None = None,
    replace: dict[str, str] | None = None,
    append: str = "",
) -> Path:
    """A copy of the shipped experiment of ``kind`` with other runs, values or tables."""
    text = (lab / "experiments" / f"{kind}.toml").read_text()
    if runs is not None:
        listed = ", ".join(f'"../raw/{r}"' for r in runs)
        text = re.sub(r"runs = \[[^\]]*\]", f"runs = [{listed}]", text, flags=re.S)
    for key, value in (replace or {}).items():
        text, n = re.subn(rf"(?m)^{re.escape(key)} = .*$", f"{key} = {value}", text)
        if n == 0:  # not in the file: add it to its table
            table = "[sample]" if key in SAMPLE_KEYS else "[rig]"
            text = text.replace(table + "\n", f"{table}\n{key} = {value}\n", 1)
    path = lab / "experiments" / f"{name}.toml"
    path.write_text(text + append)
    return path


SAMPLE_KEYS = ("fiber_diameter_mm", "coil_length_mm", "max_volume_fraction", "shear_modulus_slope_MPa_per_K")


def shipped(lab: Path, kind: str, run: int = 1) -> str:
    return (lab / "raw" / f"{kind}_run{run}.csv").read_text()


def write_run(lab: Path, data: str | bytes, name: str = "bad.csv") -> str:
    p = lab / "raw" / name
    p.write_bytes(data.encode() if isinstance(data, str) else data)
    return name


def others(kind: str) -> list[str]:
    """The shipped runs (sensing needs >= 2 runs to identify S leave-one-out)."""
    return [f"{kind}_run2.csv", f"{kind}_run3.csv"] if kind == "sensing" else []


def validate(kind, exp, out, *extra):
    return runner.invoke(
        app, ["validate", kind, str(exp), "--out", str(out), "--format", "html", "--mc-draws", "20", *extra]
    )


def assert_bad_input(result, *parts, hint=True):
    """Exit 2, one line on stderr starting 'error:', no traceback, every part present."""
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    text = result.output.strip()
    assert "Traceback" not in text
    assert len(text.splitlines()) == 1, text
    assert text.startswith("error: "), text
    for part in parts:
        assert part in text, f"{part!r} not in {text!r}"
    if hint:
        assert "(hint: " in text, text
    return text


def assert_no_report(out: Path, name: str = "bad"):
    folder = out / name
    assert not folder.exists() or not any(folder.iterdir()), list(folder.iterdir())


# --- CSV: broken files -----------------------------------------------------------------


CSV_CASES = {
    # id: (kind, file content, parts of the message)
    "empty": ("static", "", ["bad.csv", "file is empty"]),
    "blank_lines_only": ("static", "\n\n  \n", ["bad.csv", "file is empty"]),
    "header_only": (
        "static",
        "time_s,temperature_C,displacement_mm\n",
        ["bad.csv", "line 1", "header only, no data rows"],
    ),
    "missing_column": (
        "static",
        "time_s,temperature_c,displacement_mm\n0,25,0\n1,26,-0.1\n2,27,-0.2\n",
        [
            "bad.csv",
            "line 1",
            "required column 'temperature_C'",
            'temperature_C = { from = "temperature_c" }',
            "[columns]",
        ],
    ),
    "non_numeric": (
        "static",
        "time_s,temperature_C,displacement_mm\n0,25,0\n1,26,abc\n2,27,-0.2\n",
        ["bad.csv", "line 3", "column 'displacement_mm'", "non-numeric value 'abc'"],
    ),
    "duplicated_time": (
        "static",
        "time_s,temperature_C,displacement_mm\n0,25,0\n1,26,-0.1\n1,27,-0.2\n",
        ["bad.csv", "line 4", "column 'time_s'", "duplicated time 1 s", "line 3"],
    ),
    "unsorted_time": (
        "dynamic",
        "time_s,voltage_V,displacement_mm\n"
        + "".join(f"{t},0,0\n" for t in (0, 1, 2, 3, 5, 4, 6, 7, 8, 9, 10)),
        ["bad.csv", "line 7", "decreasing time 4 s after 5 s"],
    ),
    "negative_resistance": (
        "sensing",
        "displacement_mm,force_N,resistance_ohm\n0,0,30\n1,0.01,30.5\n2,0.02,-31\n3,0.03,31.5\n",
        ["bad.csv", "line 4", "column 'resistance_ohm'", "negative resistance -31 ohm"],
    ),
    "below_absolute_zero": (
        "static",
        "temperature_C,displacement_mm\n25,0\n-300,-0.1\n27,-0.2\n",
        ["bad.csv", "line 3", "column 'temperature_C'", "below absolute zero"],
    ),
    "too_short": (
        "static",
        "temperature_C,displacement_mm\n25,0\n26,-0.1\n",
        ["bad.csv", "only 2 usable data rows", "needs at least 3", "record a longer run"],
    ),
    "too_short_dynamic": (
        "dynamic",
        "time_s,voltage_V,displacement_mm\n0,0,0\n0.1,10,0\n",
        ["bad.csv", "only 2 usable data rows", "needs at least 10"],
    ),
    "utf16": (
        "static",
        "temperature_C,displacement_mm\n25,0\n".encode("utf-16"),
        ["bad.csv", "UTF-16", "UTF-8"],
    ),
    "binary": ("static", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", ["bad.csv", "not a text CSV file"]),
    "unparsable_quote": ("static", 'temperature_C,displacement_mm\n25,0\n26,"-0.1\n27,-0.2\n', ["bad.csv"]),
}


@pytest.mark.parametrize("case", sorted(CSV_CASES))
def test_broken_csv_is_a_one_line_error_and_no_report(lab, case):
    kind, data, parts = CSV_CASES[case]
    exp = experiment(lab, kind, runs=[write_run(lab, data)] + others(kind))
    out = lab / "out"
    result = validate(kind, exp, out)
    assert_bad_input(result, *parts, hint=case not in ("binary", "unparsable_quote"))
    assert_no_report(out)


@pytest.mark.parametrize(
    "value, shown", [("", "blank or NaN cell"), ("NaN", "blank or NaN cell"), ("  ", "blank or NaN cell")]
)
def test_blank_or_nan_cell_needs_drop_na_and_is_counted(lab, value, shown):
    lines = shipped(lab, "static").splitlines()
    cells = lines[5].split(",")
    cells[2] = value
    lines[5] = ",".join(cells)
    exp = experiment(lab, "static", runs=[write_run(lab, "\n".join(lines) + "\n"), "static_run2.csv"])
    out = lab / "out"
    result = validate("static", exp, out)
    assert_bad_input(result, "bad.csv", "line 6", "column 'displacement_mm'", shown, "--drop-na")
    assert_no_report(out)

    result = validate("static", exp, out, "--drop-na", "--json")
    assert result.exit_code == 0, result.output
    metrics = json.loads((out / "bad" / "metrics.json").read_text())
    bad = next(i for i in metrics["inputs"] if i["file"] == "bad.csv")
    assert bad["dropped_rows"] == 1 and bad["rows"] == len(lines) - 2
    assert any("1 rows with blank cells were dropped" in n for n in metrics["notes"])
    assert "dropped" in (out / "bad" / "report.html").read_text()


@pytest.mark.slow
def test_report_has_drop_na_too(lab, monkeypatch):
    """`tcamlab report --drop-na` passes the option to every experiment."""
    text = shipped(lab, "curvature").splitlines()
    text[3] = ",".join(text[3].split(",")[:-1] + [""])
    (lab / "raw" / "curvature_run1.csv").write_text("\n".join(text) + "\n")
    monkeypatch.chdir(lab)
    result = runner.invoke(app, ["report", "--out", "r1", "--mc-draws", "10"])
    assert result.exit_code == 2
    assert "error curvature" in result.output and "--drop-na" in result.output
    result = runner.invoke(app, ["report", "--out", "r2", "--mc-draws", "10", "--drop-na"])
    assert result.exit_code == 0, result.output
    metrics = json.loads((lab / "r2/curvature/metrics.json").read_text())
    assert metrics["inputs"][0]["dropped_rows"] == 1


def _metrics_of(result) -> dict:
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def _run_rmse(doc: dict, run: str) -> float:
    return doc["models"]["G(T)"]["displacement_mm"]["runs"][run]["rmse"]


@pytest.mark.parametrize(
    "variant", ["semicolon_decimal_comma", "semicolon_point", "bom", "latin1", "crlf_comments"]
)
def test_accepted_dialects_give_the_same_result(lab, variant):
    text = shipped(lab, "static")
    if variant == "semicolon_decimal_comma":
        data = text.replace(",", ";").replace(".", ",").encode()
    elif variant == "semicolon_point":
        data = text.replace(",", ";").encode()
    elif variant == "bom":
        data = b"\xef\xbb\xbf" + text.encode()
    elif variant == "latin1":  # an extra column whose header has a degree sign
        lines = text.splitlines()
        lines = [lines[0] + ",Ofen \u00b0C"] + [line + ",1" for line in lines[1:]]
        data = ("\n".join(lines) + "\n").encode("latin-1")
    else:
        data = ("# rig: oven 2\r\n# operator: x\r\n" + text.replace("\n", "\r\n")).encode()
    exp = experiment(lab, "static", runs=[write_run(lab, data, "variant.csv")])
    ref = experiment(lab, "static", name="ref", runs=["static_run1.csv"])
    got = _metrics_of(validate("static", exp, lab / "o1", "--json"))
    want = _metrics_of(validate("static", ref, lab / "o2", "--json"))
    assert _run_rmse(got, "variant") == pytest.approx(_run_rmse(want, "static_run1"), rel=1e-12)


def test_pull_force_of_the_wrong_sign(lab):
    df = pd.read_csv(lab / "raw/sensing_run1.csv")
    df["force_N"] = -df["force_N"]
    name = write_run(lab, df.to_csv(index=False))
    exp = experiment(lab, "sensing", runs=[name, "sensing_run2.csv"])
    out = lab / "out"
    assert_bad_input(
        validate("sensing", exp, out),
        "bad.csv",
        "column 'force_N'",
        "negative force",
        "should be positive",
        "scale = -1",
    )
    assert_no_report(out)
    result = runner.invoke(app, ["fit-spring", str(lab / "raw" / name)])
    assert_bad_input(result, "bad.csv", "negative force")


def test_wrong_sign_hint_is_valid_toml_that_keeps_the_unit(lab):
    """A load cell logging tension negative in mN: the hint is a TOML line that, pasted, reads it right."""
    import tomllib

    df = pd.read_csv(lab / "raw/sensing_run1.csv")
    df = df.rename(columns={"force_N": "Load (mN)"})
    df["Load (mN)"] = -1e3 * df["Load (mN)"]
    name = write_run(lab, df.to_csv(index=False))
    columns = '\n[columns]\nforce_N = { from = "Load (mN)", unit = "mN" }\n'
    exp = experiment(lab, "sensing", runs=[name], append=columns)
    result = validate("sensing", exp, lab / "out")
    line = 'force_N = { from = "Load (mN)", unit = "mN", scale = -1 }'
    assert_bad_input(result, "negative force", line)
    assert tomllib.loads(line)["force_N"] == {"from": "Load (mN)", "unit": "mN", "scale": -1}
    fixed = experiment(lab, "sensing", name="fixed", runs=[name], append="\n[columns]\n" + line + "\n")
    from tcamlab.config import load_experiment

    (run,) = load_experiment(fixed).read_runs()
    ref = pd.read_csv(lab / "raw/sensing_run1.csv")["force_N"].to_numpy()
    assert run.data["force"].to_numpy() == pytest.approx(ref, abs=1e-12)  # not 1000x too large


def test_a_csv_given_as_the_experiment_file_says_so(lab):
    for args in (["validate", "sensing"], ["diagnose"], ["calibrate"]):
        result = runner.invoke(app, [*args, str(lab / "raw" / "sensing_run1.csv")])
        assert_bad_input(result, "sensing_run1.csv", "is a CSV log, not an experiment file", "tcamlab init")


def test_effects_list_unknown_kind_exits_2():
    assert_bad_input(runner.invoke(app, ["effects", "list", "--kind", "bogus"]), "unknown kind 'bogus'")
    result = runner.invoke(app, ["effects", "list", "--help"])
    assert "static|dynamic|sensing|curvature" in result.output


def test_small_negative_force_at_zero_load_is_data(lab):
    """-0.4 mN of offset or noise at zero load is a measurement, not an error."""
    df = pd.read_csv(lab / "raw/sensing_run1.csv")
    zero = df["displacement_mm"] == 0
    assert zero.sum() > 5
    df.loc[zero, "force_N"] = -0.0004
    name = write_run(lab, df.to_csv(index=False), "offset.csv")
    exp = experiment(lab, "sensing", runs=[name, "sensing_run2.csv", "sensing_run3.csv"])
    result = validate("sensing", exp, lab / "out")
    assert result.exit_code == 0, result.output


# --- TOML ------------------------------------------------------------------------------


def test_toml_syntax_error_names_line_and_column(lab):
    exp = experiment(lab, "static", append="\n[rig.extra\nx = 1\n")
    text = assert_bad_input(validate("static", exp, lab / "out"), "bad.toml", "TOML syntax error")
    assert re.search(r"line \d+, column \d+", text)
    assert_no_report(lab / "out")


def test_toml_with_utf8_bom_is_read(lab):
    """Windows editors save a BOM; tomllib alone calls it an invalid statement at line 1."""
    exp = experiment(lab, "curvature", name="bom")
    exp.write_bytes(b"\xef\xbb\xbf" + exp.read_bytes())
    result = validate("curvature", exp, lab / "out")
    assert result.exit_code == 0, result.output


TOML_CASES = {
    "unknown_key": (
        None,
        lambda t: t.replace("coil_length_mm", "coil_lenght_mm"),
        ["unknown key 'sample.coil_lenght_mm'", "did you mean 'coil_length_mm'", "allowed keys"],
    ),
    "missing_key": (
        None,
        lambda t: re.sub(r"(?m)^title = .*\n", "", t),
        ["missing required key 'title'", 'title = "'],
    ),
    "wrong_type": (
        None,
        lambda t: t.replace("load_g = 50.0", 'load_g = "fifty"'),
        ["rig.load_g: expected a number, got 'fifty'", "without quotes"],
    ),
    "coil_longer_than_fiber": (
        dict(replace={"coil_length_mm": "120"}),
        None,
        ["[sample]", "coil_length", "fiber_length"],
    ),
    "negative_diameter": (
        dict(replace={"fiber_diameter_mm": "-0.17"}),
        None,
        ["[sample]", "fiber_diameter", "positive"],
    ),
    "volume_fraction_above_one": (
        dict(replace={"max_volume_fraction": "1.2"}),
        None,
        ["[sample]", "max_volume_fraction", "exceeds 1"],
    ),
    "run_missing": (
        dict(runs=["static_run1.csv", "nope.csv"]),
        None,
        ["runs[1]", "'../raw/nope.csv' not found", "relative to the experiment file"],
    ),
    "run_is_a_folder": (
        None,
        lambda t: re.sub(r"runs = \[[^\]]*\]", 'runs = ["../raw"]', t),
        ["runs[0]", "is a folder"],
    ),
    "run_with_nul": (
        None,
        lambda t: re.sub(r"runs = \[[^\]]*\]", lambda m: 'runs = ["../raw/a\\u0000.csv"]', t),
        ["runs[0]", "not a file name"],
    ),
}


@pytest.mark.parametrize("case", sorted(TOML_CASES))
def test_bad_experiment_file(lab, case):
    build, edit, parts = TOML_CASES[case]
    exp = experiment(lab, "static", **(build or {}))
    if edit:
        exp.write_text(edit(exp.read_text()))
    out = lab / "out"
    result = validate("static", exp, out)
    assert_bad_input(
        result,
        "bad.toml",
        *parts,
        hint=case not in ("coil_longer_than_fiber", "negative_diameter", "volume_fraction_above_one"),
    )
    assert_no_report(out)


@pytest.mark.parametrize("subcommand", ["dynamic", "sensing", "curvature"])
def test_kind_not_matching_the_subcommand(lab, subcommand):
    result = validate(subcommand, lab / "experiments/static.toml", lab / "out")
    assert_bad_input(
        result, "static.toml", "this is a 'static' experiment", f"not '{subcommand}'", "'static' subcommand"
    )
    assert not (lab / "out").exists()


# --- models without a physical solution ------------------------------------------------


def test_sensing_with_s_f11_above_one_names_experiment_and_run(lab):
    exp = experiment(lab, "sensing", name="stiff", replace={"spring_constant_N_per_m": "50.0"})
    out = lab / "out"
    text = assert_bad_input(
        validate("sensing", exp, out), "stiff.toml, run sensing_run1", "no physical root", "S f11 = ", ">= 1"
    )
    assert "nan" not in text.lower()
    assert_no_report(out, "stiff")


def test_static_with_nonpositive_gt_names_experiment_and_run(lab):
    exp = experiment(lab, "static", name="soft", replace={"shear_modulus_slope_MPa_per_K": "50"})
    out = lab / "out"
    assert_bad_input(
        validate("static", exp, out), "soft.toml, run static_run1", "G_t'", "non-positive", "constant-G"
    )
    assert_no_report(out, "soft")


def test_dynamic_with_nonpositive_gt_names_experiment_and_run(lab):
    exp = experiment(lab, "dynamic", name="soft", replace={"shear_modulus_slope_MPa_per_K": "30"})
    out = lab / "out"
    assert_bad_input(validate("dynamic", exp, out), "soft.toml, run dynamic_run1", "G_t'", "reaches zero")
    assert_no_report(out, "soft")


# --- size limit --------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["validate", "report", "fit-spring"])
def test_max_bytes_option_refuses_larger_files(lab, monkeypatch, command):
    monkeypatch.chdir(lab)
    if command == "validate":
        args = ["validate", "sensing", "experiments/sensing.toml", "--out", "out"]
    elif command == "report":
        args = ["report", "experiments/sensing.toml", "--out", "out"]
    else:
        args = ["fit-spring", "raw/sensing_run1.csv"]
    result = runner.invoke(app, args + ["--max-bytes", "1000"])
    if command == "report":
        assert result.exit_code == 2
        assert "error sensing" in result.output
        assert "larger than the limit of 1000 bytes" in result.output
        assert "larger than the limit" in (lab / "out/index.html").read_text()
    else:
        assert_bad_input(
            result,
            "sensing_run1.csv",
            "file is 72712 bytes",
            "larger than the limit of 1000 bytes",
            "--max-bytes",
        )
    assert_no_report(lab / "out", "sensing")
    # a limit above the file size lets it through; suffixes K/M/G work
    ok = runner.invoke(app, args + ["--max-bytes", "10M"])
    assert ok.exit_code == 0, ok.output


def test_max_bytes_must_be_positive(lab):
    result = runner.invoke(app, ["fit-spring", str(lab / "raw/sensing_run1.csv"), "--max-bytes", "-5"])
    assert result.exit_code == 2
    assert "Traceback" not in result.output and "--max-bytes" in result.output


# --- report: one broken experiment does not stop the others ------------------------------


@pytest.mark.slow
def test_report_lists_a_bad_csv_and_builds_the_rest(lab, monkeypatch):
    write_run(lab, "time_s,temperature_C,displacement_mm\n0,25,0\n1,x,0\n2,27,0\n")
    experiment(lab, "static", name="broken", runs=["bad.csv"])
    monkeypatch.chdir(lab)
    result = runner.invoke(app, ["report", "--mc-draws", "20"])
    assert result.exit_code == 2
    assert "Traceback" not in result.output
    line = next(s for s in result.output.splitlines() if s.startswith("error broken"))
    assert "line 3, column 'temperature_C': non-numeric value 'x'" in line
    for kind in ("static", "dynamic", "sensing", "curvature"):
        assert (lab / "reports" / kind / "report.html").exists()
    index = (lab / "reports/index.html").read_text()
    assert "non-numeric value" in index and 'href="broken/report.html"' not in index
    assert not (lab / "reports/broken").exists()


# --- nothing overwritten --------------------------------------------------------------------


def test_simulate_refuses_to_overwrite_unless_force(tmp_path):
    args = [
        "simulate",
        "static",
        "--experiment",
        "static",
        "--seed",
        "1",
        "--out",
        str(tmp_path),
        "--runs",
        "1",
    ]
    assert runner.invoke(app, args).exit_code == 0
    run = tmp_path / "raw" / "static_run1.csv"
    exp = tmp_path / "experiments" / "static.toml"
    run.write_text("my own lab data\n")
    before = exp.read_bytes()
    result = runner.invoke(app, [*args[:5], "2", *args[6:]])  # another seed: other bytes
    assert_bad_input(result, "would be overwritten", "static_run1.csv", "static.toml", "--force")
    assert run.read_text() == "my own lab data\n" and exp.read_bytes() == before  # nothing written
    result = runner.invoke(app, [*args[:5], "2", *args[6:], "--force"])
    assert result.exit_code == 0, result.output
    assert run.read_text() != "my own lab data\n" and exp.read_bytes() != before


def test_two_experiments_with_one_stem_get_two_reports(lab, monkeypatch):
    """lab1/case.toml and lab2/case.toml: two folders, two index rows, two links."""
    monkeypatch.chdir(lab)
    paths = []
    for folder, runs in (
        ("lab1", '["../../raw/static_run1.csv"]'),
        ("lab2", '["../../raw/static_run2.csv"]'),
    ):
        text = (lab / "experiments" / "static.toml").read_text()
        text = re.sub(r"runs = \[[^\]]*\]", f"runs = {runs}", text, flags=re.S)
        text = text.replace('title = "', f'title = "{folder}: ', 1)
        p = lab / "experiments" / folder / "case.toml"
        p.parent.mkdir()
        p.write_text(text)
        paths.append(str(p))
    result = runner.invoke(app, ["report", *paths, "--out", "out"])
    assert result.exit_code == 0, result.output
    index = (lab / "out" / "index.html").read_text()
    assert 'href="lab1-case/report.html"' in index and 'href="lab2-case/report.html"' in index
    one = json.loads((lab / "out" / "lab1-case" / "metrics.json").read_text())
    two = json.loads((lab / "out" / "lab2-case" / "metrics.json").read_text())
    assert one["title"].startswith("lab1") and two["title"].startswith("lab2")
    assert one["inputs"][0]["sha256"] != two["inputs"][0]["sha256"]
    assert not (lab / "out" / "case").exists()


def test_every_bad_columns_entry_is_listed_at_once(lab):
    columns = '\n[columns]\ntme_s = "t"\ndisplacement_mm = { from = "x", unit = "furlong" }\n'
    exp = experiment(lab, "static", append=columns)
    result = validate("static", exp, lab / "out")
    assert_bad_input(result, "2 problems in [columns]", "'tme_s'", "did you mean 'time_s'", "'furlong'")
    assert "more problem" not in result.output


@pytest.mark.parametrize(
    "runs, parts",
    [
        (
            '[{ file = "../raw/static_run1.csv", join = { file = "../raw/static_run2.csv", ofset_s = 1 } }]',
            [
                "unknown key 'runs[0].join.ofset_s'",
                "did you mean 'offset_s'",
                "allowed keys: file, columns, offset_s",
            ],
        ),
        ('["../raw/static_run1.csv", 3]', ["runs[1]: expected a string, got 3"]),
        (
            '[{ file = "../raw/static_run1.csv", join = { file = "../raw/static_run2.csv" } }]',
            ["runs[0].join.columns: names no column to take from"],
        ),
        ('[{ file = "../raw/nope.csv" }]', ["runs[0]: run file", "not found"]),
    ],
)
def test_run_tables_errors_name_the_key(lab, runs, parts):
    text = (lab / "experiments" / "static.toml").read_text()
    text = re.sub(r"runs = \[[^\]]*\]", lambda m: f"runs = {runs}", text, flags=re.S)
    p = lab / "experiments" / "bad.toml"
    p.write_text(text)
    result = runner.invoke(app, ["validate", "static", str(p), "--out", str(lab / "out")])
    assert_bad_input(result, *parts)
    assert "_RunTable" not in result.output and ".str" not in result.output


def test_validate_takes_the_kind_from_the_file(lab):
    out = lab / "out"
    result = runner.invoke(
        app, ["validate", str(lab / "experiments" / "static.toml"), "--out", str(out), "--format", "html"]
    )
    assert result.exit_code == 0, result.output
    assert (out / "static" / "report.html").exists()
    # the subcommands stay, and a wrong one still says so
    result = runner.invoke(app, ["validate", "sensing", str(lab / "experiments" / "static.toml")])
    assert_bad_input(result, "this is a 'static' experiment, not 'sensing'")
    assert "No such command" in runner.invoke(app, ["validate", "statc", "x.toml"]).output


def test_fit_spring_on_a_bare_csv_needs_only_displacement_and_force(tmp_path):
    """A pull test with no resistance column, in µm and mN: S = 0.47 mN / 100 µm = 4.7 N/m."""
    rows = ["Time [s],Extension (µm),Load [mN]"] + [
        f"{0.1 * i:.1f},{100.0 * i:.1f},{0.47 * i:.4f}" for i in range(30)
    ]
    p = tmp_path / "pull.csv"
    p.write_text("\n".join(rows) + "\n", encoding="utf-8")
    args = [
        "fit-spring",
        str(p),
        "--column",
        "displacement_mm=Extension (µm):um",
        "--column",
        "force_N=Load [mN]:mN",
    ]
    result = runner.invoke(app, [*args, "--json"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    assert doc["spring_constant_N_per_m"] == pytest.approx(4.7, rel=1e-9)
    assert_bad_input(runner.invoke(app, ["fit-spring", str(p)]), "required column 'displacement_mm'")
    assert_bad_input(
        runner.invoke(app, ["fit-spring", str(p), "--column", "force_N"]), "expected CANON=HEADER"
    )
