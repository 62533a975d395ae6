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
