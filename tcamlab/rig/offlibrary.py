"""Effects in functional forms the diagnosis's library does not have (the rig's side only).

The benchmark's out-of-library family makes each physical effect in a form
that differs from its candidate in :mod:`tcamlab.effects`, so a diagnosis
that only recognises its own terms cannot score well by construction. The
diagnosis must never import this module (``tests/test_rig_offlibrary.py``
parses its imports).

Each :class:`OffLibraryForm` has one amplitude ``a`` (zero: the thesis model)
and maps a run's exact inputs and the thesis model's exact outputs to the
logged inputs and the true outputs. Its strength is found like a library
effect's (:mod:`tcamlab.rig.strength`): the RMS, over the first run, of the
true outputs minus the thesis model's prediction from the logged inputs, in
noise sds of the kind's strength quantities.

=======================  ==========================  ==============================================
form                     nearest library effect      functional form (library form in brackets)
=======================  ==========================  ==============================================
static
quadratic-shear-modulus  shear-modulus-temperature   G = G_t - k dT - a dT^2 in the torque (2.13)
                                                     and the coil (f11, f12) [G_t - k_c dT, coil]
sigmoid-youngs-modulus   youngs-modulus-temperature  E' = E (1 - a / (1 + exp(-(T - 75 degC) / 8 K)))
                                                     [E (1 - c dT)]
smooth-glass-transition  glass-transition            strain = rho (dT + a w softplus((T - 55) / w)),
                                                     w = 12 K, a broad transition [kink at 45 degC]
radiative-thermal-lag    oven-thermal-lag            first-order lag with tau(T) = a (298 K / T)^3
                                                     [constant tau]
exponential-drift        displacement-drift          a (1 - exp(-3 t / t_end)) [a t]
dynamic
sensor-lag               response-delay              first-order low-pass of the displacement,
                                                     tau = a [pure delay]
sensing
play-hysteresis          hysteresis                  Prandtl-Ishlinskii sum of 10 play operators,
                                                     radii 0.8..8 mm, loop half-width a
                                                     [+-a switched at reversal]
smooth-slack             initial-slack               a (1 - exp(-delta / 5 mm)) [a, ramped over 0.2 mm]
solid-relaxation         stress-relaxation           standard linear solid: every step's increment
                                                     relaxes, F = S (delta - a lag_3s(delta))
                                                     [F (1 - a (1 - exp(-t_dwell / 1.5 s)))]
drifting-ambient         ambient-temperature         sensor warming linearly, a t / t_end [constant]
cubic-stiffening         stiffening-spring           F = S delta (1 + a delta^2) [S delta (1 + q delta)]
curvature
growing-compression      axial-compression           compressed share a cable / cable_max [constant]
segment-camera-offsets   camera-placement            offsets a (tip) and 0.4 a (base) [a on both]
tilted-sensor            sensor-offset-error         d1 error a on the tip, a / 3 on the base
                                                     [a on both]
=======================  ==========================  ==============================================

The dynamic thermal effects (R(T), convection, G(T) during the pulse) have no
alternative form yet: the dynamic model's kernel takes them as constants.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError, TcamlabError
from tcamlab.kinds import get_kind, predict
from tcamlab.params import SILVER_TCR
from tcamlab.signals import clock, first_order_lag

__all__ = ["OffLibraryForm", "FORMS", "forms_for", "get_form", "apply_form", "form_gap", "scale_form"]


@dataclass(frozen=True)
class Context:
    """One run as a form sees it: exact inputs, the thesis model's exact outputs and options."""

    kind: str
    sample: Any
    rig: Any
    inputs: pd.DataFrame
    outputs: Mapping[str, np.ndarray]
    opts: Mapping[str, Any]


