"""The virtual rig that lies like a real lab: true parameters off the stated ones, noisy zeros."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

from tcamlab import benchmark, instruments, rig
from tcamlab.config import load_experiment
from tcamlab.errors import ConfigError
from tcamlab.kinds import predict
from tcamlab.rig.lies import draw_parameters, stated_sds
from tcamlab.templates import template_path
from tcamlab.text import public_command

KINDS = ("static", "dynamic", "sensing", "curvature")


def template(kind):
    return load_experiment(template_path(kind), require_runs=False)


def files_of(out):
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("kind", KINDS)
def test_options_off_are_byte_identical(tmp_path, kind):
    """The defaults written out change no byte (the shipped raw/ data pin the bytes themselves:
    test_rig.test_shipped_sample_data_is_reproducible)."""
    a, b = tmp_path / "a", tmp_path / "b"
    rig.simulate(kind, template_path(kind), seed=11, out_dir=a, command="c")
    rig.simulate(
        kind,
        template_path(kind),
        seed=11,
        out_dir=b,
        command="c",
        parameter_error=0.0,
        parameter_offsets=None,
        uncertainty=None,
        noisy_zero=False,
    )
    assert files_of(a) == files_of(b)
    truth = json.loads((a / "truth" / f"{kind}.truth.json").read_text())
    assert "true_parameters" not in truth and "noisy_zero" not in truth
    assert all("zero_error" not in r for r in truth["runs"])


def test_explicit_offset_is_exact_and_the_csvs_follow_the_true_value(tmp_path):
    exp = template("dynamic")
    res = rig.simulate(
        "dynamic",
        exp,
        seed=3,
        out_dir=tmp_path,
        scatter={},
        noise_scale=0.0,
        parameter_offsets={"thermal_mass": 1.5},
    )
    rec = res.truth["true_parameters"]["thermal_mass"]
    assert rec["stated"] == exp.rig.thermal_mass and rec["sd"] == exp.rig.uncertainty["thermal_mass"]
    assert rec["true"] == pytest.approx(exp.rig.thermal_mass + 1.5 * rec["sd"], rel=1e-12)
    assert rec["offset_sd"] == pytest.approx(1.5)
    # The other stated parameters are not moved without a parameter error.
    for fld in ("heat_loss", "damping"):
        assert res.truth["true_parameters"][fld]["true"] == getattr(exp.rig, fld)
    assert all(r["rig"]["thermal_mass"] == rec["true"] for r in res.truth["runs"])
    # The experiment file states the stated value, and nothing of the lie.
    written = load_experiment(res.experiment_path)
    assert written.rig.thermal_mass == exp.rig.thermal_mass
    assert "parameter" not in res.experiment_path.read_text()
    # Refit-free: the logged displacement is the model with the TRUE C_th, up to the chain.
    true_rig = exp.rig.replace(thermal_mass=rec["true"])
    for run in written.read_runs():
        d = run.data
        with_true = predict("dynamic", exp.sample, true_rig, d)["displacement"]
        with_stated = predict("dynamic", exp.sample, exp.rig, d)["displacement"]
        logged = d["displacement"].to_numpy(float)
        chain = instruments.LASER_QUANTUM_M + instruments.LASER_LOG_RESOLUTION_M
        assert np.max(np.abs(logged - with_true)) <= chain
        assert np.max(np.abs(logged - with_stated)) > 5 * chain


def test_random_draw_is_recorded_consistently_and_kept_out_of_the_file(tmp_path, monkeypatch):
    exp = template("dynamic")
    for sub in ("lying", "honest", "again"):
        (tmp_path / sub).mkdir()
    monkeypatch.chdir(tmp_path / "lying")
    res = rig.simulate("dynamic", exp, seed=5, out_dir="lab", parameter_error=1.0)
    lying_files = [res.experiment_path.read_bytes(), res.run_paths[0].read_bytes()]
    truth = res.truth
    assert truth["parameter_error"] == 1.0
    assert set(truth["true_parameters"]) == {"thermal_mass", "heat_loss", "damping"}
    for fld, rec in truth["true_parameters"].items():
        stated, sd, z = rec["stated"], rec["sd"], rec["z"]
        s2 = math.log1p((sd / stated) ** 2)
        assert rec["distribution"] == "log-normal"
        assert rec["true"] == pytest.approx(math.exp(math.log(stated) - s2 / 2 + math.sqrt(s2) * z))
        assert rec["offset_sd"] == pytest.approx((rec["true"] - stated) / sd)
        assert rec["true"] > 0 and rec["true"] != stated
        assert all(r["rig"][fld] == rec["true"] for r in truth["runs"])
    # The written file equals the one of an honest rig: same stated values, same command.
    monkeypatch.chdir(tmp_path / "honest")
    honest = rig.simulate("dynamic", exp, seed=5, out_dir="lab")
    assert lying_files[0] == honest.experiment_path.read_bytes()
    assert lying_files[1] != honest.run_paths[0].read_bytes()
    assert "--parameter-error 1" in truth["command"]
    monkeypatch.chdir(tmp_path / "again")
    again = rig.simulate("dynamic", exp, seed=5, out_dir="lab", parameter_error=1.0)
    assert again.truth["true_parameters"] == truth["true_parameters"]


def test_draws_have_the_stated_mean_and_f_times_the_stated_sd():
    exp = template("dynamic")
    sds = stated_sds(exp)
    trues = []
    for seed in range(2000):
        _, true_rig, _ = draw_parameters(
            "dynamic", exp.sample, exp.rig, sds, error=0.5, offsets=None, seed=seed
        )
        trues.append(true_rig.thermal_mass)
    trues = np.asarray(trues)
    sd = 0.5 * sds["thermal_mass"]
    assert abs(trues.mean() - exp.rig.thermal_mass) < 4 * sd / math.sqrt(trues.size)
    assert trues.std() == pytest.approx(sd, rel=0.08)
    assert trues.min() > 0


def test_sample_parameters_from_extra_uncertainty(tmp_path):
    res = rig.simulate(
        "static",
        template("static"),
        seed=2,
        out_dir=tmp_path,
        parameter_error=1.0,
        uncertainty={"radial_cte": 8.1e-6, "youngs_modulus": 0.1725e9},
    )
    tp = res.truth["true_parameters"]
    assert tp["radial_cte"]["table"] == "sample" and tp["radial_cte"]["distribution"] == "normal"
    assert tp["radial_cte"]["offset_sd"] == pytest.approx(tp["radial_cte"]["z"])
    for r in res.truth["runs"]:
        assert r["sample"]["radial_cte"] == tp["radial_cte"]["true"]
        assert r["sample"]["youngs_modulus"] == tp["youngs_modulus"]["true"]
    written = load_experiment(res.experiment_path)
    assert written.sample.radial_cte == tp["radial_cte"]["stated"] == template("static").sample.radial_cte
    assert set(tp) == {
        "radial_cte",
        "youngs_modulus",
    }  # the unused C_th, lambda, b sds of the preset are not drawn


def test_bad_lies_are_config_errors(tmp_path):
    exp = template("dynamic")
    with pytest.raises(ConfigError, match="no stated uncertainty"):
        rig.simulate("dynamic", exp, seed=1, out_dir=tmp_path, parameter_offsets={"load": 1.0})
    with pytest.raises(ConfigError, match="parameter_error"):
        rig.simulate("dynamic", exp, seed=1, out_dir=tmp_path, parameter_error=-1.0)
    with pytest.raises(ConfigError, match="not positive"):
        rig.simulate("dynamic", exp, seed=1, out_dir=tmp_path, parameter_offsets={"thermal_mass": -4.0})
    with pytest.raises(ConfigError, match="thread_plies"):
        rig.simulate("static", template("static"), seed=1, out_dir=tmp_path, parameter_error=1.0,
                     uncertainty={"thread_plies": 1.0})  # fmt: skip


def _run_offsets(tmp_path, noisy_zero: bool, n_runs: int):
    """Per run: (mean of data - exact model over the rows after the first, recorded zero error)."""
    exp = template("dynamic")
    res = rig.simulate(
        "dynamic", exp, seed=9, out_dir=tmp_path, n_runs=n_runs, scatter={}, noisy_zero=noisy_zero
    )
    written = load_experiment(res.experiment_path)
    offsets = []
    for run in written.read_runs():
        d = run.data
        resid = d["displacement"].to_numpy(float) - predict("dynamic", exp.sample, exp.rig, d)["displacement"]
        offsets.append(float(np.mean(resid[1:])))
    zeros = [r.get("zero_error", {}).get("displacement") for r in res.truth["runs"]]
    return np.asarray(offsets), zeros


@pytest.mark.slow
def test_noisy_zero_offsets_every_run_by_about_one_laser_sd(tmp_path):
    n = 40
    noisy, zeros = _run_offsets(tmp_path / "noisy", True, n)
    tared, none = _run_offsets(tmp_path / "tared", False, n)
    laser = instruments.laser_sd()
    assert 0.7 * laser < noisy.std(ddof=1) < 1.35 * laser
    assert np.sqrt(np.mean(tared**2)) < 0.3 * laser
    assert none == [None] * n
    # The truth file's zero error is the offset the rows carry.
    se = 3 * laser / math.sqrt(999) + instruments.LASER_LOG_RESOLUTION_M
    assert np.max(np.abs(noisy - np.asarray(zeros))) < se


def test_noisy_zero_redraws_the_load_cell_tare_per_run(tmp_path):
    exp = template("sensing")
    res = rig.simulate("sensing", exp, seed=4, out_dir=tmp_path, n_runs=4, scatter={}, noisy_zero=True)
    proto = rig.protocol("sensing", exp.rig, np.random.default_rng(0))
    inputs = rig.exact_inputs("sensing", exp.sample, exp.rig, proto)
    exact = predict(
        "sensing",
        exp.sample,
        exp.rig,
        inputs,
        **rig.runs.true_options("sensing", exp.sample, exp.rig, inputs),
    )
    written = load_experiment(res.experiment_path)
    zeros = [r["zero_error"]["force"] for r in res.truth["runs"]]
    assert len(set(zeros)) == 4
    assert np.std(zeros) > 0.3 * instruments.LOADCELL_SD_N
    for run, zero in zip(written.read_runs(), zeros):
        offset = np.mean(run.data["force"].to_numpy(float) - exact["force"])
        assert offset == pytest.approx(zero, abs=0.2e-3)


def test_curvature_has_no_zeroed_channel(tmp_path):
    res = rig.simulate("curvature", template("curvature"), seed=1, out_dir=tmp_path, noisy_zero=True)
    plain = rig.simulate("curvature", template("curvature"), seed=1, out_dir=tmp_path / "plain")
    assert all(r["zero_error"] == {} for r in res.truth["runs"])
    assert [p.read_bytes() for p in res.run_paths] == [p.read_bytes() for p in plain.run_paths]


def test_public_command_hides_the_lies():
    line = "tcamlab simulate dynamic --seed 1 --parameter-error 1 --noisy-zero --effect x=3 --runs 2"
    assert public_command(line) == "tcamlab simulate dynamic --seed 1 --runs 2"
    assert public_command("tcamlab simulate static --parameter-error=2 --seed 3") == (
        "tcamlab simulate static --seed 3"
    )


def test_cli_simulate_lies(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from tcamlab.cli import app

    monkeypatch.chdir(tmp_path)
    args = ["simulate", "dynamic", "--experiment", "dynamic", "--seed", "2", "--out", "lab"]
    result = CliRunner().invoke(app, [*args, "--parameter-error", "1", "--noisy-zero"])
    assert result.exit_code == 0, result.output
    truth = json.loads((tmp_path / "lab" / "truth" / "dynamic.truth.json").read_text())
    assert truth["parameter_error"] == 1.0 and truth["noisy_zero"] is True
    assert all("displacement" in r["zero_error"] for r in truth["runs"])
    doc = tomllib.loads((tmp_path / "lab" / "experiments" / "dynamic.toml").read_text())
    assert "--parameter-error" not in doc["synthetic"]["command"]
    assert "--noisy-zero" not in doc["synthetic"]["command"]


def test_benchmark_lies_adds_scored_apart_null_cases():
    plain = benchmark.make_tasks(quick=True)
    lying = benchmark.make_tasks(quick=True, lies=True)
    extra = [t for t in lying if t["case"] == "null-miscalibrated"]
    assert [t for t in lying if t["case"] != "null-miscalibrated"] == plain
    assert len(extra) == 2 * len(KINDS)
    assert all(t["parameter_error"] == 1.0 and t["noisy_zero"] for t in extra)
    assert "null_miscalibrated" not in benchmark.score([])
    rows = [
        {**extra[0], "verdict": "attributed", "effect": "glass-transition", "aliased_with": [], "seconds": 1},
        {**extra[1], "verdict": "none", "effect": None, "aliased_with": [], "seconds": 1},
    ]
    scores = benchmark.score(rows)
    assert scores["null"]["n"] == 0
    assert scores["null_miscalibrated"]["n"] == 2
    assert scores["null_miscalibrated"]["false_attributions"] == 1


def test_benchmark_runs_a_lying_null_case():
    task = {**benchmark.lying_null_task("static", 6000), "n_boot": 50}
    out = benchmark.run_task(task)
    assert "error" not in out, out.get("error")
    assert set(out["parameter_offsets_sd"]) == {"radial_cte", "youngs_modulus"}
    assert len(out["zero_errors"]) == 3 and all("displacement" in z for z in out["zero_errors"])
    assert out["verdict"] in ("none", "attributed", "aliased", "unexplained", "miscalibrated")


def test_a_drawn_muscle_the_model_cannot_run_names_the_draw_and_writes_nothing(tmp_path):
    # seed 1 draws a dynamic muscle that heats past G_t' = 0 at twice the stated sds; the
    # model's own hint (a log's units, the file's keys) would be about a file the rig wrote
    from tcamlab.errors import ModelDomainError

    with pytest.raises(ModelDomainError) as info:
        rig.simulate("dynamic", template("dynamic"), seed=1, out_dir=tmp_path, parameter_error=2.0)
    assert "--parameter-error 2" in info.value.message and "G_t'" in info.value.message
    assert info.value.hint.startswith("another --seed")
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]
    # the same draw under the stated parameters runs
    rig.simulate("dynamic", template("dynamic"), seed=1, out_dir=tmp_path)
