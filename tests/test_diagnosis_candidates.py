"""Candidate scoring helpers of tcamlab.diagnosis.candidates, on hand-made fits."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

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


def test_a_candidate_that_only_shrinks_the_inputs_noise_gains_nothing():
    from tcamlab.diagnosis.candidates import gain_corrected_sums

    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, 1.0, 4000)
    misfit = 0.3 * np.sin(np.linspace(0.0, 6.0, noise.size))  # smooth on the rows' scale

    def problem(block):
        return SimpleNamespace(
            k=SimpleNamespace(fit_block=block),
            quantities=("displacement",),
            norm_resid=lambda i, mods, spring, mask: noise,  # the baseline: noise alone
        )

    shrunk = 0.9 * noise  # a lower gain from a noisy input: 19 % less noise variance
    plain = gain_corrected_sums(problem(1), shrunk, 0, None, None)
    corrected = gain_corrected_sums(problem(16), shrunk, 0, None, None)
    assert plain[0] == pytest.approx(0.81 * np.sum(noise**2))
    assert corrected[0] == pytest.approx(np.sum(noise**2), rel=0.01)
    # a smooth misfit still counts in full: what it adds is what it adds row by row
    worse = gain_corrected_sums(problem(16), shrunk + misfit, 0, None, None)
    plain_worse = gain_corrected_sums(problem(1), shrunk + misfit, 0, None, None)
    assert worse[0] - corrected[0] == pytest.approx(plain_worse[0] - plain[0], rel=0.01)
    assert worse[0] - corrected[0] > 0.5 * np.sum(misfit**2)
