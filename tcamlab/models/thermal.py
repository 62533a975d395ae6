"""Electro-thermal model of a conductive TCA, eq. (2.18).

C_th dT/dt = V(t)^2 / R - lambda (T - T_a).

:func:`heating_rate` is the one implementation of (2.18): the dynamic model
compiles it into its numba kernel and calls it in its scipy reference path.
The functions below are the closed-form consequences of the same equation
(steady state, time constant, exact response to a held voltage).

The voltage is taken as held between samples (zero-order hold), as an
Arduino-driven motor driver applies it. For a held voltage the equation is
linear with constant coefficients, so each sample interval has an exact
solution and the response needs no ODE solver:

T(t_k + h) = T_inf + (T(t_k) - T_inf) exp(-h / tau),  T_inf = T_a + V_k^2 / (R lambda),
tau = C_th / lambda.
"""

from __future__ import annotations

import numpy as np

from tcamlab.errors import ModelDomainError

__all__ = ["heating_rate", "temperature", "steady_state_temperature", "time_constant"]


def heating_rate(delta_T, voltage, resistance, thermal_mass, heat_loss, resistance_tc=0.0, heat_loss_tc=0.0):
    """Rate of temperature change dT/dt of eq. (2.18), plain arithmetic.

    C_th dT/dt = V^2 / (R (1 + beta dT)) - lambda (1 + gamma dT) dT.
    beta and gamma are zero in the thesis; the effect library uses them for
    a temperature-dependent resistance and heat loss. Floats or float
    ndarrays (the numba kernel compiles this same function).

    Parameters
    ----------
    delta_T : float or ndarray
        T - T_a [K].
    voltage : float or ndarray
        V [V].
    resistance : float or ndarray
        R at ambient [ohm].
    thermal_mass : float or ndarray
        C_th [J/K].
    heat_loss : float or ndarray
        lambda [W/K].
    resistance_tc : float or ndarray
        beta [1/K].
    heat_loss_tc : float or ndarray
        gamma [1/K].

    Returns
    -------
    float or ndarray
        dT/dt [K/s].
    """
    power = voltage * voltage / (resistance * (1.0 + resistance_tc * delta_T))
    return (power - heat_loss * (1.0 + heat_loss_tc * delta_T) * delta_T) / thermal_mass


def steady_state_temperature(voltage, resistance, heat_loss, ambient):
    """Temperature reached under a held voltage, (2.18) with dT/dt = 0.

    Parameters
    ----------
    voltage : array_like
        V [V].
    resistance : array_like
        R [ohm].
    heat_loss : array_like
        lambda [W/K].
    ambient : array_like
        T_a [degC].

    Returns
    -------
    ndarray
        T_inf = T_a + V^2 / (R lambda) [degC].
    """
    v = np.asarray(voltage, float)
    return np.asarray(ambient, float) + v * v / (np.asarray(resistance, float) * np.asarray(heat_loss, float))


def time_constant(thermal_mass, heat_loss):
    """Thermal time constant tau = C_th / lambda of (2.18) [s].

    Parameters
    ----------
    thermal_mass : array_like
        C_th [J/K].
    heat_loss : array_like
        lambda [W/K].

    Returns
    -------
    ndarray
        tau [s].
    """
    return np.asarray(thermal_mass, float) / np.asarray(heat_loss, float)


def temperature(time, voltage, resistance, thermal_mass, heat_loss, ambient, initial=None):
    """Temperature response to a sampled voltage profile, eq. (2.18), exact.

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times, strictly increasing [s].
    voltage : array_like, shape (n,)
        Voltage applied from each sample to the next (zero-order hold) [V].
    resistance : float
        R [ohm].
    thermal_mass : float
        C_th [J/K].
    heat_loss : float
        lambda [W/K].
    ambient : float
        T_a [degC].
    initial : float, optional
        Temperature at ``time[0]`` [degC]; default ``ambient``.

    Returns
    -------
    ndarray, shape (n,)
        Actuator temperature at the sample times [degC].

    Raises
    ------
    ModelDomainError
        For non-increasing time or non-positive R, C_th or lambda.
    """
    t = np.asarray(time, float)
    v = np.broadcast_to(np.asarray(voltage, float), t.shape)
    if t.ndim != 1 or t.size == 0:
        raise ModelDomainError("thermal model: time must be a non-empty 1-D array")
    if np.any(np.diff(t) <= 0):
        raise ModelDomainError("thermal model: time must be strictly increasing")
    for name, value in (("resistance", resistance), ("thermal_mass", thermal_mass), ("heat_loss", heat_loss)):
        if not float(value) > 0:
            raise ModelDomainError(f"thermal model: {name} = {value} must be positive")
    t_inf = steady_state_temperature(v[:-1], resistance, heat_loss, ambient)
    decay = np.exp(-np.diff(t) / time_constant(thermal_mass, heat_loss))
    # Linear recursion T_{k+1} = decay_k T_k + (1 - decay_k) T_inf_k, solved as a
    # scan on the deviation from ambient so the sum never loses precision.
    out = np.empty_like(t)
    out[0] = ambient if initial is None else initial
    prev = out[0]
    forcing = (1.0 - decay) * t_inf
    # A Python-level loop over samples would be slow for 10^7 rows; use the
    # closed form of a first-order recursion in log space where it is safe.
    log_a = np.concatenate(([0.0], np.cumsum(np.log(decay))))
    if log_a[-1] > -600.0:
        weights = np.exp(-log_a[1:])
        out[1:] = np.exp(log_a[1:]) * (prev + np.cumsum(forcing * weights))
        return out
    return _scan(decay, forcing, float(prev), out)


def _scan(decay, forcing, first, out):
    """Sequential scan for long records where the closed form would overflow."""
    from scipy.signal import lfilter

    # Piecewise-constant decay is the rule (uniform sampling): filter in blocks
    # of equal decay; fall back to a loop for irregular sampling.
    if np.allclose(decay, decay[0], rtol=1e-12, atol=0.0):
        zi = np.array([decay[0] * first])
        y, _ = lfilter([1.0], [1.0, -decay[0]], forcing, zi=zi)
        out[1:] = y
        return out
    value = first
    for k in range(decay.size):
        value = decay[k] * value + forcing[k]
        out[k + 1] = value
    return out
