"""Combined resistance model of a heated, loaded TCAM: R(T, delta) (thesis ch. 2 + ch. 3).

The thesis's future work (sec. 5.2) asks for "a sensing model that includes the
effect of temperature on the resistance". This module builds it from the two
models the thesis has, with no new physics beyond the silver's temperature
coefficient:

    R(T, delta) = R0 * g(delta) * (1 + tcr dT) / (1 + rho dT)^2,    dT = T - T_ref

* g(delta) = R / R0 of chapter 3 at constant temperature: (3.1)-(3.2) give
  R = R0 (d0 / d_m)^2 for the mechanically thinned diameter d_m, and (3.3),
  (3.5)-(3.7) with F = S delta give d_m from delta. It is
  :func:`tcamlab.models.sensing.forward` with R0 = 1 (reused, not copied).
* 1 / (1 + rho dT)^2: the fiber swells radially by (2.7)-(2.8),
  d = d0 (1 + rho dT); with the silver keeping its share of the cross-section,
  the assumption behind (3.2), the silver area grows as d^2 and R falls as
  1 / d^2.
* (1 + tcr dT): the resistivity of the silver coating (rho_Ag of (3.1)),
  "a constant if the temperature is fixed" (sec. 3.2), taken linear in T
  (silver: 3.8e-3 /K, :data:`tcamlab.params.SILVER_TCR`).

Assumptions (the thesis does not say enough to derive them; README "Self-sensing"):

1. The thermal swelling and the mechanical thinning multiply: d = d0 (1 + rho dT) u(delta),
   u = d_m / d0 of chapter 3. Chapter 2 has no mechanical thinning and chapter 3
   no swelling, so nothing in the thesis couples them further.
2. u depends on delta alone, whatever caused it: chapter 3's map from a pull
   test (F = S delta) is used for a muscle that contracts by heating under a
   hanging load. The thesis never measures R during actuation (sec. 5.2), so
   this is the model's central untested assumption.
3. The silver keeps its area share as the fiber swells (3.2); the silver's own
   expansion (about 2e-5 /K, four times smaller than rho) is not modelled apart.
4. The fiber length l is constant: chapter 3 neglects its ~4 % change, chapter
   2 the axial thermal contraction; so (3.1) changes only through A and rho_Ag.
5. One lumped temperature T (that of the electro-thermal model (2.18)) for
   the whole fiber and its coating; the resistivity is linear in T.
6. delta is the extension from the unloaded length at T_ref, positive when
   longer (chapter 3's delta, R = R0 at delta = 0, T = T_ref); a hanging load
   already stretches the muscle at rest.
7. Neighbouring coils do not touch (sec. 3.2, "as observed under a
   microscope"); contact under contraction is an effect of the effect library
   (``inter-coil-contact``), not of this model.

At T = T_ref the model is chapter 3's exactly, for any delta; with tcr = 0 and
rho = 0 it is chapter 3's at any temperature.
"""

from __future__ import annotations

import numpy as np

from tcamlab.errors import ModelDomainError
from tcamlab.models import sensing, thermal

__all__ = [
    "geometric_ratio",
    "swelling_factor",
    "coating_factor",
    "resistance",
    "resistance_derivatives",
    "invert_displacement",
    "temperature_from_power",
    "DELTA_STEP",
    "effect_factor",
    "rest_temperature",
]

DELTA_STEP = 1e-6
"""Step [m] of the central difference dR/ddelta: chapter 3's forward map is an
implicit root (solved to ~1e-14 relative), so a 1 um step keeps the round-off
(~1e-8 relative) and the truncation (~h^2 g''' / 6, below 1e-9 over a 10 mm
stroke) both far below the sensor's noise."""


def geometric_ratio(delta, *, spring_constant, **geometry):
    """R / R0 of chapter 3 at constant temperature, (3.1)-(3.7): g(delta) [-].

    Parameters
    ----------
    delta : array_like
        Extension from the unloaded length [m].
    spring_constant : float
        S in F = S delta [N/m].
    **geometry
        ``fiber_diameter``, ``fiber_length``, ``coil_length``, ``coil_diameter`` [m],
        ``twists`` [turns], ``youngs_modulus`` [Pa], optional ``thread_plies``,
        ``max_volume_fraction`` (:meth:`tcamlab.params.Sample.sensor_kwargs`).

    Returns
    -------
    ndarray
        g [-], 1 at delta = 0.
    """
    return sensing.forward(delta, 1.0, spring_constant, **geometry)


