"""Tests of tcamlab.config: experiment TOML loading, validation and writing."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import pytest

from tcamlab.config import Experiment, dumps_toml, load_experiment, write_experiment
from tcamlab.errors import ConfigError
from tcamlab.params import PRESETS, RIG_KEYS, SAMPLE_KEYS, THESIS_TCA, THESIS_TCS, Rig, Sample

RTOL = 1e-12

FULL_SAMPLE = """
[sample]
fiber_diameter_mm = 0.4
fiber_length_mm = 328
coil_length_mm = 90
coil_diameter_mm = 0.8
twists = 750
youngs_modulus_GPa = 3.45
thread_plies = 2
max_volume_fraction = 0.887
radial_cte_per_K = 8.1e-5
shear_modulus_slope_MPa_per_K = 1.11
"""


def dynamic_csv(path: Path) -> Path:
    rows = ["time_s,voltage_V,displacement_mm"] + [f"{i * 0.1:.1f},10,{-0.01 * i:.2f}" for i in range(12)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture
def lab(tmp_path):
    """An experiments/ and raw/ tree with one run."""
    dynamic_csv(tmp_path / "raw" / "step1.csv")
    (tmp_path / "experiments").mkdir()
    return tmp_path


def write_toml(lab: Path, body: str, name: str = "exp.toml") -> Path:
    p = lab / "experiments" / name
    p.write_text(body, encoding="utf-8")
    return p


HEAD = 'kind = "dynamic"\ntitle = "Voltage step"\nruns = ["../raw/step1.csv"]\n'


def raises_config(parts, func, *args, **kwargs) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        func(*args, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert "pydantic" not in msg.lower() and "errors.pydantic.dev" not in msg
    for part in parts:
        assert part in msg, f"{part!r} not in {msg!r}"
    return info.value


# --- happy paths ---------------------------------------------------------------------


def test_load_with_preset_and_overrides(lab):
    p = write_toml(
        lab,
        HEAD
        + 'notes = "first try"\n[sample]\npreset = "thesis-tca"\ncoil_length_mm = 21.0\n'
        + "[rig]\nload_g = 40\nsegment_lengths_mm = [25, 35]\n[rig.uncertainty]\ndamping_N_s_per_m = 0.2\n"
        + "load_g = 0.5\n"
        + '[columns]\ntime_s = { from = "time_s", unit = "s" }\n[thresholds]\nrmse_mm = 0.5\nr2_min = 0.9\n',
    )
    exp = load_experiment(p, expected_kind="dynamic")
    assert isinstance(exp, Experiment)
    assert exp.path == p.resolve() and exp.name == "exp" and exp.kind == "dynamic"
    assert exp.title == "Voltage step" and exp.notes == "first try"
    assert exp.runs == ((lab / "raw" / "step1.csv").resolve(),)
    assert all(r.is_absolute() for r in exp.runs)
    assert isinstance(exp.sample, Sample) and isinstance(exp.rig, Rig)
    assert math.isclose(exp.sample.coil_length, 21e-3, rel_tol=RTOL)
    assert exp.sample.fiber_diameter == THESIS_TCA.sample["fiber_diameter"].value
    assert math.isclose(exp.rig.load, 0.04, rel_tol=RTOL)
    assert exp.rig.voltage == THESIS_TCA.rig["voltage"].value
    assert exp.rig.segment_lengths == pytest.approx((25e-3, 35e-3), rel=RTOL)
    assert exp.rig.uncertainty["damping"] == pytest.approx(0.2, rel=RTOL)
    assert exp.rig.uncertainty["load"] == pytest.approx(0.5e-3, rel=RTOL)
    assert exp.rig.uncertainty["heat_loss"] == THESIS_TCA.uncertainty["heat_loss"].value
    assert exp.provenance["coil_length"] == "experiment file"
    assert exp.provenance["fiber_diameter"] == THESIS_TCA.sample["fiber_diameter"].provenance
    assert exp.provenance["load"] == "experiment file"
    assert exp.provenance["voltage"] == THESIS_TCA.rig["voltage"].provenance
    assert exp.provenance["sd(damping)"] == "experiment file"
    assert exp.provenance["sd(heat_loss)"] == THESIS_TCA.uncertainty["heat_loss"].provenance
    assert exp.columns == {"time_s": {"from": "time_s", "unit": "s"}}
    assert exp.thresholds == {"rmse_mm": 0.5, "r2_min": 0.9}
    assert exp.synthetic is None
    assert exp.raw["rig"]["load_g"] == 40
    assert exp.preset == "thesis-tca"
    with pytest.raises(dataclasses.FrozenInstanceError):
        exp.kind = "static"  # type: ignore[misc]
    runs = exp.read_runs()
    assert len(runs) == 1 and len(runs[0].data) == 12


def test_full_sample_without_preset(lab):
    p = write_toml(lab, HEAD + FULL_SAMPLE)
    exp = load_experiment(p)
    s = exp.sample
    assert math.isclose(s.fiber_diameter, 0.4e-3, rel_tol=RTOL)
    assert math.isclose(s.fiber_length, 0.328, rel_tol=RTOL)
    assert math.isclose(s.youngs_modulus, 3.45e9, rel_tol=RTOL)
    assert math.isclose(s.shear_modulus_slope, 1.11e6, rel_tol=RTOL)
    assert s.thread_plies == 2 and isinstance(s.thread_plies, int)
    for si, _ in SAMPLE_KEYS.values():
        assert exp.provenance[si] == "experiment file"
    assert exp.rig == Rig()  # nothing set: dataclass defaults
    assert "default" in exp.provenance["load"]


def test_sample_keys_convert_with_params_factors(lab):
    p = write_toml(lab, HEAD + FULL_SAMPLE)
    exp = load_experiment(p)
    raw = tomllib.loads(FULL_SAMPLE)["sample"]
    for key, (si, factor) in SAMPLE_KEYS.items():
        assert getattr(exp.sample, si) == pytest.approx(raw[key] * factor, rel=RTOL)


def test_rig_keys_convert_with_params_factors(lab):
    values = {key: 2.5 for key in RIG_KEYS if key != "segment_lengths_mm"}
    body = (
        HEAD + '[sample]\npreset = "thesis-tcs"\n[rig]\n' + "".join(f"{k} = {v}\n" for k, v in values.items())
    )
    exp = load_experiment(write_toml(lab, body))
    for key, v in values.items():
        si, factor = RIG_KEYS[key]
        assert getattr(exp.rig, si) == pytest.approx(v * factor, rel=RTOL)
        assert exp.provenance[si] == "experiment file"


def test_preset_rig_values_and_provenance(lab):
    exp = load_experiment(write_toml(lab, HEAD + '[sample]\npreset = "thesis-tcs"\n'))
    assert exp.sample == THESIS_TCS.build_sample()
    assert exp.rig.initial_resistance == THESIS_TCS.rig["initial_resistance"].value
    assert exp.provenance["initial_resistance"] == THESIS_TCS.rig["initial_resistance"].provenance
    # S is identified from pull tests, not taken from a preset
    assert exp.rig.spring_constant is None
    assert exp.provenance["twists"] == THESIS_TCS.sample["twists"].provenance


def test_synthetic_table(lab):
    body = HEAD + '[synthetic]\ngenerator = "tcamlab.simulate"\nseed = 7\n[sample]\npreset = "thesis-tca"\n'
    exp = load_experiment(write_toml(lab, body))
    assert exp.synthetic == {"generator": "tcamlab.simulate", "seed": 7, "command": None}


@pytest.mark.parametrize(
    "kind, preset", [("curvature", "thesis-robot"), ("sensing", "thesis-tcs"), ("static", "thesis-tca")]
)
def test_other_kinds(lab, kind, preset):
    body = f'kind = "{kind}"\ntitle = "x"\nruns = ["../raw/step1.csv"]\n[sample]\npreset = "{preset}"\n'
    exp = load_experiment(write_toml(lab, body), expected_kind=kind)
    assert exp.sample == PRESETS[preset].build_sample()


# --- write / round trip ------------------------------------------------------------------


def test_write_round_trip(lab):
    data = {
        "kind": "dynamic",
        "title": 'Step "50 g" \u00b0C test',
        "runs": ["../raw/step1.csv"],
        "notes": "line one\nline two\\ with backslash\ttab",
        "synthetic": {"generator": "tcamlab.simulate", "seed": 42, "command": "tcamlab simulate dynamic"},
        "sample": {"preset": "thesis-tca", "coil_length_mm": 21.5, "twists": 140, "thread_plies": 2},
        "rig": {
            "load_g": 50.0,
            "ambient_C": -5.25,
            "segment_lengths_mm": [30.0, 30.0],
            "uncertainty": {"damping_N_s_per_m": 0.12, "load_g": 1e-7},
        },
        "columns": {
            "time_s": {"from": "reltime", "unit": "ms"},
            "temperature_C": {"from": "Temp (F)", "unit": "degF"},
            "displacement_mm": {"from": "laser", "scale": 0.01, "offset": -2.5},
            "voltage_V": "volts",
        },
        "thresholds": {"rmse_mm": 0.5, "nrmse": 0.1, "r2_min": 0.9},
    }
    p = write_experiment(lab / "experiments" / "rt.toml", data, comment="written by a test\nsecond line")
    text = p.read_text(encoding="utf-8")
    assert text.startswith("# written by a test\n# second line\n")
    assert tomllib.loads(text) == data
    exp = load_experiment(p)
    assert exp.raw == data
    assert exp.title == data["title"] and exp.notes == data["notes"]
    assert exp.columns == data["columns"]
    assert exp.thresholds == data["thresholds"]
    assert exp.synthetic == data["synthetic"]
    assert exp.sample.coil_length == pytest.approx(21.5e-3, rel=RTOL)
    assert exp.sample.twists == 140
    assert exp.rig.ambient == -5.25
    assert exp.rig.uncertainty["load"] == pytest.approx(1e-10, rel=RTOL)


def test_dumps_toml_types():
    data = {
        "a": 1,
        "b": 1e-300,
        "c": float("inf"),
        "d": True,
        "e": [1, 2.5],
        "f": ["x", "y z"],
        "g h": "quoted key",
        "t": {"u": {"v": 1}},
    }
    back = tomllib.loads(dumps_toml(data))
    assert back == data
    assert math.isnan(tomllib.loads(dumps_toml({"n": float("nan")}))["n"])
    with pytest.raises(TypeError):
        dumps_toml({"x": object()})


def test_dumps_toml_numpy_scalars():
    np = pytest.importorskip("numpy")
    back = tomllib.loads(dumps_toml({"x": np.float64(0.1), "n": np.int64(3)}))
    assert back == {"x": 0.1, "n": 3}


# --- errors ---------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    p = tmp_path / "none.toml"
    raises_config([str(p), "not found"], load_experiment, p)


def test_toml_syntax_error_keeps_line_and_column(lab):
    p = write_toml(lab, HEAD + "[rig]\nload_g = = 5\n")
    raises_config([str(p), "TOML syntax error", "line 5", "column"], load_experiment, p)


@pytest.mark.parametrize(
    "body, parts",
    [
        (HEAD.replace("title", "titel"), ["unknown key 'titel'", "did you mean 'title'"]),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\nfiber_diam_mm = 0.2\n',
            ["unknown key 'sample.fiber_diam_mm'", "did you mean 'fiber_diameter_mm'"],
        ),
        (HEAD + "[rig]\nload_gram = 5\n", ["'rig.load_gram'", "did you mean 'load_g'"]),
        (HEAD + "[rig.uncertainty]\ndamping = 0.1\n", ["'rig.uncertainty.damping'", "[rig.uncertainty]"]),
        (
            HEAD + '[synthetic]\ngenerator = "x"\nseed = 1\nsed = 2\n',
            ["'synthetic.sed'", "did you mean 'seed'"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\ntime_s = { from = "t", units = "ms" }\n',
            ["columns.time_s.units", "did you mean 'unit'"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\ntme_s = "t"\n',
            ["columns", "'tme_s' is not a column of a dynamic run", "did you mean 'time_s'"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\nforce_N = "F"\n',
            ["'force_N' is not a column of a dynamic run"],
        ),
    ],
)
def test_unknown_keys(lab, body, parts):
    p = write_toml(lab, body)
    raises_config([str(p)] + parts, load_experiment, p)


@pytest.mark.parametrize(
    "body, parts",
    [
        ('title = "x"\nruns = ["../raw/step1.csv"]\n', ["missing required key 'kind'"]),
        ('kind = "dynamic"\nruns = ["../raw/step1.csv"]\n', ["missing required key 'title'"]),
        ('kind = "dynamic"\ntitle = "x"\n', ["missing required key 'runs'"]),
        ('kind = "dynamic"\ntitle = "x"\nruns = []\n', ["runs: needs at least one entry"]),
        (HEAD + '[synthetic]\ngenerator = "x"\n', ["missing required key 'synthetic.seed'"]),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\ntime_s = { unit = "ms" }\n',
            ["columns.time_s.from", "missing"],
        ),
    ],
)
def test_missing_keys(lab, body, parts):
    p = write_toml(lab, body)
    raises_config([str(p)] + parts, load_experiment, p)


def test_no_preset_lists_missing_sample_keys(lab):
    p = write_toml(lab, HEAD + "[sample]\nfiber_diameter_mm = 0.4\ntwists = 700\n")
    err = raises_config(
        [str(p), "no preset", "missing:", "fiber_length_mm", "coil_length_mm", "youngs_modulus_GPa"],
        load_experiment,
        p,
    )
    assert "twists," not in str(err).split("missing:")[1]
    assert "preset" in err.hint
    p2 = write_toml(lab, HEAD, "nosample.toml")
    raises_config([str(p2), "missing:", "fiber_diameter_mm"], load_experiment, p2)


@pytest.mark.parametrize(
    "body, parts",
    [
        (HEAD + '[rig]\nload_g = "fifty"\n', ["rig.load_g: expected a number, got 'fifty'"]),
        (HEAD + "[rig]\nload_g = true\n", ["rig.load_g: expected a number, got True"]),
        (HEAD + "[rig]\nsegment_lengths_mm = 30\n", ["rig.segment_lengths_mm: expected a list"]),
        (HEAD + '[rig]\nsegment_lengths_mm = [30, "x"]\n', ["rig.segment_lengths_mm[1]: expected a number"]),
        ('kind = "dynamic"\ntitle = 3\nruns = ["../raw/step1.csv"]\n', ["title: expected a string, got 3"]),
        ('kind = "dynamic"\ntitle = "x"\nruns = "../raw/step1.csv"\n', ["runs: expected a list"]),
        (
            'kind = "dynamik"\ntitle = "x"\nruns = ["../raw/step1.csv"]\n',
            ["kind: expected one of", "'dynamik'", "did you mean 'dynamic'"],
        ),
        (HEAD + '[sample]\npreset = "thesis-tcx"\n', ["sample.preset", "did you mean 'thesis-tc"]),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\nthread_plies = 2.5\n',
            ["sample.thread_plies: expected an integer, got 2.5"],
        ),
        (HEAD + '[synthetic]\ngenerator = "x"\nseed = "1"\n', ["synthetic.seed: expected an integer"]),
        (HEAD + "sample = 3\n", ["sample: expected a table"]),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[thresholds]\nrmse_mm = "small"\n',
            ["thresholds.rmse_mm: expected a number, got 'small'"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[thresholds]\nrmse_mm = nan\n',
            ["thresholds.rmse_mm: expected a finite number"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[rig]\nload_g = inf\n',
            ["rig.load_g: expected a finite number"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\ntime_s = 3\n',
            ["columns.time_s: expected a header"],
        ),
        (
            HEAD + '[sample]\npreset = "thesis-tca"\n[columns]\ntime_s = { from = "t", scale = "2" }\n',
            ["columns.time_s.scale: expected a number"],
        ),
        (
            HEAD
            + '[sample]\npreset = "thesis-tca"\n[columns]\ntemperature_C = { from = "T", unit = "mm" }\n',
            ["columns.temperature_C.unit", "'mm' is a length unit"],
        ),
    ],
)
def test_wrong_types(lab, body, parts):
    p = write_toml(lab, body)
    raises_config([str(p)] + parts, load_experiment, p)


def test_run_file_missing(lab):
    p = write_toml(lab, HEAD.replace("step1.csv", "step9.csv") + '[sample]\npreset = "thesis-tca"\n')
    raises_config([str(p), "runs[0]", "'../raw/step9.csv'", "not found"], load_experiment, p)


@pytest.mark.parametrize(
    "override, parts",
    [
        ("fiber_diameter_mm = -0.17", ["fiber_diameter", "positive"]),
        ("coil_length_mm = 120", ["coil_length", "not shorter than", "fiber_length"]),
        ("max_volume_fraction = 1.2", ["max_volume_fraction", "exceeds 1"]),
        ("coil_diameter_mm = 0.1", ["coil_diameter", "must exceed"]),
    ],
)
def test_impossible_sample(lab, override, parts):
    p = write_toml(lab, HEAD + f'[sample]\npreset = "thesis-tca"\n{override}\n')
    raises_config([str(p), "[sample]"] + parts, load_experiment, p)


@pytest.mark.parametrize(
    "table, parts",
    [
        ("[rig]\nresistance_ohm = 0", ["rig.resistance_ohm", "positive"]),
        ("[rig]\nload_g = -5", ["rig.load_g", "negative"]),
        ("[rig]\nambient_C = -300", ["rig.ambient_C", "outside -60 to 100"]),
        ("[rig]\nambient_C = 150", ["rig.ambient_C", "outside -60 to 100", "ambient_C = 20"]),
        ("[rig]\nstretch_factor = 1e6", ["rig.stretch_factor", "outside 0 to 10", "stretch_factor = 1"]),
        ("[rig]\nsegment_lengths_mm = [30, -1]", ["rig.segment_lengths_mm", "positive"]),
        ("[rig]\nsegment_lengths_mm = []", ["rig.segment_lengths_mm", "at least one"]),
        ("[rig.uncertainty]\ndamping_N_s_per_m = -0.1", ["rig.uncertainty.damping_N_s_per_m", "negative"]),
    ],
)
def test_impossible_rig(lab, table, parts):
    p = write_toml(lab, HEAD + f'[sample]\npreset = "thesis-tca"\n{table}\n')
    raises_config([str(p)] + parts, load_experiment, p)


@pytest.mark.parametrize(
    "table, parts",
    [
        ("[thresholds]\nrmse_mm = -1", ["thresholds.rmse_mm = -1", "not negative", "rmse_mm = 1"]),
        ("[thresholds]\nr2_min = 5", ["thresholds.r2_min = 5", "at most 1", "r2_min = 0.9"]),
    ],
)
def test_a_limit_no_run_can_meet_is_refused(lab, table, parts):
    p = write_toml(lab, HEAD + f'[sample]\npreset = "thesis-tca"\n{table}\n')
    err = raises_config([str(p)] + parts, load_experiment, p)
    key, _, value = err.hint.removeprefix("e.g. ").partition(" = ")
    write_toml(lab, HEAD + f'[sample]\npreset = "thesis-tca"\n[thresholds]\n{key} = {value}\n')
    assert load_experiment(p).thresholds[key] == float(value)  # the hint is a valid limit


def test_the_same_run_listed_twice_is_refused(lab):
    body = HEAD.replace('runs = ["../raw/step1.csv"]', 'runs = ["../raw/step1.csv", "../raw/./step1.csv"]')
    p = write_toml(lab, body + '[sample]\npreset = "thesis-tca"\n')
    raises_config([str(p), "runs[1]", "is runs[0] again"], load_experiment, p)


def test_expected_kind_mismatch(lab):
    p = write_toml(lab, HEAD + '[sample]\npreset = "thesis-tca"\n')
    err = raises_config([str(p), "'dynamic'", "'static'"], load_experiment, p, expected_kind="static")
    assert "dynamic" in err.hint


def test_not_utf8(lab):
    p = lab / "experiments" / "latin.toml"
    p.write_bytes(('title = "Ofen 20\u00b0C"\n').encode("latin-1"))
    raises_config([str(p), "UTF-8"], load_experiment, p)


def test_every_problem_reported_at_once_on_one_line(lab):
    p = write_toml(lab, 'kind = "x"\ntitle = 1\nruns = 2\nbogus = 3\n')
    err = raises_config([str(p), "4 problems", "'bogus'", "kind", "title", "runs"], load_experiment, p)
    assert "more problem" not in err.one_line() and "\n" not in err.one_line()


# --- [calibration]: the joint posterior of a calibrated file -------------------------

CAL_HEAD = (
    HEAD + '[sample]\npreset = "thesis-tca"\n[rig]\nthermal_mass_J_per_K = 0.02\ndamping_N_s_per_m = 0.7\n'
)
CAL_OK = (
    '[calibration]\nparameters = ["rig.thermal_mass_J_per_K", "rig.damping_N_s_per_m"]\n'
    'coordinates = ["log", "linear"]\nsd = [0.004, 0.03]\ncorrelation = [[1.0, -0.6], [-0.6, 1]]\n'
)


def test_calibration_table_parsed_in_si_with_its_covariance(lab):
    exp = load_experiment(write_toml(lab, CAL_HEAD + CAL_OK))
    cal = exp.calibration
    assert cal.keys == ("rig.thermal_mass_J_per_K", "rig.damping_N_s_per_m")
    assert cal.fields == (("rig", "thermal_mass"), ("rig", "damping"))
    assert cal.log == (True, False)
    # log sd is relative (no unit); the linear sd is in the key's unit, N s/m = SI here
    assert cal.sd == pytest.approx((0.004, 0.03), rel=RTOL)
    cov = cal.covariance()
    assert cov[0, 1] == pytest.approx(-0.6 * 0.004 * 0.03, rel=RTOL)
    assert cov[1, 1] == pytest.approx(0.03**2, rel=RTOL)
    assert load_experiment(write_toml(lab, CAL_HEAD, "plain.toml")).calibration is None


def test_calibration_linear_sd_converted_from_lab_units(lab):
    body = CAL_HEAD.replace("damping_N_s_per_m = 0.7\n", "damping_N_s_per_m = 0.7\nload_g = 50\n") + (
        '[calibration]\nparameters = ["rig.load_g"]\ncoordinates = ["linear"]\nsd = [2.0]\ncorrelation = [[1]]\n'
    )
    assert load_experiment(write_toml(lab, body)).calibration.sd == pytest.approx((2e-3,), rel=RTOL)


@pytest.mark.parametrize(
    ("edit", "parts"),
    [
        (
            ("sd = [0.004, 0.03]", "sd = [0.004, 0.03]\nmethod = 1"),
            ["unknown key 'calibration.method'", "[calibration]"],
        ),
        (
            ('"rig.damping_N_s_per_m"]', '"rig.dampng_N_s_per_m"]'),
            ["calibration.parameters[1]", "did you mean"],
        ),
        (
            ('"rig.damping_N_s_per_m"]', '"damping_N_s_per_m"]'),
            ["calibration.parameters[1]", "rig or sample key"],
        ),
        (
            ('"rig.damping_N_s_per_m"]', '"rig.thermal_mass_J_per_K"]'),
            ["calibration.parameters[1]", "listed twice"],
        ),
        (("sd = [0.004, 0.03]", "sd = [0.004]"), ["calibration.sd", "1 entries for 2 parameters"]),
        (("sd = [0.004, 0.03]", "sd = [0.004, -0.03]"), ["calibration.sd[1]", "must not be negative"]),
        (('"log", "linear"', '"log", "logit"'), ["calibration.coordinates[1]", "expected one of"]),
        (
            ("[-0.6, 1]]", "[-0.5, 1]]"),
            ["calibration.correlation[0][1]", "differs from calibration.correlation[1][0]"],
        ),
        (("[[1.0, -0.6]", "[[0.9, -0.6]"), ["calibration.correlation[0][0]", "diagonal must be 1"]),
        (
            ("[[1.0, -0.6], [-0.6, 1]]", "[[1.0, -1.6], [-1.6, 1]]"),
            ["calibration.correlation[0][1]", "not in [-1, 1]"],
        ),
        (("[[1.0, -0.6], [-0.6, 1]]", "[[1.0, -0.6]]"), ["calibration.correlation", "2 rows of 2 numbers"]),
        (("[[1.0, -0.6], [-0.6, 1]]", '"none"'), ["calibration.correlation", "expected a list"]),
    ],
)
def test_calibration_table_errors_are_one_line_and_name_the_key(lab, edit, parts):
    old, new = edit
    assert old in CAL_OK
    raises_config(parts, load_experiment, write_toml(lab, CAL_HEAD + CAL_OK.replace(old, new, 1)))


def test_calibration_correlation_must_be_positive_semidefinite(lab):
    three = (
        '[calibration]\nparameters = ["rig.thermal_mass_J_per_K", "rig.damping_N_s_per_m", "rig.heat_loss_W_per_K"]\n'
        'coordinates = ["log", "log", "log"]\nsd = [0.01, 0.01, 0.01]\n'
        "correlation = [[1, 0.9, -0.9], [0.9, 1, 0.9], [-0.9, 0.9, 1]]\n"
    )
    raises_config(
        ["calibration.correlation", "not positive semi-definite"],
        load_experiment,
        write_toml(lab, CAL_HEAD + three),
    )


def test_calibration_log_coordinate_needs_a_positive_value(lab):
    body = (
        CAL_HEAD
        + '[calibration]\nparameters = ["rig.spring_constant_N_per_m"]\ncoordinates = ["log"]\nsd = [0.1]\ncorrelation = [[1]]\n'
    )
    raises_config(
        ["calibration.parameters[0]", "rig.spring_constant_N_per_m has no value", "[rig]"],
        load_experiment,
        write_toml(lab, body),
    )


def test_calibration_profile_sds_go_together_and_convert_units(lab):
    body = CAL_HEAD + CAL_OK + "sd_below = [0.005, 0.04]\nsd_above = [0.003, 0.02]\n"
    cal = load_experiment(write_toml(lab, body)).calibration
    assert cal.sd_below == pytest.approx((0.005, 0.04), rel=RTOL)
    assert cal.sd_above == pytest.approx((0.003, 0.02), rel=RTOL)
    raises_config(
        ["calibration", "sd_below and sd_above go together"],
        load_experiment,
        write_toml(lab, CAL_HEAD + CAL_OK + "sd_below = [0.005, 0.04]\n", "one.toml"),
    )
    raises_config(
        ["calibration.sd_above[0]", "must not be negative"],
        load_experiment,
        write_toml(lab, body.replace("sd_above = [0.003", "sd_above = [-0.003"), "neg.toml"),
    )
