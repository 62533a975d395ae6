"""Model predictions for a whole rig run, with optional unmodelled-effect terms.

One function per rig kind maps a run's *input* columns (SI, internal names of
:mod:`tcamlab.io`) to predictions of its *measured* columns:

==========  ============================  ==============================
kind        inputs                        predicted
==========  ============================  ==============================
static      temperature (time)            displacement
dynamic     time, voltage                 displacement (temperature)
sensing     resistance (time)             displacement, force
curvature   cable, r1, r2                 kappa1, kappa2
==========  ============================  ==============================

:class:`Mods` carries the physical terms of the effect library
(:mod:`tcamlab.effects`); every field at its default gives the thesis model
back, so each effect is a nested augmentation of it. The virtual rig uses
the same functions to make data, and the diagnosis to fit candidates: one
implementation of each effect.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from tcamlab.errors import ModelDomainError
from tcamlab.models import curvature as _curv
from tcamlab.models import dynamic as _dyn
from tcamlab.models import sensing as _sens
from tcamlab.models import static as _static
from tcamlab.params import Rig, Sample

__all__ = ["Mods", "INPUTS", "OUTPUTS", "predict", "SILVER_TCR"]

INPUTS = {
    "static": ("temperature",),
    "dynamic": ("time", "voltage"),
    "sensing": ("resistance",),
    "curvature": ("cable", "r1", "r2"),
}
OUTPUTS = {
    "static": ("displacement",),
    "dynamic": ("displacement",),
    "sensing": ("displacement", "force"),
    "curvature": ("kappa1", "kappa2"),
}

SILVER_TCR = 3.8e-3
"""Temperature coefficient of resistance of silver [1/K] (CRC Handbook)."""

SLACK_RAMP = 0.2e-3
"""Sensor elongation over which a slack offset is phased in [m]: below it the
inverted elongation is within noise of zero and the slack state is unknown."""


@dataclass(frozen=True)
class Mods:
    """Physical terms beyond the thesis model (all zero: the thesis model).

    Attributes
    ----------
    shear_slope_extra : float
        Added to the sample's G_t slope k of (2.13) [Pa/K].
    youngs_modulus_slope : float
        c in E' = E (1 - c dT) in the E terms of f11 [1/K].
    glass_gain : float
        Extra radial expansion above the glass transition, as a multiple of
        rho: strain = rho (dT + g max(0, T - T_g)) [-].
    glass_temperature : float
        T_g [degC] (about 45 degC for nylon 6,6).
    lag_tau : float
        Time constant of the actuator behind the oven thermometer [s] (in
        samples when a static log has no time column).
    drift : float
        Displacement sensor drift [m/s] (per sample without a time column).
    resistance_tc : float
        beta in R(T) = R (1 + beta dT) of the heating circuit [1/K].
    heat_loss_tc : float
        gamma in lambda(T) = lambda (1 + gamma dT) [1/K] (convection).
    delay : float
        Pure delay between command and response [s].
    slack : float
        Displacement taken up before the sensor carries load [m].
    hysteresis : float
        Half-width of the loading/unloading loop in displacement [m]
        (positive: unloading reads longer than loading).
    relaxation : float
        Fraction of force lost during a dwell [-].
    relaxation_tau : float
        Time constant of that loss [s].
    temperature_offset : float
        Sensor temperature above the one R0 was taken at [K]; acts on R
        through silver's TCR.
    stiffening : float
        q in F = S delta (1 + q delta) [1/m].
    compression : float
        Fraction of the cable pull-in taken up by axial compression of the
        body instead of bending [-].
    camera_offset : float
        Curvature offset of a misplaced camera [1/m].
    offset_error : float
        Error of the sensor-to-cable distance d1 [m].
    """

    shear_slope_extra: float = 0.0
    youngs_modulus_slope: float = 0.0
    glass_gain: float = 0.0
    glass_temperature: float = 45.0
    lag_tau: float = 0.0
    drift: float = 0.0
    resistance_tc: float = 0.0
    heat_loss_tc: float = 0.0
    delay: float = 0.0
    slack: float = 0.0
    hysteresis: float = 0.0
    relaxation: float = 0.0
    relaxation_tau: float = 1.5
    temperature_offset: float = 0.0
    stiffening: float = 0.0
    compression: float = 0.0
    camera_offset: float = 0.0
    offset_error: float = 0.0

    def replace(self, **changes) -> Mods:
        return dataclasses.replace(self, **changes)


NO_MODS = Mods()


def _clock(data: pd.DataFrame) -> np.ndarray:
    """Time from the first row [s], or the sample index where there is no time."""
    if "time" in data:
        t = data["time"].to_numpy(float)
        return t - t[0]
    return np.arange(len(data), dtype=float)


def _lagged(temp: np.ndarray, clock: np.ndarray, tau: float) -> np.ndarray:
    """First-order lag of the actuator behind a stepwise oven temperature."""
    if tau <= 0:
        return temp
    out = np.empty_like(temp)
    out[0] = temp[0]
    decay = np.exp(-np.diff(clock) / tau)
    for k in range(1, temp.size):
        out[k] = temp[k] + (out[k - 1] - temp[k]) * decay[k - 1]
    return out


def predict_static(
    sample: Sample, rig: Rig, data: pd.DataFrame, mods: Mods = NO_MODS, *, constant_g: bool = False
) -> dict[str, np.ndarray]:
    """Static oven test: displacement from the first row against temperature.

    Parameters
    ----------
    sample, rig :
        Sample and rig (load, ambient = reference temperature) [SI].
    data : DataFrame
        ``temperature`` [degC], optional ``time`` [s].
    mods : Mods
        Effect terms (shear_slope_extra, youngs_modulus_slope, glass_*, lag_tau, drift).
    constant_g : bool
        Use the constant-G model of (2.12) (slope 0) instead of the sample's G(T).

    Returns
    -------
    dict
        ``displacement`` [m], zero at the first row.
    """
    clock = _clock(data)
    temp = _lagged(data["temperature"].to_numpy(float), clock, mods.lag_tau)
    dT = temp - rig.ambient
    kw = sample.model_kwargs()
    kw["shear_modulus_slope"] = (0.0 if constant_g else kw["shear_modulus_slope"]) + mods.shear_slope_extra
    if mods.glass_gain:
        above = np.maximum(0.0, temp - mods.glass_temperature)
        strain = dT + mods.glass_gain * above
        safe = np.where(np.abs(dT) > 1e-12, dT, 1.0)
        kw["radial_cte"] = np.where(np.abs(dT) > 1e-12, sample.radial_cte * strain / safe, sample.radial_cte)
    delta = _static.displacement(dT, rig.force, youngs_modulus_slope=mods.youngs_modulus_slope, **kw)
    disp = delta - delta[0] + mods.drift * clock
    return {"displacement": disp}


def predict_dynamic(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    constant_g: bool = False,
    method: str = _dyn.METHOD,
) -> dict[str, np.ndarray]:
    """Voltage-step test: displacement (and temperature) against time.

    Parameters
    ----------
    data : DataFrame
        ``time`` [s], ``voltage`` [V].
    mods : Mods
        shear_slope_extra, resistance_tc, heat_loss_tc, delay.

    Returns
    -------
    dict
        ``displacement`` [m] (zero at the first row), ``temperature`` [degC].
    """
    t = data["time"].to_numpy(float)
    v = data["voltage"].to_numpy(float)
    kw = sample.model_kwargs()
    kw["shear_modulus_slope"] = (0.0 if constant_g else kw["shear_modulus_slope"]) + mods.shear_slope_extra
    res = _dyn.response(
        t,
        v,
        load=rig.load,
        damping=rig.damping,
        thermal_mass=rig.thermal_mass,
        heat_loss=rig.heat_loss,
        resistance=rig.resistance,
        ambient=rig.ambient,
        resistance_tc=mods.resistance_tc,
        heat_loss_tc=mods.heat_loss_tc,
        method=method,
        **kw,
    )
    disp, temp = res.displacement, res.temperature
    if mods.delay:
        # Shift the output, not the held input: continuous in the delay, so fits work.
        disp = np.interp(t - mods.delay, t, disp, left=0.0)
        temp = np.interp(t - mods.delay, t, temp, left=temp[0])
    return {"displacement": disp, "temperature": temp}


def _unloading_mask(resistance: np.ndarray) -> np.ndarray:
    """Rows after the (smoothed) resistance peak: the unloading branch."""
    n = resistance.size
    k = max(1, min(9, n // 10))
    smooth = np.convolve(resistance, np.ones(k) / k, mode="same")
    peak = int(np.argmax(smooth))
    mask = np.zeros(n, dtype=bool)
    if n - peak > 2 and smooth[peak] - smooth[-1] > 0.25 * (smooth[peak] - smooth.min()):
        mask[peak + 1 :] = True
    return mask


def _time_in_dwell(resistance: np.ndarray, clock: np.ndarray) -> np.ndarray:
    """Time since the last step of a stepped pull test, from jumps in resistance."""
    jumps = np.abs(np.diff(resistance))
    scale = np.median(jumps) if jumps.size else 0.0
    thresh = max(8.0 * scale, 1e-12)
    step_rows = np.concatenate(([0], np.flatnonzero(jumps > thresh) + 1))
    last = np.zeros(resistance.size, dtype=int)
    last[step_rows] = step_rows
    last = np.maximum.accumulate(last)
    return clock - clock[last]


def predict_sensing(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    spring_constant: float,
    initial_resistance: float,
) -> dict[str, np.ndarray]:
    """Pull test: displacement and force from resistance, (3.1)-(3.7), F = S delta.

    Parameters
    ----------
    data : DataFrame
        ``resistance`` [ohm], optional ``time`` [s].
    spring_constant : float
        S [N/m].
    initial_resistance : float
        R0 [ohm].
    mods : Mods
        slack, hysteresis, relaxation(_tau), temperature_offset, stiffening.

    Returns
    -------
    dict
        ``displacement`` [m], ``force`` [N].
    """
    r = data["resistance"].to_numpy(float)
    if mods.temperature_offset:
        r = r / (1.0 + SILVER_TCR * mods.temperature_offset)
    kw = sample.sensor_kwargs()
    delta, _ = _sens.invert(r, initial_resistance, spring_constant, **kw)
    if mods.hysteresis:
        unloading = _unloading_mask(data["resistance"].to_numpy(float))
        delta = delta + mods.hysteresis * np.where(unloading, 1.0, -1.0) * np.clip(
            delta / SLACK_RAMP, 0.0, 1.0
        )
    force = spring_constant * delta * (1.0 + mods.stiffening * delta)
    if mods.relaxation:
        dwell = _time_in_dwell(data["resistance"].to_numpy(float), _clock(data))
        force = force * (1.0 - mods.relaxation * (1.0 - np.exp(-dwell / mods.relaxation_tau)))
    disp = delta + mods.slack * np.clip(delta / SLACK_RAMP, 0.0, 1.0)
    return {"displacement": disp, "force": force}


def predict_curvature(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    spring_constant: float,
    initial_resistances: tuple[float, float],
) -> dict[str, np.ndarray]:
    """Camera test: segment curvatures from R1, R2 and the cable, (4.1).

    Parameters
    ----------
    data : DataFrame
        ``cable`` [m], ``r1``, ``r2`` [ohm].
    spring_constant : float
        S of one segment [N/m].
    initial_resistances : (float, float)
        R0 of each segment [ohm].
    mods : Mods
        compression, camera_offset, offset_error.

    Returns
    -------
    dict
        ``kappa1``, ``kappa2`` [1/m].
    """
    kw = sample.sensor_kwargs()
    lengths = np.asarray(rig.segment_lengths, float)
    res = np.vstack([data["r1"].to_numpy(float), data["r2"].to_numpy(float)])
    cable = data["cable"].to_numpy(float)
    _, elong = _curv.curvatures(
        res, cable, initial_resistances, spring_constant, rig.sensor_offset, lengths, **kw
    )
    # Axial compression: a fraction a of the pull-in shortens the whole body
    # (cable and sensor lines alike) instead of bending it. The sensor length
    # from R already includes it; the bending share of each segment is its
    # sensor elongation plus the squeeze.
    squeeze = mods.compression * cable * lengths[:, None] / lengths.sum()
    bend = _curv.cable_lengths(elong + squeeze, (1.0 - mods.compression) * cable, lengths)
    cab = bend - squeeze
    d1 = rig.sensor_offset + mods.offset_error
    if d1 <= 0:
        raise ModelDomainError("curvature model: sensor offset d1 must stay positive")
    kappa = _curv.segment_curvature(lengths[:, None] + elong, cab, d1)
    kappa = kappa + mods.camera_offset
    return {"kappa1": kappa[0], "kappa2": kappa[1]}


def predict(
    kind: str, sample: Sample, rig: Rig, data: pd.DataFrame, mods: Mods = NO_MODS, **options
) -> dict[str, np.ndarray]:
    """Dispatch to the prediction of one rig kind (see the module table)."""
    fn = {
        "static": predict_static,
        "dynamic": predict_dynamic,
        "sensing": predict_sensing,
        "curvature": predict_curvature,
    }.get(kind)
    if fn is None:
        raise ValueError(f"unknown kind {kind!r}")
    return fn(sample, rig, data, mods, **options)
