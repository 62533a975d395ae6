"""The self-sensing report: the causal EKF with the load logged and withheld, whole run and
heating-only part, per run and pooled; ``validate --ignore COLUMN``."""

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.kinds import selfsensing as ss

ROOT = Path(__file__).resolve().parents[1]
RUNS = ("selfsensing_run1", "selfsensing_run2", "selfsensing_run3")
runner = CliRunner()


def copy_lab(folder: Path) -> Path:
    """The shipped selfsensing experiment and its raw logs under ``folder``; the experiment file."""
    (folder / "experiments").mkdir(parents=True)
    shutil.copy(ROOT / "experiments" / "selfsensing.toml", folder / "experiments")
    (folder / "raw").mkdir()
    for run in RUNS:
        shutil.copy(ROOT / "raw" / f"{run}.csv", folder / "raw")
    return folder / "experiments" / "selfsensing.toml"


def validate(exp: Path, out: Path, *extra) -> dict:
    res = runner.invoke(app, ["validate", str(exp), "--out", str(out), "--format", "html", *extra])
    assert res.exit_code == 0, res.output
    return json.loads((out / "selfsensing" / "metrics.json").read_text())


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    """The bundled runs validated as they are (load_N logged): (metrics.json, report folder)."""
    folder = tmp_path_factory.mktemp("logged")
    exp = copy_lab(folder)
    return validate(exp, folder / "out"), folder / "out" / "selfsensing"


def test_ignore_load_gives_the_numbers_of_a_file_without_the_column(tmp_path, logged):
    exp = copy_lab(tmp_path / "lab")
    ignored = validate(exp, tmp_path / "a", "--ignore", "load_N")
    for run in RUNS:  # the same logs with the column removed (the copies; the raw files stay)
        path = tmp_path / "lab" / "raw" / f"{run}.csv"
        pd.read_csv(path).drop(columns=["load_N"]).to_csv(path, index=False)
    stripped = validate(exp, tmp_path / "b")
    assert ignored["ignored_columns"] == ["load_N"] and stripped["ignored_columns"] == []
    assert ignored["models"] == stripped["models"]
    help_a = ignored["extras"]["ekf_with_and_without_load"]
    assert help_a == stripped["extras"]["ekf_with_and_without_load"]
    # the column really was withheld: no load-logged case, and the heating-only part ends at the
    # first heating pulse (rest 2 s, the 4 V step 3 s), not at the rider
    assert help_a["pooled"]["load_logged"] is None
    for run in RUNS:
        entry = help_a["runs"][run]
        assert entry["logs_load"] is False and entry["heating_only_until_s"] == pytest.approx(5.0)
    # with the load logged the unknown-load figures differ from the logged ones (measured pooled
    # 95 % interval 1.26 % logged, 5.63 % withheld); ignoring load_N gives the withheld ones
    help_l = logged[0]["extras"]["ekf_with_and_without_load"]
    whole_l = help_l["pooled"]["load_logged"]["whole_run"]["interval95_of_stroke"]
    whole_w = help_l["pooled"]["load_withheld"]["whole_run"]["interval95_of_stroke"]
    assert whole_l < 0.02 and whole_w > 2 * whole_l
    assert help_a["pooled"]["load_withheld"]["whole_run"]["interval95_of_stroke"] == pytest.approx(whole_w)
    html = (tmp_path / "a" / "selfsensing" / "report.html").read_text()
    assert "--ignore load_N" in html  # the command line in the provenance
    assert "treated as not logged" in html


