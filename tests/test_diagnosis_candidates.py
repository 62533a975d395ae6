"""Candidate scoring helpers of tcamlab.diagnosis.candidates, on hand-made fits."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tcamlab.diagnosis.candidates import effect_parameters


def _effect():
    params = [
        SimpleNamespace(field="lag_tau", scale=100.0, unit="s", lower=0.0, upper=5000.0),
        SimpleNamespace(field="lag_conductance_tc", scale=2e-4, unit="1/K", lower=0.0, upper=0.05),
    ]
    return SimpleNamespace(params=params)


def test_a_parameter_at_its_fitted_box_edge_is_at_bound_and_one_inside_is_not():
    # one calibrated coordinate u, then the effect's two scaled parameters; the fit's box was
    # shrunk to the model's domain (tau >= 1e-6 s), so tau at 1e-6 s is at its bound although
    # it is not at the effect's own lower bound 0
    u = np.array([0.1])
    theta = np.array([1e-8, 2.0])
    box = (np.array([-5.0, 1e-8, 0.0]), np.array([5.0, 50.0, 250.0]))
    fit = SimpleNamespace(u=u, x=np.concatenate([u, theta]), values=theta * [100.0, 2e-4], box=box)
    cov = np.diag([0.01, 1e-20, 0.25])
    out = effect_parameters(_effect(), fit, cov)
    assert out["lag_tau"]["at_bound"] is True
    assert out["lag_conductance_tc"]["at_bound"] is False
    # interval from the Laplace sd in SI: 2.0 * 2e-4 +- 1.96 * 0.5 * 2e-4
    lo, hi = out["lag_conductance_tc"]["ci95"]
    assert np.isclose(lo, 4e-4 - 1.96 * 1e-4, rtol=1e-3) and np.isclose(hi, 4e-4 + 1.96 * 1e-4, rtol=1e-3)
