"""Dynamic model (2.14)-(2.19)."""

import numpy as np
import pytest

from tcamlab.errors import ModelDomainError
from tcamlab.models import dynamic, static, thermal


def kwargs(sample, rig, **over):
    kw = dict(
        sample.model_kwargs(),
        load=rig.load,
        damping=rig.damping,
        thermal_mass=rig.thermal_mass,
        heat_loss=rig.heat_loss,
        resistance=rig.resistance,
        ambient=rig.ambient,
    )
    kw.update(over)
    return kw


def test_starts_at_rest_at_static_equilibrium(tca):
    sample, rig = tca
    t = np.linspace(0, 1, 101)
    res = dynamic.response(t, 0.0, **kwargs(sample, rig))
    # no voltage: nothing moves
    np.testing.assert_allclose(res.displacement, 0.0, atol=1e-12)
    np.testing.assert_allclose(res.temperature, rig.ambient, atol=1e-12)
    assert res.extension0 == pytest.approx(
        static.displacement(0.0, rig.force, **sample.model_kwargs()), rel=1e-12
    )


@pytest.mark.parametrize("method", ["dp5", "RK45"])
@pytest.mark.parametrize("slope", [0.0, 1.11e6], ids=["constant-G", "G(T)"])
def test_held_voltage_settles_at_static_displacement(tca, method, slope):
    sample, rig = tca
    # choose V for a 100 K rise, inside the G_t' > 0 range (10 V would give ~280 K)
    volts = np.sqrt(100.0 * rig.resistance * rig.heat_loss)
    t = np.arange(0.0, 60.0 + 1e-9, 0.01)
    res = dynamic.response(t, volts, **kwargs(sample, rig, shear_modulus_slope=slope), method=method)
    t_inf = thermal.steady_state_temperature(volts, rig.resistance, rig.heat_loss, rig.ambient)
    assert res.temperature[-1] == pytest.approx(t_inf, rel=1e-6)
    kw = dict(sample.model_kwargs(), shear_modulus_slope=slope)
    expected = static.displacement(t_inf - rig.ambient, rig.force, **kw) - static.displacement(
        0.0, rig.force, **kw
    )
    assert res.displacement[-1] == pytest.approx(expected, rel=1e-5)
    assert expected < 0  # contraction


def test_fast_path_agrees_with_solve_ivp_on_the_thesis_pulse(tca):
    sample, rig = tca
    t = np.arange(0.0, 10.0 + 1e-9, 0.001)
    v = np.where(t < 1.0 - 1e-9, 10.0, 0.0)
    fast = dynamic.response(t, v, **kwargs(sample, rig))
    ref = dynamic.response(
        t, v, **kwargs(sample, rig), method="DOP853", rtol=1e-11, atol=(1e-9, 1e-14, 1e-13)
    )
    np.testing.assert_allclose(fast.displacement, ref.displacement, rtol=0, atol=1e-9)
    assert fast.displacement.min() < -1e-4  # the pulse contracts the TCA


def test_ten_volts_held_is_refused(tca):
    sample, rig = tca
    t = np.arange(0.0, 30.0, 0.01)
    with pytest.raises(ModelDomainError, match=r"G_t'"):
        dynamic.response(t, 10.0, **kwargs(sample, rig))
    with pytest.raises(ModelDomainError, match=r"G_t'"):
        dynamic.response(t[:300], 10.0, **kwargs(sample, rig), method="RK45")


def test_lognormal_draws_keep_mean_sd_and_positivity(rng):
    x = dynamic.lognormal_draws(0.00893, 0.01615, 400_000, rng)
    assert x.min() > 0
    assert x.mean() == pytest.approx(0.00893, rel=0.03)
    assert x.std() == pytest.approx(0.01615, rel=0.1)


def test_monte_carlo_band_brackets_nominal(tca):
    sample, rig = tca
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    v = np.where(t < 1.0 - 1e-9, 10.0, 0.0)
    mc = dynamic.monte_carlo(t, v, sample, rig, n_draws=300, seed=3)
    nominal = dynamic.response(t, v, **kwargs(sample, rig)).displacement
    lo, mid, hi = mc.band()
    inside = (nominal >= lo - 1e-9) & (nominal <= hi + 1e-9)
    assert inside.mean() > 0.95
    assert mc.valid.sum() + mc.n_invalid == 300
    assert set(mc.draws) >= {"thermal_mass", "heat_loss", "damping"}
    # same seed, same draws
    again = dynamic.monte_carlo(t, v, sample, rig, n_draws=300, seed=3)
    np.testing.assert_array_equal(mc.draws["heat_loss"], again.draws["heat_loss"])


def test_bad_time_grid(tca):
    sample, rig = tca
    with pytest.raises(ModelDomainError):
        dynamic.response([0.0, 0.0, 1.0], 1.0, **kwargs(sample, rig))


def test_kernels_compile_the_package_equations():
    # One implementation per equation, compiled once: every numba kernel calls the
    # wrappers in models.compiled, which wrap the very functions the numpy models
    # and the scipy reference path call.
    import inspect

    from tcamlab.estimation import observer_kernel as OK
    from tcamlab.models import _dynamic_kernel as DK
    from tcamlab.models import _static_kernel as SK
    from tcamlab.models import coil, compiled, thermal

    assert compiled.heating_rate.py_func is thermal.heating_rate
    assert compiled.torque_from_strain.py_func is static.torque_from_strain
    assert compiled.compliance_terms.py_func is coil.compliance_terms
    assert compiled.compliance_coefficients.py_func is coil.compliance_coefficients
    assert compiled.restoring_force.py_func is coil.restoring_force
    assert compiled.acceleration.py_func is dynamic.acceleration
    assert compiled.pitch_residual.py_func is static.pitch_residual
    for mod in (DK, SK, OK):
        src = inspect.getsource(mod)
        assert "compiled." in src, mod.__name__
        # no kernel wraps a package function itself (that compiled it twice)
        assert ")(coil." not in src and ")(static." not in src and ")(thermal." not in src, mod.__name__


def test_kernel_temperature_matches_exact_held_voltage_solution(tca):
    # (2.18) integrated by the dp5 kernel against its closed form (thermal.temperature).
    sample, rig = tca
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    v = np.where(t < 1.0 - 1e-9, 10.0, 0.0)
    res = dynamic.response(t, v, **kwargs(sample, rig))
    exact = thermal.temperature(t, v, rig.resistance, rig.thermal_mass, rig.heat_loss, rig.ambient)
    np.testing.assert_allclose(res.temperature, exact, rtol=1e-7)