def test_pooled_figures_are_those_of_the_runs_errors_together(logged):
    metrics, folder = logged
    info = metrics["extras"]["ekf_with_and_without_load"]
    rows = pd.read_csv(folder / "predictions.csv")
    for case, slug in (("load_logged", "EKF_causal"), ("load_withheld", "EKF_load_withheld")):
        parts = {"whole_run": [], "heating_only": []}
        strokes, own = [], []
        for run in RUNS:
            r = rows[rows["run"] == run]
            measured = r["measured_displacement_mm"].to_numpy()
            e = r[f"predicted_displacement_mm__{slug}"].to_numpy() - (
                measured - r["zero_displacement_mm"].to_numpy()
            )
            load = pd.read_csv(ROOT / "raw" / f"{run}.csv")["load_N"].to_numpy()
            k = int(np.flatnonzero(load != load[0])[0])  # the rider goes on: the logged load steps
            assert info["runs"][run]["heating_only_rows"] == k
            strokes.append(np.ptp(measured))
            parts["whole_run"].append(e)
            parts["heating_only"].append(e[:k])
            own.append(np.ptp(measured[:k]))
        stroke = np.mean(strokes)
        e = np.concatenate(parts["heating_only"])
        lo, hi = np.percentile(e, [2.5, 97.5])
        got = info["pooled"][case]["heating_only_own_stroke"]
        assert got["stroke_mm"] == pytest.approx(np.mean(own), rel=1e-9) and np.mean(own) < 0.8 * stroke
        assert got["interval95_of_stroke"] == pytest.approx((hi - lo) / np.mean(own), rel=1e-3)
        for part, errs in parts.items():
            e = np.concatenate(errs)
            lo, hi = np.percentile(e, [2.5, 97.5])
            got = info["pooled"][case][part]
            assert got["mean_error_of_stroke"] == pytest.approx(e.mean() / stroke, rel=1e-3, abs=2e-6)
            assert got["interval95_of_stroke"] == pytest.approx((hi - lo) / stroke, rel=1e-3)
            assert got["n"] == e.size
    # the heating-only part is the rows before the rider, not the whole run
    assert (
        info["pooled"]["load_logged"]["heating_only"]["n"] < info["pooled"]["load_logged"]["whole_run"]["n"]
    )


def test_the_report_table_has_a_row_per_run_and_pooled(logged):
    html = (logged[1] / "report.html").read_text()
    assert (
        "load withheld: heating only, own stroke" in html and "What the estimator does without help" in html
    )
    cell = logged[0]["extras"]["ekf_with_and_without_load"]["pooled"]["load_withheld"]["whole_run"]
    shown = f"{cell['mean_error_of_stroke']:+.2%} / {cell['interval95_of_stroke']:.2%}".replace(
        "%", "\u00a0%"
    )
    assert shown in html


def test_the_laser_alone_at_rest_is_the_floor_of_every_interval(logged):
    """The last row: the laser's 95 % interval over the runs' rest rows, each about its mean (the
    raw logs read directly), as % of each column's pooled stroke; measured 20 um, the log's 1 um
    steps, 6.7 % of the heating-only part's own stroke."""
    from tcamlab.kinds import rest_rows

    metrics, folder = logged
    info = metrics["extras"]["ekf_with_and_without_load"]
    rest = []
    for run in RUNS:
        raw = pd.read_csv(ROOT / "raw" / f"{run}.csv")
        frame = pd.DataFrame({"time": raw["time_s"], "voltage": raw["voltage_V"]})
        laser = raw["displacement_mm"].to_numpy()[rest_rows(ss.KIND, frame)]
        rest.append(laser - laser.mean())
    lo, hi = np.percentile(np.concatenate(rest), [2.5, 97.5])
    floor = info["laser_at_rest"]
    assert floor["interval95_width_mm"] == pytest.approx(hi - lo, rel=1e-9)
    assert floor["n"] == sum(r.size for r in rest)
    for case in ("load_logged", "load_withheld"):
        for part, cell in info["pooled"][case].items():
            assert floor[case][part] == pytest.approx((hi - lo) / cell["stroke_mm"], rel=1e-9)
            assert cell["interval95_of_stroke"] >= floor[case][part]  # no estimator beats its reference
    assert "laser alone at rest" in (folder / "report.html").read_text()
    net = info["beyond_laser"]
    for case in ("load_logged", "load_withheld"):
        for part, cell in info["pooled"][case].items():
            want = np.sqrt(cell["interval95_of_stroke"] ** 2 - floor[case][part] ** 2)
            assert net[case][part] == pytest.approx(want, rel=1e-9)
    assert "beyond the laser" in (folder / "report.html").read_text()


