"""Coil compliances (2.11) and the compiled copies of the shared equation functions."""

import math

import numpy as np
import pytest

from tcamlab.models import coil, dynamic, static, thermal


def random_coils(rng, n=500):
    """n random parameter sets over the physical range of the thesis samples."""
    return dict(
        s=rng.uniform(0.05, 0.95, n),
        d=rng.uniform(0.1e-3, 0.6e-3, n),
        l=rng.uniform(0.05, 0.4, n),
        n=rng.uniform(20.0, 200.0, n),
        g=rng.uniform(5e7, 5e8, n),
        e=rng.uniform(1e9, 5e9, n),
    )


def test_compliance_coefficients_hand_values():
    a, b, c = coil.compliance_coefficients(0.2e-3, 0.1, 50.0)
    ln = 0.1 / 50.0
    assert a == pytest.approx(8 * 50 * ln**3 / (math.pi**3 * 0.2e-3**4), rel=1e-15)
    assert b == pytest.approx(8 * 50 * ln / (math.pi * 0.2e-3**2), rel=1e-15)
    assert c == pytest.approx(8 * 50 * ln**2 / (math.pi**2 * 0.2e-3**4), rel=1e-15)


def test_compliance_derivatives_match_finite_differences(rng):
    p = random_coils(rng)
    a, b, c = coil.compliance_coefficients(p["d"], p["l"], p["n"])
    h = 1e-6
    f11, df11, f12, df12 = coil.compliance_terms(p["s"], a, b, c, p["g"], p["e"])
    up = coil.compliance_terms(p["s"] + h, a, b, c, p["g"], p["e"])
    dn = coil.compliance_terms(p["s"] - h, a, b, c, p["g"], p["e"])
    np.testing.assert_allclose(df11, (up[0] - dn[0]) / (2 * h), rtol=1e-6, atol=1e-9 * np.abs(f11).max())
    np.testing.assert_allclose(df12, (up[2] - dn[2]) / (2 * h), rtol=1e-6, atol=1e-9 * np.abs(f12).max())


def test_compiled_equation_functions_agree_with_numpy(rng):
    # The kernels compile these same functions; numba may round pow and
    # division differently, so compare at many points to a tight tolerance.
    numba = pytest.importorskip("numba")
    p = random_coils(rng)
    a, b, c = coil.compliance_coefficients(p["d"], p["l"], p["n"])
    jit_coef = numba.njit(coil.compliance_coefficients)
    jit_terms = numba.njit(coil.compliance_terms)
    jit_torque = numba.njit(static.torque_from_strain)
    jit_heat = numba.njit(thermal.heating_rate)
    jit_acc = numba.njit(dynamic.acceleration)
    terms = coil.compliance_terms(p["s"], a, b, c, p["g"], p["e"])
    strain = rng.uniform(0.0, 0.02, p["s"].size)
    phi = rng.uniform(500.0, 5000.0, p["s"].size)
    torque = static.torque_from_strain(p["g"], phi, p["d"], p["l"], strain)
    dT = rng.uniform(-10.0, 200.0, p["s"].size)
    heat = thermal.heating_rate(dT, 8.0, 40.0, 0.0266, 0.00893, 3e-3, 2e-3)
    acc = dynamic.acceleration(p["s"], p["g"] * 1e-9, 0.05, 0.84, 0.49)
    for i in range(p["s"].size):
        got = jit_coef(p["d"][i], p["l"][i], p["n"][i])
        np.testing.assert_allclose(got, (a[i], b[i], c[i]), rtol=1e-14)
        got = jit_terms(p["s"][i], a[i], b[i], c[i], p["g"][i], p["e"][i])
        np.testing.assert_allclose(got, [t[i] for t in terms], rtol=1e-14)
        assert jit_torque(p["g"][i], phi[i], p["d"][i], p["l"][i], strain[i]) == pytest.approx(
            torque[i], rel=1e-14
        )
        assert jit_heat(dT[i], 8.0, 40.0, 0.0266, 0.00893, 3e-3, 2e-3) == pytest.approx(heat[i], rel=1e-14)
        assert jit_acc(p["s"][i], p["g"][i] * 1e-9, 0.05, 0.84, 0.49) == pytest.approx(acc[i], rel=1e-14)


def test_restoring_force_inverts_2_11(rng):
    p = random_coils(rng)
    a, b, c = coil.compliance_coefficients(p["d"], p["l"], p["n"])
    f11, _, f12, _ = coil.compliance_terms(p["s"], a, b, c, p["g"], p["e"])
    force = rng.uniform(0.0, 1.0, p["s"].size)
    tau = rng.uniform(-1e-4, 1e-4, p["s"].size)
    delta = f11 * force - f12 * tau  # (2.11)
    np.testing.assert_allclose(coil.restoring_force(delta, f11, f12, tau), force, rtol=1e-9, atol=1e-12)
