"""The rig-kind registry: every registered kind fills in every part, consistently.

In the manner of python-control's ``kwargs_test.py``: the checks scan the
registry rather than list the kinds, so a new kind is held to them as soon as
it is registered.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect

import numpy as np
import pandas as pd
import pytest

from tcamlab import io as tio
from tcamlab import kinds
from tcamlab.config import load_experiment
from tcamlab.effects import EFFECTS, Mods
from tcamlab.errors import ConfigError, InputError
from tcamlab.params import Preset

ROOT = __import__("pathlib").Path(__file__).resolve().parent.parent
KIND_NAMES = sorted(kinds.REGISTRY)
CALLABLES = (
    "predict",
    "run_options",
    "validation_extras",
    "regimes",
    "figures",
    "extras_section",
    "protocol",
    "exact_inputs",
    "instrument_sd",
    "measure",
)


def test_registry_holds_the_four_thesis_kinds_and_nothing_else_branches_on_them():
    assert set(kinds.KINDS) == {"static", "dynamic", "sensing", "curvature", "selfsensing"}
    assert kinds.KINDS == tio.KINDS
    for name, kind in kinds.REGISTRY.items():
        assert kind.name == name


@pytest.mark.parametrize("name", KIND_NAMES)
def test_every_part_is_filled_in(name):
    kind = kinds.get_kind(name)
    for f in dataclasses.fields(kind):
        value = getattr(kind, f.name)
        if f.name == "strength_quantities":
            assert value is None or set(value) <= set(kind.outputs)
            continue
        if f.name == "rest_rule":  # None: the leading rows
            assert value is None or callable(value)
            continue
        assert value is not None, f"{name}: {f.name} is not set"
        if f.name in CALLABLES:
            assert callable(value), f"{name}: {f.name} is not callable"
    assert isinstance(kind.preset, Preset)
    assert kind.description and kind.min_rows >= 2 and kind.default_runs >= 1


@pytest.mark.parametrize("name", KIND_NAMES)
def test_columns_inputs_outputs_agree(name):
    kind = kinds.get_kind(name)
    internal = {tio.VARIABLE_MAP[c][0] for c in kind.required_columns}
    optional = {tio.VARIABLE_MAP[c][0] for c in kind.optional_columns}
    # every input and output is a logged column; the model predicts what is measured
    assert set(kind.outputs) <= internal
    assert {c for c in kind.inputs if c != "time"} <= internal
    assert set(kind.inputs) <= internal | optional
    assert not set(kind.inputs) & set(kind.outputs)
    assert set(kind.tension_outputs) <= set(kind.outputs)
    # an operating point may also be set by an optional logged column (a static run's load)
    assert set(kind.shared_inputs) <= set(kind.inputs) | optional
    assert set(kind.noisy_inputs) <= set(kind.inputs)
    assert kind.x_column in internal | optional
    # the virtual rig writes every required column, with a precision for each
    assert internal <= set(kind.logged_columns)
    canon = [tio.INTERNAL_TO_CANONICAL[c] for c in kind.logged_columns]
    assert set(canon) == set(kind.decimals)
    assert not set(kind.written_rig_fields) & set(kind.hidden_rig_fields)


@pytest.mark.parametrize("name", KIND_NAMES)
def test_predict_signature_and_variants(name):
    """predict(sample, rig, data, mods, **options): variants' options are keyword-only parameters."""
    kind = kinds.get_kind(name)
    params = inspect.signature(kind.predict).parameters
    assert list(params)[:4] == ["sample", "rig", "data", "mods"]
    assert params["mods"].default == Mods()
    for extra in kind.variants.values():
        assert set(extra) <= {p for p, v in params.items() if v.kind is v.KEYWORD_ONLY}
    assert kind.primary == next(iter(kind.variants))


@pytest.mark.parametrize("name", KIND_NAMES)
def test_every_effect_acts_through_fields_the_kind_documents(name):
    """Each effect of the kind sets Mods fields that the kind's predict docstring names."""
    kind = kinds.get_kind(name)
    doc = inspect.getdoc(kinds.get_kind(name).predict) or ""
    mine = [e for e in EFFECTS.values() if e.kind == name]
    assert mine, f"{name} has no effect in the library"
    for effect in mine:
        for p in effect.params:
            stem = p.field.split("_")[0]
            assert stem in doc, f"{effect.name}: {p.field} not documented in {kind.name}.predict"


