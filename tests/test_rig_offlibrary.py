"""Out-of-library effect forms of the virtual rig (tcamlab.rig.offlibrary)."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from tcamlab.config import load_experiment
from tcamlab.effects import NO_MODS, get_effect
from tcamlab.kinds import predict
from tcamlab.rig import noise_sd, simulate
from tcamlab.rig.offlibrary import FORMS, form_gap, play, scale_form
from tcamlab.rig.runs import exact_inputs, protocol, true_options
from tcamlab.templates import template_path

PACKAGE = Path(__file__).resolve().parent.parent / "tcamlab"


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names |= {f"{node.module}.{a.name}" for a in node.names}
    return names


def test_the_diagnosis_never_imports_the_offlibrary_forms():
    files = sorted((PACKAGE / "diagnosis").rglob("*.py")) + [PACKAGE / "effects.py"]
    assert len(files) > 3
    for f in files:
        bad = {n for n in _imports(f) if "offlibrary" in n}
        assert not bad, f"{f} imports {bad}"


def test_play_operator():
    x = np.array([0.0, 1.0, 2.0, 1.5, 0.0])
    assert play(x, 0.5).tolist() == [0.0, 0.5, 1.5, 1.5, 0.5]


def _run(kind):
    exp = load_experiment(template_path(kind), require_runs=False)
    prog = {"oven": "heat-cool"} if kind == "static" else {}
    proto = protocol(kind, exp.rig, np.random.default_rng(0), **prog)
    inputs = exact_inputs(kind, exp.sample, exp.rig, proto)
    opts = true_options(kind, exp.sample, exp.rig, inputs)
    outputs = predict(kind, exp.sample, exp.rig, inputs, **opts)
    return exp, proto, inputs, opts, outputs, noise_sd(kind, exp.sample, exp.rig)


def _best_candidate_share(kind, form, exp, proto, opts, gap, sd, quantities):
    """RMS left when the nearest library effect is fitted to the form's gap, over the gap's RMS."""
    target = np.concatenate([gap[q] / sd[q] for q in quantities])
    eff = get_effect(form.nearest, kind)
    p = eff.params[0]

    def sse(x):
        try:
            m = eff.mods([x])
            i2 = exact_inputs(kind, exp.sample, exp.rig, proto, m)
            o2, b2 = (
                predict(kind, exp.sample, exp.rig, i2, m, **opts),
                predict(kind, exp.sample, exp.rig, i2, NO_MODS, **opts),
            )
            c = np.concatenate([(np.asarray(o2[q]) - np.asarray(b2[q])) / sd[q] for q in quantities])
            return float(np.sum((target - c) ** 2))
        except Exception:
            return np.inf

    mags = p.scale * np.geomspace(1e-3, 1e3, 60)
    grid = np.concatenate([-mags[::-1], [0.0], mags])
    grid = grid[(grid >= p.lower) & (grid <= p.upper)]
    vals = [sse(x) for x in grid]
    i = int(np.argmin(vals))
    res = minimize_scalar(
        sse, bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]), method="bounded"
    )
    return float(np.sqrt(min(res.fun, vals[i]) / np.sum(target**2)))


@pytest.mark.slow
@pytest.mark.parametrize("key", sorted(FORMS), ids=lambda k: f"{k[0]}-{k[1]}")
def test_form_has_its_strength_and_differs_from_the_candidate(key):
    kind, _ = key
    form = FORMS[key]
    exp, proto, inputs, opts, outputs, sd = _run(kind)
    info = scale_form(form, 3.0, kind, exp.sample, exp.rig, inputs, outputs, opts, sd)
    assert info["limited_by"] is None
    assert info["achieved_strength"] == pytest.approx(3.0, rel=1e-6)
    assert info["amplitude"] > 0
    gap = form_gap(form, info["amplitude"], kind, exp.sample, exp.rig, inputs, outputs, opts)
    share = _best_candidate_share(kind, form, exp, proto, opts, gap, sd, info["quantities"])
    # The candidate explains part of the gap (the same physics) but not all of it: at 3x
    # the least that is left is 6 % of the gap's RMS (smooth glass transition, 0.19 noise sds).
    assert 0.05 <= share < 0.95, share


def test_simulate_records_the_form_and_the_experiment_does_not(tmp_path):
    sim = simulate(
        "sensing", template_path("sensing"), seed=3, out_dir=tmp_path, offlibrary={"play-hysteresis": 3.0}
    )
    truth = json.loads(sim.truth_path.read_text())
    rec = truth["offlibrary"]["play-hysteresis"]
    assert rec["nearest"] == "hysteresis" and rec["achieved_strength"] == pytest.approx(3.0, rel=1e-6)
    assert truth["effects"] == {}
    text = sim.experiment_path.read_text()
    assert "hysteresis" not in text and "offlibrary" not in text
