"""tcamlab design and the runs already made: a protocol no harsher than them is never out of
bounds for the model's domain at a fit, a clear diagnosis names what it found, and a stored
diagnosis of another experiment (or of other runs) is refused."""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
from typer.testing import CliRunner

from tcamlab.cli import app
from tcamlab.config import load_experiment
from tcamlab.design import design
from tcamlab.design.hypotheses import hypotheses
from tcamlab.design.protocols import menu, protocol_frames
from tcamlab.design.survived import no_harsher
from tcamlab.models import static as static_model
from tcamlab.rig import simulate
from tcamlab.templates import TEMPLATES

ALIASED = json.loads(
    (Path(__file__).parent / "data" / "design" / "static_aliased.diagnosis.json").read_text()
)


def _at_the_edge(exp, rise_K: float) -> dict:
    """The aliased static fixture recast as a clear ``miscalibrated`` verdict whose fitted G_t
    slope puts G_t' = 0 at ``rise_K`` above ambient: a fit at the edge of the model's domain on
    the heating runs it was fitted to (oven to 150 degC)."""
    d = copy.deepcopy(ALIASED)
    d.update(verdict="miscalibrated", effect=None, aliased_with=[])
    d["recalibration"] = {"named": ["shear_modulus_slope", "youngs_modulus"]}
    (h,) = [h for h in hypotheses(d, "static") if h.name == "recalibration"]
    sample = h.at(h.u(), h.effect_values, exp.sample, exp.rig, "static")[0]
    g = float(static_model.shear_modulus_of(sample))
    rec = next(c for c in d["ranking"] if c["effect"] == "recalibration")
    rec["recalibrated"]["shear_modulus_slope"]["value"] = g / rise_K
    return d


def test_a_fit_at_the_domains_edge_leaves_the_runs_already_made_within_bounds(tmp_path):
    path = simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path).experiment_path
    exp = load_experiment(path)
    res = design(exp, _at_the_edge(exp, 130.2), n_draws=12)
    by = {c.name: c for c in res.candidates}
    # the sample went through heating to 150 degC at the stated load: no draw condemns it
    for name in ("repeat (same protocol)", "heat-cool", "1 degC steps 35-60 degC"):
        assert by[name].survived and by[name].feasible, (name, by[name].limit)
    # a heavier load or a hotter oven than the runs made is still judged by the fit
    assert not by["second load 2x"].survived
    assert res.best is not None and res.best.survived
    assert "miscalibrated: shear_modulus_slope, youngs_modulus moved" in res.message


def test_no_harsher_reads_peaks_and_time_under_voltage():
    exp = load_experiment(TEMPLATES / "static.toml", require_runs=False)
    tables = dict((p.name, p.table) for p in menu("static", exp.sample, exp.rig))
    made = [
        f.assign(temperature=f["temperature"] + 0.3)
        for f in protocol_frames("static", exp.rig, tables["repeat (same protocol)"])
    ]
    made = [m.drop(columns="load") for m in made]  # a log without the load ran at the stated one
    assert no_harsher(protocol_frames("static", exp.rig, tables["heat-cool"]), made, exp.rig)
    assert not no_harsher(protocol_frames("static", exp.rig, tables["second load 2x"]), made, exp.rig)
    assert not no_harsher(protocol_frames("static", exp.rig, tables["repeat (same protocol)"]), [], exp.rig)
    t = np.arange(0.0, 3.0, 0.01)
    pulse = pd.DataFrame({"time": t, "voltage": np.where(t < 1.0, 10.0, 0.0)})
    longer = pulse.assign(voltage=np.where(t < 2.0, 10.0, 0.0))
    lower = pulse.assign(voltage=np.where(t < 1.0, 8.0, 0.0))
    assert no_harsher([lower, pulse], [pulse], exp.rig)
    assert not no_harsher([longer], [pulse], exp.rig)


def _lab(tmp_path) -> tuple[Path, Path]:
    """A simulated static experiment and a diagnosis.json recording it (and its runs)."""
    path = simulate("static", TEMPLATES / "static.toml", seed=1, out_dir=tmp_path).experiment_path
    exp = load_experiment(path)
    from tcamlab.io import sha256_file

    inputs = [{"path": path.name, "role": "experiment", "sha256": sha256_file(path)}]
    inputs += [{"path": p.name, "role": "run", "sha256": sha256_file(p)} for p in exp.runs]
    diag = tmp_path / "reports" / exp.name / "diagnosis.json"
    diag.parent.mkdir(parents=True)
    record = {"inputs": inputs, "name": exp.name, "path": str(path), "kind": "static"}
    diag.write_text(json.dumps({**ALIASED, "experiment": record}), encoding="utf-8")
    return path, diag


def test_cli_refuses_a_diagnosis_of_another_experiment(tmp_path):
    path, diag = _lab(tmp_path)
    other = path.with_name("other.toml")
    shutil.copy(path, other)
    other.write_text(other.read_text() + "# another sample\n", encoding="utf-8")
    result = CliRunner().invoke(app, ["design", str(other), "--diagnosis", str(diag)])
    assert result.exit_code == 2, result.output
    line = result.output.strip()
    assert len(line.splitlines()) == 1 and "diagnosis.json: a diagnosis of" in line and "other.toml" in line
    assert "tcamlab diagnose" in line and "other.toml --out reports" in line


def test_cli_refuses_a_diagnosis_of_runs_changed_since(tmp_path):
    path, diag = _lab(tmp_path)
    run = load_experiment(path).runs[0]
    run.write_text(run.read_text() + "\n", encoding="utf-8")
    result = CliRunner().invoke(app, ["design", str(path), "--diagnosis", str(diag)])
    assert result.exit_code == 2, result.output
    line = result.output.strip()
    assert len(line.splitlines()) == 1 and "1 added or changed since" in line and "--force" in line