def swelling_factor(temperature, reference_temperature, radial_cte):
    """Factor of the fiber's radial swelling on R, (2.8) with (3.2): 1 / (1 + rho dT)^2 [-].

    Parameters
    ----------
    temperature, reference_temperature : array_like
        T, T_ref [degC].
    radial_cte : array_like
        rho [1/K], positive when the fiber swells.
    """
    dt = np.asarray(temperature, float) - np.asarray(reference_temperature, float)
    grow = 1.0 + np.asarray(radial_cte, float) * dt
    if np.any(~(grow > 0)):
        raise ModelDomainError("self-sensing model: 1 + rho dT must stay positive")
    return 1.0 / grow**2


def coating_factor(temperature, reference_temperature, tcr):
    """Factor of the silver's resistivity on R: 1 + tcr (T - T_ref) [-].

    Parameters
    ----------
    temperature, reference_temperature : array_like
        T, T_ref [degC].
    tcr : array_like
        Temperature coefficient of resistance [1/K] (silver 3.8e-3).
    """
    dt = np.asarray(temperature, float) - np.asarray(reference_temperature, float)
    return 1.0 + np.asarray(tcr, float) * dt


def resistance(
    temperature,
    delta,
    *,
    initial_resistance,
    reference_temperature,
    tcr,
    radial_cte,
    spring_constant,
    **geometry,
):
    """Resistance of a heated, stretched or contracted TCAM, R(T, delta) [ohm].

    R = R0 g(delta) (1 + tcr dT) / (1 + rho dT)^2 (module docstring: (3.1)-(3.7),
    (2.7)-(2.8), assumptions 1-7).

    Parameters
    ----------
    temperature : array_like
        Fiber temperature T [degC].
    delta : array_like
        Extension from the unloaded length at T_ref [m] (broadcast with T).
    initial_resistance : float
        R0 at delta = 0 and T = T_ref [ohm].
    reference_temperature : float
        T_ref [degC], where R0 was taken.
    tcr : float
        Silver's temperature coefficient of resistance [1/K].
    radial_cte : float
        rho of (2.7) [1/K].
    spring_constant : float
        S of chapter 3 [N/m].
    **geometry
        As :func:`geometric_ratio`.

    Returns
    -------
    ndarray
        R [ohm].
    """
    g = geometric_ratio(delta, spring_constant=spring_constant, **geometry)
    heat = coating_factor(temperature, reference_temperature, tcr) * swelling_factor(
        temperature, reference_temperature, radial_cte
    )
    return np.asarray(initial_resistance, float) * g * heat


def resistance_derivatives(
    temperature,
    delta,
    *,
    initial_resistance,
    reference_temperature,
    tcr,
    radial_cte,
    spring_constant,
    **geometry,
):
    """Partial derivatives of :func:`resistance`: (dR/dT [ohm/K], dR/ddelta [ohm/m]).

    dR/dT is analytic: R0 g [tcr / (1 + rho dT)^2 - 2 rho (1 + tcr dT) / (1 + rho dT)^3].
    dR/ddelta is a central difference of g with step :data:`DELTA_STEP`, times the
    thermal factors (g is an implicit root of chapter 3's equations).

    Parameters
    ----------
    As :func:`resistance`.

    Returns
    -------
    tuple of ndarray
        dR/dT [ohm/K], dR/ddelta [ohm/m], broadcast over T and delta.
    """
    t = np.asarray(temperature, float)
    d = np.asarray(delta, float)
    t, d = np.broadcast_arrays(t, d)
    r0 = np.asarray(initial_resistance, float)
    dt = t - reference_temperature
    grow = 1.0 + radial_cte * dt
    coat = 1.0 + tcr * dt
    g = geometric_ratio(d, spring_constant=spring_constant, **geometry)
    h = DELTA_STEP
    g_plus = geometric_ratio(d + h, spring_constant=spring_constant, **geometry)
    g_minus = geometric_ratio(d - h, spring_constant=spring_constant, **geometry)
    dg = (g_plus - g_minus) / (2.0 * h)
    d_dt = r0 * g * (tcr / grow**2 - 2.0 * radial_cte * coat / grow**3)
    d_ddelta = r0 * dg * coat / grow**2
    return d_dt, d_ddelta