def test_the_interval_beyond_the_laser_recovers_the_estimators_own():
    """An estimate off by N(0, 3 um) scored against a laser with N(0, 10 um) noise on a 0.2 mm
    stroke: the interval against the laser is 20.5 % of the stroke, the laser alone 19.6 %, and
    the net width is the estimator's own 5.9 %, within a tenth; without a floor there is none."""
    rng = np.random.default_rng(7)
    n, stroke = 200_000, 0.2e-3
    own, laser = rng.normal(0.0, 3e-6, n), rng.normal(0.0, 10e-6, n)
    cell = ss.published_metrics(own - laser, np.array([0.0, stroke]))
    width = lambda x: np.subtract(*np.percentile(x, [97.5, 2.5])) / stroke  # noqa: E731
    floor = {"load_withheld": dict.fromkeys(ss.PARTS, width(laser))}
    pooled = {"load_withheld": dict.fromkeys(ss.PARTS, cell), "load_logged": None}
    net = ss.beyond_laser(pooled, floor)
    assert cell["interval95_of_stroke"] == pytest.approx(0.205, abs=0.003)
    assert net["load_withheld"]["whole_run"] == pytest.approx(width(own), rel=0.1)
    assert net["load_logged"] is None
    assert ss.beyond_laser(pooled, {"load_withheld": None})["load_withheld"] is None


def test_too_few_rest_rows_give_no_laser_floor(tmp_path):
    """Runs that start 5 rows before the drive moves (15 rest rows in all, under
    FLOOR_MIN_ROWS): no floor is read and the table has no such row, rather than one made of
    the extreme rows."""
    exp = copy_lab(tmp_path / "lab")
    for run in RUNS:
        path = tmp_path / "lab" / "raw" / f"{run}.csv"
        raw = pd.read_csv(path)
        moved = int(np.flatnonzero(np.abs(raw["voltage_V"] - raw["voltage_V"].iloc[0]) > 0.1)[0])
        raw.iloc[moved - 5 :].to_csv(path, index=False)
    metrics = validate(exp, tmp_path / "out")
    floor = metrics["extras"]["ekf_with_and_without_load"]["laser_at_rest"]
    assert floor["n"] == 15 and floor["interval95_width_mm"] is None and floor["load_logged"] is None
    assert "laser alone at rest" not in (tmp_path / "out" / "selfsensing" / "report.html").read_text()


def constructed_run(load=None):
    """12 s at 100 Hz: 2 s at the probe, a 6 V pulse to 5 s, the probe, 4 V from 8 s to the end."""
    t = np.arange(1200) / 100.0
    v = np.where((t >= 2.0) & (t < 5.0), 6.0, np.where(t >= 8.0, 4.0, ss.PROBE_V))
    data = pd.DataFrame({"time": t, "voltage": v, "current": v / 40.0})
    if load is not None:
        data["load"] = load
    return data


def test_heating_only_part_ends_at_a_known_load_step():
    f = np.full(1200, 0.4903)
    f[737:] += 0.049  # the 5 g rider at 7.37 s, between the pulses
    k, rule = ss.heating_only_rows(constructed_run(f))
    assert k == 737 and "7.37 s" in rule
    # a load cell's noise (0.3 mN) is no change: the whole run
    noisy = 0.4903 + np.random.default_rng(1).normal(0.0, 3e-4, 1200)
    assert ss.heating_only_rows(constructed_run(noisy))[0] == 1200
    # without a logged load: rest and the first heating pulse, up to the first row back at the probe
    k, rule = ss.heating_only_rows(constructed_run())
    assert k == 500 and "first heating pulse" in rule


@pytest.mark.parametrize(
    "name, words",
    [("load_n", ("not a column", "did you mean 'load_N'")), ("current_A", ("required column",))],
)
def test_a_bad_ignore_name_exits_2_on_one_line(tmp_path, name, words):
    res = runner.invoke(
        app,
        [
            "validate",
            str(ROOT / "experiments" / "selfsensing.toml"),
            "--out",
            str(tmp_path),
            "--ignore",
            name,
        ],
    )
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1 and "Traceback" not in res.output
    assert all(w in res.output for w in words) and "load_N, resistance_ohm, temperature_C" in res.output
    assert not (tmp_path / "selfsensing").exists()
