"""The virtual rig: determinism, hidden effects, noise floor, effect strengths."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from tcamlab import kinds, rig
from tcamlab.config import load_experiment
from tcamlab.effects import NO_MODS, Effect, EffectParam, Mods, combine, effects_for, get_effect
from tcamlab.errors import ConfigError
from tcamlab.io import read_run
from tcamlab.kinds import get_kind, predict
from tcamlab.rig import strength as rig_strength

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "tcamlab" / "templates"
KINDS = kinds.KINDS


def template(kind):
    return load_experiment(TEMPLATES / f"{kind}.toml", require_runs=False)


def model_options(kind, exp):
    """Options of forward.predict as the pipeline would know them (S from the template)."""
    if kind == "sensing":
        return {
            "spring_constant": template(kind).rig.spring_constant,
            "initial_resistance": exp.rig.initial_resistance,
        }
    if kind == "curvature":
        return {
            "spring_constant": exp.rig.spring_constant,
            "initial_resistances": (exp.rig.initial_resistance,) * 2,
        }
    if kind == "selfsensing":
        return {"initial_resistance": exp.rig.initial_resistance}
    return {}


def true_rig(kind, exp):
    """The generated experiment's rig with the template's S (hidden from the file)."""
    if kind == "sensing":
        return exp.rig.replace(spring_constant=template(kind).rig.spring_constant)
    return exp.rig


def residuals(kind, exp, mods=NO_MODS, **options):
    """{quantity: residuals pooled over runs} of the thesis model on the experiment's data."""
    out = {q: [] for q in get_kind(kind).outputs}
    for run in exp.read_runs():
        pred = predict(kind, exp.sample, exp.rig, run.data, mods, **(options or model_options(kind, exp)))
        for q in out:
            out[q].append(run.data[q].to_numpy(float) - np.asarray(pred[q], float))
    return {q: np.concatenate(v) for q, v in out.items()}


def files_of(res):
    return [res.experiment_path, *res.run_paths, res.truth_path]


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """Effect-free experiments of every kind (seed 11)."""
    out = tmp_path_factory.mktemp("clean")
    return {kind: rig.simulate(kind, TEMPLATES / f"{kind}.toml", seed=11, out_dir=out) for kind in KINDS}


# --- templates and config ----------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_templates_load_without_runs(kind):
    exp = template(kind)
    assert exp.kind == kind and exp.runs == ()
    assert "synthetic" in exp.title
    with pytest.raises(Exception):  # noqa: B017 (any refusal will do)
        load_experiment(TEMPLATES / f"{kind}.toml")  # runs = [] is refused by default


# --- files ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_written_files_load_back(clean, kind):
    res = clean[kind]
    exp = load_experiment(res.experiment_path, expected_kind=kind)
    assert len(exp.runs) == rig.DEFAULT_RUNS[kind] == 3
    assert exp.synthetic["seed"] == 11
    assert exp.synthetic["generator"].startswith("tcamlab simulate ")
    assert "synthetic" in exp.notes.lower()
    for p in res.run_paths:
        run = read_run(p, kind)
        assert set(get_kind(kind).outputs) <= set(run.data.columns)
        assert set(get_kind(kind).inputs) <= set(run.data.columns)
    assert [Path(p).resolve() for p in res.run_paths] == list(exp.runs)
    raw = tomllib.loads(res.experiment_path.read_text())
    assert all(r.startswith("../raw/") for r in raw["runs"])
    # Lab units in the file agree with the template's SI values.
    tmpl = template(kind)
    for f, v in tmpl.sample.model_kwargs().items():
        assert getattr(exp.sample, f) == pytest.approx(v, rel=1e-12), f
    truth = json.loads(res.truth_path.read_text())
    assert truth["seed"] == 11 and truth["effects"] == {} and len(truth["runs"]) == 3


def test_sensing_file_has_r0_but_not_s(clean):
    raw = tomllib.loads(clean["sensing"].experiment_path.read_text())
    assert raw["rig"]["initial_resistance_ohm"] == 30.0
    assert "spring_constant_N_per_m" not in raw["rig"]
    assert "spring_constant" not in clean["sensing"].experiment_path.read_text()


