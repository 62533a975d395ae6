"""Observability of the self-sensing filter: the Gramian on a known linear case, and on the
virtual rig (synthetic: tcamlab.rig.selfsensing.powered_run, no noise drawn)."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tcamlab.config import load_experiment
from tcamlab.estimation import observability as ob
from tcamlab.estimation import observer as so

ROOT = Path(__file__).resolve().parents[1]


def test_gramian_of_a_constant_velocity_track_is_the_closed_form():
    # x_(k+1) = x_k + dt v_k, v constant, x read with sd 2: W = sum_k [1, k dt]' [1, k dt] / 4
    dt, n = 0.1, 6
    a = [np.array([[1.0, dt], [0.0, 1.0]])] * (n - 1)
    w = ob.linear_gramian(a, [np.array([1.0, 0.0])] * n, [2.0] * n)
    k = np.arange(n)
    expected = np.array([[n, dt * k.sum()], [dt * k.sum(), dt**2 * (k**2).sum()]]) / 4.0
    np.testing.assert_allclose(w, expected, rtol=1e-14)
    verdict = ob.summarise(w, names=("x", "v"))
    assert verdict.rank == 2
    assert verdict.condition == pytest.approx(np.linalg.cond(expected), rel=1e-9)


def test_a_state_the_reading_never_sees_is_the_null_direction():
    # only v is read and x never feeds it: rank 1, the weakest direction is x
    a = [np.eye(2)] * 4
    w = ob.linear_gramian(a, [np.array([0.0, 1.0])] * 5, [1.0] * 5)
    verdict = ob.summarise(w, names=("x", "v"))
    assert verdict.rank == 1
    assert verdict.condition == float("inf")
    assert abs(verdict.weakest["x"]) == pytest.approx(1.0)
    np.testing.assert_allclose(w, [[0.0, 0.0], [0.0, 5.0]])


def test_marginal_is_the_schur_complement():
    w = np.array([[4.0, 2.0, 0.0], [2.0, 3.0, 1.0], [0.0, 1.0, 2.0]])
    other = w[np.ix_([1, 2], [1, 2])]
    expected = 4.0 - np.array([2.0, 0.0]) @ np.linalg.inv(other) @ np.array([2.0, 0.0])
    assert ob.marginal(w, [0])[0, 0] == pytest.approx(expected, rel=1e-12)


def _probe_run(volts):
    from tcamlab.rig.selfsensing import powered_run

    exp = load_experiment(ROOT / "experiments" / "selfsensing.toml")
    t = np.arange(volts.size) / 100.0
    run = powered_run(exp.sample, exp.rig, t, volts, np.full(t.size, exp.rig.load))
    states = np.column_stack(
        [run.temperature, run.extension, np.gradient(run.extension, t), np.full(t.size, exp.rig.force), 0 * t]
    )
    config = so.config_from(exp.sample, exp.rig, noise=so.THETA_NOISE)
    return config, pd.DataFrame({"time": t, "voltage": volts, "current": run.current}), states


def test_a_held_probe_cannot_split_the_load_from_theta_a_second_level_can():
    held = ob.gramian(*_probe_run(np.full(1000, 1.5)))
    # T, F, theta over 10 s at a held 1.5 V: one combination of F and theta is not seen
    assert held.rank == 2
    assert held.condition > 1e12
    two = ob.gramian(*_probe_run(np.where(np.arange(1000) < 500, 1.5, 3.0)))
    assert two.rank == 3
    assert two.condition < 1e3  # measured 147
    assert two.sd["F"] < 5.0  # mN; measured 2.4
