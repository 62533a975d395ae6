"""The virtual rig under a designed protocol file: the experiment it writes lists the runs so
far (each with its own column layout) and the new ones, and a sensor without its S and R0 is
refused naming the file."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.design import protocol_toml
from tcamlab.errors import ConfigError
from tcamlab.kinds import static
from tcamlab.rig import simulate
from tcamlab.templates import TEMPLATES


def _lab_with_columns(tmp_path):
    """A simulated static experiment whose logs name the temperature "Temp (C)", read through
    its [columns] table, and its designed protocol file (second load 1.5x)."""
    first = simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path).experiment_path
    for run in load_experiment(first).runs:
        head, rest = run.read_text().split("\n", 1)
        run.write_text(head.replace("temperature_C", "Temp (C)") + "\n" + rest, encoding="utf-8")
    text = first.read_text() + '\n[columns]\ntemperature_C = { from = "Temp (C)" }\n'
    first.write_text(text, encoding="utf-8")
    exp = load_experiment(first)
    table = dict(static.design_menu(exp.sample, exp.rig))["second load 1.5x"]
    nxt = first.with_name(f"{exp.name}.next.toml")
    nxt.write_text(protocol_toml(exp.raw, table, "test"), encoding="utf-8")
    return exp, nxt


def test_a_designed_experiment_with_columns_lists_the_runs_so_far_and_the_new(tmp_path):
    exp, nxt = _lab_with_columns(tmp_path)
    out = simulate("static", nxt, seed=2, out_dir=tmp_path, name="again")
    both = load_experiment(out.experiment_path)
    assert list(both.runs) == [*exp.runs, *out.run_paths]
    runs = both.read_runs()
    # the old runs through their own layout, the new ones through the canonical headers
    assert [r.source_columns["temperature"] for r in runs] == ["Temp (C)"] * 3 + ["temperature_C"] * 4
    assert "columns" not in both.raw


def test_a_sensor_without_s_and_r0_is_refused_naming_the_file(tmp_path):
    text = (TEMPLATES / "sensing.toml").read_text()
    kept = [
        line
        for line in text.splitlines()
        if not line.startswith(("spring_constant_N_per_m", "initial_resistance_ohm"))
    ]
    path = tmp_path / "mine.toml"
    path.write_text("\n".join(kept) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        simulate("sensing", path, seed=2, out_dir=tmp_path)
    # the preset states R0; S is the sensor's own
    assert "mine.toml" in info.value.message and "spring_constant_N_per_m" in info.value.message
    assert "spring_constant_N_per_m = 4.7" in info.value.hint
    result = CliRunner().invoke(
        app, ["simulate", "sensing", "--experiment", str(path), "--seed", "2", "--out", str(tmp_path)]
    )
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1
    # the hint's lines make the file simulate
    path.write_text(text, encoding="utf-8")
    assert simulate("sensing", path, seed=2, out_dir=tmp_path / "ok").run_paths


def test_a_self_sensing_muscle_without_s_is_refused_naming_the_file(tmp_path):
    """The self-sensing rig raised "needs initial_resistance and spring_constant in [rig]" with
    no file and no hint; its protocol without the current passed."""
    text = (TEMPLATES / "selfsensing.toml").read_text()
    kept = [line for line in text.splitlines() if not line.startswith("spring_constant_N_per_m")]
    path = tmp_path / "muscle.toml"
    path.write_text("\n".join(kept) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        simulate("selfsensing", path, seed=2, out_dir=tmp_path)
    assert (
        "muscle.toml" in info.value.message and "the muscle's spring_constant_N_per_m" in info.value.message
    )
    assert "spring_constant_N_per_m = 2.5" in info.value.hint
    from tcamlab.kinds.selfsensing_protocol import protocol_runs

    rig = load_experiment(TEMPLATES / "selfsensing.toml", require_runs=False).rig
    with pytest.raises(ConfigError, match="channels lacks 'current_A'"):
        protocol_runs({"channels": ["time_s", "voltage_V", "load_N", "displacement_mm"]}, rig)
    assert len(protocol_runs({"channels": ["time_s", "voltage_V", "current_A", "displacement_mm"]}, rig)) == 1
