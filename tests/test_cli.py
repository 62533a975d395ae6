"""Every CLI command through Typer's test runner, on the shipped sample data."""

import hashlib
import json
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest
from typer.main import get_command
from typer.testing import CliRunner

from tcamlab import kinds
from tcamlab.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()
KINDS = kinds.KINDS


def _all_commands(cmd, path=()):
    yield path, cmd
    # Typer >= 0.22 vendors its own click: duck-type groups by their .commands
    if hasattr(cmd, "commands"):
        for name, sub in cmd.commands.items():
            yield from _all_commands(sub, path + (name,))


def test_every_command_has_help_with_an_example():
    root = get_command(app)
    seen = 0
    for path, cmd in _all_commands(root):
        result = runner.invoke(app, list(path) + ["--help"])
        assert result.exit_code == 0, path
        assert cmd.help, f"{' '.join(path)} has no help text"
        if not hasattr(cmd, "commands") or path:
            assert "Example:" in cmd.help, f"{' '.join(path)} help lacks an example"
        seen += 1
    assert seen >= 12


PLACEHOLDER = re.compile(r"<(str|int|float|bool|list|path|file|dict|tuple)\b[^>]*>")


def test_help_shows_choices_and_defaults_never_type_placeholders():
    """Typer appends ``<str>``, ``<int range>``, ``<list[Path]>`` where no metavar is given:
    every option and argument of every command has one, and a file argument says how to
    write it for one's own CSV logs (``tcamlab init``, ``[columns]``)."""
    root = get_command(app)
    for path, cmd in _all_commands(root):
        text = runner.invoke(app, list(path) + ["--help"], terminal_width=200).output
        found = PLACEHOLDER.findall(text)
        assert not found, f"tcamlab {' '.join(path)} --help shows placeholders {found}:\n{text}"
        if any(p.param_type_name == "argument" and "EXPERIMENT" in (p.metavar or "") for p in cmd.params):
            assert "tcamlab init" in text and "[columns]" in text, " ".join(path)
    text = runner.invoke(app, ["simulate", "--help"], terminal_width=200).output
    assert "[static|dynamic|sensing|curvature|selfsensing]" in text and "--oven [heating|heat-cool]" in text
    assert "[default: 1.0]" in text  # --noise-scale's default
    text = runner.invoke(app, ["validate", "static", "--help"], terminal_width=200).output
    assert "--format html,pdf[,png,svg]" in text and "[default: html,pdf]" in text
    assert "[default: reports]" in text
    for path in (["validate"], ["fit-spring"], ["init"]):
        text = runner.invoke(app, path + ["--help"], terminal_width=200).output
        assert "tcamlab init" in text and "[columns]" in text, path


def _hashes(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.glob("*"))}


