"""Tests of tcamlab.io: CSV ingestion, unit conversion and input errors."""

from __future__ import annotations

import hashlib
import math
import shutil
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tcamlab import io as tio
from tcamlab.errors import InputError
from tcamlab.io import (
    MIN_ROWS,
    OPTIONAL,
    REQUIRED,
    UNITS,
    VARIABLE_MAP,
    canonical_to_internal,
    convert,
    internal_to_canonical,
    read_run,
    sha256_file,
)

DATA = Path(__file__).parent / "data" / "io"
RTOL = 1e-12


def write(tmp_path: Path, text: str, name: str = "run.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode("utf-8"))
    return p


def dynamic_text(n: int = 12, header: str = "time_s,voltage_V,displacement_mm") -> str:
    rows = [header] + [f"{i * 0.1:.1f},{10 if i else 0},{-0.01 * i:.3f}" for i in range(n)]
    return "\n".join(rows) + "\n"


def raises_input(match_parts, func, *args, **kwargs) -> InputError:
    with pytest.raises(InputError) as info:
        func(*args, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg, msg
    for part in match_parts:
        assert part in msg, f"{part!r} not in {msg!r}"
    return info.value


# --- mapping and units -----------------------------------------------------------


def test_every_canonical_column_is_mapped_with_a_known_unit():
    for kind in REQUIRED:
        for canon in REQUIRED[kind] + OPTIONAL[kind]:
            name, unit = VARIABLE_MAP[canon]
            assert unit in UNITS
            assert canon.startswith(name) or name in ("r1", "r2")
    assert set(MIN_ROWS) == set(REQUIRED) == set(OPTIONAL)


@pytest.mark.parametrize(
    "value, unit, to, expected",
    [
        (1500.0, "ms", "s", 1.5),
        (250.0, "us", "s", 250e-6),
        (2.0, "min", "s", 120.0),
        (212.0, "degF", "degC", 100.0),
        (-40.0, "degF", "degC", -40.0),
        (32.0, "degF", "degC", 0.0),
        (300.0, "K", "degC", 26.85),
        (0.0, "K", "degC", -273.15),
        (125.0, "um", "m", 125e-6),
        (2.5, "mm", "m", 2.5e-3),
        (1.0, "in", "m", 0.0254),
        (4.7, "kohm", "ohm", 4700.0),
        (250.0, "mohm", "ohm", 0.25),
        (2.0, "Mohm", "ohm", 2e6),
        (50.0, "gf", "N", 50 * 9.80665e-3),
        (1.0, "kgf", "N", 9.80665),
        (50.0, "g", "N", 50 * 9.80665e-3),  # a load cell read out in grams
        (0.05, "kg", "N", 0.05 * 9.80665),
        (1.0, "lbf", "N", 4.4482216152605),
        (3.0, "mN", "N", 3e-3),
        (2.0, "per_mm", "per_m", 2000.0),
        (2.0, "per_cm", "per_m", 200.0),
        (100.0, "degC", "degF", 212.0),
        (1.5, "s", "ms", 1500.0),
    ],
)
def test_convert_exact_values(value, unit, to, expected):
    np.testing.assert_allclose(convert(value, unit, to), expected, rtol=RTOL, atol=1e-12)


def test_convert_rejects_wrong_dimension_and_unknown_unit():
    with pytest.raises(ValueError, match="cannot convert"):
        convert(1.0, "ms", "m")
    with pytest.raises(ValueError, match="unknown unit"):
        convert(1.0, "furlong", "m")


def test_canonical_internal_round_trip():
    df = pd.DataFrame(
        {
            "time_s": [0.0, 1.0],
            "temperature_C": [20.0, 80.0],
            "displacement_mm": [0.0, -1.5],
            "kappa1_per_mm": [0.0, 0.02],
            "cable_mm": [0.0, 3.0],
            "extra": ["a", "b"],
        }
    )
    internal = canonical_to_internal(df)
    assert list(internal.columns) == ["time", "temperature", "displacement", "kappa1", "cable", "extra"]
    np.testing.assert_allclose(internal["displacement"], [0.0, -1.5e-3], rtol=RTOL)
    np.testing.assert_allclose(internal["kappa1"], [0.0, 20.0], rtol=RTOL)
    np.testing.assert_allclose(internal["cable"], [0.0, 3e-3], rtol=RTOL)
    np.testing.assert_allclose(internal["temperature"], [20.0, 80.0], rtol=RTOL)
    back = internal_to_canonical(internal)
    assert list(back.columns) == list(df.columns)
    for col in df.columns[:-1]:
        np.testing.assert_allclose(back[col], df[col], rtol=RTOL, atol=1e-15)


# --- happy paths -------------------------------------------------------------------


def test_read_dynamic_canonical(tmp_path):
    p = write(tmp_path, dynamic_text())
    run = read_run(p, "dynamic")
    assert list(run.data.columns) == ["time", "voltage", "displacement"]
    assert all(dt == np.float64 for dt in run.data.dtypes)
    assert isinstance(run.data.index, pd.RangeIndex)
    assert run.n_rows_raw == 12 and run.n_dropped == 0
    np.testing.assert_allclose(run.data["displacement"].iloc[-1], -0.11e-3, rtol=RTOL)
    np.testing.assert_allclose(run.data["time"].iloc[-1], 1.1, rtol=RTOL)
    assert run.source_columns == {"time": "time_s", "voltage": "voltage_V", "displacement": "displacement_mm"}
    assert run.sha256 == hashlib.sha256(p.read_bytes()).hexdigest()
    assert run.kind == "dynamic" and run.path == p


def test_optional_columns_are_read_when_present(tmp_path):
    text = "time_s,voltage_V,displacement_mm,current_A,temperature_C,unused\n" + "".join(
        f"{i},{5},{0.01 * i},{0.2},{20 + i},x\n" for i in range(10)
    )
    run = read_run(write(tmp_path, text), "dynamic")
    assert set(run.data.columns) == {"time", "voltage", "displacement", "current", "temperature"}


def test_foreign_headers_mapped_to_si():
    columns = {
        "time_s": {"from": "reltime", "unit": "ms"},
        "temperature_C": {"from": "Temp (F)", "unit": "degF"},
        "displacement_mm": {"from": "laser", "scale": 0.01, "offset": -2.5},
        "voltage_V": "volts",
    }
    run = read_run(DATA / "foreign_headers.csv", "dynamic", columns)
    i = np.arange(12)
    np.testing.assert_allclose(run.data["time"], i * 0.5, rtol=RTOL)
    np.testing.assert_allclose(run.data["temperature"], (68 + 18 * i - 32) * 5 / 9, rtol=RTOL)
    # laser = 250 - 3 i counts -> (0.01 * counts - 2.5) mm = -0.03 i mm
    np.testing.assert_allclose(run.data["displacement"], -0.03e-3 * i, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(run.data["voltage"], np.where(i >= 2, 10.0, 0.0), rtol=RTOL)
    assert run.source_columns["temperature"] == "Temp (F)"
    assert run.header_line == 3


@pytest.mark.parametrize(
    "header, unit, raw, expected_si, canon",
    [
        ("t_ms", "ms", [0, 1500, 3000], [0.0, 1.5, 3.0], "time_s"),
        ("T_K", "K", [293.15, 353.15, 373.15], [20.0, 80.0, 100.0], "temperature_C"),
        ("T_F", "degF", [32, 212, 392], [0.0, 100.0, 200.0], "temperature_C"),
        ("d_um", "um", [0, -150, -300], [0.0, -150e-6, -300e-6], "displacement_mm"),
    ],
)
def test_static_unit_conversion_in_columns(tmp_path, header, unit, raw, expected_si, canon):
    base = {"time_s": [0, 1, 2], "temperature_C": [20, 60, 100], "displacement_mm": [0, -1, -2]}
    base[canon] = raw
    headers = {c: (header if c == canon else c) for c in base}
    text = (
        ",".join(headers.values())
        + "\n"
        + "".join(",".join(str(base[c][k]) for c in base) + "\n" for k in range(3))
    )
    run = read_run(write(tmp_path, text), "static", {canon: {"from": header, "unit": unit}})
    np.testing.assert_allclose(run.data[VARIABLE_MAP[canon][0]], expected_si, rtol=RTOL, atol=1e-12)


def test_sensing_units_kohm_and_gf(tmp_path):
    text = "d,F (gf),R (kohm)\n0,0,1.5\n1,10,1.6\n2,20,1.7\n"
    columns = {
        "displacement_mm": "d",
        "force_N": {"from": "F (gf)", "unit": "gf"},
        "resistance_ohm": {"from": "R (kohm)", "unit": "kohm"},
    }
    run = read_run(write(tmp_path, text), "sensing", columns)
    np.testing.assert_allclose(run.data["force"], [0.0, 10 * 9.80665e-3, 20 * 9.80665e-3], rtol=RTOL)
    np.testing.assert_allclose(run.data["resistance"], [1500.0, 1600.0, 1700.0], rtol=RTOL)
    np.testing.assert_allclose(run.data["displacement"], [0.0, 1e-3, 2e-3], rtol=RTOL)


def test_curvature_kind(tmp_path):
    text = "cable_mm,r1_ohm,r2_ohm,kappa1_per_mm,kappa2_per_mm\n0,10,10,0,0\n2,10.5,10.2,0.01,0.005\n"
    run = read_run(write(tmp_path, text), "curvature")
    np.testing.assert_allclose(run.data["kappa1"], [0.0, 10.0], rtol=RTOL)
    np.testing.assert_allclose(run.data["cable"], [0.0, 2e-3], rtol=RTOL)


def test_bom_and_comment_lines():
    run = read_run(DATA / "bom_comments.csv", "sensing")
    assert run.header_line == 3
    assert list(run.data.columns) == ["displacement", "force", "resistance"]
    # a -0.4 mN reading at zero load is data, not a wrong sign
    np.testing.assert_allclose(run.data["force"], [-0.0004, 0.05, 0.11, 0.16], rtol=RTOL)


def test_latin1_header_with_degree_sign():
    columns = {
        "temperature_C": {"from": "Temp (\u00b0F)", "unit": "degF"},
        "displacement_mm": "L\u00e4nge (mm)",
    }
    run = read_run(DATA / "latin1_degF.csv", "static", columns)
    np.testing.assert_allclose(run.data["temperature"], [0.0, 100.0, 200.0], rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(run.data["displacement"], [0.0, -1.5e-3, -3.25e-3], rtol=RTOL)


def test_semicolon_with_decimal_comma_and_crlf():
    run = read_run(DATA / "semicolon_decimal_comma.csv", "static")
    np.testing.assert_allclose(run.data["temperature"], [20.5, 40.0, 60.25], rtol=RTOL)
    np.testing.assert_allclose(run.data["displacement"], [0.0, -0.125e-3, -0.5e-3], rtol=RTOL)
    np.testing.assert_allclose(run.data["time"], [0.0, 1.5, 3.0], rtol=RTOL)


def test_semicolon_with_decimal_point(tmp_path):
    text = "temperature_C;displacement_mm\n20.5;0\n40;-0.25\n60;-0.5\n"
    run = read_run(write(tmp_path, text), "static")
    np.testing.assert_allclose(run.data["temperature"], [20.5, 40.0, 60.0], rtol=RTOL)


def test_tab_separated(tmp_path):
    text = "temperature_C\tdisplacement_mm\n20\t0\n40\t-0.25\n60\t-0.5\n"
    run = read_run(write(tmp_path, text), "static")
    np.testing.assert_allclose(run.data["displacement"], [0.0, -0.25e-3, -0.5e-3], rtol=RTOL)


def test_displacement_is_rezeroed_to_first_row(tmp_path):
    text = "temperature_C,displacement_mm\n20,12.0\n40,11.5\n60,11.0\n"
    run = read_run(write(tmp_path, text), "static")
    np.testing.assert_allclose(run.data["displacement"], [0.0, -0.5e-3, -1.0e-3], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(run.displacement_zero, 12e-3, rtol=RTOL)


def test_trailing_blank_lines_are_ignored(tmp_path):
    run = read_run(write(tmp_path, dynamic_text() + "\n\n  \n"), "dynamic")
    assert run.n_rows_raw == 12 and run.n_dropped == 0


def test_quoted_headers_and_whitespace(tmp_path):
    text = '"temperature_C", "displacement_mm"\n 20 , 0 \n40, -0.5\n60,-1\n'
    run = read_run(write(tmp_path, text), "static")
    np.testing.assert_allclose(run.data["temperature"], [20.0, 40.0, 60.0], rtol=RTOL)


def test_raw_file_bytes_unchanged(tmp_path):
    src = DATA / "foreign_headers.csv"
    p = tmp_path / "copy.csv"
    shutil.copyfile(src, p)
    before = p.read_bytes()
    h_before = sha256_file(p)
    mtime = p.stat().st_mtime_ns
    run = read_run(
        p,
        "dynamic",
        {
            "time_s": {"from": "reltime", "unit": "ms"},
            "voltage_V": "volts",
            "displacement_mm": "laser",
            "temperature_C": {"from": "Temp (F)", "unit": "degF"},
        },
    )
    assert p.read_bytes() == before
    assert sha256_file(p) == h_before == run.sha256 == hashlib.sha256(before).hexdigest()
    assert p.stat().st_mtime_ns == mtime


def test_large_file_parses(tmp_path):
    n = 200_000
    t = np.arange(n) / 1000.0
    df = pd.DataFrame(
        {
            "time_s": t,
            "voltage_V": np.where(t % 2 < 1, 10.0, 0.0),
            "displacement_mm": -0.5 * np.sin(t),
            "temperature_C": 20 + np.cos(t),
        }
    )
    p = tmp_path / "big.csv"
    df.to_csv(p, index=False, float_format="%.6f")
    run = read_run(p, "dynamic")
    assert len(run.data) == n
    np.testing.assert_allclose(run.data["time"].to_numpy(), t, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(run.data["displacement"].to_numpy(), -0.5e-3 * np.sin(t), atol=1e-9)


# --- errors --------------------------------------------------------------------------


def test_missing_file(tmp_path):
    p = tmp_path / "nope.csv"
    raises_input([str(p), "not found"], read_run, p, "static")


def test_empty_file(tmp_path):
    p = write(tmp_path, "")
    raises_input([str(p), "empty"], read_run, p, "static")
    p2 = write(tmp_path, "\n  \n\n", "blank.csv")
    raises_input([str(p2), "empty"], read_run, p2, "static")


def test_comments_only(tmp_path):
    p = write(tmp_path, "# just metadata\n# more\n")
    raises_input([str(p), "no header line"], read_run, p, "static")


def test_header_only(tmp_path):
    p = write(tmp_path, "# meta\ntemperature_C,displacement_mm\n")
    raises_input([str(p), "line 2", "no data rows"], read_run, p, "static")


def test_missing_required_column_did_you_mean(tmp_path):
    p = write(tmp_path, dynamic_text(header="time_s,voltage_V,displacment_mm"))
    err = raises_input([str(p), "line 1", "'displacement_mm'"], read_run, p, "dynamic")
    # The hint proposes the mapping (valid TOML), not the typo as the column's name.
    assert "did you mean" not in str(err)
    line = 'displacement_mm = { from = "displacment_mm" }'
    assert line in err.hint and "[columns]" in err.hint
    assert tomllib.loads(line) == {"displacement_mm": {"from": "displacment_mm"}}


def test_missing_mapped_column(tmp_path):
    p = write(tmp_path, dynamic_text())
    raises_input(
        [str(p), "'reltime'", "time_s"], read_run, p, "dynamic", {"time_s": {"from": "reltime", "unit": "ms"}}
    )


def test_a_missing_column_hint_carries_the_unit_its_near_header_names(tmp_path):
    # "voltage_mV" holds the voltage in mV: the proposed line must say so, or the column
    # would be read in V, 1000 x off, without a word
    p = write(tmp_path, dynamic_text(header="time_s,voltage_mV,displacement_mm"))
    err = raises_input(["the file has 'voltage_mV'"], read_run, p, "dynamic")
    line = str(err).split("[columns] as ", 1)[1].rstrip(")")
    assert line == 'voltage_V = { from = "voltage_mV", unit = "mV" }'
    entry = tomllib.loads(line)["voltage_V"]
    frame = read_run(p, "dynamic", {"voltage_V": entry}).data
    assert frame["voltage"].iloc[1] == pytest.approx(0.010)
    # a header in the canonical unit needs none
    p = write(tmp_path, dynamic_text(header="time_s,volt_V,displacement_mm"), "b.csv")
    err = raises_input(["the file has 'volt_V'"], read_run, p, "dynamic")
    assert str(err).endswith('voltage_V = { from = "volt_V" })')


def test_unknown_columns_key_and_bad_unit(tmp_path):
    p = write(tmp_path, dynamic_text())
    raises_input(["'force_N' is not a column of a dynamic run"], read_run, p, "dynamic", {"force_N": "F"})
    raises_input(["did you mean 'time_s'"], read_run, p, "dynamic", {"tme_s": "t"})
    raises_input(
        ["'ms' is a time unit", "temperature"],
        read_run,
        p,
        "dynamic",
        {"temperature_C": {"from": "T", "unit": "ms"}},
    )
    raises_input(
        ["unknown unit 'fortnight'"],
        read_run,
        p,
        "dynamic",
        {"time_s": {"from": "time_s", "unit": "fortnight"}},
    )
    raises_input(
        ["unknown key 'units'", "did you mean 'unit'"],
        read_run,
        p,
        "dynamic",
        {"time_s": {"from": "time_s", "units": "ms"}},
    )


def test_unknown_kind(tmp_path):
    p = write(tmp_path, dynamic_text())
    raises_input(["unknown run kind 'dynamo'"], read_run, p, "dynamo")


def test_duplicate_header(tmp_path):
    p = write(tmp_path, "temperature_C,displacement_mm,temperature_C\n1,2,3\n2,3,4\n3,4,5\n")
    raises_input([str(p), "'temperature_C' appears in columns 1, 3"], read_run, p, "static")


def test_non_numeric_cell_names_line_and_column(tmp_path):
    lines = dynamic_text().splitlines()
    lines[5] = "0.5,10,oops"  # editor line 6 of the data block; 2 comment lines shift it
    p = write(tmp_path, "# a\n# b\n" + "\n".join(lines) + "\n")
    raises_input([str(p), "line 8", "column 'displacement_mm'", "'oops'"], read_run, p, "dynamic")


def test_non_numeric_first_bad_across_columns(tmp_path):
    lines = dynamic_text().splitlines()
    lines[7] = "0.7,10,bad2"
    lines[4] = "0.4,ten,-0.04"
    p = write(tmp_path, "\n".join(lines) + "\n")
    raises_input(["line 5", "column 'voltage_V'", "'ten'"], read_run, p, "dynamic")


def test_comment_after_header_is_reported(tmp_path):
    lines = dynamic_text().splitlines()
    lines.insert(3, "# pause")
    p = write(tmp_path, "\n".join(lines) + "\n")
    raises_input(["line 4", "'# pause'"], read_run, p, "dynamic")


def test_blank_cells_error_and_drop_na(tmp_path):
    lines = dynamic_text(14).splitlines()
    lines[3] = "0.2,10,"  # blank cell, line 4
    lines[6] = "0.5,NaN,-0.05"  # NaN, line 7
    lines[9] = ""  # blank line, line 10
    p = write(tmp_path, "\n".join(lines) + "\n")
    err = raises_input(
        [str(p), "line 4", "column 'displacement_mm'", "blank or NaN", "3 rows"], read_run, p, "dynamic"
    )
    assert "drop_na" in err.hint
    run = read_run(p, "dynamic", drop_na=True)
    assert run.n_rows_raw == 14
    assert run.n_dropped == 3
    assert len(run.data) == 11
    assert isinstance(run.data.index, pd.RangeIndex)
    assert not run.data.isna().any().any()


def test_whitespace_only_cell_counts_as_blank(tmp_path):
    lines = dynamic_text().splitlines()
    lines[3] = "0.2,  ,-0.02"
    p = write(tmp_path, "\n".join(lines) + "\n")
    raises_input(["line 4", "column 'voltage_V'", "blank"], read_run, p, "dynamic")
    assert read_run(p, "dynamic", drop_na=True).n_dropped == 1


def test_drop_na_leaving_too_few_rows(tmp_path):
    p = write(tmp_path, "temperature_C,displacement_mm\n20,0\n,1\n40,\n60,-1\n")
    raises_input(["only 2 usable data rows", "2 dropped", "at least 3"], read_run, p, "static", drop_na=True)


@pytest.mark.parametrize("bad, word", [("0.3", "duplicated"), ("0.1", "decreasing")])
def test_time_not_increasing(tmp_path, bad, word):
    lines = dynamic_text().splitlines()
    lines[5] = f"{bad},10,-0.04"  # line 6, after 0.3 on line 5
    p = write(tmp_path, "\n".join(lines) + "\n")
    raises_input([str(p), "line 6", "column 'time_s'", word, "line 5"], read_run, p, "dynamic")


def test_time_not_finite(tmp_path):
    lines = dynamic_text().splitlines()
    lines[4] = "inf,10,-0.03"
    p = write(tmp_path, "\n".join(lines) + "\n")
    raises_input([str(p), "line 5", "column 'time_s'", "non-finite"], read_run, p, "dynamic")


def test_file_too_large(tmp_path):
    p = write(tmp_path, dynamic_text())
    err = raises_input([str(p), "larger than the limit"], read_run, p, "dynamic", max_bytes=50)
    assert "max_bytes" in err.hint
    assert tio.DEFAULT_MAX_BYTES == 2 * 1024**3


def test_negative_resistance(tmp_path):
    p = write(tmp_path, "displacement_mm,force_N,resistance_ohm\n0,0,30\n1,0.1,-30.5\n2,0.2,31\n")
    raises_input([str(p), "line 3", "column 'resistance_ohm'", "negative resistance"], read_run, p, "sensing")
    p2 = write(
        tmp_path, "cable_mm,r1_ohm,r2_ohm,kappa1_per_mm,kappa2_per_mm\n0,10,10,0,0\n1,10,-1,0,0\n", "curv.csv"
    )
    raises_input([str(p2), "line 3", "column 'r2_ohm'"], read_run, p2, "curvature")


def test_temperature_below_absolute_zero(tmp_path):
    p = write(tmp_path, "T,displacement_mm\n20,0\n-10,-1\n40,-2\n")
    raises_input(
        [str(p), "line 3", "column 'T' (temperature_C)", "below absolute zero"],
        read_run,
        p,
        "static",
        {"temperature_C": {"from": "T", "unit": "K"}},
    )


def test_a_hanging_load_that_does_not_pull(tmp_path):
    rows = ["time_s,voltage_V,displacement_mm,load_N"] + [f"{0.1 * i:.1f},0,0,{-0.49:.2f}" for i in range(30)]
    p = write(tmp_path, "\n".join(rows) + "\n", "dyn.csv")
    err = raises_input(
        [str(p), "column 'load_N'", "averages -0.49 N", "must be positive"], read_run, p, "dynamic"
    )
    assert "scale = -1" in err.hint
    # the suggested fix works: the weight reads back as 0.49 N
    run = read_run(p, "dynamic", tomllib.loads(err.hint.rsplit(" as ", 1)[1]))
    assert run.data["load"].iloc[0] == pytest.approx(0.49)
    zero = write(tmp_path, "\n".join(r.replace("-0.49", "0.00") for r in rows) + "\n", "zero.csv")
    err = raises_input([str(zero), "averages 0 N"], read_run, zero, "dynamic")
    assert "load_g" in err.hint
    # an oven test's coil may hang free (zero), never pushed
    static = ["time_s,temperature_C,displacement_mm,load_N"] + [f"{i},{25 + i},0,{{}}" for i in range(30)]
    free = write(tmp_path, "\n".join(static).format(*["0"] * 30) + "\n", "free.csv")
    assert read_run(free, "static").data["load"].max() == 0.0
    pushed = write(tmp_path, "\n".join(static).format(*["-0.2"] * 30) + "\n", "pushed.csv")
    raises_input([str(pushed), "column 'load_N'", "at least 0"], read_run, pushed, "static")


def test_pull_force_of_wrong_sign(tmp_path):
    rows = ["displacement_mm,force_N,resistance_ohm", "0,0.0004,30"] + [
        f"{i},{-0.05 * i},{30 + 0.5 * i}" for i in range(1, 8)
    ]
    p = write(tmp_path, "\n".join(rows) + "\n")
    err = raises_input([str(p), "column 'force_N'", "negative force"], read_run, p, "sensing")
    assert "scale = -1" in err.hint
    # the suggested fix works
    run = read_run(p, "sensing", {"force_N": {"from": "force_N", "scale": -1}})
    assert run.data["force"].iloc[-1] > 0


def test_pull_force_small_negative_offset_is_data(tmp_path):
    # offset of -0.4 mN everywhere, loaded rows mostly positive
    rows = ["displacement_mm,force_N,resistance_ohm", "0,-0.0004,30", "0.5,-0.0004,30.1"] + [
        f"{i},{0.05 * i - 0.0004},{30 + 0.5 * i}" for i in range(1, 8)
    ]
    run = read_run(write(tmp_path, "\n".join(rows) + "\n"), "sensing")
    assert len(run.data) == 9


@pytest.mark.parametrize("kind", sorted(MIN_ROWS))
def test_run_too_short(tmp_path, kind):
    cols = REQUIRED[kind]
    n = MIN_ROWS[kind] - 1
    rows = [",".join(cols)] + [",".join(str(float(i + 1)) for _ in cols) for i in range(n)]
    p = write(tmp_path, "\n".join(rows) + "\n")
    raises_input([str(p), f"only {n} usable data row", f"at least {MIN_ROWS[kind]}"], read_run, p, kind)


def test_utf16_is_refused(tmp_path):
    p = tmp_path / "u16.csv"
    p.write_bytes("temperature_C,displacement_mm\n1,2\n".encode("utf-16"))
    raises_input([str(p), "UTF-16"], read_run, p, "static")


def test_messages_are_one_line_with_hint(tmp_path):
    p = write(tmp_path, dynamic_text(header="time_s,voltage_V,disp"))
    with pytest.raises(InputError) as info:
        read_run(p, "dynamic")
    assert info.value.hint
    assert "\n" not in info.value.one_line()


# --- property test -----------------------------------------------------------------

_cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64).map(repr),
    st.integers(-(10**6), 10**6).map(str),
    st.sampled_from(
        [
            "",
            " ",
            "NaN",
            "nan",
            "NA",
            "inf",
            "-inf",
            "1e400",
            "abc",
            "#",
            '"',
            "1,5",
            ";",
            "\t",
            "0x10",
            "1_000",
            "--1",
            "+2",
            ".5",
            "5.",
            "1e-3",
            "°",
            "\u00e4",
            "\x00",
        ]
    ),
    st.text(max_size=4),
)


@st.composite
def _csv_texts(draw):
    kind = draw(st.sampled_from(sorted(REQUIRED)))
    cols = list(REQUIRED[kind]) + draw(
        st.lists(st.sampled_from(OPTIONAL[kind] + ("junk",)), max_size=2, unique=True)
    )
    if draw(st.booleans()):
        cols = draw(st.permutations(cols))
    if draw(st.integers(0, 9)) == 0:
        cols = cols[:-1]  # sometimes a missing required column
    sep = draw(st.sampled_from([",", ";", "\t"]))
    n_rows = draw(st.integers(0, 12))
    rows = []
    for i in range(n_rows):
        if draw(st.integers(0, 3)) == 0:
            row = [draw(_cells) for _ in cols]
        else:
            row = [str(i if c == "time_s" else draw(st.floats(0, 100, allow_nan=False))) for c in cols]
        rows.append(sep.join(row))
    preamble = draw(st.lists(st.sampled_from(["# meta", "", "#x,y"]), max_size=2))
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    text = eol.join(preamble + [sep.join(cols)] + rows) + draw(st.sampled_from(["", eol, eol * 2]))
    bom = draw(st.booleans())
    return kind, text, bom


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_csv_texts())
def test_random_csv_parses_or_raises_input_error(case):
    kind, text, bom = case
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "r.csv"
        p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode("utf-8", errors="surrogatepass"))
        for drop in (False, True):
            try:
                run = read_run(p, kind, drop_na=drop)
            except InputError as exc:
                assert "\n" not in str(exc)
                continue
            df = run.data
            expected = {VARIABLE_MAP[c][0] for c in REQUIRED[kind]}
            assert expected <= set(df.columns)
            assert all(dt == np.float64 for dt in df.dtypes)
            assert isinstance(df.index, pd.RangeIndex)
            assert np.isfinite(df.to_numpy()).all()
            assert len(df) >= MIN_ROWS[kind]
            assert len(df) + run.n_dropped == run.n_rows_raw
            if "time" in df:
                assert (np.diff(df["time"].to_numpy()) > 0).all()
            for name in ("resistance", "r1", "r2"):
                if name in df:
                    assert (df[name] >= 0).all()
            if "displacement" in df:
                assert df["displacement"].iloc[0] == 0.0
            assert not math.isnan(float(df.iloc[0, 0]))


# --- unit aliases -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "written, value, canonical, expected",
    [
        ("µm", 250.0, "displacement_mm", 250e-6),  # micro sign U+00B5
        ("μm", 250.0, "displacement_mm", 250e-6),  # Greek mu U+03BC
        ("um", 250.0, "displacement_mm", 250e-6),
        ("micron", 250.0, "displacement_mm", 250e-6),
        ("Ω", 31.5, "resistance_ohm", 31.5),
        ("Ω", 31.5, "resistance_ohm", 31.5),  # ohm sign U+2126
        ("Ohm", 31.5, "resistance_ohm", 31.5),
        ("ohms", 31.5, "resistance_ohm", 31.5),
        ("kΩ", 0.0315, "resistance_ohm", 31.5),
        ("kOhm", 0.0315, "resistance_ohm", 31.5),
        ("°C", 25.0, "temperature_C", 25.0),
        ("deg C", 25.0, "temperature_C", 25.0),
        ("K", 298.15, "temperature_C", 25.0),
        ("degF", 77.0, "temperature_C", 25.0),
        ("F", 77.0, "temperature_C", 25.0),
        ("°F", 212.0, "temperature_C", 100.0),
        ("mN", 1500.0, "force_N", 1.5),
        ("kN", 0.0015, "force_N", 1.5),
        ("msec", 1500.0, "time_s", 1.5),
    ],
)
def test_unit_aliases_are_real_conversions(tmp_path, written, value, canonical, expected):
    kind = "static" if canonical in ("displacement_mm", "temperature_C") else "sensing"
    others = {
        "temperature_C": lambda i: 25 + i,
        "displacement_mm": lambda i: 0.1 * i,
        "force_N": lambda i: 0.01 * i,
        "resistance_ohm": lambda i: 30 + i,
        "time_s": lambda i: i,
    }
    cols = [c for c in REQUIRED[kind] + ("time_s",) if c != canonical]
    text = "x," + ",".join(cols) + "\n"
    text += "".join(
        f"{value * (1 + 0.1 * i)!r}," + ",".join(repr(others[c](i)) for c in cols) + "\n" for i in range(12)
    )
    run = read_run(write(tmp_path, text), kind, {canonical: {"from": "x", "unit": written}})
    got = run.data[VARIABLE_MAP[canonical][0]].to_numpy()
    if canonical == "displacement_mm":  # re-zeroed on the first row
        assert got[1] == pytest.approx(0.1 * expected, rel=1e-9)
    elif canonical == "temperature_C":  # an offset unit: check two points
        assert got[0] == pytest.approx(expected, rel=1e-9)
        assert got[1] == pytest.approx(tio.convert(value * 1.1, written, "degC"), rel=1e-9)
    else:
        assert got[0] == pytest.approx(expected, rel=1e-9) and got[1] == pytest.approx(
            1.1 * expected, rel=1e-9
        )


def test_temperature_units_convert_with_their_offsets():
    assert tio.convert(300.0, "K", "degC") == pytest.approx(26.85)
    assert tio.convert(212.0, "°F", "°C") == pytest.approx(100.0)
    assert tio.convert(0.0, "degC", "F") == pytest.approx(32.0)


def test_unknown_unit_never_suggests_a_prefix_off(tmp_path):
    p = write(tmp_path, dynamic_text())
    for unit in ("xm", "µmm", "Mm"):
        err = raises_input(
            [f"unknown unit {unit!r}"],
            read_run,
            p,
            "dynamic",
            {"displacement_mm": {"from": "displacement_mm", "unit": unit}},
        )
        assert "did you mean 'm'" not in str(err) and "did you mean 'mm'" not in str(err)
    err = raises_input(
        ["unknown unit 'kohmm'", "did you mean"],
        read_run,
        p,
        "dynamic",
        {"resistance_ohm": {"from": "displacement_mm", "unit": "kohmm"}},
    )
    assert "did you mean 'kohm'" in str(err)
    assert tio.unit_key("MM") is None and tio.unit_key("mohm") == "mohm" and tio.unit_key("Mohm") == "Mohm"


# --- real formats declared in [columns] -------------------------------------------------------


def test_title_row_and_units_row(tmp_path):
    """A rheometer export: a title line, the header, a units row in brackets; units come from it."""
    text = "Rheometer export 2019-06-11,,\nTime,Gap,Axial force,R\n[s],[µm],[mN],[kΩ]\n"
    text += "".join(f"{0.5 * i},{1000 + 10 * i},{5.0 * i},{0.03 + 1e-5 * i}\n" for i in range(12))
    p = write(tmp_path, text)
    cols = {"header_row": 2, "units_row": 3, "time_s": "Time", "displacement_mm": "Gap"}
    cols |= {"force_N": "Axial force", "resistance_ohm": "R"}
    run = read_run(p, "sensing", cols)
    assert len(run.data) == 12 and run.header_line == 2
    assert run.data["displacement"].iloc[1] == pytest.approx(10e-6)
    assert run.data["force"].iloc[1] == pytest.approx(5e-3)
    assert run.data["resistance"].iloc[0] == pytest.approx(30.0)
    # a unit stated in [columns] wins over the units row
    cols["displacement_mm"] = {"from": "Gap", "unit": "mm"}
    assert read_run(p, "sensing", cols).data["displacement"].iloc[1] == pytest.approx(10e-3)
    # without header_row the title is taken for the header and the columns are not found
    raises_input(["not found in the header"], read_run, p, "sensing", {"time_s": "Time"})


def test_units_row_with_an_unknown_unit_names_the_line(tmp_path):
    text = "Temp,Gap\n°C,furlongs\n" + "".join(f"{i},{i * 0.1}\n" for i in range(12))
    p = write(tmp_path, text)
    raises_input(
        ["line 2", "'Gap'", "'furlongs'", "not a length unit", "displacement_mm holds a length"],
        read_run,
        p,
        "static",
        {"header_row": 1, "units_row": 2, "temperature_C": "Temp", "displacement_mm": "Gap"},
    )


def test_headerless_file_is_refused_unless_declared_and_keeps_its_first_row(tmp_path):
    rows = [f"{25 + i},{-0.01 * i:.3f}" for i in range(20)]
    p = write(tmp_path, "\n".join(rows) + "\n")
    raises_input(["line 1 holds only numbers", "looks like data", "header_row = 0"], read_run, p, "static")
    run = read_run(
        p, "static", {"header_row": 0, "temperature_C": {"from": 1}, "displacement_mm": {"from": 2}}
    )
    assert len(run.data) == 20 and run.data["temperature"].iloc[0] == 25.0  # the first row is data
    assert run.source_columns == {"temperature": "column 1", "displacement": "column 2"}
    raises_input(["needs a column number"], read_run, p, "static", {"header_row": 0, "temperature_C": "T"})
    raises_input(
        ["column 5", "has 2 columns"], read_run, p, "static", {"header_row": 0, "temperature_C": {"from": 5}}
    )


def test_repeated_headers_mapped_by_position(tmp_path):
    text = "Temp (degC),Contraction (%),Temp (degC),Contraction (%)\n"
    text += "".join(f"{25 + i},{0.5 * i},{26 + i},{0.4 * i}\n" for i in range(12))
    p = write(tmp_path, text)
    err = raises_input(["appears in columns 1, 3"], read_run, p, "static", {"temperature_C": "Temp (degC)"})
    assert "temperature_C = { from = 1 }" in err.hint
    cols = {"temperature_C": {"from": 3}, "displacement_mm": {"from": 4, "scale": -0.2}}
    run = read_run(p, "static", cols)
    assert run.data["temperature"].iloc[0] == 26.0
    assert run.data["displacement"].iloc[1] == pytest.approx(-0.4 * 0.2e-3)


def test_wall_clock_time_stamps(tmp_path):
    rows = ["stamp,voltage_V,displacement_mm"]
    rows += [f"2019-06-11 14:03:{52.123456 + 0.1 * i:09.6f},10,{-0.01 * i:.3f}" for i in range(8)]
    rows += [f"2019-06-11 14:04:{0.923456 + 0.1 * i:09.6f},10,-0.1" for i in range(4)]  # across a minute
    p = write(tmp_path, "\n".join(rows) + "\n")
    run = read_run(p, "dynamic", {"time_s": {"from": "stamp", "unit": "datetime"}})
    t = run.data["time"].to_numpy()
    assert t[0] == 0.0 and t[1] == pytest.approx(0.1, abs=1e-9) and t[8] == pytest.approx(8.8, abs=1e-9)
    clock = "\n".join(["t,voltage_V,displacement_mm"] + [f"14:03:5{i}.5,10,0.0" for i in range(10)]) + "\n"
    run = read_run(write(tmp_path, clock, "c.csv"), "dynamic", {"time_s": {"from": "t", "unit": "clock"}})
    assert run.data["time"].iloc[9] == pytest.approx(9.0)
    bad = clock.replace("14:03:55.5", "soon", 1)
    raises_input(
        ["line 7", "'t'", "'soon' is not a time stamp"],
        read_run,
        write(tmp_path, bad, "b.csv"),
        "dynamic",
        {"time_s": {"from": "t", "unit": "datetime"}},
    )
    raises_input(
        ["for time_s only"],
        read_run,
        p,
        "dynamic",
        {"displacement_mm": {"from": "stamp", "unit": "datetime"}},
    )


def test_per_run_scale_overrides_in_the_experiment_file(tmp_path):
    """Strain logs of two samples of different lengths: each run's own scale turns % into mm."""
    from tcamlab.config import load_experiment

    raw = tmp_path / "raw"
    raw.mkdir()
    for name in ("a", "b"):
        (raw / f"{name}.csv").write_text(
            "T,strain\n" + "".join(f"{25 + 5 * i},{0.5 * i}\n" for i in range(12))
        )
    exp = tmp_path / "e.toml"
    exp.write_text(
        'kind = "static"\ntitle = "two lengths"\n'
        'runs = ["raw/a.csv", { file = "raw/b.csv", columns = { displacement_mm = { scale = -0.3 } } }]\n'
        '[sample]\npreset = "thesis-tca"\n'
        '[columns]\ntemperature_C = "T"\ndisplacement_mm = { from = "strain", scale = -0.2 }\n'
    )
    a, b = load_experiment(exp).read_runs()
    assert a.data["displacement"].iloc[2] == pytest.approx(-0.2e-3)  # 1 % of 20 mm
    assert b.data["displacement"].iloc[2] == pytest.approx(-0.3e-3)  # 1 % of 30 mm


def test_skip_rows_and_bad_layout_keys(tmp_path):
    p = write(tmp_path, "Vibrometer 7\n" + "".join(f"{25 + i},{0.1 * i}\n" for i in range(12)))
    cols = {"header_row": 0, "skip_rows": 1, "temperature_C": {"from": 1}, "displacement_mm": {"from": 2}}
    assert len(read_run(p, "static", cols).data) == 12
    raises_input(["header_row: expected a line number >= 0"], read_run, p, "static", {"header_row": -1})
    raises_input(["units_row", "no units row"], read_run, p, "static", {"header_row": 0, "units_row": 2})
    raises_input(
        ["units_row = 1 must come after header_row = 2"],
        read_run,
        p,
        "static",
        {"header_row": 2, "units_row": 1},
    )
    raises_input(["skip_rows = 3 skips the header"], read_run, p, "static", {"header_row": 2, "skip_rows": 3})
    raises_input(["header_row = 40", "only"], read_run, p, "static", {"header_row": 40})


def test_temperatures_in_kelvin_read_as_degc_are_questioned(tmp_path):
    rows = ["T,displacement_mm"] + [f"{293.15 + 5 * i:.2f},{-0.01 * i:.3f}" for i in range(12)]
    p = write(tmp_path, "\n".join(rows) + "\n")
    err = raises_input(
        ["every temperature is above 200 degC", "is this column in kelvin?"],
        read_run,
        p,
        "static",
        {"temperature_C": "T"},
    )
    line = 'temperature_C = { from = "T", unit = "K" }'
    assert line in err.hint and tomllib.loads(line)
    run = read_run(p, "static", tomllib.loads(line))
    assert run.data["temperature"].iloc[0] == pytest.approx(20.0)


# --- two instruments, two clocks ---------------------------------------------------------


def two_clock_lab(tmp_path: Path, offset: float) -> Path:
    """A laser logging displacement at 10 Hz and a thermocouple logger at 1 Hz on its own clock."""
    raw = tmp_path / "raw"
    raw.mkdir(exist_ok=True)
    (raw / "laser.csv").write_text(
        "Time [s],Position (mm)\n" + "".join(f"{0.1 * i:.1f},{-0.01 * i:.3f}\n" for i in range(101))
    )
    (raw / "tc.csv").write_text("t,T (C)\n" + "".join(f"{i},{25 + 5 * i}\n" for i in range(13)))
    exp = tmp_path / "oven.toml"
    exp.write_text(
        'kind = "static"\ntitle = "two clocks"\n'
        'runs = [{ file = "raw/laser.csv", join = { file = "raw/tc.csv", offset_s = '
        + repr(offset)
        + ', columns = { time_s = "t", temperature_C = "T (C)" } } }]\n'
        '[sample]\npreset = "thesis-tca"\n'
        '[columns]\ntime_s = "Time [s]"\ndisplacement_mm = "Position (mm)"\n'
    )
    return exp


def test_two_files_two_clocks_joined_on_time_with_an_offset(tmp_path):
    from tcamlab.config import load_experiment

    (run,) = load_experiment(two_clock_lab(tmp_path, -0.5)).read_runs()
    t = run.data["time"].to_numpy()
    # the logger's clock runs 0.5 s ahead: its reading at t + 0.5 s belongs to the laser's t
    np.testing.assert_allclose(run.data["temperature"].to_numpy(), 25 + 5 * (t + 0.5), rtol=1e-12)
    assert len(run.data) == 101 and run.join["rows_outside_overlap"] == 0
    assert run.join["offset_s"] == -0.5 and run.join["overlap_s"] == [0.0, 10.0]
    assert run.join["sha256"] == sha256_file(tmp_path / "raw" / "tc.csv")
    assert run.source_columns["temperature"] == "raw/tc.csv: T (C)" or run.source_columns[
        "temperature"
    ].endswith("tc.csv: T (C)")
    # a later start: the laser's rows before the logger's first reading are dropped, not extrapolated
    (late,) = load_experiment(two_clock_lab(tmp_path, 2.0)).read_runs()
    assert late.join["rows_outside_overlap"] == 20 and late.data["time"].iloc[0] == pytest.approx(2.0)
    assert late.data["temperature"].iloc[0] == pytest.approx(25.0)
    with pytest.raises(InputError, match="do not overlap"):
        load_experiment(two_clock_lab(tmp_path, 50.0)).read_runs()


def test_two_clock_check_reports_the_join(tmp_path):
    from tcamlab.starter import check_experiment

    text = "\n".join(check_experiment(two_clock_lab(tmp_path, -0.5)).lines())
    assert "joined" in text and "tc.csv (13 rows) on time + offset_s -0.5 s" in text
    assert "overlap 0 to 10 s, 0 rows outside it dropped, linear interpolation" in text


def test_globs_in_runs_expand_sorted_relative_to_the_experiment_file(tmp_path):
    from tcamlab.config import load_experiment
    from tcamlab.errors import ConfigError

    raw = tmp_path / "raw"
    raw.mkdir()
    for name in ("pull_2", "pull_10", "pull_1", "other"):
        (raw / f"{name}.csv").write_text(
            "temperature_C,displacement_mm\n" + "".join(f"{25 + i},{-0.01 * i}\n" for i in range(12))
        )
    (tmp_path / "e").mkdir()
    exp = tmp_path / "e" / "oven.toml"
    exp.write_text(
        'kind = "static"\ntitle = "globbed"\nruns = ["../raw/pull_*.csv"]\n[sample]\npreset = "thesis-tca"\n'
    )
    loaded = load_experiment(exp)
    assert [r.name for r in loaded.runs] == ["pull_1.csv", "pull_10.csv", "pull_2.csv"]
    assert len(loaded.read_runs()) == 3
    exp.write_text(exp.read_text().replace("pull_*", "nothing_*"))
    with pytest.raises(ConfigError, match="matches no file"):
        load_experiment(exp)


def test_the_joined_file_is_in_every_output_s_provenance(tmp_path, monkeypatch):
    """The second instrument's file of a two-clock run is an input like the run's own CSV:
    its path and SHA-256 are in metrics.json, the report's input table and provenance, and
    calibration.json (the diagnosis names only the experiment file)."""
    import json

    from tcamlab.pipeline import calibrate_experiment, validate_experiment

    monkeypatch.chdir(tmp_path)
    exp = two_clock_lab(tmp_path, -0.5)
    sha = sha256_file(tmp_path / "raw" / "tc.csv")
    outcome = validate_experiment(exp, tmp_path / "out", formats="html")
    metrics = json.loads((outcome.out_dir / "metrics.json").read_text())
    (entry,) = metrics["inputs"]
    assert entry["path"] == "raw/laser.csv" and entry["sha256"] == sha256_file(tmp_path / "raw/laser.csv")
    assert entry["joined"] == {"file": "tc.csv", "path": "raw/tc.csv", "sha256": sha, "offset_s": -0.5}
    html = (outcome.out_dir / "report.html").read_text()
    assert html.count(sha) >= 2 and "joined to raw/laser.csv" in html and "sha256 raw/tc.csv" in html
    cal = calibrate_experiment([exp], params="shear_modulus_slope", out_dir=tmp_path / "cal")
    doc = json.loads(next(f for f in cal.files if f.name == "calibration.json").read_text())
    joined = [i for i in doc["inputs"] if i["role"] == "joined"]
    assert [(Path(i["path"]).name, i["sha256"]) for i in joined] == [("tc.csv", sha)]


def test_a_run_with_tcamlabs_own_headers_beside_mapped_runs_gets_a_per_run_hint(tmp_path):
    """Earlier runs map 'Temp (F)' in [columns]; a designed run logged as temperature_C fails that
    mapping, and the hint proposes this run's own columns (followed, the experiment reads)."""
    from tcamlab.config import load_experiment
    from tcamlab.errors import InputError

    raw = tmp_path / "raw"
    raw.mkdir()
    (raw / "lab.csv").write_text("Temp (F),disp\n" + "".join(f"{77 + 9 * i},{-0.01 * i}\n" for i in range(6)))
    (raw / "new.csv").write_text(
        "temperature_C,displacement_mm\n" + "".join(f"{25 + 5 * i},{-0.01 * i}\n" for i in range(6))
    )
    body = (
        'kind = "static"\ntitle = "t"\nruns = ["../raw/lab.csv", RUN]\n[sample]\npreset = "thesis-tca"\n'
        '[columns]\ntemperature_C = { from = "Temp (F)", unit = "degF" }\ndisplacement_mm = "disp"\n'
    )
    (tmp_path / "experiments").mkdir()
    path = tmp_path / "experiments" / "e.toml"
    path.write_text(body.replace("RUN", '"../raw/new.csv"'))
    with pytest.raises(InputError) as info:
        load_experiment(path).read_runs()
    assert "give this run its own columns" in info.value.hint
    assert '{ file = "new.csv", columns = { temperature_C = "temperature_C" } }' in info.value.hint
    own = '{ file = "../raw/new.csv", columns = { temperature_C = "temperature_C", displacement_mm = "displacement_mm" } }'
    path.write_text(body.replace("RUN", own))
    runs = load_experiment(path).read_runs()
    assert (
        runs[0].data["temperature"].iloc[0] == pytest.approx(25.0)
        and runs[1].data["temperature"].iloc[1] == 30.0
    )


def test_a_run_logged_backwards_is_told_to_sort_its_rows(tmp_path):
    """Rows newest first: the hint says to sort them, not to split concatenated runs."""
    lines = dynamic_text().splitlines()
    backwards = write(tmp_path, "\n".join([lines[0], *lines[:0:-1]]) + "\n", "back.csv")
    err = raises_input(["back.csv", "decreasing time 1 s after 1.1 s"], read_run, backwards, "dynamic")
    assert "sort them oldest first" in err.hint
    glued = write(tmp_path, "\n".join([*lines, *lines[1:]]) + "\n", "glued.csv")
    assert "split concatenated runs" in raises_input(["glued.csv"], read_run, glued, "dynamic").hint


def test_an_optional_channel_mapped_for_every_run_says_to_map_it_per_run(tmp_path):
    """The designed runs log a load cell the first runs did not: mapping it in [columns] reaches
    the old runs too, and the hint says to give it to the new runs' own columns."""
    old = write(tmp_path, dynamic_text(), "old.csv")
    columns = {"load_N": {"from": "Masse [g]", "unit": "gf"}}
    err = raises_input(
        ["old.csv", "mapped column 'Masse [g]' (for load_N) not found"], read_run, old, "dynamic", columns
    )
    assert (
        'in their own columns in runs, e.g. { file = "new.csv", columns = { load_N = "Masse [g]" } }'
        in err.hint
    )
