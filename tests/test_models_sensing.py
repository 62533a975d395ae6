"""Sensing model (section 3.2)."""

import math

import numpy as np
import pytest
from conftest import geometry
from hypothesis import given, settings
from hypothesis import strategies as st

from tcamlab.errors import ModelDomainError
from tcamlab.models import sensing, static
from tcamlab.params import THESIS_TCS


def test_diameter_from_resistance_hand_value():
    # R = 1.21 R0 -> d = d0 / 1.1
    assert sensing.diameter_from_resistance(36.3, 30.0, 0.4e-3) == pytest.approx(0.4e-3 / 1.1)


def test_torque_3_3_hand_value():
    d0, d, g, n_turns, l = 0.4e-3, 0.39e-3, 1.7e8, 750.0, 0.328
    expected = g * math.pi * d**4 / 32 * 2 * math.pi * n_turns * (1 - d0 / d) / l
    assert sensing.torque(d, d0, n_turns, l, g) == pytest.approx(expected, rel=1e-14)
    assert expected < 0


def test_thesis_tcs_bias_angle_uses_twists_per_length(tcs):
    sample, _ = tcs
    # 750 twists over 328 mm at d0 = 0.4 mm
    assert math.degrees(static.bias_angle(0.4e-3, 750, 0.328)) == pytest.approx(70.81, abs=0.01)


def test_forward_then_inverse_recovers_displacement_and_force(tcs):
    sample, rig = tcs
    kw = geometry(sample)
    # Down to 1 um: below that R differs from R0 by less than ~1e-8 relative and
    # double precision in R, not the solver, limits the recovery.
    delta = np.concatenate([np.linspace(-2e-3, 50e-3, 200), [1e-6, -1e-6, 0.0]])
    r = sensing.forward(delta, rig.initial_resistance, rig.spring_constant, **kw)
    got, force = sensing.invert(r, rig.initial_resistance, rig.spring_constant, **kw)
    nz = delta != 0
    np.testing.assert_allclose(got[nz], delta[nz], rtol=1e-9)
    np.testing.assert_allclose(force[nz], rig.spring_constant * delta[nz], rtol=1e-9)
    assert got[~nz] == 0.0


def test_solution_satisfies_equation_3_6(tcs):
    sample, rig = tcs
    kw = geometry(sample)
    r = np.array([30.3, 31.0])
    delta, _ = sensing.invert(r, 30.0, rig.spring_constant, **kw)
    d = sensing.diameter_from_resistance(r, 30.0, sample.fiber_diameter)
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    s = sample.sin_alpha0 + delta / sample.fiber_length
    f11, f12 = static.compliances(s, d, sample.fiber_length, sample.n_coils, g, sample.youngs_modulus)
    tau = sensing.torque(d, sample.fiber_diameter, sample.twists, sample.fiber_length, g)
    np.testing.assert_allclose(delta * (1 - rig.spring_constant * f11), -f12 * tau, rtol=1e-10)
    assert np.all(delta > 0) and delta[1] > delta[0]


def test_conditioning_statuses(tcs):
    sample, _ = tcs
    kw = geometry(sample)
    stiff = sensing.conditioning(1.0, **kw).spring_stiffness_model
    assert sensing.conditioning(0.6 * stiff, **kw).status == "ok"
    ill = sensing.conditioning(0.98 * stiff, **kw)
    assert ill.status == "ill-conditioned"
    assert ill.margin == pytest.approx(0.02, rel=1e-9)
    assert "0.98" in ill.describe()
    none = sensing.conditioning(1.2 * stiff, **kw)
    assert none.status == "no-physical-root"
    with pytest.raises(ModelDomainError, match="no physical root"):
        sensing.invert(31.0, 30.0, 1.2 * stiff, **kw)


def test_resistance_must_be_positive(tcs):
    sample, rig = tcs
    with pytest.raises(ModelDomainError, match="positive"):
        sensing.invert([30.0, -1.0], 30.0, rig.spring_constant, **geometry(sample))


def test_unreachable_compression_is_reported(tcs):
    sample, rig = tcs
    with pytest.raises(ModelDomainError, match="no physical root"):
        sensing.invert(5.0, 30.0, rig.spring_constant, **geometry(sample))


@settings(max_examples=50, deadline=None)
@given(r1=st.floats(30.0, 33.0), r2=st.floats(30.0, 33.0), frac=st.floats(0.2, 0.9))
def test_property_monotone_and_finite(r1, r2, frac):
    s = THESIS_TCS.build_sample()
    kw = geometry(s)
    spring = frac * sensing.conditioning(1.0, **kw).spring_stiffness_model
    d, _ = sensing.invert(np.array([r1, r2]), 30.0, spring, **kw)
    assert np.all(np.isfinite(d)) and np.all(d >= 0)
    if r1 < r2:
        assert d[0] <= d[1]