@pytest.mark.parametrize("name", KIND_NAMES)
def test_predict_on_the_bundled_run_gives_every_output(name):
    exp = load_experiment(ROOT / "experiments" / f"{name}.toml")
    run = exp.read_runs()[0]
    kind = kinds.get_kind(name)
    training = [(r.data, np.ones(len(r.data), bool)) for r in exp.read_runs()[1:]]
    ro = kind.run_options(exp.sample, exp.rig, run.data, training=training)
    out = kinds.predict(name, exp.sample, exp.rig, run.data, **ro.options)
    for q in kind.outputs:
        assert np.asarray(out[q]).shape == (len(run.data),)
        assert np.all(np.isfinite(out[q]))
    for q in kind.outputs:
        labels = kind.regimes(run.data, q, [r.data for r in exp.read_runs()])
        assert labels and all(len(v) == len(run.data) for v in labels.values())


def test_unknown_kind_fails_in_one_place_with_the_choices():
    with pytest.raises(
        ConfigError, match="unknown kind 'oven'.*static, dynamic, sensing, curvature, selfsensing"
    ):
        kinds.get_kind("oven")
    with pytest.raises(ConfigError):
        kinds.predict("oven", None, None, pd.DataFrame())


def test_resistance_rule_is_the_stated_value_else_the_mean_at_rest():
    """One R0 rule for sensing and curvature: the rig's value wins; else the rest rows' mean."""
    sens = kinds.get_kind("sensing")
    preset = sens.preset
    sample, rig = preset.build_sample(), preset.build_rig()
    data = pd.DataFrame({"resistance": [30.02, 29.97, 30.01, 31.5, 33.0, 34.0], "time": np.arange(6.0)})
    # 3 rows at rest (within 2 % of the 4.03 ohm range of the first value), then the pull
    stated = sens.run_options(sample, rig.replace(initial_resistance=29.0), data)
    assert stated.options["initial_resistance"] == 29.0
    assert stated.info["initial_resistance_source"] == "experiment file"
    free = sens.run_options(sample, rig.replace(initial_resistance=None), data)
    assert free.options["initial_resistance"] == pytest.approx(30.0, abs=1e-12)
    assert free.info["initial_resistance_source"] == "mean of the 3 rows at rest"
    assert "spring_constant" not in free.options  # S is left to the caller without training data

    curv = kinds.get_kind("curvature")
    robot = curv.preset.build_rig()
    frame = pd.DataFrame(
        {"cable": [0, 0, 1e-3, 2e-3], "r1": [10.01, 9.99, 10.5, 11], "r2": [20, 20.02, 21, 22]}
    )
    ro = curv.run_options(curv.preset.build_sample(), robot.replace(initial_resistance=None), frame)
    assert ro.options["initial_resistances"] == pytest.approx((10.0, 20.01))
    ro = curv.run_options(curv.preset.build_sample(), robot.replace(initial_resistance=12.0), frame)
    assert ro.options["initial_resistances"] == (12.0, 12.0)


def test_spring_constant_is_never_identified_on_the_run_itself():
    sens = kinds.get_kind("sensing")
    sample, rig = sens.preset.build_sample(), sens.preset.build_rig().replace(spring_constant=None)
    x = np.linspace(0, 0.02, 20)
    other = pd.DataFrame({"displacement": x, "force": 3.0 * x, "resistance": 30 + x})
    own = pd.DataFrame({"displacement": x, "force": 9.0 * x, "resistance": 30 + x})
    ro = sens.run_options(sample, rig, own, training=[(other, np.ones(20, bool))], training_runs=["b"])
    assert ro.options["spring_constant"] == pytest.approx(3.0)
    assert ro.info["spring_constant_source"] == "identified leave-one-run-out from b"
    with pytest.raises(InputError, match="cannot be identified without using the run"):
        sens.run_options(sample, rig, own, training=[], where="x.toml")


