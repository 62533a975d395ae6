"""Each effect term of tcamlab.effects.Mods, checked directly for sign and size.

For every field: prediction with the term minus prediction without, on a
small hand-made input frame, against a value derived by hand here (exact
where the term has a closed form, first order otherwise). No virtual rig.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import quad

from tcamlab.effects import SLACK_RAMP, Mods
from tcamlab.kinds import predict
from tcamlab.models import sensing, static
from tcamlab.params import SILVER_TCR, THESIS_ROBOT, THESIS_TCA, THESIS_TCS, THESIS_TCS_SPRING_CONSTANT

NONE = Mods()


def test_every_mods_field_is_covered():
    """A new Mods field must get a test here too."""
    covered = {
        "shear_slope_extra",
        "coil_shear_slope",
        "youngs_modulus_slope",
        "glass_gain",
        "glass_temperature",
        "lag_tau",
        "lag_conductance_tc",
        "drift",
        "resistance_tc",
        "heat_loss_tc",
        "delay",
        "slack",
        "slack_length",
        "hysteresis",
        "relaxation",
        "relaxation_tau",
        "temperature_offset",
        "stiffening",
        "compression",
        "camera_offset",
        "offset_error",
        # self-sensing: hand values in tests/test_kind_selfsensing.py
        "contact_slope",
        "contact_onset",
        "r0_drift",
        "tcr_extra",
    }
    assert set(Mods.__dataclass_fields__) == covered
    fixed = {"glass_temperature", "relaxation_tau", "contact_onset"}
    assert all(getattr(NONE, f) == 0.0 for f in covered - fixed)


# ---------------------------------------------------------------------------
# static: displacement against oven temperature (thesis-tca)
# ---------------------------------------------------------------------------

TCA_SAMPLE = THESIS_TCA.build_sample()
TCA_RIG = THESIS_TCA.build_rig()
TEMPS = np.array([20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0])  # first row at ambient (20 degC)


def _static(mods=NONE, temps=TEMPS, time=None, sample=TCA_SAMPLE):
    data = pd.DataFrame({"temperature": temps})
    if time is not None:
        data["time"] = time
    return predict("static", sample, TCA_RIG, data, mods)["displacement"]


def _abs_static(dT, sample=TCA_SAMPLE, **kw):
    """Absolute extension of the model at rise dT (not re-zeroed)."""
    args = sample.model_kwargs()
    args.update(kw)
    return static.displacement(np.asarray(dT, float), TCA_RIG.force, **args)


def _equilibrium_derivatives(dT):
    """Pieces of h(s) = l (s - s0) - F f11(s, E) + tau f12(s) at the solved s, by hand.

    Returns (h'(s), tau, G_T, f12, df11/dE) with derivatives by central differences
    of the Castigliano compliances, not of the solver.
    """
    s_ = TCA_SAMPLE
    F = TCA_RIG.force
    l = s_.fiber_length
    s0 = s_.coil_length / l
    n = static.n_coils(l, s_.coil_length, s_.coil_diameter)
    g_t = float(
        static.sample_shear_modulus(
            s_.fiber_diameter, l, s_.twists, s_.youngs_modulus, s_.thread_plies, s_.max_volume_fraction
        )
    )
    g_T = g_t - s_.shear_modulus_slope * dT
    tau = float(static.torque(dT, g_T, s_.fiber_diameter, s_.twists, l, s_.radial_cte))
    d = s_.fiber_diameter * (1.0 + s_.radial_cte * dT)
    E = s_.youngs_modulus
    s = s0 + float(_abs_static(dT)) / l

    def f(s, e=E):
        return static.compliances(s, d, l, n, g_t, e)

    hs = 1e-7
    df11_ds = (f(s + hs)[0] - f(s - hs)[0]) / (2 * hs)
    df12_ds = (f(s + hs)[1] - f(s - hs)[1]) / (2 * hs)
    he = E * 1e-6
    df11_dE = (f(s, E + he)[0] - f(s, E - he)[0]) / (2 * he)
    # residual check: the model's s solves the equation we differentiate
    f11, f12 = f(s)
    assert abs(l * (s - s0) - F * f11 + tau * f12) < 1e-9 * l
    h_prime = l - F * df11_ds + tau * df12_ds
    return h_prime, tau, g_T, f12, df11_dE


def test_drift_adds_rate_times_time():
    d = 2e-6  # m/s
    t = np.array([0.0, 30.0, 75.0, 100.0, 160.0, 200.0, 300.0]) + 1000.0
    diff = _static(Mods(drift=d), time=t) - _static(time=t)
    np.testing.assert_allclose(diff, d * (t - t[0]), rtol=0, atol=1e-15)
    # without a time column the clock is the sample index
    diff = _static(Mods(drift=d)) - _static()
    np.testing.assert_allclose(diff, d * np.arange(TEMPS.size), rtol=0, atol=1e-15)


def test_shear_slope_extra_sign_and_first_order_size():
    k = 5e4  # Pa/K, small: first order
    diff = _static(Mods(shear_slope_extra=k)) - _static()
    # exactly the sample with slope k larger
    same = _static(sample=TCA_SAMPLE.replace(shear_modulus_slope=TCA_SAMPLE.shear_modulus_slope + k))
    np.testing.assert_allclose(_static(Mods(shear_slope_extra=k)), same, rtol=0, atol=1e-15)
    assert diff[0] == 0.0  # no rise, no torque change
    # G falls faster -> less untwisting torque -> less contraction: positive difference
    assert np.all(diff[1:] > 0)
    # first order: tau is linear in G, dtau = -k dT tau / G_T; ds = -f12 dtau / h'
    for j in (2, 4, 6):
        dT = TEMPS[j] - TCA_RIG.ambient
        h_prime, tau, g_T, f12, _ = _equilibrium_derivatives(dT)
        hand = TCA_SAMPLE.fiber_length * f12 * tau * k * dT / (g_T * h_prime)
        assert diff[j] == pytest.approx(hand, rel=0.02)


def _hand_coil_softened(dT, k_c):
    """Extension at rise dT with G_t - k_c dT in f11, f12, by brentq on h(s) by hand [m]."""
    from scipy.optimize import brentq

    s_ = TCA_SAMPLE
    F, l = TCA_RIG.force, s_.fiber_length
    s0 = s_.coil_length / l
    n = static.n_coils(l, s_.coil_length, s_.coil_diameter)
    g_t = float(
        static.sample_shear_modulus(
            s_.fiber_diameter, l, s_.twists, s_.youngs_modulus, s_.thread_plies, s_.max_volume_fraction
        )
    )
    tau = float(
        static.torque(dT, g_t - s_.shear_modulus_slope * dT, s_.fiber_diameter, s_.twists, l, s_.radial_cte)
    )
    d = s_.fiber_diameter * (1.0 + s_.radial_cte * dT)

    def h(s):
        f11, f12 = static.compliances(s, d, l, n, g_t - k_c * dT, s_.youngs_modulus)
        return l * (s - s0) - F * f11 + tau * f12

    return l * (brentq(h, 1e-9, 1.0 - 1e-9, xtol=1e-15) - s0)


def test_coil_shear_slope_softens_the_coil_as_by_hand():
    """G(T) in the coil (f11, f12), which (2.13) leaves at G_t: the hand solve of (2.11)."""
    k_c = 2e4  # Pa/K
    out = _static(Mods(coil_shear_slope=k_c))
    hand = np.array([_hand_coil_softened(T - TCA_RIG.ambient, k_c) for T in TEMPS])
    np.testing.assert_allclose(out, hand - hand[0], rtol=1e-6, atol=1e-12)
    # a softer coil under the load extends: the difference grows with the rise
    diff = out - _static()
    assert diff[0] == 0.0 and np.all(np.diff(diff) > 0)
    # and it is not the torque's slope: the same k in the torque moves the coil far less
    torque_only = _static(Mods(shear_slope_extra=k_c)) - _static()
    assert np.max(np.abs(torque_only)) < 0.1 * np.max(diff)


def test_youngs_modulus_slope_sign_and_first_order_size():
    c = 2e-4  # 1/K
    diff = _static(Mods(youngs_modulus_slope=c)) - _static()
    assert diff[0] == 0.0
    # E falls -> f11 (compliance) rises -> the load stretches the coil more: positive
    assert np.all(diff[1:] > 0)
    for j in (2, 4, 6):
        dT = TEMPS[j] - TCA_RIG.ambient
        h_prime, _, _, _, df11_dE = _equilibrium_derivatives(dT)
        dE = -TCA_SAMPLE.youngs_modulus * c * dT
        hand = TCA_SAMPLE.fiber_length * TCA_RIG.force * df11_dE * dE / h_prime
        assert hand > 0
        assert diff[j] == pytest.approx(hand, rel=0.02)


def test_glass_transition_only_above_glass_temperature():
    g, tg = 0.5, 45.0
    mods = Mods(glass_gain=g, glass_temperature=tg)
    diff = _static(mods) - _static()
    below = TEMPS <= tg
    np.testing.assert_allclose(diff[below], 0.0, atol=1e-15)
    # above: more radial swelling -> more untwisting torque -> more contraction
    assert np.all(diff[~below] < 0)
    # exactly the thesis model with rho' = rho (dT + g (T - Tg)) / dT at that point
    base0 = float(_abs_static(0.0))
    for j in np.flatnonzero(~below):
        dT = TEMPS[j] - TCA_RIG.ambient
        rho_eff = TCA_SAMPLE.radial_cte * (dT + g * (TEMPS[j] - tg)) / dT
        hand = float(_abs_static(dT, radial_cte=rho_eff)) - base0
        assert _static(mods)[j] == pytest.approx(hand, rel=1e-9, abs=1e-15)
    # the knee moves with glass_temperature
    diff_hi = _static(Mods(glass_gain=g, glass_temperature=65.0)) - _static()
    np.testing.assert_allclose(diff_hi[TEMPS <= 65.0], 0.0, atol=1e-15)
    assert np.all(diff_hi[TEMPS > 65.0] < 0)


def test_lag_tau_sees_an_older_cooler_temperature():
    tau = 60.0
    t = np.arange(7) * 60.0
    temps = np.array([20.0, 20.0, 60.0, 60.0, 60.0, 60.0, 60.0])
    lagged = _static(Mods(lag_tau=tau), temps=temps, time=t)
    # by hand: first-order lag of a step held since the previous sample
    hand_T = temps.copy()
    hand_T[2:] = 60.0 - 40.0 * np.exp(-np.arange(1, 6) * 60.0 / tau)
    hand = _static(temps=hand_T, time=t)
    np.testing.assert_allclose(lagged, hand, rtol=1e-9, atol=1e-15)
    diff = lagged - _static(temps=temps, time=t)
    assert np.all(diff[:2] == 0.0)
    # heating: the actuator is cooler than the oven, so contracts less
    assert np.all(diff[2:] > 0) and np.all(np.diff(diff[2:]) < 0)


def test_lag_conductance_shortens_the_lag_as_the_oven_warms():
    from scipy.integrate import solve_ivp

    tau, gamma = 120.0, 0.01
    t = np.array([0.0, 30.0, 90.0, 200.0, 400.0, 700.0])
    temps = np.array([20.0, 80.0, 80.0, 120.0, 60.0, 60.0])
    # by hand: y' = (x - y)(1 + gamma ((x + y) / 2 - T_ambient)) / tau, x held, integrated finely
    hand_T = [temps[0]]
    for k in range(1, t.size):

        def rhs(_, y, x=temps[k]):
            return (x - y) * (1.0 + gamma * (0.5 * (x + y) - TCA_RIG.ambient)) / tau

        sol = solve_ivp(rhs, (t[k - 1], t[k]), [hand_T[-1]], rtol=1e-11, atol=1e-11)
        hand_T.append(sol.y[0, -1])
    mods = Mods(lag_tau=tau, lag_conductance_tc=gamma)
    lagged = _static(mods, temps=temps, time=t)
    np.testing.assert_allclose(lagged, _static(temps=np.array(hand_T), time=t), rtol=1e-7, atol=1e-13)
    # warmer than ambient the coefficient is larger, so the actuator is nearer the oven
    one_tau = _static(Mods(lag_tau=tau), temps=temps, time=t)
    no_lag = _static(temps=temps, time=t)
    assert np.all(np.abs(lagged - no_lag)[1:] < np.abs(one_tau - no_lag)[1:])
    # without a lag the coefficient does nothing
    np.testing.assert_array_equal(_static(Mods(lag_conductance_tc=gamma), temps=temps, time=t), no_lag)


# ---------------------------------------------------------------------------
# dynamic: voltage pulse (thesis-tca)
# ---------------------------------------------------------------------------

DT = 0.01
T_DYN = np.round(np.arange(0.0, 3.0 + DT / 2, DT), 10)
V_DYN = np.where(T_DYN < 1.0, TCA_RIG.voltage, 0.0)
V_DYN[0] = TCA_RIG.voltage


def _dynamic(mods=NONE, sample=TCA_SAMPLE):
    data = pd.DataFrame({"time": T_DYN, "voltage": V_DYN})
    return predict("dynamic", sample, TCA_RIG, data, mods)


@pytest.fixture(scope="module")
def dyn_base():
    return _dynamic()


def _pulse_rise(t):
    """dT0(t) of C T' = P - lambda T during the pulse, by hand."""
    p = TCA_RIG.voltage**2 / TCA_RIG.resistance
    a = TCA_RIG.heat_loss / TCA_RIG.thermal_mass
    return p / TCA_RIG.heat_loss * (1.0 - np.exp(-a * t))


def test_dynamic_baseline_is_the_hand_thermal_solution(dyn_base):
    # Sanity of the frame used below: the model's temperature in the pulse is dT0(t).
    on = (T_DYN > 0) & (T_DYN <= 1.0)
    np.testing.assert_allclose(
        dyn_base["temperature"][on] - TCA_RIG.ambient, _pulse_rise(T_DYN[on]), rtol=1e-5
    )
    assert dyn_base["displacement"][np.argmin(np.abs(T_DYN - 1.0))] < 0  # heating contracts


def test_delay_shifts_the_output_in_time(dyn_base):
    m = 25
    out = _dynamic(Mods(delay=m * DT))
    np.testing.assert_allclose(out["displacement"][m:], dyn_base["displacement"][:-m], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["displacement"][:m], 0.0, atol=1e-15)
    # the laser's record lags; the heating, and so the temperature and current, do not
    np.testing.assert_array_equal(out["temperature"], dyn_base["temperature"])
    np.testing.assert_array_equal(out["current"], dyn_base["current"])
    # half a sample: linear interpolation between neighbours
    half = _dynamic(Mods(delay=DT / 2))["displacement"]
    b = dyn_base["displacement"]
    np.testing.assert_allclose(half[1:], 0.5 * (b[1:] + b[:-1]), rtol=0, atol=1e-12)


SIGNED = (
    (("dynamic", "response-delay"), "delay"),
    (("sensing", "initial-slack"), "slack"),
    (("static", "shear-modulus-temperature"), "coil_shear_slope"),
    (("dynamic", "shear-modulus-temperature"), "coil_shear_slope"),
    (("static", "youngs-modulus-temperature"), "youngs_modulus_slope"),
    (("dynamic", "convective-heat-loss"), "heat_loss_tc"),
    (("sensing", "stress-relaxation"), "relaxation"),
    (("sensing", "stiffening-spring"), "stiffening"),
    (("curvature", "axial-compression"), "compression"),
)
UNSIGNED = (
    (("static", "displacement-drift"), "drift"),
    (("dynamic", "resistance-temperature"), "resistance_tc"),
    (("sensing", "hysteresis"), "hysteresis"),
    (("sensing", "ambient-temperature"), "temperature_offset"),
    (("curvature", "camera-placement"), "camera_offset"),
    (("curvature", "sensor-offset-error"), "offset_error"),
)


def test_an_effect_whose_cause_has_a_direction_is_never_fitted_or_made_the_other_way():
    # A response cannot lead its step, a warming fibre softens, a dwell loses force: fitted
    # the other way the term is no longer its cause (below 0 the delay took up part of R(T),
    # a response that settles sooner), so the fit's box and the rig's ray both stop at 0.
    from tcamlab.effects import EFFECTS
    from tcamlab.errors import ConfigError
    from tcamlab.rig import strength as rig_strength

    for key, field in SIGNED:
        param = next(p for p in EFFECTS[key].params if p.field == field)
        assert param.lower == 0.0 < param.upper, key
        with pytest.raises(ConfigError, match="cannot take a negative"):
            rig_strength.ray_bound(EFFECTS[key], -1.0)
    for key, field in UNSIGNED:
        param = next(p for p in EFFECTS[key].params if p.field == field)
        assert param.lower < 0.0 < param.upper, key
        assert rig_strength.ray_bound(EFFECTS[key], -1.0) < 0


def test_resistance_tc_first_order_cooling(dyn_base):
    beta = 1e-4
    out = _dynamic(Mods(resistance_tc=beta))
    dtemp = out["temperature"] - dyn_base["temperature"]
    # u = dT/dbeta: C u' = -(P/R-normalised) dT0 - lambda u  ->  closed form in the pulse
    p = TCA_RIG.voltage**2 / TCA_RIG.resistance
    c, lam = TCA_RIG.thermal_mass, TCA_RIG.heat_loss
    a = lam / c
    on = (T_DYN > 0.1) & (T_DYN <= 1.0)
    t = T_DYN[on]
    u = -(p * p / (c * lam)) * ((1.0 - np.exp(-a * t)) / a - t * np.exp(-a * t))
    np.testing.assert_allclose(dtemp[on], beta * u, rtol=0.02)
    assert np.all(dtemp[T_DYN > 0.05] < 0)
    # cooler -> less contraction: displacement (negative) rises
    ddisp = out["displacement"] - dyn_base["displacement"]
    assert np.all(ddisp[T_DYN > 0.2] > 0)


def test_heat_loss_tc_first_order_cooling(dyn_base):
    gamma = 1e-4
    out = _dynamic(Mods(heat_loss_tc=gamma))
    dtemp = out["temperature"] - dyn_base["temperature"]
    lam, c = TCA_RIG.heat_loss, TCA_RIG.thermal_mass
    a = lam / c
    for t in (0.3, 0.6, 1.0):
        # C u' = -lambda dT0^2 - lambda u  ->  u(t) = -a int_0^t exp(-a (t - s)) dT0(s)^2 ds
        u = -a * quad(lambda s, t=t: math.exp(-a * (t - s)) * _pulse_rise(s) ** 2, 0.0, t)[0]
        j = int(np.argmin(np.abs(T_DYN - t)))
        assert dtemp[j] == pytest.approx(gamma * u, rel=0.02)
    assert np.all(dtemp[T_DYN > 0.05] < 0)
    ddisp = out["displacement"] - dyn_base["displacement"]
    assert np.all(ddisp[T_DYN > 0.2] > 0)


def test_dynamic_coil_shear_slope_extends_while_hot(dyn_base):
    """The coil softens while the fiber is warm: the loaded coil extends, temperature unchanged."""
    out = _dynamic(Mods(coil_shear_slope=2e4))
    np.testing.assert_allclose(out["temperature"], dyn_base["temperature"], rtol=0, atol=1e-9)
    ddisp = out["displacement"] - dyn_base["displacement"]
    assert np.all(ddisp[T_DYN > 0.2] > 0)
    # largest where the fiber is hottest (end of the pulse, plus the mechanics' lag)
    j_hot = int(np.argmax(dyn_base["temperature"]))
    assert abs(int(np.argmax(ddisp)) - j_hot) * DT < 0.3


def test_dynamic_shear_slope_extra_sign(dyn_base):
    k = 5e4
    out = _dynamic(Mods(shear_slope_extra=k))
    same = _dynamic(sample=TCA_SAMPLE.replace(shear_modulus_slope=TCA_SAMPLE.shear_modulus_slope + k))
    np.testing.assert_allclose(out["displacement"], same["displacement"], rtol=0, atol=1e-15)
    # temperature unaffected; less torque -> less contraction
    np.testing.assert_allclose(out["temperature"], dyn_base["temperature"], rtol=0, atol=1e-9)
    ddisp = out["displacement"] - dyn_base["displacement"]
    assert np.all(ddisp[T_DYN > 0.2] > 0)
    # size: the mechanics low-pass the quasi-static change, so the dynamic change
    # stays below the largest quasi-static one so far (first order, static IFT above)
    # and is a sizeable part of it at the displacement peak
    j = int(np.argmin(dyn_base["displacement"]))
    qs = []
    for dT in dyn_base["temperature"][1 : j + 1] - TCA_RIG.ambient:
        h_prime, tau, g_T, f12, _ = _equilibrium_derivatives(dT)
        qs.append(TCA_SAMPLE.fiber_length * f12 * tau * k * dT / (g_T * h_prime))
    assert 0.5 * max(qs) < ddisp[j] <= 1.03 * max(qs)


# ---------------------------------------------------------------------------
# sensing: displacement and force from resistance (thesis-tcs)
# ---------------------------------------------------------------------------

TCS_SAMPLE = THESIS_TCS.build_sample()
S = THESIS_TCS_SPRING_CONSTANT.value
R0 = THESIS_TCS.build_rig().initial_resistance
TCS_RIG = THESIS_TCS.build_rig(spring_constant=S)
SENS_OPTS = {"spring_constant": S, "initial_resistance": R0}


def _resistance(delta):
    return sensing.forward(np.asarray(delta, float), R0, S, **TCS_SAMPLE.sensor_kwargs())


def _sensing(r, mods=NONE, time=None):
    data = pd.DataFrame({"resistance": r})
    if time is not None:
        data["time"] = time
    return predict("sensing", TCS_SAMPLE, TCS_RIG, data, mods, **SENS_OPTS)


# loading 0 -> 5 mm (51 rows), unloading back to 0.05 mm (50 rows)
DELTA_TRI = np.concatenate([np.linspace(0.0, 5e-3, 51), np.linspace(5e-3, 0.05e-3, 51)[1:]])
APEX = 50


def test_sensing_baseline_recovers_the_hand_displacement():
    out = _sensing(_resistance(DELTA_TRI))
    np.testing.assert_allclose(out["displacement"], DELTA_TRI, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["force"], S * DELTA_TRI, rtol=0, atol=1e-8)


def test_hysteresis_unloading_reads_longer_loading_shorter():
    h = 0.1e-3
    r = _resistance(DELTA_TRI)
    base = _sensing(r)
    out = _sensing(r, Mods(hysteresis=h))
    diff = out["displacement"] - base["displacement"]
    ramp = np.clip(DELTA_TRI / SLACK_RAMP, 0.0, 1.0)
    sign = np.where(np.arange(DELTA_TRI.size) > APEX, 1.0, -1.0)
    hand = h * sign * ramp
    np.testing.assert_allclose(diff, hand, rtol=0, atol=1e-9)
    # the sign, spelled out: past the ramp, unloading +h and loading -h
    past = DELTA_TRI > SLACK_RAMP
    load_rows = past & (np.arange(DELTA_TRI.size) <= APEX)
    unload_rows = past & (np.arange(DELTA_TRI.size) > APEX)
    assert load_rows.sum() > 10 and unload_rows.sum() > 10
    np.testing.assert_allclose(diff[unload_rows], +h, rtol=0, atol=1e-9)
    np.testing.assert_allclose(diff[load_rows], -h, rtol=0, atol=1e-9)
    # the force follows the shifted elongation, F = S delta
    np.testing.assert_allclose(out["force"] - base["force"], S * hand, rtol=0, atol=1e-8)


def test_slack_adds_offset_to_displacement_only():
    sl = 0.3e-3
    r = _resistance(DELTA_TRI)
    base = _sensing(r)
    out = _sensing(r, Mods(slack=sl))
    hand = sl * np.clip(DELTA_TRI / SLACK_RAMP, 0.0, 1.0)
    np.testing.assert_allclose(out["displacement"] - base["displacement"], hand, rtol=0, atol=1e-9)
    assert np.all(
        out["displacement"][DELTA_TRI > SLACK_RAMP] - base["displacement"][DELTA_TRI > SLACK_RAMP] > 0
    )
    np.testing.assert_array_equal(out["force"], base["force"])


def test_slack_length_takes_the_slack_up_gradually():
    sl, length = 0.3e-3, 2e-3
    r = _resistance(DELTA_TRI)
    base = _sensing(r)
    out = _sensing(r, Mods(slack=sl, slack_length=length))
    # by hand: the offset grows linearly over SLACK_RAMP + length, then stays
    hand = sl * np.minimum(np.maximum(DELTA_TRI, 0.0) / (SLACK_RAMP + length), 1.0)
    np.testing.assert_allclose(out["displacement"] - base["displacement"], hand, rtol=0, atol=1e-9)
    assert hand.max() == pytest.approx(sl) and np.any((hand > 0) & (hand < 0.5 * sl))
    np.testing.assert_array_equal(out["force"], base["force"])
    # without slack the length does nothing
    np.testing.assert_array_equal(
        _sensing(r, Mods(slack_length=length))["displacement"], base["displacement"]
    )


def test_stiffening_adds_s_q_delta_squared():
    q = 40.0  # 1/m
    r = _resistance(DELTA_TRI)
    base = _sensing(r)
    out = _sensing(r, Mods(stiffening=q))
    np.testing.assert_allclose(out["force"] - base["force"], S * q * DELTA_TRI**2, rtol=1e-6, atol=1e-10)
    # 5 mm: +20 % force
    assert out["force"][APEX] / base["force"][APEX] == pytest.approx(1.0 + q * 5e-3, rel=1e-6)
    np.testing.assert_array_equal(out["displacement"], base["displacement"])


def test_relaxation_loses_the_fraction_after_a_dwell():
    frac, tau = 0.2, 1.5
    # a staircase: 4 steps of 20 rows, 1 s apart; each step dwells 19 s
    levels = np.repeat([1e-3, 2e-3, 3e-3, 4e-3], 20)
    t = np.arange(levels.size, dtype=float)
    r = _resistance(levels)
    base = _sensing(r, time=t)
    out = _sensing(r, Mods(relaxation=frac, relaxation_tau=tau), time=t)
    dwell = np.tile(np.arange(20, dtype=float), 4)
    hand = -base["force"] * frac * (1.0 - np.exp(-dwell / tau))
    np.testing.assert_allclose(out["force"] - base["force"], hand, rtol=1e-9, atol=1e-12)
    # after a long dwell (19 s >> 1.5 s) the force is down by the whole fraction
    end = dwell == 19
    np.testing.assert_allclose(out["force"][end] / base["force"][end], 1.0 - frac, rtol=1e-4)
    # right at a step nothing is lost yet
    np.testing.assert_allclose(out["force"][dwell == 0], base["force"][dwell == 0], rtol=1e-12)
    np.testing.assert_array_equal(out["displacement"], base["displacement"])


def test_temperature_offset_reads_shorter_by_the_tcr_share():
    dT = 2.0  # K
    delta = np.array([1e-3, 2e-3, 4e-3])
    r = _resistance(delta)
    base = _sensing(r)
    out = _sensing(r, Mods(temperature_offset=dT))
    # exactly the thesis inversion of R / (1 + TCR dT)
    same = _sensing(r / (1.0 + SILVER_TCR * dT))
    np.testing.assert_allclose(out["displacement"], same["displacement"], rtol=0, atol=1e-15)
    # first order: dR = -R TCR dT / (1 + TCR dT); ddelta = dR / (dR/ddelta), the slope
    # of the forward model R(delta) by central differences
    h = 1e-7
    slope = (_resistance(delta + h) - _resistance(delta - h)) / (2 * h)
    assert np.all(slope > 0)  # stretching raises R
    hand = -r * SILVER_TCR * dT / (1.0 + SILVER_TCR * dT) / slope
    diff = out["displacement"] - base["displacement"]
    assert np.all(diff < 0)
    np.testing.assert_allclose(diff, hand, rtol=0.05)


# ---------------------------------------------------------------------------
# curvature: two segments from R1, R2 and the cable (thesis-robot)
# ---------------------------------------------------------------------------

ROBOT_SAMPLE = THESIS_ROBOT.build_sample()
ROBOT_RIG = THESIS_ROBOT.build_rig()
R0_SEG = ROBOT_RIG.initial_resistance
S_SEG = ROBOT_RIG.spring_constant
L_SEG = np.asarray(ROBOT_RIG.segment_lengths)
D1 = ROBOT_RIG.sensor_offset
CURV_OPTS = {"spring_constant": S_SEG, "initial_resistances": (R0_SEG, R0_SEG)}
# elongations of the two segments [m] and the cable pull-in [m]
E1 = np.array([0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3])
E2 = np.array([0.2e-3, 0.6e-3, 1.2e-3, 1.6e-3])
CABLE = np.array([1.0e-3, 2.0e-3, 3.0e-3, 4.0e-3])


def _segment_resistance(e, length):
    ratio = length / ROBOT_SAMPLE.coil_length
    kw = ROBOT_SAMPLE.sensor_kwargs()
    kw.update(fiber_length=kw["fiber_length"] * ratio, coil_length=length, twists=kw["twists"] * ratio)
    return sensing.forward(e, R0_SEG, S_SEG, **kw)


def _curvature(mods=NONE):
    data = pd.DataFrame(
        {"cable": CABLE, "r1": _segment_resistance(E1, L_SEG[0]), "r2": _segment_resistance(E2, L_SEG[1])}
    )
    out = predict("curvature", ROBOT_SAMPLE, ROBOT_RIG, data, mods, **CURV_OPTS)
    return np.vstack([out["kappa1"], out["kappa2"]])


def _hand_kappa(a=0.0, d1=D1):
    """Eq. (4.1) with proportional cable sharing and a compressed fraction a, by hand."""
    e = np.vstack([E1, E2])
    lengths = L_SEG[:, None]
    squeeze = a * CABLE * lengths / L_SEG.sum()
    pull = (1.0 - a) * CABLE
    share = (e + squeeze) / (e + squeeze).sum(axis=0)
    cab = lengths - pull * share - squeeze
    return (lengths + e - cab) / (cab * d1)


def test_curvature_baseline_is_eq_4_1():
    np.testing.assert_allclose(_curvature(), _hand_kappa(), rtol=1e-6)
    assert np.all(_curvature() > 0)


def test_camera_offset_adds_exactly():
    c = 3.5  # 1/m
    np.testing.assert_allclose(_curvature(Mods(camera_offset=c)) - _curvature(), c, rtol=0, atol=1e-12)


def test_offset_error_scales_by_d1_over_d1_plus_e():
    e = 1e-3
    base = _curvature()
    diff = _curvature(Mods(offset_error=e)) - base
    np.testing.assert_allclose(diff, -base * e / (D1 + e), rtol=1e-9)
    assert np.all(diff < 0)  # sensor further from the cable: smaller curvature reading


def test_compression_matches_hand_formula():
    a = 0.2
    diff = _curvature(Mods(compression=a)) - _curvature()
    hand = _hand_kappa(a) - _hand_kappa(0.0)
    np.testing.assert_allclose(diff, hand, rtol=1e-5, atol=1e-9)
    # the squeezed part of the pull-in is shared by length, not by elongation: the
    # segment stretched beyond its length share (segment 1 here) bends less, the other more
    assert np.all(E1 / (E1 + E2) > L_SEG[0] / L_SEG.sum())
    assert np.all(diff[0] < 0) and np.all(diff[1] > 0)
