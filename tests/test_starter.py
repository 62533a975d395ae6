"""Tests of ``tcamlab init`` (tcamlab.starter) on files written like real instruments' exports.

The CSV texts below are hand-written in the layouts found in published logs of
twisted-and-coiled nylon actuators (a rheometer export with a title row, a
units row and tension negative; an oven log in Fahrenheit and micrometres;
a header-less vibrometer log; side-by-side blocks with repeated headers;
wall-clock time stamps). Their numbers are made up for the tests.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.errors import ConfigError
from tcamlab.io import convert
from tcamlab.starter import PLACEHOLDER, inspect_csv, placeholders, split_header, starter_text, write_starter

runner = CliRunner()

SAMPLE = {
    "fiber_diameter_mm": 0.4,
    "fiber_length_mm": 328.0,
    "coil_length_mm": 90.0,
    "coil_diameter_mm": 0.8,
    "twists": 750.0,
    "load_g": 50.0,
    "ambient_C": 21.0,
    "voltage_V": 10.0,
    "pulse_s": 1.0,
    "resistance_ohm": 40.0,
    "sensor_offset_mm": 9.0,
    "spring_constant_N_per_m": 14.1,
}


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(text.encode("utf-8"))
    return path


def fill(text: str, values: dict) -> str:
    """Replace every placeholder: ``key = "FILL IN..."`` by ``values[key]`` (a TOML literal or number)."""

    def sub(m: re.Match) -> str:
        key = m.group(1)
        return f"{key} = {values[key]}"

    text = re.sub(r'^(\w+) = "' + PLACEHOLDER + r'[^"]*"', sub, text, flags=re.M)
    # inline tables of [columns]: `from = "FILL IN..."` / `scale = "FILL IN..."` keyed by the column
    for key, value in values.items():
        if "." in key:
            canon, sub_key = key.split(".")
            text = re.sub(
                rf'^({canon} = {{.*?){sub_key} = "{PLACEHOLDER}[^"]*"',
                rf"\g<1>{sub_key} = {value}",
                text,
                flags=re.M,
            )
    assert PLACEHOLDER not in text.replace(f'"{PLACEHOLDER}', "").replace(PLACEHOLDER + '"', ""), text
    return text


def rheometer_csv(lab: Path) -> Path:
    """A rheometer export: title row, header, units row in brackets, tension negative, µm."""
    rows = ["Rheometer export 2019-06-11 14:03,,,", "Time,Gap,Axial force,R", "[s],[µm],[N],[Ohm]"]
    for i in range(12):
        rows.append(f"{0.5 * i:.1f},{1000 + 20 * i:.1f},{-0.005 * i:.4f},{30 + 0.02 * i:.3f}")
    return write(lab / "raw" / "pull1.csv", "\n".join(rows) + "\n")


@pytest.mark.parametrize(
    "header, name, unit",
    [
        ("Extension (µm)", "Extension", "µm"),
        ("Load [mN]", "Load", "mN"),
        ("Temp (F)", "Temp", "F"),
        ("R (Ohm)", "R", "Ohm"),
        ("Time [s]", "Time", "s"),
        ("Axial force [N]", "Axial force", "N"),
        ("Force/N", "Force", "N"),
        ("temperature_C", "temperature_C", "degC"),
        ("laser", "laser", None),
    ],
)
def test_split_header(header, name, unit):
    assert split_header(header) == (name, unit)


def test_rheometer_export_title_units_row_and_negative_tension(tmp_path):
    csv = rheometer_csv(tmp_path)
    layout = inspect_csv(csv)
    assert (layout.header_row, layout.units_row) == (2, 3)
    assert layout.title_rows == ["Rheometer export 2019-06-11 14:03"]
    text = starter_text("sensing", csv, tmp_path / "experiments" / "pull.toml")
    doc = tomllib.loads(text)
    assert doc["runs"] == ["../raw/pull1.csv"]
    cols = doc["columns"]
    assert cols["header_row"] == 2 and cols["units_row"] == 3
    assert cols["displacement_mm"] == {"from": "Gap", "unit": "um"}
    assert cols["force_N"] == {"from": "Axial force", "unit": "N", "scale": -1}
    assert cols["resistance_ohm"] == {"from": "R", "unit": "ohm"}
    assert cols["time_s"] == {"from": "Time", "unit": "s"}


def test_round_trip_the_starter_loads_once_filled_and_reads_si(tmp_path):
    csv = rheometer_csv(tmp_path)
    res = write_starter("sensing", csv, tmp_path / "experiments" / "pull.toml")
    text = res.path.read_text(encoding="utf-8")
    # every sample key and the kind's rig keys are there, with definition, measure and typical
    for key in ("fiber_diameter_mm", "fiber_length_mm", "coil_length_mm", "coil_diameter_mm", "twists"):
        assert f"# {key}: " in text and f'{key} = "{PLACEHOLDER}' in text
    assert "#   measure: " in text and "#   typical: " in text
    assert "OUTSIDE diameter" in text and "total number of turns" in text
    assert "# initial_resistance_ohm = " in text and "# spring_constant_N_per_m = " in text
    with pytest.raises(ConfigError) as info:
        load_experiment(res.path)
    msg = str(info.value)
    for key in ("sample.fiber_diameter_mm", "sample.twists", "rig.ambient_C"):
        assert key in msg
    assert "6 values still to fill in" in msg and "more problem" not in msg
    res.path.write_text(fill(text, SAMPLE), encoding="utf-8")
    exp = load_experiment(res.path)
    assert exp.sample.coil_length == pytest.approx(0.090) and exp.sample.twists == 750.0
    assert exp.rig.ambient == 21.0 and exp.rig.spring_constant is None
    (run,) = exp.read_runs()
    d = run.data
    # µm -> m, re-zeroed; tension made positive; ohm as is
    np.testing.assert_allclose(d["displacement"].to_numpy()[:3], [0.0, 20e-6, 40e-6], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(d["force"].to_numpy()[:3], [0.0, 0.005, 0.010], rtol=1e-12)
    assert d["resistance"].iloc[1] == pytest.approx(30.02)
    assert len(d) == 12  # no data row lost to the title or units rows


def test_oven_log_fahrenheit_micrometres_static(tmp_path):
    rows = ["Temp (F),Extension (µm),Time [s]"]
    rows += [f"{77 + 9 * i},{-25.0 * i:.1f},{10 * i}" for i in range(12)]
    csv = write(tmp_path / "oven.csv", "\n".join(rows) + "\n")
    out = tmp_path / "experiments" / "oven.toml"
    res = write_starter("static", csv, out)
    doc = tomllib.loads(res.path.read_text(encoding="utf-8"))
    assert doc["columns"]["temperature_C"] == {"from": "Temp (F)", "unit": "degF"}
    assert doc["columns"]["displacement_mm"] == {"from": "Extension (µm)", "unit": "um"}
    assert set(placeholders(doc)) == {
        "sample.fiber_diameter_mm",
        "sample.fiber_length_mm",
        "sample.coil_length_mm",
        "sample.coil_diameter_mm",
        "sample.twists",
        "rig.load_g",
        "rig.ambient_C",
    }
    sample = dict(
        SAMPLE, fiber_diameter_mm=0.17, fiber_length_mm=95.0, coil_length_mm=20.0, coil_diameter_mm=0.36
    )
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), sample), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    assert run.data["temperature"].iloc[0] == pytest.approx(25.0)  # 77 degF
    assert run.data["temperature"].iloc[1] == pytest.approx(30.0)
    assert run.data["displacement"].iloc[2] == pytest.approx(-50e-6)


def test_headerless_vibrometer_log_keeps_its_first_row(tmp_path):
    rows = [f"{0.001 * i:.3f},{25 + i},{0.5 * i:.2f}" for i in range(15)]
    csv = write(tmp_path / "vib.csv", "\n".join(rows) + "\n")
    res = write_starter("static", csv, tmp_path / "exp" / "vib.toml")
    text = res.path.read_text(encoding="utf-8")
    assert "header_row = 0" in text and 'first data row: column 1 = "0.000"' in text
    assert "columns.temperature_C.from" in res.placeholders
    filled = fill(
        text,
        dict(
            SAMPLE,
            fiber_diameter_mm=0.17,
            fiber_length_mm=95.0,
            coil_length_mm=20.0,
            coil_diameter_mm=0.36,
            **{"temperature_C.from": 2, "displacement_mm.from": 3},
        ),
    )
    res.path.write_text(filled, encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    assert len(run.data) == 15 and run.data["temperature"].iloc[0] == 25.0


def test_repeated_header_blocks_mapped_by_position_with_a_strain_scale(tmp_path):
    rows = ["Temp (degC),Contraction (%),Temp (degC),Contraction (%)"]
    rows += [f"{25 + 5 * i},{0.5 * i},{26 + 5 * i},{0.4 * i}" for i in range(12)]
    csv = write(tmp_path / "blocks.csv", "\n".join(rows) + "\n")
    res = write_starter("static", csv, tmp_path / "e" / "blocks.toml")
    doc = tomllib.loads(res.path.read_text(encoding="utf-8"))
    assert doc["columns"]["temperature_C"] == {"from": 1, "unit": "degC"}
    assert doc["columns"]["displacement_mm"]["from"] == 2
    assert "columns.displacement_mm.scale" in res.placeholders
    sample = dict(
        SAMPLE, fiber_diameter_mm=0.17, fiber_length_mm=95.0, coil_length_mm=20.0, coil_diameter_mm=0.36
    )
    sample["displacement_mm.scale"] = -0.2  # 20 mm coil: 1 % contraction = -0.2 mm
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), sample), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    assert run.data["displacement"].iloc[2] == pytest.approx(-0.2e-3)  # 1 % of 20 mm, shorter
    assert run.source_columns["temperature"] == "Temp (degC)"


def test_wall_clock_time_stamps_become_seconds(tmp_path):
    rows = ["Timestamp,Voltage (V),Position (mm)"]
    rows += [f"2019-06-11 14:03:{52 + i * 0.25:09.6f},{10 if i else 0},{-0.01 * i:.3f}" for i in range(12)]
    csv = write(tmp_path / "step.csv", "\n".join(rows) + "\n")
    res = write_starter("dynamic", csv, tmp_path / "e" / "step.toml")
    doc = tomllib.loads(res.path.read_text(encoding="utf-8"))
    assert doc["columns"]["time_s"] == {"from": "Timestamp", "unit": "datetime"}
    assert doc["rig"]["thermal_mass_J_per_K"] == 0.0266  # a typical value, not a placeholder
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), SAMPLE), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    np.testing.assert_allclose(run.data["time"].to_numpy()[:3], [0.0, 0.25, 0.5], atol=1e-9)


def test_curvature_starter_lists_the_robot_keys(tmp_path):
    rows = ["Cable (mm),R1 (Ohm),R2 (kΩ),kappa1 (1/mm),kappa2 (1/mm)"]
    rows += [f"{i},{10 + i * 0.01},{0.01 + i * 1e-5},{0.001 * i},{0.002 * i}" for i in range(12)]
    csv = write(tmp_path / "robot.csv", "\n".join(rows) + "\n")
    doc = tomllib.loads(starter_text("curvature", csv, tmp_path / "robot.toml"))
    cols = doc["columns"]
    assert cols["cable_mm"]["from"] == "Cable (mm)" and cols["r1_ohm"]["from"] == "R1 (Ohm)"
    assert cols["r2_ohm"] == {"from": "R2 (kΩ)", "unit": "kohm"}
    assert cols["kappa2_per_mm"] == {"from": "kappa2 (1/mm)", "unit": "per_mm"}
    assert {"rig.sensor_offset_mm", "rig.segment_lengths_mm"} <= set(placeholders(doc))


def test_init_never_overwrites_and_cli_exit_codes(tmp_path):
    csv = rheometer_csv(tmp_path)
    out = tmp_path / "experiments" / "pull.toml"
    r = runner.invoke(app, ["init", "sensing", "--csv", str(csv), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "displacement_mm  <- 'Gap' [um]" in r.output and "values to fill in" in r.output
    assert "force_N          <- 'Axial force' [N, scale -1]" in r.output
    before = out.read_bytes()
    r = runner.invoke(app, ["init", "sensing", "--csv", str(csv), "--out", str(out)])
    assert r.exit_code == 2 and "already exists" in r.output and "Traceback" not in r.output
    assert out.read_bytes() == before
    r = runner.invoke(app, ["init", "sensin", "--csv", str(csv), "--out", str(tmp_path / "x.toml")])
    assert r.exit_code == 2 and "did you mean 'sensing'" in r.output
    r = runner.invoke(
        app, ["init", "static", "--csv", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "y.toml")]
    )
    assert r.exit_code == 2 and "not found" in r.output
    r = runner.invoke(app, ["init", "--help"])
    assert "static|dynamic|sensing|curvature" in r.output


def test_semicolon_decimal_comma_latin1_export(tmp_path):
    """A German-locale logger: ';' separators, decimal commas, Latin-1 '°C' and 'µm'."""
    rows = ["Zeit [s];Temp (°C);Weg [µm]"] + [
        f"{i},0;{25 + i},5;{-1.5 * i:.1f}".replace(".", ",") for i in range(12)
    ]
    csv = tmp_path / "ofen.csv"
    csv.write_bytes(("\n".join(rows) + "\n").encode("latin-1"))
    res = write_starter("static", csv, tmp_path / "e" / "ofen.toml")
    doc = tomllib.loads(res.path.read_text(encoding="utf-8"))
    assert doc["columns"] == {
        "time_s": {"from": "Zeit [s]", "unit": "s"},
        "temperature_C": {"from": "Temp (°C)", "unit": "degC"},
        "displacement_mm": {"from": "Weg [µm]", "unit": "um"},
    }
    sample = dict(
        SAMPLE, fiber_diameter_mm=0.17, fiber_length_mm=95.0, coil_length_mm=20.0, coil_diameter_mm=0.36
    )
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), sample), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    assert run.data["temperature"].iloc[1] == pytest.approx(26.5)
    assert run.data["displacement"].iloc[2] == pytest.approx(-3e-6)


def test_metadata_block_above_the_header_and_a_headerless_log_with_a_title(tmp_path):
    """Full-width metadata lines above the header, and a title above a header-less log."""
    rows = ["Operator,Jane,2019-06-11", "Sample,TCA 3,50 g", "Time,Voltage,Displacement", "s,V,mm"]
    rows += [f"{0.1 * i:.1f},{10 if i else 0},{-0.01 * i:.3f}" for i in range(12)]
    csv = write(tmp_path / "meta.csv", "\n".join(rows) + "\n")
    layout = inspect_csv(csv)
    assert (layout.header_row, layout.units_row) == (3, 4) and len(layout.title_rows) == 2
    doc = tomllib.loads(starter_text("dynamic", csv, tmp_path / "m.toml"))
    assert doc["columns"]["header_row"] == 3 and doc["columns"]["voltage_V"] == {
        "from": "Voltage",
        "unit": "V",
    }

    rows = ["Vibrometer log 2019-06-11"] + [f"{0.001 * i:.3f},{25 + i},{0.5 * i:.2f}" for i in range(15)]
    csv = write(tmp_path / "vib.csv", "\n".join(rows) + "\n")
    res = write_starter("static", csv, tmp_path / "exp" / "vib.toml")
    text = res.path.read_text(encoding="utf-8")
    assert "header_row = 0" in text and "skip_rows = 1" in text
    sample = dict(
        SAMPLE, fiber_diameter_mm=0.17, fiber_length_mm=95.0, coil_length_mm=20.0, coil_diameter_mm=0.36
    )
    sample |= {"temperature_C.from": 2, "displacement_mm.from": 3}
    res.path.write_text(fill(text, sample), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    assert len(run.data) == 15 and run.data["temperature"].iloc[0] == 25.0  # first data row kept


def test_a_title_that_says_fill_in_is_not_a_placeholder(tmp_path):
    csv = rheometer_csv(tmp_path)
    res = write_starter("sensing", csv, tmp_path / "experiments" / "pull.toml")
    text = fill(res.path.read_text(encoding="utf-8"), SAMPLE).replace(
        'title = "', 'title = "Fill in later: ', 1
    )
    res.path.write_text(text, encoding="utf-8")
    assert load_experiment(res.path).title.startswith("Fill in later")


def test_check_is_a_dry_run_listing_every_problem(tmp_path):
    csv = rheometer_csv(tmp_path)
    res = write_starter("sensing", csv, tmp_path / "experiments" / "pull.toml")
    r = runner.invoke(app, ["check", str(res.path)])
    assert r.exit_code == 2 and "6 values still to fill in" in r.output and "Traceback" not in r.output
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), SAMPLE), encoding="utf-8")
    r = runner.invoke(app, ["check", str(res.path), "--rows", "2"])
    assert r.exit_code == 0, r.output
    out = r.output
    assert "displacement_mm  <- 'Gap' [um] -> displacement [m]" in out
    assert "force_N          <- 'Axial force' [N, scale -1] -> force [N]" in out
    assert "first rows in SI: displacement [m], force [N], resistance [ohm], time [s]" in out
    assert "    2e-05, 0.005, 30.02, 0.5\n" in out  # row 2 in SI: 20 µm, a 5 mN pull, at 0.5 s
    assert "sample.coil_length = 90 mm  (experiment file)" in out and "no problems found" in out
    assert not list((tmp_path / "experiments").glob("*.html"))  # writes nothing
    # two broken runs: both problems listed, not only the first
    bad = csv.with_name("bad.csv")
    bad.write_text(csv.read_text().replace("0.5,1020.0", "0.5,abc"))
    bad.with_name("bad2.csv").write_text(bad.read_text())
    text = res.path.read_text(encoding="utf-8").replace(
        'runs = ["../raw/pull1.csv"]', 'runs = ["../raw/bad.csv", "../raw/pull1.csv", "../raw/bad2.csv"]'
    )
    res.path.write_text(text, encoding="utf-8")
    r = runner.invoke(app, ["check", str(res.path)])
    assert r.exit_code == 2 and r.output.count("problem: ") == 2 and "non-numeric value 'abc'" in r.output
    assert "pull1.csv: 12 rows" in r.output


def test_the_own_data_guide_defines_every_parameter():
    """docs/own_data.md lists every key the starter explains, so the two cannot drift apart."""
    from tcamlab.starter import GUIDE

    text = (Path(__file__).resolve().parents[1] / "docs" / "own_data.md").read_text(encoding="utf-8")
    for key, g in GUIDE.items():
        assert f"| `{key}`" in text and g.definition in text, key


def test_unknown_channels_are_listed_not_guessed(tmp_path):
    rows = ["Time [s],Torque [µNm],T,Extension (µm),Normal stress [Pa]"]
    rows += [f"{0.1 * i:.1f},{0.5 * i},{25 + i},{10.0 * i},{100 * i}" for i in range(12)]
    csv = write(tmp_path / "rheo.csv", "\n".join(rows) + "\n")
    r = runner.invoke(app, ["init", "static", "--csv", str(csv), "--out", str(tmp_path / "o.toml")])
    assert r.exit_code == 0, r.output
    assert "not used: 'Torque [µNm]' (column 2), 'Normal stress [Pa]' (column 5)" in r.output
    cols = tomllib.loads((tmp_path / "o.toml").read_text(encoding="utf-8"))["columns"]
    assert cols["temperature_C"] == {"from": "T", "unit": "degC"} and cols["time_s"]["from"] == "Time [s]"


def test_a_self_sensing_log_with_the_load_in_grams_maps_it_as_a_force(tmp_path):
    """A powered-muscle log whose load cell reads in grams ("Load (g)") and current in mA: the
    load is mapped to load_N as gram-force (50 g reads 0.49 N), not left unused."""
    rows = ["Time (s),Voltage (V),Current (mA),Load (g),Displacement (mm)"]
    rows += [f"{0.01 * i:.2f},1.5,{35.0 + 0.01 * i:.2f},50.0,{0.001 * i:.3f}" for i in range(12)]
    csv = write(tmp_path / "raw" / "ss.csv", "\n".join(rows) + "\n")
    res = write_starter("selfsensing", csv, tmp_path / "experiments" / "ss.toml")
    cols = tomllib.loads(res.path.read_text(encoding="utf-8"))["columns"]
    assert cols["load_N"] == {"from": "Load (g)", "unit": "gf"}
    assert cols["current_A"] == {"from": "Current (mA)", "unit": "mA"}
    assert convert(50.0, cols["load_N"]["unit"], "N") == pytest.approx(0.49033, rel=1e-4)
    # a muscle's S is required (no log gives it): a value to fill in, not a commented-out line
    rig = tomllib.loads(res.path.read_text(encoding="utf-8"))["rig"]
    assert rig["spring_constant_N_per_m"] == "FILL IN: N/m"


def test_pull_tester_headers_with_units_in_them(tmp_path):
    """A pull tester's export: units in the headers ("Extension (µm)", "Load [mN]", "R (Ohm)")
    and in a spelling per column; every channel mapped with its unit, read in SI once filled."""
    rows = ["Time [s],Extension (µm),Load [mN],R (Ohm)"]
    rows += [f"{0.5 * i:.1f},{50.0 * i:.1f},{0.235 * i:.4f},{30 + 0.01 * i:.3f}" for i in range(12)]
    csv = write(tmp_path / "raw" / "pull.csv", "\n".join(rows) + "\n")
    res = write_starter("sensing", csv, tmp_path / "experiments" / "pull.toml")
    cols = tomllib.loads(res.path.read_text(encoding="utf-8"))["columns"]
    assert cols == {
        "time_s": {"from": "Time [s]", "unit": "s"},
        "displacement_mm": {"from": "Extension (µm)", "unit": "um"},
        "force_N": {"from": "Load [mN]", "unit": "mN"},
        "resistance_ohm": {"from": "R (Ohm)", "unit": "ohm"},
    }
    res.path.write_text(fill(res.path.read_text(encoding="utf-8"), SAMPLE), encoding="utf-8")
    (run,) = load_experiment(res.path).read_runs()
    # 50 µm and 0.235 mN per row: S = 4.7 N/m, the thesis sensor's
    np.testing.assert_allclose(run.data["displacement"].to_numpy()[:2], [0.0, 50e-6], atol=1e-15)
    np.testing.assert_allclose(run.data["force"].to_numpy()[:2], [0.0, 0.235e-3], atol=1e-15)
    assert run.data["resistance"].iloc[1] == pytest.approx(30.01)


def test_check_applies_the_runs_rules_and_flags_channels_beyond_a_muscle(tmp_path):
    """What validate refuses per run (a dynamic load of 0) is a problem in check too, and a voltage
    logged in mV but read as V (up to 10,000 V) is a warning naming the likely unit."""
    from tcamlab.starter import check_experiment

    rows = ["time_s,voltage_V,displacement_mm"] + [
        f"{0.1 * i:.1f},{10000 if i > 2 else 0},0" for i in range(30)
    ]
    write(tmp_path / "raw" / "step.csv", "\n".join(rows) + "\n")
    body = 'kind = "dynamic"\ntitle = "t"\nruns = ["../raw/step.csv"]\n[sample]\npreset = "thesis-tca"\n'
    exp = write(tmp_path / "experiments" / "e.toml", body + "[rig]\nload_g = 0\n")
    report = check_experiment(exp)
    assert any("rig load_g = 0 g" in p and "load_g = 50" in p for p in report.problems), report.problems
    assert any("voltage reaches 1e+04 V" in w and 'unit = "mV"' in w for w in report.warnings), (
        report.warnings
    )
    exp.write_text(body + "[rig]\nload_g = 50\n", encoding="utf-8")
    assert check_experiment(exp).problems == []


def test_check_refuses_a_self_sensing_log_sampled_slower_than_the_muscle_heats(tmp_path):
    """A time column in ms read as s puts the rows 10 s apart, beyond the thermal time constant
    C_th/lambda (3 s): the estimator cannot follow it, so check names the time unit."""
    import pandas as pd

    from tcamlab.starter import check_experiment

    root = Path(__file__).resolve().parent.parent
    frame = pd.read_csv(root / "raw" / "selfsensing_run1.csv")
    frame["time_s"] = frame["time_s"] * 1000.0
    (tmp_path / "raw").mkdir()
    frame.to_csv(tmp_path / "raw" / "run.csv", index=False)
    text = (root / "experiments" / "selfsensing.toml").read_text()
    text = text.replace(text.split("\n")[2], 'runs = ["../raw/run.csv"]')
    exp = write(tmp_path / "experiments" / "ss.toml", text)
    problems = check_experiment(exp).problems
    assert any("rows are 10 s apart" in p and 'unit = "ms"' in p for p in problems), problems


def test_a_text_column_beside_the_data_does_not_hide_the_rows(tmp_path):
    """An oven log with an operator's initials on every row was "no data rows found"; its rows
    are data (most cells numbers), the text column is listed as not used."""
    rows = ["# Oven rig 3", "Extension (um),operator,Temp (F),t (ms)"]
    rows += [f"{-26.0 * i:.1f},JS,{77.0 + 9.4 * i:.2f},{300000 * i}" for i in range(12)]
    csv = write(tmp_path / "raw" / "oven.csv", "\n".join(rows) + "\n")
    res = write_starter("static", csv, tmp_path / "experiments" / "oven.toml")
    cols = tomllib.loads(res.path.read_text(encoding="utf-8"))["columns"]
    assert cols["temperature_C"] == {"from": "Temp (F)", "unit": "degF"}
    assert cols["displacement_mm"] == {"from": "Extension (um)", "unit": "um"}
    assert "'operator' (column 2)" in res.path.read_text(encoding="utf-8")


def test_check_warns_when_the_stated_step_voltage_is_no_runs_voltage(tmp_path):
    """validate drives the dynamic model with the logged voltage: a stated voltage_V of 0 or 20 V
    beside runs at 10 V changed no figure and passed check without a word."""
    from tcamlab.starter import check_experiment

    rows = ["time_s,voltage_V,displacement_mm"] + [
        f"{0.1 * i:.1f},{10 if 2 < i < 12 else 0},0" for i in range(30)
    ]
    write(tmp_path / "raw" / "step.csv", "\n".join(rows) + "\n")
    body = 'kind = "dynamic"\ntitle = "t"\nruns = ["../raw/step.csv"]\n[sample]\npreset = "thesis-tca"\n'
    for volts, warned in ((0.0, True), (20.0, True), (10.2, False)):
        exp = write(tmp_path / "experiments" / "e.toml", body + f"[rig]\nload_g = 50\nvoltage_V = {volts}\n")
        hits = [w for w in check_experiment(exp).warnings if "is the peak voltage of no run" in w]
        assert bool(hits) is warned, (volts, hits)
        assert not hits or "logged peaks: 10 V" in hits[0]


def test_check_warns_when_an_oven_log_starts_far_below_the_stated_ambient(tmp_path):
    """ambient_C = 100 beside an oven log from 25 degC: every modelled rise counts from ambient,
    and validate gave R² 0.65 without a word on it."""
    from tcamlab.starter import check_experiment

    rows = ["time_s,temperature_C,displacement_mm"] + [
        f"{60 * i},{25 + 5 * i},{-0.01 * i}" for i in range(20)
    ]
    write(tmp_path / "raw" / "oven.csv", "\n".join(rows) + "\n")
    body = 'kind = "static"\ntitle = "t"\nruns = ["../raw/oven.csv"]\n[sample]\npreset = "thesis-tca"\n'
    for ambient, warned in ((100.0, True), (20.0, False), (30.0, False)):
        exp = write(
            tmp_path / "experiments" / "e.toml", body + f"[rig]\nload_g = 50\nambient_C = {ambient}\n"
        )
        hits = [w for w in check_experiment(exp).warnings if "below the stated ambient_C" in w]
        assert bool(hits) is warned, (ambient, hits)
        assert not hits or "falls to 25 degC, 75 K below" in hits[0]


def test_a_german_testing_machine_export_maps_strain_and_force(tmp_path):
    # semicolons, decimal commas, German headers: "Dehnung [%]" is a strain of the coil length
    rows = ["Zeit [s];Standardkraft [N];Dehnung [%];Widerstand [Ohm]"]
    rows += [
        f"{i * 0.1:.1f};{0.01 * i:.3f};{0.5 * i:.2f};{30 + 0.01 * i:.3f}".replace(".", ",") for i in range(15)
    ]
    csv = write(tmp_path / "zug.csv", "\n".join(rows) + "\n")
    res = write_starter("sensing", csv, tmp_path / "e" / "zug.toml")
    cols = tomllib.loads(res.path.read_text(encoding="utf-8"))["columns"]
    assert cols["force_N"]["from"] == "Standardkraft [N]"
    assert cols["displacement_mm"]["from"] == "Dehnung [%]"
    assert "columns.displacement_mm.scale" in res.placeholders