@pytest.mark.parametrize("name", KIND_NAMES)
def test_virtual_rig_parts_agree_with_the_logged_columns(name):
    """protocol -> exact_inputs -> predict -> measure gives exactly the logged columns, each with an sd."""
    kind = kinds.get_kind(name)
    sample = kind.preset.build_sample()
    rig = kind.preset.build_rig().replace(**kind.simulation_rig_defaults)
    assert set(kind.simulation_rig_defaults) <= {f.name for f in dataclasses.fields(rig)}
    assert set(kind.program_options) <= set(inspect.signature(kind.protocol).parameters)
    sd = kind.instrument_sd(1.0)
    # the chains a protocol's channels may add (the voltage-step test's current and temperature)
    extra = getattr(importlib.import_module(kind.protocol.__module__), "channel_sd", lambda _: {})(1.0)
    assert not set(sd) & set(extra)
    assert set(sd) | set(extra) == set(kind.logged_columns) and all(v >= 0 for v in sd.values())
    required = {tio.VARIABLE_MAP[c][0] for c in kind.required_columns}
    # the stated condition, and the second one where the kind has it (static: a logged load)
    conditions = [{}] + ([{"condition": 1}] if "condition" in kind.program_options else [])
    for cond in conditions:
        proto = kind.protocol(rig, np.random.default_rng(0), **cond)
        inputs = kind.exact_inputs(sample, rig, proto, Mods())
        assert set(kind.inputs) <= set(inputs.columns)
        outputs = kind.predict(sample, rig, inputs, **kind.run_options(sample, rig, inputs).options)
        logged = kind.measure(inputs, outputs, np.random.default_rng(1), 1.0)
        # the kind's logged columns in file order; an optional one only where the run has it
        assert tuple(logged.columns) == tuple(c for c in kind.logged_columns if c in logged.columns)
        assert required <= set(logged.columns)
        assert len(logged) == len(proto)
        if extra:  # every added channel, in the logged columns' order
            more = kind.measure(inputs, outputs, np.random.default_rng(1), 1.0, channels=tuple(extra))
            assert tuple(more.columns) == tuple(c for c in kind.logged_columns if c in more.columns)
            assert set(extra) <= set(more.columns)
        # exact chains only: zero noise leaves a noise-free logged column equal to the exact value
        quiet = kind.measure(inputs, outputs, np.random.default_rng(1), 0.0)
        for c, v in sd.items():
            if v == 0 and c in quiet:
                assert np.array_equal(quiet[c].to_numpy(), inputs[c].to_numpy(float)), c
    if kind.name == "static":
        assert "load" in logged.columns  # the second condition logs its load
    if "load_N" in kind.program_options:  # a run at another load logs it, and the model reads it
        heavy = kind.exact_inputs(
            sample, rig, kind.protocol(rig, np.random.default_rng(0), load_N=2 * rig.force), Mods()
        )
        logged = kind.measure(heavy, kind.predict(sample, rig, heavy), np.random.default_rng(1), 1.0)
        assert np.allclose(logged["load"], 2 * rig.force)
        stated = kind.predict(sample, rig, heavy.drop(columns="load"))["displacement"]
        assert not np.allclose(kind.predict(sample, rig, heavy)["displacement"], stated)


@pytest.mark.parametrize("name", KIND_NAMES)
def test_calibration_parameters_name_real_fields(name):
    from tcamlab.params import Rig, Sample

    kind = kinds.get_kind(name)
    assert kind.calibration
    fields = {"sample": set(Sample.__dataclass_fields__), "rig": set(Rig.__dataclass_fields__)}
    for p in kind.calibration:
        assert p.field in fields[p.where], f"{name}: {p.field} is not a {p.where} field"
        assert p.default_sd > 0 and p.symbol and p.unit and p.pinned_by
    assert set(kind.nuisance_zeros) <= set(kind.outputs)


def _pull(rest, noise, rng, n=40):
    """A run logged at rest (``rest`` readings of R), then pulled: the cable jumps to a tenth
    of its range and ramps on, R along a straight line with noise."""
    return pd.DataFrame(
        {
            "cable": np.r_[np.zeros(len(rest)), np.linspace(0.1, 1.0, n) * 1e-2],
            "r1": np.r_[rest, np.linspace(10.5, 12.0, n) + rng.normal(0.0, noise, n)],
        }
    )