def test_protocols_are_as_documented():
    r = template("static").rig
    g = np.random.default_rng(0)
    st = rig.protocol("static", r, g)
    assert len(st) == 26 and np.allclose(np.diff(st["time"]), 300.0)
    assert abs(st["temperature"].iloc[0] - 25) < 2 and abs(st["temperature"].iloc[-1] - 150) < 2
    dy = rig.protocol("dynamic", template("dynamic").rig, g)
    assert len(dy) == 1000 and np.all(np.diff(dy["time"]) > 0)
    ms = dy["time"].to_numpy() * 1000
    assert np.allclose(ms, np.round(ms)) and np.all(np.abs(np.diff(ms) - 10) <= 2)
    on = dy["voltage"].to_numpy() > 0
    assert on.sum() == 100 and set(np.unique(dy["voltage"])) == {0.0, 10.0}
    assert dy["time"][on].iloc[0] == pytest.approx(0.5, abs=2e-3)
    se = rig.protocol("sensing", template("sensing").rig, g)
    x = se["elongation"].to_numpy()
    assert x.max() == pytest.approx(50e-3) and x[0] == 0 and x[-1] == 0
    assert np.allclose(np.diff(se["time"]), 0.1)
    cu = rig.protocol("curvature", template("curvature").rig, g)
    assert np.allclose(cu["cable"], np.arange(11) * 1e-3)


def test_dynamic_csv_time_is_integer_ms_and_voltage_as_commanded(clean):
    text = clean["dynamic"].run_paths[0].read_text().splitlines()
    assert text[0] == "time_s,voltage_V,displacement_mm"
    assert text[1] == "0.000,0.000,0.000"  # row 0 is the laser tare
    assert "temperature_C" not in text[0]


# --- determinism -------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_same_bytes_other_seed_other_data(tmp_path, kind):
    tpl = TEMPLATES / f"{kind}.toml"
    a = rig.simulate(kind, tpl, seed=3, out_dir=tmp_path / "a", command="x")
    b = rig.simulate(kind, tpl, seed=3, out_dir=tmp_path / "b", command="x")
    c = rig.simulate(kind, tpl, seed=4, out_dir=tmp_path / "c", command="x")
    for fa, fb in zip(files_of(a), files_of(b)):
        assert fa.read_bytes() == fb.read_bytes(), fa.name
    for fa, fc in zip(a.run_paths, c.run_paths):
        assert fa.read_bytes() != fc.read_bytes()


def test_shipped_sample_data_is_reproducible(tmp_path):
    """experiments/<kind>.toml and raw/ are what scripts/make_sample_data.sh makes."""
    for kind in KINDS:
        shipped = ROOT / "experiments" / f"{kind}.toml"
        if not shipped.exists():
            pytest.skip("sample data not generated")
        cmd = f"tcamlab simulate {kind} --experiment {kind} --seed 1 --out ."  # as recorded
        res = rig.simulate(kind, TEMPLATES / f"{kind}.toml", seed=1, out_dir=tmp_path, command=cmd)
        assert res.experiment_path.read_bytes() == shipped.read_bytes()
        for p in res.run_paths:
            assert p.read_bytes() == (ROOT / "raw" / p.name).read_bytes(), p.name


# --- effects are hidden -------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_experiment_and_csvs_do_not_reveal_effects(tmp_path, kind):
    names = [e.name for e in effects_for(kind)]
    active = {names[-1]: 4.0}
    cmd = f"tcamlab simulate {kind} --seed 2 --effect {names[-1]}=4"
    eff = rig.simulate(
        kind, TEMPLATES / f"{kind}.toml", seed=2, out_dir=tmp_path / "e", effects=active, command=cmd
    )
    none = rig.simulate(
        kind,
        TEMPLATES / f"{kind}.toml",
        seed=2,
        out_dir=tmp_path / "n",
        command=f"tcamlab simulate {kind} --seed 2",
    )
    # The experiment file is the same as without the effect ...
    assert eff.experiment_path.read_bytes() == none.experiment_path.read_bytes()
    # ... and neither it nor the CSVs name an effect or its parameters.
    info = eff.truth["effects"][names[-1]]
    texts = [eff.experiment_path.read_text()] + [p.read_text() for p in eff.run_paths]
    words = names + [f for e in effects_for(kind) for f in e.param_names] + ["effect"]
    values = [repr(v) for v in info["parameters"].values()] + [
        f"{v:.6g}" for v in info["parameters"].values()
    ]
    for text in texts:
        low = text.lower()
        for w in words + values:
            assert w.lower() not in low, w
    # The truth file has it all.
    assert info["requested_strength"] == 4.0
    assert info["achieved_strength"] == pytest.approx(4.0, rel=1e-6)
    assert "--effect" in eff.truth["command"]
    truth = json.loads(eff.truth_path.read_text())
    assert set(truth["effects"]) == {names[-1]}
    assert truth["mods"] and truth["noise_sd"]
    # The data do differ.
    assert eff.run_paths[0].read_bytes() != none.run_paths[0].read_bytes()


