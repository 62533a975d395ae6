"""Electro-thermal model (2.18): exact solution and steady state."""

import math

import numpy as np
import pytest

from tcamlab.errors import ModelDomainError
from tcamlab.models import thermal


def test_steady_state_of_thesis_pulse_held_is_about_300_C():
    # 10 V on 40 ohm: 2.5 W / 0.00893 W/K = 280 K above 20 degC
    t_inf = thermal.steady_state_temperature(10.0, 40.0, 0.00893, 20.0)
    assert t_inf == pytest.approx(20.0 + 2.5 / 0.00893, rel=1e-14)
    assert 290 < t_inf < 310


def test_step_response_matches_analytic_exponential():
    t = np.linspace(0.0, 10.0, 1001)
    temp = thermal.temperature(t, 6.0, 40.0, 0.0266, 0.00893, 20.0)
    tau = 0.0266 / 0.00893
    rise = 36.0 / 40.0 / 0.00893
    expected = 20.0 + rise * (1 - np.exp(-t / tau))
    np.testing.assert_allclose(temp, expected, rtol=1e-12, atol=1e-10)


def test_pulse_then_cooling_is_exact_at_any_sampling():
    tau = 0.0266 / 0.00893
    rise = 100.0 / 40.0 / 0.00893
    for step in (0.001, 0.05):
        t = np.arange(0.0, 5.0 + step / 2, step)
        v = np.where(t < 1.0 - 1e-12, 10.0, 0.0)
        temp = thermal.temperature(t, v, 40.0, 0.0266, 0.00893, 20.0)
        peak = 20.0 + rise * (1 - math.exp(-1.0 / tau))
        after = t >= 1.0 - 1e-12
        expected = 20.0 + (peak - 20.0) * np.exp(-(t[after] - 1.0) / tau)
        np.testing.assert_allclose(temp[after], expected, rtol=1e-10)


def test_long_uniform_record_uses_stable_scan():
    # 2 million samples: the closed form would overflow; lfilter path must agree with a loop
    n = 2_000_000
    t = np.arange(n) * 0.002
    v = np.where((t % 20.0) < 2.0, 8.0, 0.0)
    temp = thermal.temperature(t, v, 40.0, 0.0266, 0.00893, 20.0)
    assert np.all(np.isfinite(temp))
    k = n - 1000
    decay = math.exp(-0.002 / (0.0266 / 0.00893))
    value = temp[k]
    for j in range(k, k + 500):
        t_inf = 20.0 + v[j] ** 2 / 40.0 / 0.00893
        value = decay * value + (1 - decay) * t_inf
    assert temp[k + 500] == pytest.approx(value, rel=1e-9)


def test_irregular_sampling():
    t = np.array([0.0, 0.1, 0.35, 0.36, 2.0])
    temp = thermal.temperature(t, 5.0, 40.0, 0.0266, 0.00893, 20.0)
    tau = 0.0266 / 0.00893
    expected = 20.0 + 25.0 / 40.0 / 0.00893 * (1 - np.exp(-t / tau))
    np.testing.assert_allclose(temp, expected, rtol=1e-12)


def test_bad_inputs_raise():
    with pytest.raises(ModelDomainError):
        thermal.temperature([0.0, 0.0], 1.0, 40.0, 0.0266, 0.00893, 20.0)
    with pytest.raises(ModelDomainError):
        thermal.temperature([0.0, 1.0], 1.0, 40.0, 0.0, 0.00893, 20.0)