@dataclass(frozen=True)
class OffLibraryForm:
    """A physical effect in a form outside the effect library.

    Attributes
    ----------
    name : str
        Identifier (``offlibrary={name: strength}`` of :func:`tcamlab.rig.simulate`).
    kind : str
        Rig kind.
    nearest : str
        The library effect that stands for the same physics (a right diagnosis names it).
    form : str
        The functional form, in words.
    scale : float
        Typical amplitude [SI of ``a``], where the strength search starts.
    upper : float
        Largest amplitude allowed.
    apply : callable
        ``apply(a, ctx) -> (logged inputs, true outputs)``.
    """

    name: str
    kind: str
    nearest: str
    form: str
    scale: float
    upper: float
    apply: Callable[[float, Context], tuple[pd.DataFrame, dict]]


# --- static -------------------------------------------------------------------------------


def _static_with(a_mods: Mods, ctx: Context, temperature=None):
    data = ctx.inputs if temperature is None else ctx.inputs.assign(temperature=temperature)
    return ctx.inputs, dict(predict("static", ctx.sample, ctx.rig, data, a_mods, **ctx.opts))


def _dT(ctx: Context) -> np.ndarray:
    return ctx.inputs["temperature"].to_numpy(float) - ctx.rig.ambient


def _quadratic_shear(a, ctx):
    # A physical G(T) acts on the torque and the coil alike: (2.13)'s slope becomes
    # k + a dT and the coil's k_c = a dT, row by row, so both see G_t - k dT - a dT^2.
    # (An earlier version of this form acted on the torque only and levelled off, - k dT + a dT^2:
    # the library's coil softening could follow it only with a coil that stiffens as it
    # warms, k_c < 0, which the library no longer fits.)
    dT = _dT(ctx)
    return _static_with(Mods(shear_slope_extra=a * dT, coil_shear_slope=a * dT), ctx)


def _sigmoid_youngs(a, ctx):
    temp = ctx.inputs["temperature"].to_numpy(float)
    drop = a / (1.0 + np.exp(-(temp - 75.0) / 8.0))
    dT = _dT(ctx)
    safe = np.where(np.abs(dT) > 1e-9, dT, 1.0)
    # E' = E (1 - c dT) with c = drop / dT row by row gives E (1 - drop).
    return _static_with(Mods(youngs_modulus_slope=np.where(np.abs(dT) > 1e-9, drop / safe, 0.0)), ctx)


def _softplus(x):
    return np.logaddexp(0.0, x)


def _smooth_glass(a, ctx):
    w, tg = 12.0, 55.0
    temp = ctx.inputs["temperature"].to_numpy(float)
    extra = w * (_softplus((temp - tg) / w) - _softplus((ctx.rig.ambient - tg) / w))
    # The library's kink max(0, T - T_g) equals `extra` for T_g = T - extra (row by row).
    return _static_with(Mods(glass_gain=a, glass_temperature=temp - extra), ctx)


