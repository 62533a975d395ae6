"""Static model (section 2.3): hand-derived values and physical properties."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tcamlab.errors import ModelDomainError
from tcamlab.models import static
from tcamlab.params import THESIS_TCA


def test_volume_fraction_two_ply():
    # V_f = (r_f / r)^2 V_fmax with r_f = r / 2 (section 2.5.1)
    assert static.volume_fraction(2, 0.887) == pytest.approx(0.887 / 4, rel=1e-15)


def test_bias_angle_hand_value():
    # alpha_f = atan(pi d phi), phi = 150 turns / 0.095 m
    expected = math.atan(math.pi * 0.17e-3 * 150 / 0.095)
    assert static.bias_angle(0.17e-3, 150, 0.095) == pytest.approx(expected, rel=1e-14)
    assert math.degrees(expected) == pytest.approx(40.14, abs=0.01)


def test_transverse_shear_modulus_hand_value_at_60_degrees():
    # cos(60 deg) = 1/2: numerator 4 Vf E (pi/6 - sqrt(3)/8)^2,
    # denominator pi (2 + pi) (2/3 - 1/2 + 1/24) (1/2)
    vf, e = 0.2, 3.0e9
    num = 4 * vf * e * (math.pi / 6 - math.sqrt(3) / 8) ** 2
    den = math.pi * (2 + math.pi) * (2 / 3 - 0.5 + 1 / 24) * 0.5
    got = static.transverse_shear_modulus(e, vf, math.pi / 3)
    assert got == pytest.approx(num / den, rel=1e-13)
    assert got == pytest.approx(1.34516e8, rel=1e-5)  # decimal check by hand


def test_thesis_tca_shear_modulus_allows_the_oven_range(tca):
    sample, _ = tca
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    # G_t' of (2.13) must stay positive over the 25-150 degC oven test at T_a = 20 degC.
    assert static.max_temperature_rise(g, 1.11e6) > 130.0


def test_shear_modulus_slope_is_gpa_per_kelvin():
    # (2.13) with the text's 0.00111 GPa/degC: 100 K lowers G by 111 MPa.
    assert static.shear_modulus_at(100.0, 500e6, 1.11e6) == pytest.approx(389e6, rel=1e-15)


def test_models_refuse_non_positive_shear_modulus():
    with pytest.raises(ModelDomainError, match=r"\(2.13\)"):
        static.shear_modulus_at(np.array([10.0, 500.0]), 300e6, 1.11e6)


def test_torque_forms_2_6_and_2_9_agree():
    g, d0, n_turns, l, rho, dT = 2e8, 0.17e-3, 150.0, 0.095, 8.1e-5, 80.0
    d = d0 * (1 + rho * dT)
    j = math.pi * d**4 / 32
    tau_26 = g * j * (2 * math.pi * n_turns) * (1 - d0 / d) / l
    assert static.torque(dT, g, d0, n_turns, l, rho) == pytest.approx(tau_26, rel=1e-12)
    assert static.torque(0.0, g, d0, n_turns, l, rho) == 0.0


def test_compliances_hand_value_at_zero_pitch():
    # alpha = 0: f11 = 8 l^3 / (pi^3 d^4 n^2 G) + 8 l / (pi d^2) / (2 G); f12 = 8 l^2 / (pi^2 d^4 n G)
    d, l, n, g, e = 0.2e-3, 0.1, 50.0, 2e8, 3e9
    f11_hand = 8 * l**3 / (math.pi**3 * d**4 * n**2 * g) + 8 * l / (math.pi * d**2) / (2 * g)
    f12_hand = 8 * l**2 / (math.pi**2 * d**4 * n * g)
    f11, f12 = static.compliances(0.0, d, l, n, g, e)
    assert f11 == pytest.approx(f11_hand, rel=1e-13)
    assert f12 == pytest.approx(f12_hand, rel=1e-13)
    # alpha = 90 deg: only the axial-stretch term B / (2E) = 4 l / (pi d^2 E) remains
    f11, f12 = static.compliances(1.0, d, l, n, g, e)
    assert f11 == pytest.approx(4 * l / (math.pi * d**2 * e), rel=1e-13)
    assert f12 == pytest.approx(0.0, abs=1e-20)


def test_n_coils():
    assert static.n_coils(0.095, 0.02, 0.36e-3) == pytest.approx(
        0.095 * math.sqrt(1 - (0.02 / 0.095) ** 2) / (math.pi * 0.36e-3), rel=1e-14
    )


@pytest.mark.parametrize("method", ["jit", "numpy"])
@pytest.mark.parametrize("slope", [0.0, 1.11e6], ids=["constant-G", "G(T)"])
def test_solvers_agree(tca, method, slope):
    sample, _ = tca
    rng = np.random.default_rng(7)
    dT = rng.uniform(0, 130, 2000)
    force = rng.uniform(0.0, 1.0, 2000)
    kw = dict(sample.model_kwargs(), shear_modulus_slope=slope)
    got = static.displacement(dT, force, **kw, method=method)
    # residual of (2.10)-(2.11) at the returned root, computed independently
    s = sample.sin_alpha0 + got / sample.fiber_length
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    d = sample.fiber_diameter * (1 + sample.radial_cte * dT)
    f11, f12 = static.compliances(s, d, sample.fiber_length, sample.n_coils, g, sample.youngs_modulus)
    tau = static.torque(
        dT,
        static.shear_modulus_at(dT, g, slope),
        sample.fiber_diameter,
        sample.twists,
        sample.fiber_length,
        sample.radial_cte,
    )
    np.testing.assert_allclose(got, f11 * force - f12 * tau, rtol=0, atol=1e-13)


@pytest.mark.parametrize("slope", [0.0, 1.11e6], ids=["constant-G", "G(T)"])
def test_zero_temperature_rise_gives_the_spring_extension(tca, slope):
    sample, rig = tca
    kw = dict(sample.model_kwargs(), shear_modulus_slope=slope)
    delta = float(static.displacement(0.0, rig.force, **kw))
    # delta must satisfy delta = f11(alpha) F exactly at the solved pitch angle
    s = sample.sin_alpha0 + delta / sample.fiber_length
    g = static.sample_shear_modulus(
        sample.fiber_diameter, sample.fiber_length, sample.twists, sample.youngs_modulus
    )
    f11, _ = static.compliances(
        s, sample.fiber_diameter, sample.fiber_length, sample.n_coils, g, sample.youngs_modulus
    )
    assert delta == pytest.approx(f11 * rig.force, rel=1e-10)
    # small force: linear spring with the compliance at alpha0
    f11_0, _ = static.compliances(
        sample.sin_alpha0,
        sample.fiber_diameter,
        sample.fiber_length,
        sample.n_coils,
        g,
        sample.youngs_modulus,
    )
    small = 1e-6
    assert float(static.displacement(0.0, small, **kw)) == pytest.approx(f11_0 * small, rel=1e-5)


def test_constant_and_temperature_dependent_g_agree_at_zero_rise(tca):
    sample, rig = tca
    kw = sample.model_kwargs()
    a = static.displacement(0.0, rig.force, **dict(kw, shear_modulus_slope=0.0))
    b = static.displacement(0.0, rig.force, **dict(kw, shear_modulus_slope=1.11e6))
    assert a == pytest.approx(b, rel=1e-14)


def test_heating_thesis_tca_under_load_contracts(tca):
    sample, rig = tca
    temps = np.arange(0.0, 131.0, 5.0)
    for slope in (0.0, 1.11e6):
        d = static.displacement(temps, rig.force, **dict(sample.model_kwargs(), shear_modulus_slope=slope))
        assert np.all(np.diff(d) < 0), "extension must fall as temperature rises"
        assert d[-1] < d[0] - 1e-4  # more than 0.1 mm of contraction over 130 K


def test_softening_shear_modulus_reduces_contraction(tca):
    sample, rig = tca
    kw = sample.model_kwargs()
    const = static.displacement(130.0, rig.force, **dict(kw, shear_modulus_slope=0.0))
    soft = static.displacement(130.0, rig.force, **dict(kw, shear_modulus_slope=1.11e6))
    base = static.displacement(0.0, rig.force, **kw)
    # a smaller G gives a smaller torque (2.6), so less contraction
    assert base - soft < base - const


def test_internal_force_balances_the_load_at_equilibrium(tca):
    sample, rig = tca
    kw = sample.model_kwargs()
    for dT in (0.0, 60.0):
        delta = static.displacement(dT, rig.force, **kw)
        assert static.internal_force(delta, dT, **kw) == pytest.approx(rig.force, rel=1e-9)


def test_full_output_returns_solver_result(tca):
    sample, rig = tca
    delta, res = static.displacement(
        np.array([0.0, 50.0]), rig.force, **sample.model_kwargs(), full_output=True, method="numpy"
    )
    assert res.converged.all() and res.iterations < 20
    assert np.allclose(res.root, sample.sin_alpha0 + delta / sample.fiber_length, rtol=1e-14)


def test_broadcasting_shapes(tca):
    sample, _ = tca
    d = static.displacement(np.zeros((3, 1)), np.array([0.1, 0.2]), **sample.model_kwargs())
    assert d.shape == (3, 2)


def test_no_equilibrium_is_a_domain_error(tca):
    sample, _ = tca
    # a force far beyond what straightens the coil has no root in [0, 90] deg
    with pytest.raises(ModelDomainError, match="no equilibrium"):
        static.displacement(0.0, -50.0, **sample.model_kwargs())


@settings(max_examples=60, deadline=None)
@given(
    dT=st.floats(0.0, 120.0),
    force=st.floats(0.01, 1.0),
    twists=st.floats(80.0, 200.0),
    coil_mm=st.floats(12.0, 40.0),
)
def test_property_finite_and_monotone(dT, force, twists, coil_mm):
    # Constant G: heating always shortens. (With G(T) the torque G_t'(T) rho dT
    # peaks near dT = G_t / (2 k), so "hotter is shorter" need not hold there.)
    s = THESIS_TCA.build_sample(twists=twists, coil_length=coil_mm * 1e-3, shear_modulus_slope=0.0)
    kw = s.model_kwargs()
    g = static.sample_shear_modulus(s.fiber_diameter, s.fiber_length, twists, s.youngs_modulus)
    dT = min(dT, 0.9 * float(g) / 1.11e6)
    d = static.displacement(np.array([dT, dT, dT + 1.0]), np.array([force, force * 1.1, force]), **kw)
    assert np.all(np.isfinite(d))
    assert d[1] > d[0]  # more load, longer
    assert d[2] < d[0]  # hotter, shorter
    assert -s.coil_length < d[0] < s.fiber_length - s.coil_length


@settings(max_examples=40, deadline=None)
@given(dT=st.floats(0.0, 150.0), force=st.floats(0.0, 1.0))
def test_property_temperature_dependent_model_finite_in_range(dT, force):
    s = THESIS_TCA.build_sample()
    d = static.displacement(dT, force, **s.model_kwargs())
    assert np.isfinite(d) and -s.coil_length < d < s.fiber_length - s.coil_length


def test_no_equilibrium_names_the_point_its_inputs_and_the_stated_values():
    """A load no coil of this sample can hold: the message names the equation, the point's
    temperature rise and force, and G_t and rho (it gave only an index before)."""
    kw = THESIS_TCA.build_sample().model_kwargs()
    with pytest.raises(
        ModelDomainError, match=r"\(2.10\)-\(2.11\).* at dT = 10 K, F = 200 N \(point 1; 1 of 2"
    ):
        static.displacement(np.array([0.0, 10.0]), np.array([0.5, 200.0]), **kw)


def test_a_fiber_with_no_bias_angle_is_a_domain_error_not_nan():
    """150 twists over 1e9 m leave alpha_f about 1e-13 rad and (2.12) 0 / 0: refused naming the
    fabrication keys (it leaked a numpy warning and gave NaN predictions); the thesis TCA's G_t
    stays finite."""
    import warnings

    assert np.isfinite(static.sample_shear_modulus(0.17e-3, 95e-3, 150.0, 3.45e9))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelDomainError, match="fiber_diameter_mm, fiber_length_mm and twists"):
            static.sample_shear_modulus(0.17e-3, 1e9, 150.0, 3.45e9)
