"""Validation: the metrics of every variant, quantity and run, computed against hand values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tcamlab.config import load_experiment
from tcamlab.kinds import KINDS, get_kind
from tcamlab.validation import validate

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("kind", KINDS)
def test_metrics_are_predicted_minus_measured_in_lab_units(kind):
    """bias = mean(predicted - measured), R² centred on the measurement, per run and pooled."""
    res = validate(load_experiment(ROOT / "experiments" / f"{kind}.toml"), mc_draws=0)
    k = get_kind(kind)
    assert res.variants == list(k.variants) and res.primary == k.primary
    for variant in res.variants:
        pooled_e, pooled_m = [], []
        for q in k.outputs:
            column = {"displacement": "displacement_mm", "force": "force_N"}.get(q, f"{q}_per_mm")
            factor = {"displacement": 1e3, "force": 1.0}.get(q, 1e-3)
            for p in res.predictions:
                meas = p.data[q].to_numpy() * factor
                e = p.predicted[variant][q] * factor - meas
                m = res.metrics[variant][column]["runs"][p.name]
                assert m["bias"] == pytest.approx(np.mean(e), rel=1e-12, abs=1e-15)
                assert m["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-12)
                r2 = 1.0 - np.sum(e**2) / np.sum((meas - meas.mean()) ** 2)
                assert m["r2"] == pytest.approx(r2, rel=1e-12)
            pooled_e.append(
                np.concatenate(
                    [
                        p.predicted[variant][q] * factor - p.data[q].to_numpy() * factor
                        for p in res.predictions
                    ]
                )
            )
            pooled_m.append(res.metrics[variant][column]["pooled"])
        for e, m in zip(pooled_e, pooled_m):
            assert m["bias"] == pytest.approx(np.mean(e), rel=1e-12, abs=1e-15)
            assert m["n"] == e.size


def test_constant_g_and_gt_differ_on_the_static_test():
    """The two static variants are different models: G(T) softens with temperature."""
    res = validate(load_experiment(ROOT / "experiments" / "static.toml"))
    p = res.predictions[0]
    diff = np.abs(p.predicted["G(T)"]["displacement"] - p.predicted["constant-G"]["displacement"])
    assert diff[0] == 0.0 and diff.max() > 1e-5  # same zero, apart by > 10 um when hot


def _null_dynamic(tmp_path, seed):
    """Synthetic: the virtual rig (tcamlab.rig.simulate), exact parameters, no effect, four
    runs each zeroed on one noisy reading (noisy_zero), seed as given."""
    from tcamlab import rig
    from tcamlab.templates import template_path

    res = rig.simulate(
        "dynamic", template_path("dynamic"), seed=seed, out_dir=tmp_path / str(seed), n_runs=4,
        scatter={}, noisy_zero=True,
    )  # fmt: skip
    return load_experiment(res.experiment_path), res.truth


def test_null_dynamic_with_noisy_zeros_validates_at_the_noise_floor(tmp_path):
    """With each run's zero estimated, the displacement RMSE is the laser's noise sd; without,
    it is about sqrt(2) of it (each run keeps its first reading's noise as an offset)."""
    from tcamlab import instruments

    laser = instruments.laser_sd()
    raw_ms, row0_residuals = [], []
    for seed in (31, 32, 33):
        exp, truth = _null_dynamic(tmp_path, seed)
        res = validate(exp, mc_draws=0)
        m = res.metrics["G(T)"]["displacement_mm"]["pooled"]
        assert 0.9 <= m["rmse"] * 1e-3 / laser <= 1.15, seed
        # the re-zeroed first row is a measured point: counted, and no longer a zero residual
        assert m["n"] == 4000 and m["n_zeros"] == 4
        for p, t in zip(res.predictions, truth["runs"]):
            z = p.zeros["displacement"]
            assert z.source == "rest rows" and z.rows == 50
            assert abs(z.value - t["zero_error"]["displacement"]) < 4 * z.stderr
            row0 = p.predicted["G(T)"]["displacement"][0] - p.data["displacement"].iloc[0]
            assert row0 == pytest.approx(z.value, abs=1e-15)
            row0_residuals.append(row0)
        raw = validate(exp, mc_draws=0, zeros=False).metrics["G(T)"]["displacement_mm"]["pooled"]
        raw_ms.append((raw["rmse"] * 1e-3 / laser) ** 2)
    # the same data without the zeros: what this test would see if they were not estimated
    assert math.sqrt(np.mean(raw_ms)) > 1.2
    assert np.count_nonzero(row0_residuals) >= 10  # a quantised log may average to exactly 0


def test_zeros_are_reported_in_metrics_json_and_predictions_csv():
    """metrics.json carries each zero in lab units with its interval; predictions.csv keeps the
    logged value and adds the zero, so the residual can be recomputed from the file."""
    res = validate(load_experiment(ROOT / "experiments" / "sensing.toml"), mc_draws=0)
    doc = res.to_dict()
    zeros = doc["zeros"]["runs"]
    assert set(zeros) == {p.name for p in res.predictions}
    for p in res.predictions:
        z = zeros[p.name]["force_N"]
        assert z["value"] == pytest.approx(p.zeros["force"].value) and z["source"] == "rest rows"
        assert z["ci95"][0] < z["value"] < z["ci95"][1] and z["stderr"] > 0
    table = res.to_pandas()
    first = table[table["run"] == res.predictions[0].name]
    logged = res.runs[0].data["force"].to_numpy()
    np.testing.assert_allclose(first["measured_force_N"], logged)
    resid = first["predicted_force_N__thesis"] - (first["measured_force_N"] - first["zero_force_N"])
    e = res.predictions[0].predicted["thesis"]["force"] - res.predictions[0].data["force"].to_numpy()
    np.testing.assert_allclose(resid, e, atol=1e-15)
    assert "zero_displacement_mm" not in table  # the encoder is not zeroed on the run


def test_every_model_is_scored_after_its_own_nuisance_zero():
    """A second model whose estimate is referenced to its own rest (the self-sensing EKF) is not
    charged the primary model's rest offset: the measurement keeps the primary's zero, the
    other model's prediction moves by the difference of the two zeros."""
    import pandas as pd

    from tcamlab.kinds import get_kind
    from tcamlab.validation import RunPrediction, _subtract_zeros

    kind = get_kind("static")
    primary, other = list(kind.variants)
    n = 60
    temp = np.r_[np.full(20, 25.0), np.linspace(25.0, 150.0, n - 20)]
    truth = 1e-5 * (temp - 25.0)
    measured = truth + 3e-4  # the laser's zero: 0.3 mm
    data = pd.DataFrame({"time": np.arange(n, dtype=float), "temperature": temp, "displacement": measured})
    # the primary is right; the other is right up to a 0.5 mm offset of its own reference
    p = RunPrediction("run1", data, {primary: {"displacement": truth}, other: {"displacement": truth + 5e-4}})
    _subtract_zeros(kind, [p])
    assert p.zeros["displacement"].value == pytest.approx(3e-4)
    np.testing.assert_allclose(p.data["displacement"], truth, atol=1e-15)
    # the other model after its own zero: no error left (with the primary's it would be 0.5 mm)
    np.testing.assert_allclose(p.predicted[other]["displacement"], truth, atol=1e-15)
    # each model's own zero is recorded (metrics.json zeros.by_model)
    assert p.variant_zeros[primary]["displacement"] is p.zeros["displacement"]
    assert p.variant_zeros[other]["displacement"].value == pytest.approx(-2e-4)


def _static_rewritten(tmp_path, temperature_unit="K", displacement_scale=1):
    """The bundled static experiment with its temperatures written in degF, declared in
    ``temperature_unit`` (K: they load, above absolute zero, but start near -196 degC), and its
    displacement read with ``displacement_scale``."""
    root = Path(__file__).resolve().parent.parent
    exp = load_experiment(root / "experiments" / "static.toml")
    runs = []
    for i, r in enumerate(exp.read_runs()):
        d = r.data
        f = d["temperature"].to_numpy() * 9 / 5 + 32
        lines = ["t,T_F,x"] + [
            f"{t:.6g},{tf:.6g},{1e3 * x:.6g}" for t, tf, x in zip(d["time"], f, d["displacement"])
        ]
        (tmp_path / f"run{i}.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
        runs.append(f'"run{i}.csv"')
    body = (root / "experiments" / "static.toml").read_text(encoding="utf-8")
    body = body.replace(
        body[body.index("runs = [") : body.index("]", body.index("runs = [")) + 1],
        f"runs = [{', '.join(runs)}]",
    )
    body += (
        f'\n[columns]\ntime_s = {{from = "t", unit = "s"}}\ntemperature_C = {{from = "T_F", unit = "{temperature_unit}"}}\n'
        f'displacement_mm = {{from = "x", unit = "mm", scale = {displacement_scale}}}\n'
    )
    path = tmp_path / "static.toml"
    path.write_text(body, encoding="utf-8")
    return load_experiment(path)


def test_a_temperature_in_another_unit_is_a_warning_of_validate_calibrate_and_diagnose(tmp_path):
    """A degF column read as K gave `miscalibrated (radial_cte)` and a validation with no word
    on the unit; every command that gives a figure now says the temperature is implausible."""
    from tcamlab.calibration import calibrate
    from tcamlab.diagnosis import diagnose

    exp = _static_rewritten(tmp_path)
    res = validate(exp, mc_draws=0)
    first = res.warnings[0]
    assert first.check == "implausible-value" and first.quantity == "temperature"
    assert first.values["lowest"] == pytest.approx(-196, abs=2) and 'unit = "degF"' in first.message
    assert "implausible-value" in res.to_dict()["warnings"][0]["check"]
    cal = calibrate(exp, params="radial_cte")
    assert sum("temperature falls to" in n for n in cal.notes) == 3
    diag = diagnose(exp, effects=["displacement-drift"], n_boot=50)
    assert len(diag.warnings) == 3 and diag.to_dict()["warnings"] == diag.warnings
    # the bundled log, in degC, carries none
    bundled = load_experiment(Path(__file__).resolve().parent.parent / "experiments" / "static.toml")
    assert not [w for w in validate(bundled, mc_draws=0).warnings if w.check == "implausible-value"]


def test_a_displacement_logged_with_the_opposite_sign_is_a_warning_and_not_a_calibration(tmp_path):
    """An oven log whose contraction counts positive (scale +0.2 for a % column where -0.2 is
    right): validate and diagnose say the measurement moves against the model; calibrate, which
    fits it by flipping rho's sign against the box edge, says both, and validating the
    calibrated file (R² 0.999) warns that rho has the opposite sign to the stated value."""
    from tcamlab.calibration import calibrate, calibrated_path, calibrated_text
    from tcamlab.diagnosis import diagnose

    exp = _static_rewritten(tmp_path, temperature_unit="degF", displacement_scale=-1)
    res = validate(exp, mc_draws=0)
    flipped = [w for w in res.warnings if w.check == "opposite-direction"]
    assert len(flipped) == 1 and flipped[0].values["correlation"] < -0.99
    (tmp_path / "ok").mkdir()
    assert not [w for w in validate(_static_rewritten(tmp_path / "ok", "degF"), mc_draws=0).warnings]
    cal = calibrate(exp)
    rho = next(p for p in cal.parameters if p.field == "radial_cte")
    assert rho.value < 0
    assert any("rho) = " in n and "opposite sign to the stated 8.1e-05" in n for n in cal.notes)
    assert any("rho) stopped at the edge of its search range" in n for n in cal.notes)
    out = calibrated_path(exp)
    out.write_text(calibrated_text(exp, cal), encoding="utf-8")
    calibrated = load_experiment(out)
    signs = [w for w in validate(calibrated, mc_draws=0).warnings if "opposite sign" in w.message]
    assert [w.check for w in signs] == ["parameter-far-from-stated"]
    diag = diagnose(exp, effects=["displacement-drift"], n_boot=50)
    assert any("moves against the model" in w for w in diag.warnings)


def test_one_dead_channel_beside_live_runs_is_named():
    """A laser stuck at 0 in one run of three: the pooled measurement varies, so only the run's
    own check can say its channel is dead."""
    import dataclasses

    exp = load_experiment(Path(__file__).resolve().parent.parent / "experiments" / "static.toml")
    runs = exp.read_runs()
    dead = runs[1].data.assign(displacement=0.0)
    runs[1] = dataclasses.replace(runs[1], data=dead)
    warned = [w for w in validate(exp, runs, mc_draws=0).warnings if w.check == "flat-prediction"]
    assert [w.run for w in warned] == ["static_run2"] and "is constant (0 mm on every row)" in warned[
        0
    ].message
    assert not [w for w in validate(exp, mc_draws=0).warnings if w.check == "flat-prediction"]
