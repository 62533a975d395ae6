"""tcamlab design: the separation criterion, the menus' limits, the ranking on an aliased
static case, the protocol file through the virtual rig, and the CLI's refusal to overwrite."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.design import design, protocol_toml
from tcamlab.design.score import pair_separation, refit_separation, separation
from tcamlab.kinds import dynamic, static
from tcamlab.models import static as static_model
from tcamlab.rig import simulate
from tcamlab.templates import TEMPLATES

# A static diagnosis as tcamlab diagnose wrote it (3 heating runs at one load, the true
# effect youngs-modulus-temperature withheld): recalibration and shear-modulus-temperature
# fit the withheld runs alike. Only the fields design reads, covariances to 4 digits.
ALIASED = {
    "kind": "static",
    "verdict": "miscalibrated",
    "effect": None,
    "aliased_with": ["shear-modulus-temperature"],
    "noise_floor": {"by_quantity": {"displacement": {"sigma": 0.00576, "unit": "mm"}}},
    "ranking": [
        {
            "effect": "recalibration",
            "recalibrated": {
                "radial_cte": {
                    "value": 7.913e-05,
                    "ci95": [6.633e-05, 9.194e-05],
                    "unit": "1/K",
                    "prior_sd": 2.43e-05,
                },
                "shear_modulus_slope": {
                    "value": 1.1976e6,
                    "ci95": [9.803e5, 1.415e6],
                    "unit": "Pa/K",
                    "prior_sd": 3.33e5,
                },
                "youngs_modulus": {
                    "value": 3.3764e9,
                    "ci95": [2.357e9, 4.836e9],
                    "unit": "Pa",
                    "prior_sd": 6.9e8,
                },
            },
            "recalibrated_shift": {
                "covariance": [
                    [0.07229, -0.07296, -0.04872],
                    [-0.07296, 0.1109, 0.05435],
                    [-0.04872, 0.05435, 0.0336],
                ]
            },
            "parameters": {},
        },
        {
            "effect": "shear-modulus-temperature",
            "recalibrated": {
                "radial_cte": {
                    "value": 8.310e-05,
                    "ci95": [5.019e-05, 1.160e-04],
                    "unit": "1/K",
                    "prior_sd": 2.43e-05,
                },
                "shear_modulus_slope": {
                    "value": 1.1385e6,
                    "ci95": [6.598e5, 1.617e6],
                    "unit": "Pa/K",
                    "prior_sd": 3.33e5,
                },
                "youngs_modulus": {
                    "value": 3.4501e9,
                    "ci95": [2.331e9, 5.106e9],
                    "unit": "Pa",
                    "prior_sd": 6.9e8,
                },
            },
            "recalibrated_shift": {
                "covariance": [
                    [0.4774, -0.4902, -0.0003524],
                    [-0.4902, 0.538, -0.0003208],
                    [-0.0003524, -0.0003208, 0.04],
                ]
            },
            "parameters": {
                "coil_shear_slope": {
                    "value": 4109.4,
                    "ci95": [-27555.0, 35774.0],
                    "stderr": 16155.7,
                    "unit": "Pa/K",
                }
            },
        },
    ],
}


def test_pair_separation_by_hand():
    # rows: (0 - 1)^2 / (1 + 0.1 + 0.1) + (2 - 0)^2 / (1 + 0.5 + 0.5) = 1/1.2 + 4/2
    d = pair_separation([0.0, 2.0], [0.1, 0.5], [1.0, 0.0], [0.1, 0.5], 1.0)
    assert d == pytest.approx(1 / 1.2 + 2.0)
    # three hypotheses: the hardest pair is the closest (a vs c: 0.25 / 1)
    worst, D = separation([np.array([0.0]), np.array([3.0]), np.array([0.5])], [np.zeros(1)] * 3, 1.0)
    assert worst == pytest.approx(0.25) and D[0, 1] == pytest.approx(9.0) and D[1, 2] == pytest.approx(6.25)


def test_refit_separation_by_hand():
    # i: two rows at 1, no spread; j: rows at 0 with draws 0 +- 1 moving both rows together.
    # R = z^T (I + A A^T)^-1 z with z = (1, 1), A = [[1, -1], [1, -1]]: 2 / (1 + 4) = 0.4;
    # the diagonal D sees only var_j = 2 per row: 2 x 1 / (1 + 2)
    i = np.array([[1.0, 1.0]])
    j = np.array([[1.0, 1.0], [-1.0, -1.0]])
    assert refit_separation(i, j, 1.0) == pytest.approx(0.4)
    assert pair_separation(i.mean(0), 0.0, j.mean(0), j.var(0, ddof=1), 1.0) == pytest.approx(2 / 3)


def test_static_menu_stays_where_g_is_positive():
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    for slope in (exp.sample.shear_modulus_slope, 1.6 * exp.sample.shear_modulus_slope):
        sample = exp.sample.replace(shear_modulus_slope=slope)
        g = static_model.sample_shear_modulus(
            sample.fiber_diameter,
            sample.fiber_length,
            sample.twists,
            sample.youngs_modulus,
            sample.thread_plies,
            sample.max_volume_fraction,
        )
        limit_c = exp.rig.ambient + float(static_model.max_temperature_rise(g, slope))
        for name, table in static.design_menu(sample, exp.rig):
            if name.startswith("wider"):
                assert table["temperature_C"][1] <= min(limit_c - static.G_LIMIT_MARGIN_C, static.MAX_OVEN_C)
                assert table["temperature_C"][1] > 150.0


def test_dynamic_menu_has_second_voltages_and_a_train():
    exp = load_experiment(TEMPLATES / "dynamic.toml", require_runs=False)
    menu = dict(dynamic.design_menu(exp.sample, exp.rig))
    v0 = exp.rig.voltage
    assert menu["second voltage 0.8x"]["voltages_V"] == [v0, round(0.8 * v0, 3)]
    frames = [
        dynamic.protocol(exp.rig, np.random.default_rng(0), **o)
        for o in dynamic.protocol_runs(menu["pulse train of 3"], exp.rig)
    ]
    on = np.diff((frames[0]["voltage"].to_numpy() > 0).astype(int))
    assert (on == 1).sum() == 3


def test_design_ranks_a_second_load_above_a_repeat_on_an_aliased_static_case():
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    res = design(exp, ALIASED, n_draws=8)
    by = {c.name: c for c in res.candidates}
    assert res.status == "ambiguous" and res.best is not None
    assert len(res.best.table["loads_g"]) == 2
    assert by["second load 1.5x"].separation_refit > by["repeat (same protocol)"].separation_refit
    for other in ("repeat (same protocol)", "longer dwell 900 s"):
        assert by["second load 1.5x"].per_hour > by[other].per_hour
        assert by["second load 1.5x"].separation > by[other].separation


def test_clear_diagnosis_needs_no_separating_experiment():
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    clear = {**ALIASED, "verdict": "miscalibrated", "aliased_with": []}
    res = design(exp, clear, n_draws=12)
    assert res.status == "clear" and "no further experiment" in res.message
    # for precision: every feasible protocol narrows the recalibrated parameters, more runs more
    by = {c.name: c for c in res.candidates if c.feasible}
    assert all(0 < c.information_gain and max(c.sd_ratio.values()) <= 1.0 + 1e-9 for c in by.values())
    assert by["second load 1.5x"].information_gain > by["repeat (same protocol)"].information_gain
    res = design(exp, {**ALIASED, "verdict": "unexplained", "aliased_with": []})
    assert res.status == "unexplained" and res.best is None and "outside the library" in res.message


def test_protocol_file_round_trips_through_the_rig(tmp_path):
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    table = dict(static.design_menu(exp.sample, exp.rig))["second load 1.5x, heat-cool"]
    path = tmp_path / "t.next.toml"
    path.write_text(protocol_toml(exp.raw, table, "test"), encoding="utf-8")
    back = load_experiment(path, require_runs=False)
    assert back.raw["protocol"] == table
    out = simulate("static", path, seed=2, out_dir=tmp_path / "sim")
    assert len(out.run_paths) == table["runs"]
    loads = []
    for p in out.run_paths:
        lines = p.read_text().splitlines()
        assert lines[0].split(",")[2] == "load_N" and len(lines) == 1 + 51  # heat-cool: 51 readings
        loads.append(float(lines[1].split(",")[2]))
    g = 9.80665e-3
    assert loads == pytest.approx([50 * g, 75 * g, 50 * g, 75 * g], rel=1e-5)


def test_cli_refuses_to_overwrite_the_protocol_file(tmp_path):
    exp = simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path).experiment_path
    diag = tmp_path / "diagnosis.json"
    diag.write_text(json.dumps(ALIASED), encoding="utf-8")
    target = exp.with_name(exp.stem + ".next.toml")
    target.write_text("# mine\n", encoding="utf-8")
    result = CliRunner().invoke(app, ["design", str(exp), "--diagnosis", str(diag)])
    assert result.exit_code == 2
    assert len(result.output.strip().splitlines()) == 1 and "exists" in result.output
    assert target.read_text() == "# mine\n"


def test_cli_writes_the_protocol_file_and_design_json(tmp_path):
    exp = simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path).experiment_path
    diag = tmp_path / "diagnosis.json"
    diag.write_text(json.dumps(ALIASED), encoding="utf-8")
    result = CliRunner().invoke(
        app, ["design", str(exp), "--diagnosis", str(diag), "--out", str(tmp_path / "rep")]
    )
    assert result.exit_code == 0, result.output
    assert "separation" in result.output and "out of bounds" in result.output
    written = load_experiment(exp.with_name(exp.stem + ".next.toml"))
    assert len(written.raw["protocol"]["loads_g"]) == 2 and written.runs == load_experiment(exp).runs
    saved = json.loads((tmp_path / "rep" / exp.stem / "design.json").read_text())
    assert saved["status"] == "ambiguous" and f"*{saved['best']}" in result.output