# --- noise floor ----------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_thesis_model_fits_effect_free_data_within_noise(clean, kind):
    exp = load_experiment(clean[kind].experiment_path)
    sd = rig.noise_sd(kind, exp.sample, true_rig(kind, exp))
    res = residuals(kind, exp)
    for q, r in res.items():
        ratio = math.sqrt(np.mean(r**2)) / sd[q]
        assert 0.7 < ratio < 1.5, (q, ratio)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_noise_floor_with_more_seeds(tmp_path, kind):
    """The noise sd is the floor on average, not only for one lucky seed."""
    ratios = {q: [] for q in get_kind(kind).outputs}
    for seed in (21, 22):
        res = rig.simulate(kind, TEMPLATES / f"{kind}.toml", seed=seed, out_dir=tmp_path / str(seed))
        exp = load_experiment(res.experiment_path)
        sd = rig.noise_sd(kind, exp.sample, true_rig(kind, exp))
        for q, r in residuals(kind, exp).items():
            ratios[q].append(math.sqrt(np.mean(r**2)) / sd[q])
    for q, v in ratios.items():
        assert 0.75 < np.mean(v) < 1.3, (q, v)


def test_noise_sd_contents():
    sd = rig.noise_sd("sensing")
    # Resistance noise propagated through the sensing inversion dominates displacement.
    assert sd["displacement"] > 10 * rig.instrument_sd("sensing")["displacement"]
    assert sd["resistance"] == pytest.approx(math.sqrt(2e-3**2 + 1e-3**2 / 12))
    st = rig.noise_sd("static")
    q = rig.LASER_QUANTUM_M
    assert q == pytest.approx(10e-3 / 1023)
    assert st["displacement"] >= math.sqrt(5e-6**2 + q**2 / 12)
    assert rig.noise_sd("dynamic")["displacement"] == pytest.approx(
        rig.instrument_sd("dynamic")["displacement"]
    )
    assert rig.noise_sd("curvature")["kappa1"] > 0.2
    assert rig.noise_sd("static", noise_scale=2.0)["temperature"] > 0.39


def test_noise_scale_zero_leaves_only_quantisation(tmp_path):
    res = rig.simulate(
        "curvature", TEMPLATES / "curvature.toml", seed=1, out_dir=tmp_path, noise_scale=0.0, scatter={}
    )
    exp = load_experiment(res.experiment_path)
    for q, r in residuals("curvature", exp).items():
        # resistance rounding to 1 mohm is all that is left
        assert math.sqrt(np.mean(r**2)) < 0.25 * rig.noise_sd("curvature")[q]


# --- effect strengths ---------------------------------------------------------------------------

CASES = [(k, e.name) for k in KINDS for e in effects_for(k)]


@pytest.mark.slow
@pytest.mark.parametrize("kind,name", CASES)
def test_strength_is_in_noise_sd(tmp_path, kind, name):
    res = rig.simulate(kind, TEMPLATES / f"{kind}.toml", seed=7, out_dir=tmp_path, effects={name: 5.0})
    info = res.truth["effects"][name]
    achieved = info["achieved_strength"]
    if info["limited_by"] is None:
        assert achieved == pytest.approx(5.0, rel=1e-6)
    else:  # the parameter hit its bound or the model's domain: recorded, and smaller
        assert achieved < 5.0
    exp = load_experiment(res.experiment_path)
    sd = res.truth["noise_sd"]
    res_q = residuals(kind, exp)
    z = np.concatenate([res_q[q] / sd[q] for q in info["quantities"]])
    gap = math.sqrt(np.mean(z**2))
    expected = math.sqrt(1.0 + achieved**2)
    assert 0.7 * expected < gap < 1.3 * expected, (gap, expected)
    # The active effect's model explains the data to the noise again.
    mods = Mods().replace(**info["parameters"], **info["fixed"])
    res_m = residuals(kind, exp, mods)
    z = np.concatenate([res_m[q] / sd[q] for q in info["quantities"]])
    assert math.sqrt(np.mean(z**2)) < 1.5