def invert_displacement(
    resistance_value,
    temperature,
    *,
    initial_resistance,
    reference_temperature,
    tcr,
    radial_cte,
    spring_constant,
    **geometry,
):
    """delta from R at a known T: chapter 3's inversion of the thermally corrected R [m].

    R / [(1 + tcr dT) / (1 + rho dT)^2] is the resistance the muscle would have at
    T_ref, which :func:`tcamlab.models.sensing.invert` maps to delta ((3.1)-(3.7)).

    Parameters
    ----------
    resistance_value : array_like
        Measured R [ohm].
    temperature : array_like
        T [degC] (measured, or from the electro-thermal model).
    initial_resistance, reference_temperature, tcr, radial_cte, spring_constant, **geometry :
        As :func:`resistance`.

    Returns
    -------
    ndarray
        delta [m], extension from the unloaded length.

    Raises
    ------
    ModelDomainError
        Where chapter 3's equation has no physical root (see :func:`tcamlab.models.sensing.invert`).
    """
    heat = coating_factor(temperature, reference_temperature, tcr) * swelling_factor(
        temperature, reference_temperature, radial_cte
    )
    r_ref = np.asarray(resistance_value, float) / heat
    delta, _ = sensing.invert(r_ref, initial_resistance, spring_constant, **geometry)
    return delta


def temperature_from_power(time, power, *, thermal_mass, heat_loss, ambient, initial=None):
    """Temperature from the measured electrical power, eq. (2.18) with P = V I [degC].

    C_th dT/dt = P(t) - lambda (T - T_a), P held between samples (zero-order hold),
    solved exactly per interval by :func:`tcamlab.models.thermal.temperature`
    (which takes V^2 / R: here sqrt(P) through a 1 ohm resistor). Driving it by
    the measured power, not V^2 / R with a constant R, is what lets R vary with
    T and delta (the thesis holds R constant in (2.18)).

    Parameters
    ----------
    time : array_like, shape (n,)
        Strictly increasing [s].
    power : array_like, shape (n,)
        V I [W], >= 0.
    thermal_mass : float
        C_th [J/K].
    heat_loss : float
        lambda [W/K].
    ambient : float
        T_a [degC].
    initial : float, optional
        T at ``time[0]`` [degC]; default ``ambient``.

    Returns
    -------
    ndarray
        T [degC].
    """
    p = np.asarray(power, float)
    if np.any(p < 0):
        raise ModelDomainError(
            "self-sensing model: negative electrical power", hint="check the sign of the current column"
        )
    return thermal.temperature(time, np.sqrt(p), 1.0, thermal_mass, heat_loss, ambient, initial)


def effect_factor(time, contraction, mods=None):
    """Factor of the library's self-sensing effects on R [-].

    (1 + r0_drift t) (1 - contact_slope max(0, c - contact_onset)), c the contraction
    from rest [m] (positive when shorter), t [s] from the first row.
    """
    if mods is None:
        return np.ones(np.broadcast_shapes(np.shape(time), np.shape(contraction)))
    t = np.asarray(time, float)
    c = np.asarray(contraction, float)
    contact = 1.0 - mods.contact_slope * np.maximum(0.0, c - mods.contact_onset)
    if np.any(contact <= 0):
        raise ModelDomainError("self-sensing model: inter-coil contact would short the whole muscle")
    return (1.0 + mods.r0_drift * t) * contact


def rest_temperature(power, heat_loss, ambient):
    """Steady temperature under a held probe power, (2.18) with dT/dt = 0 [degC]."""
    return ambient + power / heat_loss