def test_rest_reading_is_the_mean_at_rest_with_its_run_to_run_sd():
    kind = kinds.get_kind("curvature")
    rng = np.random.default_rng(1)
    runs = [_pull([10.00, 10.02], 1e-4, rng), _pull([10.04], 1e-4, rng), _pull([9.98], 1e-4, rng)]
    mean, sd = kinds.rest_reading(kind, runs, ("r1",))
    at_rest = np.array([10.0, 10.02, 10.04, 9.98])  # rows before the cable moves
    assert mean == pytest.approx(at_rest.mean())
    # spread of all readings over sqrt(runs), not sqrt(readings)
    assert sd == pytest.approx(np.std(at_rest, ddof=1) / np.sqrt(3))
    assert kinds.rest_reading(kind, runs[1:2], ("r1",)) is None  # one reading: no spread
    assert kinds.rest_reading(kind, runs, ("r2",)) is None


def test_readings_that_agree_by_chance_keep_the_columns_noise():
    # three readings 0.1 mOhm apart on a meter whose noise over the run is 2 mOhm
    kind = kinds.get_kind("curvature")
    rng = np.random.default_rng(2)
    runs = [_pull([10.0 + 1e-4 * k], 2e-3, rng, n=200) for k in range(3)]
    mean, sd = kinds.rest_reading(kind, runs, ("r1",))
    assert mean == pytest.approx(10.0001)
    assert sd == pytest.approx(2e-3 / np.sqrt(3), rel=0.15)


def test_identical_readings_at_rest_keep_the_logging_step_as_their_spread():
    kind = kinds.get_kind("curvature")
    steps = np.ones(39)
    steps[[9, 19, 29]] = 2  # a smooth ramp on a 3-decimal log: step 0.001 ohm
    ramp = 10.0 + 0.001 * np.r_[0, np.cumsum(steps)]
    runs = [pd.DataFrame({"cable": np.arange(40) * 1e-4, "r1": ramp}) for _ in range(3)]
    mean, sd = kinds.rest_reading(kind, runs, ("r1",))
    assert mean == pytest.approx(10.0)
    assert sd == pytest.approx(0.001 / np.sqrt(12) / np.sqrt(3), rel=1e-6)


def test_only_the_curvature_r0_is_read_at_rest():
    # the straight body at zero cable has its sensors at rest length: the ohmmeters read R0
    read = {
        (n, p.field): p.read_at_rest
        for n in KIND_NAMES
        for p in kinds.get_kind(n).calibration
        if p.read_at_rest
    }
    assert read == {("curvature", "initial_resistance"): ("r1", "r2")}


def test_scored_quantities_are_the_outputs_and_what_every_run_logs_of_the_prediction():
    import pandas as pd

    from tcamlab.kinds import get_kind, scored_quantities

    kind = get_kind("dynamic")
    pred = {"displacement": 0, "temperature": 0, "current": 0, "resistance": 0}
    both = [pd.DataFrame(columns=["time", "voltage", "current", "displacement"])] * 2
    assert scored_quantities(kind, pred, both) == ("displacement", "current")
    one = [both[0], pd.DataFrame(columns=["time", "voltage", "displacement"])]
    assert scored_quantities(kind, pred, one) == ("displacement",)  # not every run logs it
    # an input the model passes through is never scored (its residual would be 0)
    assert scored_quantities(kind, {**pred, "voltage": 0}, both) == ("displacement", "current")


def test_a_pull_that_starts_at_the_first_row_has_no_rows_at_rest_beyond_it():
    """A pull at 38 um a row from the first row over 60 mm, with the resistance still within its
    noise for 30 rows: only the first row is at rest (the 2 % rule alone counted 33 moving rows
    and biased the R0 read from them). A log that waits 200 noisy rows before the pull keeps them."""
    from tcamlab.kinds import rest_rows

    rng = np.random.default_rng(5)
    n = 1600
    x = 0.0385e-3 * np.arange(n)
    r = 30.0 * (1 + 0.002 * x / 1e-3) + rng.normal(0, 0.005, n)
    kind = kinds.get_kind("sensing")
    moving = pd.DataFrame({"displacement": x, "force": 4.7 * x, "resistance": r})
    assert rest_rows(kind, moving).tolist() == [0]
    wait = np.r_[np.zeros(200), x[: n - 200]] + rng.normal(0, 1e-6, n)
    r_wait = 30.0 * (1 + 0.002 * wait / 1e-3) + rng.normal(0, 0.005, n)
    resting = pd.DataFrame({"displacement": wait, "force": 4.7 * wait, "resistance": r_wait})
    assert 195 <= rest_rows(kind, resting).size <= 201