def test_explicit_value_and_two_effects(tmp_path):
    res = rig.simulate(
        "static",
        TEMPLATES / "static.toml",
        seed=1,
        out_dir=tmp_path,
        effects={"glass-transition": {"value": 0.2}, "displacement-drift": 3.0},
    )
    eff = res.truth["effects"]
    assert eff["glass-transition"]["parameters"] == {"glass_gain": 0.2}
    assert eff["glass-transition"]["achieved_strength"] > 0
    assert eff["displacement-drift"]["achieved_strength"] == pytest.approx(3.0, rel=1e-6)
    assert res.truth["mods"]["glass_gain"] == 0.2
    assert res.truth["mods"]["drift"] == eff["displacement-drift"]["parameters"]["drift"]
    assert res.truth["mods"].get("glass_temperature", 45.0) == 45.0


def test_negative_strength_goes_the_other_way():
    t = template("static")
    proto = rig.protocol("static", t.rig, np.random.default_rng(0))
    sd = rig.noise_sd("static", t.sample, t.rig)
    pos = rig.scale_effect("static", "displacement-drift", 2.0, t.sample, t.rig, proto, sd)
    neg = rig.scale_effect("static", "displacement-drift", -2.0, t.sample, t.rig, proto, sd)
    assert pos["parameters"]["drift"] > 0 > neg["parameters"]["drift"]
    assert neg["achieved_strength"] == pytest.approx(2.0, rel=1e-6)


# --- the static G(T) model ------------------------------------------------------------------------


def test_g_of_t_fits_the_static_sample_data_better_than_constant_g(clean):
    shipped = ROOT / "experiments" / "static.toml"
    exp = load_experiment(shipped if shipped.exists() else clean["static"].experiment_path)
    g_t = residuals("static", exp)["displacement"]
    const = residuals("static", exp, constant_g=True)["displacement"]
    sd = rig.noise_sd("static", exp.sample, exp.rig)["displacement"]
    assert math.sqrt(np.mean(g_t**2)) < 1.5 * sd
    assert math.sqrt(np.mean(const**2)) > 5 * math.sqrt(np.mean(g_t**2))


# --- scatter ---------------------------------------------------------------------------------------


def test_runs_differ_by_the_scatter(clean):
    truth = clean["static"].truth
    twists = [r["sample"]["twists"] for r in truth["runs"]]
    assert len(set(twists)) == 3
    assert np.allclose(twists, 150.0, rtol=0.01)
    lengths = [r["rig"]["segment_lengths"] for r in clean["curvature"].truth["runs"]]
    coils = [r["sample"]["coil_length"] for r in clean["curvature"].truth["runs"]]
    for seg, coil in zip(lengths, coils):
        assert sum(seg) == pytest.approx(coil)


def test_bad_arguments_are_config_errors(tmp_path):
    from tcamlab.errors import ConfigError

    with pytest.raises(ConfigError):
        rig.simulate("static", TEMPLATES / "dynamic.toml", seed=1, out_dir=tmp_path)
    with pytest.raises(ConfigError):
        rig.simulate(
            "static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path, effects={"no-such-effect": 1.0}
        )
    with pytest.raises(ConfigError):
        rig.simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path, scatter={"colour": 0.1})


# --- effects with two parameters ------------------------------------------------------------------


