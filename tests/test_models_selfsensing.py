"""Combined self-sensing resistance model R(T, delta) (chapters 2 + 3)."""

import numpy as np
import pytest

from tcamlab.models import selfsensing as ss
from tcamlab.models import sensing, thermal
from tcamlab.params import SILVER_TCR, THESIS_TCS, Sample

S = 4.7  # N/m, the thesis-tcs simulation value (S f11 = 0.6)
R0 = 30.0
T_REF = 20.0
RHO = 8.1e-5


@pytest.fixture(scope="module")
def geo():
    return Sample(**{k: v.value for k, v in THESIS_TCS.sample.items()}).sensor_kwargs()


def model(geo, **over):
    kw = dict(
        initial_resistance=R0,
        reference_temperature=T_REF,
        tcr=SILVER_TCR,
        radial_cte=RHO,
        spring_constant=S,
        **geo,
    )
    kw.update(over)
    return kw


def test_equals_chapter_3_at_reference_temperature(geo):
    delta = np.linspace(-2e-3, 40e-3, 25)
    got = ss.resistance(T_REF, delta, **model(geo))
    want = sensing.forward(delta, R0, S, **geo)
    # exact up to the rounding of R0 * (1 / u^2) against R0 / u^2
    np.testing.assert_allclose(got, want, rtol=4e-16, atol=0)


def test_hand_value_when_heated(geo):
    # dT = 50 K at delta = 10 mm: R = R_ch3(10 mm) (1 + 0.0038*50) / (1 + 8.1e-5*50)^2
    r3 = float(sensing.forward(10e-3, R0, S, **geo))
    want = r3 * 1.19 / 1.00405**2
    got = float(ss.resistance(70.0, 10e-3, **model(geo)))
    assert got == pytest.approx(want, rel=1e-14)
    # silver's 0.38 %/K beats the swelling's 0.016 %/K: R rises 18.0 % when heated 50 K
    assert got / r3 == pytest.approx(1.180419, rel=1e-6)


def test_limits_tcr_and_rho_zero(geo):
    delta = np.array([0.0, 5e-3, 20e-3])
    plain = sensing.forward(delta, R0, S, **geo)
    # both off: chapter 3 at any temperature
    np.testing.assert_allclose(
        ss.resistance(95.0, delta, **model(geo, tcr=0.0, radial_cte=0.0)), plain, rtol=1e-15
    )
    # tcr alone: the silver's factor only
    np.testing.assert_allclose(
        ss.resistance(95.0, delta, **model(geo, radial_cte=0.0)), plain * (1 + SILVER_TCR * 75), rtol=1e-14
    )
    # rho alone: R falls as the fiber swells (more silver cross-section)
    swollen = ss.resistance(95.0, delta, **model(geo, tcr=0.0))
    np.testing.assert_allclose(swollen, plain / (1 + RHO * 75) ** 2, rtol=1e-14)
    assert np.all(swollen < plain)


def test_derivatives_match_finite_differences(geo):
    t = np.array([20.0, 60.0, 110.0])
    d = np.array([0.0, 8e-3, 30e-3])
    kw = model(geo)
    d_dt, d_dd = ss.resistance_derivatives(t, d, **kw)
    ht, hd = 1e-3, 2e-5
    fd_t = (ss.resistance(t + ht, d, **kw) - ss.resistance(t - ht, d, **kw)) / (2 * ht)
    fd_d = (ss.resistance(t, d + hd, **kw) - ss.resistance(t, d - hd, **kw)) / (2 * hd)
    np.testing.assert_allclose(d_dt, fd_t, rtol=1e-7)
    np.testing.assert_allclose(d_dd, fd_d, rtol=1e-5)
    # analytic dR/dT at delta = 0, T = T_ref: R0 (tcr - 2 rho)
    assert d_dt[0] == pytest.approx(R0 * (SILVER_TCR - 2 * RHO), rel=1e-12)
    assert np.all(d_dd > 0)  # stretching thins the fiber: R rises


def test_invert_recovers_delta_when_heated(geo):
    t = np.array([20.0, 45.0, 80.0, 120.0])
    d = np.array([3e-3, 12e-3, 25e-3, 0.5e-3])
    kw = model(geo)
    r = ss.resistance(t, d, **kw)
    np.testing.assert_allclose(ss.invert_displacement(r, t, **kw), d, rtol=1e-8)
    # ignoring the heating (T = T_ref) reads the silver's rise as a large stretch
    wrong = ss.invert_displacement(r, np.full(4, T_REF), **kw)
    assert np.all(wrong[1:] > d[1:] + 5e-3)


def test_temperature_from_power_is_thermal_model_with_v2_over_r():
    t = np.linspace(0.0, 5.0, 501)
    v = np.where((t > 0.5) & (t < 2.0), 10.0, 0.0)
    r = 40.0
    want = thermal.temperature(t, v, r, 0.0266, 0.00893, 20.0)
    got = ss.temperature_from_power(t, v * v / r, thermal_mass=0.0266, heat_loss=0.00893, ambient=20.0)
    np.testing.assert_allclose(got, want, rtol=1e-13)