# Stiff springs: S f11(alpha0) up to 0.95. Just below R0 the equation has two
# roots (e.g. -0.045 mm and -44.35 mm at S f11 = 0.9, R = R0 (1 - 1e-5)); the
# physical one is small and continuous through delta = 0 at R = R0.
STIFF_FRACTIONS = (0.5, 0.8, 0.9, 0.95)
NEAR_R0 = np.array([-1e-5, -3e-6, -1e-6, 0.0, 1e-6, 3e-6, 1e-5])


def _first_order_delta(sample, spring, rel):
    """delta ~ -f12 tau / (1 - S f11) at alpha0, d0, with tau linear in R - R0 (3.1)-(3.6)."""
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    f11, f12 = static.compliances(
        sample.sin_alpha0,
        sample.fiber_diameter,
        sample.fiber_length,
        sample.n_coils,
        g,
        sample.youngs_modulus,
    )
    # d / d0 = sqrt(R0 / R) ~ 1 - rel / 2, so 1 - d0 / d ~ -rel / 2 (3.3).
    dtau_drel = -0.5 * g * math.pi * sample.fiber_diameter**4 / 32 * 2 * math.pi * sample.twists
    dtau_drel /= sample.fiber_length
    return -f12 * dtau_drel * rel / (1 - spring * f11)


@pytest.mark.parametrize("frac", STIFF_FRACTIONS)
def test_stiff_spring_near_r0_picks_the_small_continuous_root(tcs, frac):
    sample, _ = tcs
    kw = geometry(sample)
    r0 = 30.0
    spring = frac * sensing.conditioning(1.0, **kw).spring_stiffness_model
    r = r0 * (1 + NEAR_R0)
    delta, _ = sensing.invert(r, r0, spring, **kw)
    # continuous through 0 at R0, increasing in R, signed like R - R0
    assert delta[NEAR_R0 == 0] == 0.0
    assert np.all(np.diff(delta) > 0)
    np.testing.assert_array_equal(np.sign(delta), np.sign(NEAR_R0))
    # small: first-order value from the linearised equation, independent of invert
    lin = _first_order_delta(sample, spring, NEAR_R0)
    assert np.all(np.abs(delta) < 0.2e-3)
    nz = NEAR_R0 != 0
    np.testing.assert_allclose(delta[nz], lin[nz], rtol=0.01)
    # and from the forward model's slope dR/ddelta at 0 (central difference)
    h = 1e-7
    r_pm = sensing.forward(np.array([h, -h]), r0, spring, **kw)
    slope = (r_pm[0] - r_pm[1]) / (2 * h)
    np.testing.assert_allclose(delta[nz], (r[nz] - r0) / slope, rtol=0.01)
    # forward(invert(R)) == R
    np.testing.assert_allclose(sensing.forward(delta, r0, spring, **kw), r, rtol=1e-13)


@pytest.mark.parametrize("frac", STIFF_FRACTIONS)
def test_stiff_spring_compression_root_is_nearest_zero(tcs, frac):
    # Every root of (3.6) between delta and 0 would be a sign change of the
    # residual: there must be none, so the returned root is the one nearest 0.
    sample, _ = tcs
    kw = geometry(sample)
    spring = frac * sensing.conditioning(1.0, **kw).spring_stiffness_model
    r = 30.0 * (1 - np.array([1e-5, 1e-4]))
    delta, _ = sensing.invert(r, 30.0, spring, **kw)
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    for ri, di in zip(r, delta):
        d = sensing.diameter_from_resistance(ri, 30.0, sample.fiber_diameter)
        tau = sensing.torque(d, sample.fiber_diameter, sample.twists, sample.fiber_length, g)
        x = np.linspace(di * (1 - 1e-6), 0.0, 2001)
        f11, f12 = static.compliances(
            sample.sin_alpha0 + x / sample.fiber_length,
            d,
            sample.fiber_length,
            sample.n_coils,
            g,
            sample.youngs_modulus,
        )
        assert np.all(x * (1 - spring * f11) + f12 * tau > 0)


def test_forward_outside_the_domain_names_the_model_the_point_and_s(tcs):
    """An extension with no physical coil diameter is a domain error naming the map, the
    point and the stated S (it was a bare 'no sign change in bracket' before)."""
    kw = geometry(tcs[0])
    stretch = np.array([0.0, 10e-3, 230e-3])  # the 4.7 N/m sensor has no diameter at 230 mm
    with pytest.raises(
        ModelDomainError, match=r"at delta = 230 mm \(point 2; 1 of 3 points\) for S = 4.7 N/m"
    ):
        sensing.forward(stretch, 30.0, 4.7, **kw)
    sensing.forward(stretch[:2], 30.0, 4.7, **kw)  # the points inside the domain solve