def test_two_parameter_effect_is_scaled_along_its_scale_vector(tmp_path):
    """A combined effect ('+'-joined names) scales both parameters together; the truth has both."""
    res = rig.simulate(
        "sensing",
        TEMPLATES / "sensing.toml",
        seed=5,
        out_dir=tmp_path,
        effects={"initial-slack+stress-relaxation": 3.0},
    )
    truth = json.loads(res.truth_path.read_text())
    info = truth["effects"]["initial-slack+stress-relaxation"]
    params = info["parameters"]
    assert set(params) == {"slack", "slack_length", "relaxation"}
    assert info["limited_by"] is None
    assert info["achieved_strength"] == pytest.approx(3.0, rel=1e-6)
    # All moved along (+scale): slack 0.5 mm, its take-up length 1 mm, relaxation 0.02.
    assert params["slack"] > 0 and params["relaxation"] / params["slack"] == pytest.approx(0.02 / 0.5e-3)
    assert params["slack_length"] / params["slack"] == pytest.approx(1e-3 / 0.5e-3)
    assert info["fixed"] == {"relaxation_tau": 1.5}
    assert truth["mods"] == params
    # The recorded parameters give the recorded strength when put back as values.
    t = template("sensing")
    proto = rig.protocol("sensing", t.rig, np.random.default_rng([5, 0]))
    sd = rig.noise_sd("sensing", t.sample, t.rig)
    joined = combine(get_effect("initial-slack", "sensing"), get_effect("stress-relaxation", "sensing"))
    again = rig.scale_effect(
        "sensing",
        joined,
        {"value": [params["slack"], params["slack_length"], params["relaxation"]]},
        t.sample,
        t.rig,
        proto,
        sd,
    )
    assert again["achieved_strength"] == pytest.approx(3.0, rel=1e-6)


def test_two_parameter_effect_object_stops_at_the_tighter_bound():
    """An Effect built from two EffectParams: the ray ends where the first parameter bound is met."""
    t = template("sensing")
    effect = Effect(
        "slack-and-stiffening",
        "sensing",
        (EffectParam("slack", "m", 0.5e-3, -2e-3, 10e-3), EffectParam("stiffening", "1/m", 5.0, -50.0, 0.5)),
        "test effect",
        "none",
        "none",
    )
    # The ray coordinate is the slack; stiffening = 1e4 slack. Along +scale stiffening
    # reaches its 0.5 when slack is 0.05 mm; along -scale slack meets its -2 mm first.
    assert rig_strength.ray_bound(effect, 1.0) == pytest.approx(0.05e-3)
    assert rig_strength.ray_bound(effect, -1.0) == pytest.approx(-2e-3)
    proto = rig.protocol("sensing", t.rig, np.random.default_rng(0))
    sd = rig.noise_sd("sensing", t.sample, t.rig)
    info = rig.scale_effect("sensing", effect, 1e6, t.sample, t.rig, proto, sd)
    assert info["limited_by"] == "bound"
    assert info["parameters"]["stiffening"] == pytest.approx(0.5)
    assert info["parameters"]["slack"] == pytest.approx(0.05e-3)
    with pytest.raises(ConfigError, match="one value per parameter"):
        rig.scale_effect("sensing", effect, {"value": 1e-4}, t.sample, t.rig, proto, sd)


def test_effects_that_cannot_act_together_are_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot act together"):
        rig.simulate(
            "static",
            TEMPLATES / "static.toml",
            seed=1,
            out_dir=tmp_path,
            effects={"displacement-drift+displacement-drift": 1.0},
        )


# --- two-condition experiments ---------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["static", "dynamic"])
def test_two_conditions_alternate_and_the_model_still_fits_within_noise(tmp_path, kind):
    from tcamlab.kinds.dynamic import SECOND_VOLTAGE_FACTOR
    from tcamlab.kinds.static import SECOND_LOAD_FACTOR

    res = rig.simulate(kind, TEMPLATES / f"{kind}.toml", seed=3, out_dir=tmp_path, conditions=2, n_runs=3)
    exp = load_experiment(res.experiment_path)
    runs = exp.read_runs()
    if kind == "static":
        loads = [float(r.data["load"].iloc[0]) for r in runs]
        expected = [exp.rig.force, exp.rig.force * SECOND_LOAD_FACTOR, exp.rig.force]
        assert loads == pytest.approx(expected, rel=1e-5)
        assert "load_N" in Path(res.run_paths[1]).read_text().splitlines()[0]
    else:
        peaks = [float(r.data["voltage"].max()) for r in runs]
        assert peaks == pytest.approx(
            [exp.rig.voltage, exp.rig.voltage * SECOND_VOLTAGE_FACTOR, exp.rig.voltage]
        )
    # the thesis model, given each run's logged condition, fits every run to within noise
    sd = rig.noise_sd(kind, exp.sample, true_rig(kind, exp))
    for q, r in residuals(kind, exp).items():
        assert 0.7 < math.sqrt(np.mean(r**2)) / sd[q] < 1.5, q
    assert "--conditions 2" in json.loads(Path(res.truth_path).read_text())["command"]


