"""Tests of tcamlab.io.quantisation: the logging step and the error second differences miss."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tcamlab.io import quantisation as Q
from tcamlab.signals import second_difference_sigma

ADC_STEP = 10e-3 / 1023  # the voltage-step rig's 10-bit laser ADC [m]


def _slow_reading(sigma, step, n=100_000, seed=0, decimals_m=1e-6):
    """A slow ramp with a wobble, white noise ``sigma``, quantised, written to ``decimals_m``."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1e-3, n) + 0.3e-3 * np.sin(np.linspace(0.0, 20.0, n))
    r = np.round((x + sigma * rng.normal(size=n)) / step) * step
    return x, np.round(r / decimals_m) * decimals_m


def test_hidden_variance_is_a_twelfth_of_the_step_squared_without_noise_and_gone_with_it():
    assert Q.hidden_variance(0.0, 2.0) == pytest.approx(4.0 / 12.0, rel=2e-3)
    assert Q.hidden_variance(1.0, 2.0) < 1e-4 * 4.0 / 12.0  # sigma = q / 2: exp(-pi^2)
    assert Q.hidden_variance(0.3, 2.0) < Q.hidden_variance(0.2, 2.0) < Q.hidden_variance(0.1, 2.0)


def test_a_noiseless_staircase_is_not_believed():
    # sigma = 0: second differences see 0.26 um of a 2.8 um error; beyond MAX_HIDDEN_TO_SEEN
    # the lattice is taken for the protocol's and nothing is added (the old floor stands)
    x, r = _slow_reading(0.0, ADC_STEP)
    seen = second_difference_sigma(r - x) ** 2
    assert Q.hidden_variance(0.0, ADC_STEP) > Q.MAX_HIDDEN_TO_SEEN**2 * seen
    assert Q.unseen_variance(r, x, seen) == (0.0, None)


def test_logging_step_recovers_an_adc_code_written_with_fewer_decimals():
    _, r = _slow_reading(1e-6, ADC_STEP)
    assert Q.logging_step(r) == pytest.approx(ADC_STEP, rel=3e-3)
    assert Q.logging_step(np.random.default_rng(1).normal(size=2000)) is None  # continuous


@pytest.mark.parametrize("sigma", [0.5e-6, 1e-6, 2e-6, 5e-6])
def test_second_differences_plus_the_hidden_part_give_the_whole_error(sigma):
    x, r = _slow_reading(sigma, ADC_STEP)
    e = r - x
    seen = second_difference_sigma(e) ** 2
    hidden, step = Q.unseen_variance(r, x, seen)
    assert step is not None
    total = float(np.mean(e * e))
    # the whole error is sigma^2 + q^2/12; second differences alone miss most of it when quiet
    assert math.sqrt(seen + hidden) == pytest.approx(math.sqrt(total), rel=0.01)
    if sigma <= 1e-6:
        assert math.sqrt(seen) < 0.85 * math.sqrt(total)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 3.0), st.floats(0.1, 10.0))
def test_white_sigma_inverts_the_seen_variance(ratio, step):
    sigma = ratio * step
    seen = sigma**2 + step**2 / 12.0 - Q.hidden_variance(sigma, step)
    if seen > 1e-3 * step**2:  # below that, the truncated series cannot resolve sigma
        assert Q.white_sigma(seen, step) == pytest.approx(sigma, rel=1e-3, abs=1e-6 * step)


def test_a_lattice_the_true_values_sit_on_is_no_quantiser():
    # an encoder logging a 10 mm/s move at 10 Hz between 2 mm dwells reads whole mm only,
    # and the positions sit on that lattice: the model's predictions (noisy through R)
    # do not sweep through the "step"
    pos = np.concatenate([np.full(50, 2e-3 * k) for k in range(25)])
    pos = np.concatenate([[p, p + 1e-3] if i % 50 == 49 else [p] for i, p in enumerate(pos)])
    assert Q.logging_step(pos) == pytest.approx(1e-3)
    pred = pos + np.random.default_rng(2).normal(0.0, 60e-6, pos.size)
    seen = second_difference_sigma(pos - pred) ** 2
    assert Q.phase_concentration(pred, 1e-3) > 0.9
    assert Q.unseen_variance(pos, pred, seen) == (0.0, None)
    # the same predictions spread over the step (a swept quantity) do count
    swept = pos + np.random.default_rng(3).uniform(0.0, 1e-3, pos.size)
    assert Q.phase_concentration(swept, 1e-3) < 0.1


def test_a_reading_that_jumps_many_steps_per_row_hides_nothing():
    # one reading per oven step: the quantisation error is white and already seen
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.uniform(50, 60, 400)) * ADC_STEP
    r = np.round(x / ADC_STEP) * ADC_STEP
    assert not Q.slow_rows(r, ADC_STEP).any()
    assert Q.unseen_variance(r, x, 1e-12) == (0.0, None)