def variable_lag(x: np.ndarray, t: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """First-order lag of a stepwise signal with a time constant per sample [s] (x held between samples)."""
    out = np.empty_like(x, dtype=float)
    out[0] = x[0]
    for k in range(1, x.size):
        out[k] = x[k] + (out[k - 1] - x[k]) * math.exp(-(t[k] - t[k - 1]) / tau[k])
    return out


def _radiative_lag(a, ctx):
    if a <= 0:
        return _static_with(NO_MODS, ctx)
    temp = ctx.inputs["temperature"].to_numpy(float)
    # Radiative coupling to the oven walls grows as T^3, so the lag shortens as it warms.
    tau = a * (298.15 / (temp + 273.15)) ** 3
    return _static_with(NO_MODS, ctx, temperature=variable_lag(temp, clock(ctx.inputs), tau))


def _exponential_drift(a, ctx):
    t = clock(ctx.inputs)
    out = dict(ctx.outputs)
    out["displacement"] = out["displacement"] + a * (1.0 - np.exp(-3.0 * t / t[-1]))
    return ctx.inputs, out


# --- dynamic ------------------------------------------------------------------------------


def _sensor_lag(a, ctx):
    out = dict(ctx.outputs)
    out["displacement"] = first_order_lag(out["displacement"], clock(ctx.inputs), a)
    return ctx.inputs, out


# --- sensing ------------------------------------------------------------------------------

PLAY_RADII = 8e-3 * np.arange(1, 11) / 10.0
"""Radii of the Prandtl-Ishlinskii play operators [m]."""


def play(x: np.ndarray, r: float) -> np.ndarray:
    """Play (backlash) operator of radius ``r``: the output follows ``x`` only once it is ``r`` away."""
    y = np.empty_like(x, dtype=float)
    prev = x[0]
    for k, v in enumerate(x):
        prev = max(v - r, min(v + r, prev))
        y[k] = prev
    return y


def _sensing_out(ctx: Context, delta: np.ndarray, force_factor=1.0) -> dict:
    s = ctx.opts["spring_constant"]
    return {"displacement": delta, "force": s * delta * force_factor}


def _play_hysteresis(a, ctx):
    delta = np.asarray(ctx.outputs["displacement"], float)
    loop = sum(play(delta, r) - delta for r in PLAY_RADII) / len(PLAY_RADII)
    return ctx.inputs, _sensing_out(ctx, delta + a * loop / PLAY_RADII.mean())


def _smooth_slack(a, ctx):
    delta = np.asarray(ctx.outputs["displacement"], float)
    out = _sensing_out(ctx, delta)
    out["displacement"] = delta + a * (1.0 - np.exp(-np.maximum(delta, 0.0) / 5e-3))
    return ctx.inputs, out


SOLID_TAU_S = 3.0
"""Relaxation time of the standard linear solid [s]."""


def _solid_relaxation(a, ctx):
    # Boltzmann superposition: sum_j d_delta_j (1 - a (1 - exp(-(t - t_j) / tau))) = delta - a lag(delta).
    delta = np.asarray(ctx.outputs["displacement"], float)
    lagged = first_order_lag(delta, clock(ctx.inputs), SOLID_TAU_S)
    out = _sensing_out(ctx, delta)
    out["force"] = ctx.opts["spring_constant"] * (delta - a * lagged)
    return ctx.inputs, out


def _drifting_ambient(a, ctx):
    t = clock(ctx.inputs)
    logged = ctx.inputs.assign(
        resistance=ctx.inputs["resistance"].to_numpy(float) * (1 + SILVER_TCR * a * t / t[-1])
    )
    return logged, dict(ctx.outputs)


def _cubic_stiffening(a, ctx):
    delta = np.asarray(ctx.outputs["displacement"], float)
    return ctx.inputs, _sensing_out(ctx, delta, 1.0 + a * delta**2)


# --- curvature ----------------------------------------------------------------------------


def _curvature(ctx: Context, mods: Mods) -> dict:
    return dict(predict("curvature", ctx.sample, ctx.rig, ctx.inputs, mods, **ctx.opts))


def _growing_compression(a, ctx):
    cable = ctx.inputs["cable"].to_numpy(float)
    share = a * cable / max(float(np.max(np.abs(cable))), 1e-12)
    return ctx.inputs, _curvature(ctx, Mods(compression=share))


def _segment_camera(a, ctx):
    out = dict(ctx.outputs)
    out["kappa1"] = np.asarray(out["kappa1"], float) + a
    out["kappa2"] = np.asarray(out["kappa2"], float) + 0.4 * a
    return ctx.inputs, out


def _tilted_sensor(a, ctx):
    tip = _curvature(ctx, Mods(offset_error=a))
    base = _curvature(ctx, Mods(offset_error=a / 3.0))
    return ctx.inputs, {"kappa1": tip["kappa1"], "kappa2": base["kappa2"]}


def _f(name, kind, nearest, form, scale, upper, fn):
    return OffLibraryForm(name, kind, nearest, form, scale, upper, fn)


FORMS: dict[tuple[str, str], OffLibraryForm] = {
    (f.kind, f.name): f
    for f in (
        _f(
            "quadratic-shear-modulus",
            "static",
            "shear-modulus-temperature",
            "G = G_t - k dT - a dT^2 in the torque and the coil (softening that speeds up), a [Pa/K^2]",
            50.0,
            1e5,
            _quadratic_shear,
        ),
        _f(
            "sigmoid-youngs-modulus",
            "static",
            "youngs-modulus-temperature",
            "E' = E (1 - a / (1 + exp(-(T - 75 degC) / 8 K))), a DMA-like step, a [-]",
            0.05,
            0.6,
            _sigmoid_youngs,
        ),
        _f(
            "smooth-glass-transition",
            "static",
            "glass-transition",
            "radial strain rho (dT + a w softplus((T - 55 degC) / w)), w = 12 K, a [-]",
            0.5,
            20.0,
            _smooth_glass,
        ),
        _f(
            "radiative-thermal-lag",
            "static",
            "oven-thermal-lag",
            "first-order lag with tau(T) = a (298 K / T)^3, a [s]",
            60.0,
            3600.0,
            _radiative_lag,
        ),
        _f(
            "exponential-drift",
            "static",
            "displacement-drift",
            "warm-up drift a (1 - exp(-3 t / t_end)), a [m]",
            1e-5,
            5e-3,
            _exponential_drift,
        ),
        _f(
            "sensor-lag",
            "dynamic",
            "response-delay",
            "first-order low-pass of the displacement, tau = a [s]",
            0.05,
            2.0,
            _sensor_lag,
        ),
        _f(
            "play-hysteresis",
            "sensing",
            "hysteresis",
            "Prandtl-Ishlinskii sum of 10 play operators (radii 0.8..8 mm), loop half-width a [m]",
            0.3e-3,
            5e-3,
            _play_hysteresis,
        ),
        _f(
            "smooth-slack",
            "sensing",
            "initial-slack",
            "slack taken up gradually, a (1 - exp(-delta / 5 mm)), a [m]",
            0.5e-3,
            10e-3,
            _smooth_slack,
        ),
        _f(
            "solid-relaxation",
            "sensing",
            "stress-relaxation",
            "standard linear solid: F = S (delta - a lag(delta)), tau = 3 s, a [-]",
            0.02,
            0.5,
            _solid_relaxation,
        ),
        _f(
            "drifting-ambient",
            "sensing",
            "ambient-temperature",
            "the sensor warms linearly through the run, a t / t_end, a [K]",
            2.0,
            30.0,
            _drifting_ambient,
        ),
        _f(
            "cubic-stiffening",
            "sensing",
            "stiffening-spring",
            "F = S delta (1 + a delta^2), a [1/m^2]",
            100.0,
            1e5,
            _cubic_stiffening,
        ),
        _f(
            "growing-compression",
            "curvature",
            "axial-compression",
            "compressed share of the pull a cable / cable_max, a [-]",
            0.05,
            0.9,
            _growing_compression,
        ),
        _f(
            "segment-camera-offsets",
            "curvature",
            "camera-placement",
            "curvature offsets a on the tip and 0.4 a on the base, a [1/m]",
            1.0,
            50.0,
            _segment_camera,
        ),
        _f(
            "tilted-sensor",
            "curvature",
            "sensor-offset-error",
            "d1 error a on the tip segment and a / 3 on the base, a [m]",
            0.3e-3,
            4e-3,
            _tilted_sensor,
        ),
    )
}


def forms_for(kind: str) -> list[OffLibraryForm]:
    """The out-of-library forms of one rig kind."""
    return [f for (k, _), f in FORMS.items() if k == kind]


def get_form(name: str, kind: str) -> OffLibraryForm:
    """The named form of a rig kind; :class:`~tcamlab.errors.ConfigError` otherwise."""
    try:
        return FORMS[(kind, name)]
    except KeyError:
        names = ", ".join(f.name for f in forms_for(kind)) or "none"
        raise ConfigError(
            f"unknown {kind} out-of-library form {name!r}", hint=f"{kind} forms: {names}"
        ) from None


def apply_form(
    form: OffLibraryForm, a: float, kind, sample, rig, inputs, outputs, opts
) -> tuple[pd.DataFrame, dict]:
    """(logged inputs, true outputs) of one run with the form at amplitude ``a`` [SI]."""
    return form.apply(float(a), Context(kind, sample, rig, inputs, dict(outputs), dict(opts)))


def form_gap(
    form: OffLibraryForm, a: float, kind, sample, rig, inputs, outputs, opts
) -> dict[str, np.ndarray]:
    """True outputs minus the thesis model's prediction from the logged inputs, per output [SI]."""
    logged, true = apply_form(form, a, kind, sample, rig, inputs, outputs, opts)
    base = predict(kind, sample, rig, logged, NO_MODS, **opts)
    return {q: np.asarray(true[q], float) - np.asarray(base[q], float) for q in get_kind(kind).outputs}


def _rms(gap, sd, quantities) -> float:
    return float(math.sqrt(np.mean(np.concatenate([(gap[q] / sd[q]) ** 2 for q in quantities]))))


def scale_form(
    form: OffLibraryForm, strength: float, kind, sample, rig, inputs, outputs, opts, sd: Mapping[str, float]
) -> dict[str, Any]:
    """The amplitude giving a strength (RMS gap in noise sds), searched on one run.

    Parameters
    ----------
    form : OffLibraryForm
    strength : float or {"amplitude": a}
        Target RMS gap in noise sds of the kind's strength quantities (or the
        output the form moves most); or the amplitude itself [SI] (the same muscle under
        another protocol, :func:`tcamlab.rig.same_truth`).
    kind, sample, rig, inputs, outputs, opts :
        The first run: its true sample and rig [SI], exact inputs, the thesis
        model's exact outputs and predict options.
    sd : mapping
        Noise floor per quantity (:func:`tcamlab.rig.noise_sd`) [SI].

    Returns
    -------
    dict
        ``form``, ``nearest``, ``requested_strength``, ``amplitude`` [SI],
        ``achieved_strength``, ``quantities``, ``limited_by`` (None, ``"bound"``, ``"domain"``).
    """
    k = get_kind(kind)

    def gap(a):
        return form_gap(form, a, kind, sample, rig, inputs, outputs, opts)

    trial = gap(form.scale)
    quantities = k.strength_quantities or (max(k.outputs, key=lambda q: _rms(trial, sd, (q,))),)
    if isinstance(strength, Mapping):
        a = float(strength["amplitude"])
        achieved = _rms(gap(a), sd, quantities)
        return _form_info(form, float("nan"), a, achieved, quantities, None)

    def f(a):
        return _rms(gap(a), sd, quantities) - float(strength)

    lo, hi, limited = 0.0, form.scale, None
    while True:
        try:
            val = f(hi)
        except TcamlabError:
            hi, limited = 0.9 * (lo + 0.5 * (hi - lo)), "domain"
            break
        if val >= 0:
            break
        if hi >= form.upper:
            limited = "bound"
            break
        lo, hi = hi, min(2.0 * hi, form.upper)
    a = hi if limited else float(brentq(f, lo, hi, xtol=1e-12 * form.scale, rtol=1e-10))
    return _form_info(form, float(strength), a, _rms(gap(a), sd, quantities), quantities, limited)


def _form_info(form: OffLibraryForm, requested, a, achieved, quantities, limited) -> dict[str, Any]:
    return {
        "form": form.name,
        "nearest": form.nearest,
        "description": form.form,
        "requested_strength": requested,
        "amplitude": float(a),
        "achieved_strength": achieved,
        "quantities": list(quantities),
        "limited_by": limited,
    }