def test_a_static_run_logged_at_the_rig_load_predicts_as_the_rig_load():
    import pandas as pd

    exp = template("static")
    frame = pd.DataFrame({"temperature": np.linspace(25.0, 120.0, 12)})
    base = predict("static", exp.sample, exp.rig, frame)["displacement"]
    same = predict("static", exp.sample, exp.rig, frame.assign(load=exp.rig.force))["displacement"]
    heavier = predict("static", exp.sample, exp.rig, frame.assign(load=2 * exp.rig.force))["displacement"]
    np.testing.assert_allclose(same, base, rtol=0, atol=1e-15)
    # a heavier load changes the contraction with temperature (f11 F of (2.9) scales with it)
    assert np.max(np.abs(heavier - base)) > 1e-6


def test_a_kind_without_a_second_condition_refuses_two(tmp_path):
    with pytest.raises(ConfigError, match="no second condition"):
        rig.simulate("curvature", TEMPLATES / "curvature.toml", seed=1, out_dir=tmp_path, conditions=2)
    with pytest.raises(ConfigError, match="1 or 2"):
        rig.simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path, conditions=3)


def _with_protocol(tmp_path, channels):
    """The dynamic template with a [protocol] table of one 10 V pulse, two runs, these channels."""
    text = (TEMPLATES / "dynamic.toml").read_text()
    text += (
        '\n[protocol]\nkind = "dynamic"\nvoltages_V = [10.0]\npulse_s = 1.0\nruns = 2\n'
        f"channels = {json.dumps(channels)}\n"
    )
    path = tmp_path / "next.toml"
    path.write_text(text)
    return path


def test_a_protocols_channels_add_the_current_and_temperature_to_a_voltage_step_log(tmp_path):
    """SYNTHETIC (seed 3): current_A and temperature_C are the model's current and temperature
    through the current sense and the thermometer; the other columns are those of the same
    protocol without them, draw for draw."""
    base = ["time_s", "voltage_V", "displacement_mm"]
    plain = rig.simulate("dynamic", _with_protocol(tmp_path, base), seed=3, out_dir=tmp_path / "a")
    more = rig.simulate(
        "dynamic",
        _with_protocol(tmp_path, [*base, "current_A", "temperature_C"]),
        seed=3,
        out_dir=tmp_path / "b",
    )
    exp = load_experiment(more.experiment_path)
    for p0, p1 in zip(plain.run_paths, more.run_paths):
        a = read_run(p0, "dynamic", exp.columns).data
        b = read_run(p1, "dynamic", exp.columns).data
        assert "current" not in a and "temperature" not in a
        np.testing.assert_array_equal(a["displacement"].to_numpy(), b["displacement"].to_numpy())
        model = predict("dynamic", exp.sample, exp.rig, b[["time", "voltage"]], NO_MODS)
        on = b["voltage"].to_numpy() > 0
        assert model["current"][on] == pytest.approx(10.0 / 40.0)  # the thesis's constant R
        # the sense's noise (0.05 mA) and its 98 uA quantum, the thermometer's 0.2 degC and 0.1 degC
        assert np.abs(b["current"].to_numpy() - model["current"]).max() < 0.3e-3
        assert np.abs(b["temperature"].to_numpy() - model["temperature"]).max() < 1.2
        assert np.ptp(b["temperature"].to_numpy()) > 20.0  # the pulse heats the coil


def test_a_channel_the_voltage_step_rig_cannot_log_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="'force_N' is not a column the voltage-step rig logs"):
        rig.simulate(
            "dynamic", _with_protocol(tmp_path, ["time_s", "force_N"]), seed=1, out_dir=tmp_path / "c"
        )


def test_the_added_channels_chains_are_as_documented():
    from tcamlab.kinds import dynamic

    sd = dynamic.channel_sd()
    assert sd["current"] == pytest.approx(math.hypot(0.05e-3, 0.4 / 4095 / math.sqrt(12)))
    assert sd["temperature"] == pytest.approx(math.hypot(0.2, 0.1 / math.sqrt(12)))
    # the default log, and the load of a run at a second load (a known weight: exact)
    assert set(dynamic.instrument_sd()) == {"time", "voltage", "load", "displacement"}
    assert dynamic.instrument_sd()["load"] == 0.0
