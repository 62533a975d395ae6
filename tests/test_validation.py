"""Validation: the metrics of every variant, quantity and run, computed against hand values."""

from __future__ import annotations

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