class _Counter(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags = {}

    def handle_starttag(self, tag, attrs):
        self.tags[tag] = self.tags.get(tag, 0) + 1


@pytest.mark.parametrize("kind", KINDS)
def test_validate_writes_every_output(lab, kind):
    before = _hashes(lab / "raw")
    out = lab / "reports"
    result = runner.invoke(
        app,
        ["validate", kind, str(lab / "experiments" / f"{kind}.toml"), "--out", str(out), "--mc-draws", "200"],
    )
    assert result.exit_code == 0, result.output
    folder = out / kind
    for name in ("report.html", "report.pdf", "metrics.json", "predictions.csv"):
        assert (folder / name).stat().st_size > 0
    metrics = json.loads((folder / "metrics.json").read_text())
    assert metrics["kind"] == kind and metrics["synthetic"]["seed"] is not None
    pooled = next(iter(metrics["models"][metrics["primary_model"]].values()))["pooled"]
    # sample data are model + measurement noise: the model explains them
    assert pooled["r2"] > 0.95
    parser = _Counter()
    parser.feed((folder / "report.html").read_text())
    assert parser.tags.get("svg", 0) >= 2 and parser.tags.get("table", 0) >= 3
    assert "script" not in parser.tags
    from pypdf import PdfReader

    reader = PdfReader(str(folder / "report.pdf"))
    text = "".join(page.extract_text() for page in reader.pages)
    assert "SYNTHETIC" in text and "RMSE" in text
    assert _hashes(lab / "raw") == before  # raw data never written


def test_static_sample_shows_gt_beats_constant_g(lab):
    out = lab / "reports"
    result = runner.invoke(
        app,
        [
            "validate",
            "static",
            str(lab / "experiments/static.toml"),
            "--out",
            str(out),
            "--json",
            "--format",
            "html",
        ],
    )
    assert result.exit_code == 0
    doc = json.loads(result.output)
    gt = doc["models"]["G(T)"]["displacement_mm"]["pooled"]["rmse"]
    cg = doc["models"]["constant-G"]["displacement_mm"]["pooled"]["rmse"]
    assert gt < cg


def test_validate_kind_mismatch_is_a_one_line_error(lab):
    result = runner.invoke(app, ["validate", "dynamic", str(lab / "experiments/static.toml")])
    assert result.exit_code == 2
    assert "static" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_threshold_failure_exits_1(lab):
    exp = lab / "experiments/static.toml"
    text = exp.read_text()
    assert "\nrmse_mm = 0.02\n" in text  # the bundled file's limit, made impossible
    exp.write_text(text.replace("\nrmse_mm = 0.02\n", "\nrmse_mm = 1e-6\n"))
    result = runner.invoke(app, ["validate", "static", str(exp), "--out", str(lab / "r"), "--format", "html"])
    assert result.exit_code == 1
    assert "FAIL" in result.output


@pytest.mark.slow
def test_report_builds_index_and_combined_pdf(lab, monkeypatch):
    monkeypatch.chdir(lab)
    result = runner.invoke(app, ["report", "--mc-draws", "100"])
    assert result.exit_code == 0, result.output
    index = (lab / "reports/index.html").read_text()
    for kind in KINDS:
        assert f'href="{kind}/report.html"' in index
    from pypdf import PdfReader

    assert len(PdfReader(str(lab / "reports/reports.pdf")).pages) >= 5


@pytest.mark.slow
def test_report_lists_a_broken_experiment_and_builds_the_rest(lab, monkeypatch):
    monkeypatch.chdir(lab)
    (lab / "experiments/broken.toml").write_text(
        'kind = "static"\ntitle = "x"\nruns = ["nope.csv"]\n[sample]\npreset = "thesis-tca"\n'
    )
    result = runner.invoke(app, ["report", "--mc-draws", "50"])
    assert result.exit_code == 2
    assert "error broken" in result.output
    assert (lab / "reports/static/report.html").exists()
    assert "nope.csv" in (lab / "reports/index.html").read_text()


def test_reports_are_byte_identical_on_rerun(lab):
    outs = []
    for k in range(2):
        out = lab / f"r{k}"
        result = runner.invoke(
            app, ["validate", "sensing", str(lab / "experiments/sensing.toml"), "--out", str(out)]
        )
        assert result.exit_code == 0
        outs.append(
            {
                n: (out / "sensing" / n).read_bytes()
                for n in ("report.html", "report.pdf", "metrics.json", "predictions.csv")
            }
        )
    assert outs[0] == outs[1]


def test_fit_spring_json_recovers_the_simulated_spring_constant(lab):
    import tomllib

    truth_s = tomllib.loads((ROOT / "tcamlab/templates/sensing.toml").read_text())["rig"][
        "spring_constant_N_per_m"
    ]
    runs = sorted((lab / "raw").glob("sensing_run*.csv"))
    assert len(runs) >= 2
    result = runner.invoke(app, ["fit-spring", *map(str, runs), "--json", "--plot", str(lab / "fit.svg")])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    assert doc["spring_constant_N_per_m"] == pytest.approx(truth_s, rel=0.02)
    assert (lab / "fit.svg").read_text().lstrip().startswith("<svg")
    # the experiment file works as input too
    result = runner.invoke(app, ["fit-spring", str(lab / "experiments/sensing.toml")])
    assert result.exit_code == 0 and "pooled" in result.output


@pytest.mark.parametrize(
    "name, signature",
    [("fit.pdf", b"%PDF-"), ("fit.png", b"\x89PNG\r\n\x1a\n"), ("fit.SVG", b"<svg")],
)
def test_fit_spring_plot_is_the_format_its_extension_names(lab, name, signature):
    runs = [str(p) for p in sorted((lab / "raw").glob("sensing_run*.csv"))]
    result = runner.invoke(app, ["fit-spring", *runs, "--plot", str(lab / name)])
    assert result.exit_code == 0, result.output
    data = (lab / name).read_bytes()
    assert data.lstrip().startswith(signature)
    # never over an existing file without --force
    again = runner.invoke(app, ["fit-spring", *runs, "--plot", str(lab / name)])
    assert again.exit_code == 2 and "--force" in again.output
    forced = runner.invoke(app, ["fit-spring", *runs, "--plot", str(lab / name), "--force"])
    assert forced.exit_code == 0 and (lab / name).read_bytes() == data  # same input, same bytes


@pytest.mark.parametrize("name", ["fit.jpg", "fit", "fit.svg.txt"])
def test_fit_spring_refuses_an_unknown_plot_format(lab, name):
    runs = [str(p) for p in sorted((lab / "raw").glob("sensing_run*.csv"))]
    result = runner.invoke(app, ["fit-spring", *runs, "--plot", str(lab / name)])
    assert result.exit_code == 2
    assert ".png, .svg, .pdf" in result.output and "Traceback" not in result.output
    assert not (lab / name).exists()


def test_fit_spring_text_labels_f0_r2_and_the_standard_error(lab):
    """The bundled pull tests' load cell reads -0.4 mN at rest: the default fit reports F0 and
    warns; R² is labelled; ± is named a standard error; --origin is labelled and warned about."""
    runs = [str(p) for p in sorted((lab / "raw").glob("sensing_run*.csv"))]
    out = runner.invoke(app, ["fit-spring", *runs, "--no-branches"]).output
    assert "± is one standard error" in out and "R² (centred)" in out
    pooled = next(line for line in out.splitlines() if line.strip().startswith("pooled"))
    lo, hi = (float(v) for v in re.search(r"95% CI ([\d.]+) to ([\d.]+)", pooled).groups())
    assert lo <= 4.7 <= hi
    assert "mean F0 = -0.3" in pooled and "warning: the load cell's zero is off" in out
    forced = runner.invoke(app, ["fit-spring", *runs, "--no-branches", "--origin"]).output
    assert "R² (uncentred)" in forced and "F0 = 0 (forced)" in forced
    assert "warning: forced through the origin" in forced and "biased" in forced
    doc = json.loads(runner.invoke(app, ["fit-spring", *runs, "--json"]).output)
    assert doc["r2_kind"] == "centred" and doc["warnings"] and doc["pooled"]["intercept_significant"]
    assert doc["ci95_N_per_m"][0] <= 4.7 <= doc["ci95_N_per_m"][1]


def test_fit_spring_bad_file_is_a_clear_error(lab):
    bad = lab / "bad.csv"
    bad.write_text("displacement_mm,force_N\n1,2\n")
    result = runner.invoke(app, ["fit-spring", str(bad)])
    assert result.exit_code == 2
    # F = S delta needs no resistance: the file is refused for being one row long
    assert "bad.csv" in result.output and "only 1 usable data row" in result.output


def test_foreign_headers_and_units_through_columns_alone(lab):
    import pandas as pd

    src = pd.read_csv(lab / "raw/static_run1.csv")
    foreign = pd.DataFrame(
        {"Temp (F)": src["temperature_C"] * 9 / 5 + 32, "laser": (src["displacement_mm"] + 2.5) / 0.01}
    )
    foreign.to_csv(lab / "raw/foreign.csv", index=False)
    text = (lab / "experiments/static.toml").read_text()
    import re

    text = re.sub(r"runs = \[[^\]]*\]", 'runs = ["../raw/foreign.csv"]', text, flags=re.S)
    text += (
        '\n[columns]\ntemperature_C = { from = "Temp (F)", unit = "degF" }\n'
        'displacement_mm = { from = "laser", scale = 0.01, offset = -2.5 }\n'
    )
    (lab / "experiments/foreign.toml").write_text(text)
    result = runner.invoke(
        app,
        [
            "validate",
            "static",
            str(lab / "experiments/foreign.toml"),
            "--out",
            str(lab / "r"),
            "--json",
            "--format",
            "html",
        ],
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    ref = runner.invoke(
        app,
        [
            "validate",
            "static",
            str(lab / "experiments/static.toml"),
            "--out",
            str(lab / "r2"),
            "--json",
            "--format",
            "html",
        ],
    )
    run1 = json.loads(ref.output)["models"]["G(T)"]["displacement_mm"]["runs"]["static_run1"]
    got = doc["models"]["G(T)"]["displacement_mm"]["runs"]["foreign"]
    assert got["rmse"] == pytest.approx(run1["rmse"], rel=1e-6)


def test_effects_list_and_version():
    result = runner.invoke(app, ["effects", "list", "--json"])
    assert result.exit_code == 0
    names = {(e["kind"], e["name"]) for e in json.loads(result.output)}
    assert ("static", "glass-transition") in names and len(names) >= 17
    assert runner.invoke(app, ["--version"]).output.startswith("tcamlab ")


def test_simulate_writes_an_experiment_that_validates(tmp_path):
    result = runner.invoke(
        app,
        [
            "simulate",
            "static",
            "--experiment",
            str(ROOT / "tcamlab/templates/static.toml"),
            "--seed",
            "5",
            "--out",
            str(tmp_path),
            "--runs",
            "2",
        ],
    )
    assert result.exit_code == 0, result.output
    exp = tmp_path / "experiments/static.toml"
    assert exp.exists()
    result = runner.invoke(
        app, ["validate", "static", str(exp), "--out", str(tmp_path / "r"), "--format", "html"]
    )
    assert result.exit_code == 0, result.output


def test_simulate_unknown_effect_is_a_clear_error(tmp_path):
    result = runner.invoke(
        app,
        [
            "simulate",
            "static",
            "--experiment",
            str(ROOT / "tcamlab/templates/static.toml"),
            "--seed",
            "1",
            "--out",
            str(tmp_path),
            "--effect",
            "glass-transitoin=3",
        ],
    )
    assert result.exit_code == 2
    assert "glass-transition" in result.output


@pytest.mark.slow
def test_diagnose_command_on_a_simulated_experiment(tmp_path):
    result = runner.invoke(
        app,
        [
            "simulate",
            "curvature",
            "--experiment",
            str(ROOT / "tcamlab/templates/curvature.toml"),
            "--seed",
            "4",
            "--out",
            str(tmp_path),
            "--effect",
            "camera-placement=10",
        ],
    )
    assert result.exit_code == 0, result.output
    exp = tmp_path / "experiments/curvature.toml"
    result = runner.invoke(app, ["diagnose", str(exp), "--json", "--out", str(tmp_path / "d")])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    # fitted with the recalibrated d1 and S, axial compression can mimic the offset on three
    # runs: attributed, or aliased with camera placement named first
    assert doc["verdict"] in ("attributed", "aliased") and doc["effect"] == "camera-placement"
    for name in ("diagnosis.json", "diagnosis.html", "diagnosis.pdf"):
        assert (tmp_path / "d/curvature" / name).stat().st_size > 0
    text = runner.invoke(app, ["diagnose", str(exp), "--effects", "camera-placement"])
    assert text.exit_code == 0 and "verdict: attributed" in text.output


@pytest.mark.slow
def test_benchmark_diagnose_command_on_a_tiny_subset(tmp_path):
    result = runner.invoke(
        app,
        [
            "benchmark",
            "diagnose",
            "--quick",
            "--seeds",
            "1",
            "--kind",
            "dynamic",
            "--effect",
            "response-delay",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "strength 3.0x: top-1 1.00" in result.output
    assert (tmp_path / "benchmark.json").exists() and (tmp_path / "benchmark.md").exists()
    bad = runner.invoke(app, ["benchmark", "diagnose", "--kind", "oven"])
    assert bad.exit_code == 2


def test_simulate_takes_a_bare_kind_for_the_shipped_template(tmp_path):
    args = ["simulate", "sensing", "--experiment", "sensing", "--seed", "2", "--out", str(tmp_path)]
    result = runner.invoke(app, args + ["--runs", "1"])
    assert result.exit_code == 0, result.output
    text = (tmp_path / "experiments/sensing.toml").read_text()
    assert "--experiment sensing --seed 2" in text


def test_diagnose_writes_all_or_nothing(tmp_path, monkeypatch):
    import tcamlab.report.pdf as pdf
    from tcamlab.pipeline import diagnose_experiment, simulate_experiment

    sim = simulate_experiment("curvature", "curvature", seed=4, out_dir=tmp_path, runs=2)

    def boom(doc):
        raise RuntimeError("renderer crashed")

    monkeypatch.setattr(pdf, "render_pdf", boom)
    with pytest.raises(RuntimeError):
        diagnose_experiment(sim.experiment_path, out_dir=tmp_path / "d")
    assert not (tmp_path / "d/curvature").exists() or list((tmp_path / "d/curvature").iterdir()) == []


@pytest.mark.slow
def test_validate_diagnose_calibrate_name_by_path_and_refuse_a_rerun(lab, monkeypatch):
    """Two valid ``case.toml`` in different folders get two output folders (the second named
    by its path, as ``report`` names them); a second run of the same file into the same
    folder is refused without --force and changes no byte."""
    monkeypatch.chdir(lab)
    for d in ("lab1", "lab2"):
        (lab / d).mkdir()
        (lab / d / "case.toml").write_bytes((lab / "experiments/sensing.toml").read_bytes())
    commands = {
        "metrics.json": ["validate", "{}", "--out", "R", "--format", "html"],
        "diagnosis.json": ["diagnose", "{}", "--out", "R", "--effects", "initial-slack"],
        "calibration.json": ["calibrate", "{}", "--out", "R", "--params", "spring_constant"],
    }
    for record, args in commands.items():
        for d in ("lab1", "lab2"):
            r = runner.invoke(app, [a.format(f"{d}/case.toml") for a in args])
            assert r.exit_code == 0, (record, d, r.output)
        assert (lab / "R/case" / record).exists() and (lab / "R/lab2-case" / record).exists(), record
        before = _hashes(lab / "R/case")
        for f in (lab / "lab1").glob("*.calibrated.toml"):
            f.unlink()  # calibrate's own refusal of the calibrated file is tested apart
        r = runner.invoke(app, [a.format("lab1/case.toml") for a in args])
        assert r.exit_code == 2 and f"R/case/{record}" in r.output and "exists" in r.output, r.output
        assert "--force" in r.output
        assert "Traceback" not in r.output and _hashes(lab / "R/case") == before
    metrics = json.loads((lab / "R/lab2-case/metrics.json").read_text())
    assert metrics["experiment_file"]["path"] == "lab2/case.toml"
    r = runner.invoke(app, ["validate", "lab1/case.toml", "--out", "R", "--format", "html", "--force"])
    assert r.exit_code == 0 and "wrote R/case" in r.output, r.output
    assert sorted(p.name for p in (lab / "R").iterdir()) == ["case", "lab2-case"]


def test_benchmark_refuses_an_unknown_effect_before_simulating(tmp_path):
    """A misspelt --effect used to run the null cases alone and exit 0."""
    out = tmp_path / "bench"
    r = runner.invoke(app, ["benchmark", "diagnose", "--quick", "--effect", "hysterisis", "--out", str(out)])
    assert (
        r.exit_code == 2
        and "unknown effect 'hysterisis'" in r.output
        and "did you mean 'hysteresis'" in r.output
    )
    r = runner.invoke(
        app,
        ["benchmark", "diagnose", "--quick", "--kind", "static", "--effect", "hysteresis", "--out", str(out)],
    )
    assert r.exit_code == 2 and "unknown effect 'hysteresis' of static" in r.output
    assert not out.exists()


def test_benchmark_refuses_to_overwrite_a_benchmark_before_simulating(tmp_path, monkeypatch):
    import tcamlab.benchmark

    out = tmp_path / "bench"
    out.mkdir()
    (out / "benchmark.md").write_text("an earlier run\n")
    ran = []
    monkeypatch.setattr(tcamlab.benchmark, "run_benchmark", lambda *a, **k: ran.append(1))
    r = runner.invoke(app, ["benchmark", "diagnose", "--quick", "--kind", "static", "--out", str(out)])
    assert r.exit_code == 2 and "benchmark.md: benchmark output exists" in r.output
    assert "--force" in r.output and "Traceback" not in r.output and not ran
    assert (out / "benchmark.md").read_text() == "an earlier run\n"
    r = runner.invoke(
        app, ["benchmark", "diagnose", "--quick", "--kind", "static", "--out", str(out), "--force"]
    )
    assert ran == [1]
