"""Effect strengths of the virtual rig: the noise floor and the search for an effect's parameters.

A strength is the RMS gap between the effect's prediction and the thesis
model's, over the first run's protocol, in multiples of the noise floor
(:func:`noise_sd`) of the quantities it refers to. :func:`scale_effect`
finds the parameters giving a strength: all of the effect's parameters
move together along their ``scale`` vector (:class:`tcamlab.effects.EffectParam`),
so a two-parameter effect is scaled as one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from tcamlab.effects import NO_MODS, Effect, Mods, combine, get_effect
from tcamlab.errors import ConfigError, TcamlabError
from tcamlab.kinds import get_kind, predict
from tcamlab.params import Rig, Sample
from tcamlab.rig.runs import exact_inputs, instrument_sd, protocol, true_options

__all__ = ["DOMAIN_BACKOFF", "noise_sd", "resolve_effect", "ray_ratios", "ray_bound", "scale_effect"]

DOMAIN_BACKOFF = 0.9
"""When a strength cannot be reached inside the model's domain (e.g. G_t' > 0 of
(2.13) for a steeper shear-modulus slope), the parameters are set to this fraction
of the largest valid ones and the achieved strength is recorded."""


# --- noise floor -------------------------------------------------------------------------


def noise_sd(
    kind: str, sample: Sample | None = None, rig: Rig | None = None, *, noise_scale: float = 1.0
) -> dict[str, float]:
    """Noise floor of each quantity of a rig kind (SI).

    For a measured output (displacement, force, kappa1, kappa2) it is the
    standard deviation expected of ``data - model(logged inputs)`` with the
    thesis model exact: the output's own chain (:func:`instrument_sd`) plus
    the logged inputs' noise propagated through the model (linearised,
    mean square over the default protocol; first row and later rows
    perturbed separately, since displacement is taken from the first row).
    For a logged input it is that input's chain. This is the unit of effect
    strengths and of the noise-floor checks.

    Parameters
    ----------
    kind : str
        Rig kind.
    sample, rig : optional
        Default: the thesis preset of the kind, with the kind's
        :attr:`~tcamlab.kinds.Kind.simulation_rig_defaults` (sensing S).
    noise_scale : float
        Multiplies every instrument noise sd (not the quantisation).

    Returns
    -------
    dict
        Quantity (internal name) -> sd [SI].
    """
    k = get_kind(kind)
    sample = k.preset.build_sample() if sample is None else sample
    if rig is None:
        rig = k.preset.build_rig().replace(**k.simulation_rig_defaults)
    inst = instrument_sd(kind, noise_scale)
    out = dict(inst)
    if not k.noisy_inputs:
        return out
    inputs = exact_inputs(kind, sample, rig, protocol(kind, rig, np.random.default_rng(0)))
    var = _propagated_variance(kind, sample, rig, inputs, inst)
    for q in k.outputs:
        out[q] = float(math.sqrt(inst[q] ** 2 + float(np.mean(var[q]))))
    return out


def _propagated_variance(
    kind: str, sample: Sample, rig: Rig, inputs: pd.DataFrame, inst: Mapping[str, float]
) -> dict[str, np.ndarray]:
    """Per row, the squared output change of one-sd steps of each noisy input (first row, then the rest)."""
    k = get_kind(kind)
    opts = true_options(kind, sample, rig, inputs)
    base = predict(kind, sample, rig, inputs, **opts)
    var = {q: np.zeros(len(inputs)) for q in k.outputs}
    first = np.zeros(len(inputs))
    first[0] = 1.0
    for col in k.noisy_inputs:
        for mask in (first, 1.0 - first):
            pert = inputs.copy()
            pert[col] = pert[col].to_numpy(float) + inst[col] * mask
            moved = predict(kind, sample, rig, pert, **opts)
            for q in var:
                var[q] += (np.asarray(moved[q]) - np.asarray(base[q])) ** 2
    return var


# --- effects and their parameter ray ------------------------------------------------------


def resolve_effect(name: str | Effect, kind: str) -> Effect:
    """A library effect by name; several names joined by ``+`` act together as one effect.

    ``"initial-slack+stress-relaxation"`` is :func:`tcamlab.effects.combine`
    of the two: its parameters are scaled together to one strength (whereas
    two separate effects are each scaled to their own). An :class:`Effect`
    object is returned as it is.

    Raises
    ------
    ConfigError
        An unknown name, or effects that set a common Mods field.
    """
    if isinstance(name, Effect):
        return name
    parts = [get_effect(n.strip(), kind) for n in name.split("+")]
    if len(parts) == 1:
        return parts[0]
    joined = combine(*parts)
    if joined is None:
        raise ConfigError(f"effects {name!r} cannot act together", hint="they set a common Mods field")
    return joined


def ray_ratios(effect: Effect) -> tuple[float, ...]:
    """Each parameter's ``scale`` over the first's [-]: the ray the strength search moves along.

    The search coordinate ``x`` is the first parameter's value [its SI unit];
    parameter i is ``x * ratio_i`` (``ratio_0`` is exactly 1).
    """
    s0 = effect.params[0].scale
    return tuple(1.0 if i == 0 else p.scale / s0 for i, p in enumerate(effect.params))


def ray_values(effect: Effect, x: float) -> list[float]:
    """The parameter values [SI] at coordinate ``x`` of the ray (:func:`ray_ratios`)."""
    return [x * r for r in ray_ratios(effect)]


def ray_bound(effect: Effect, direction: float) -> float:
    """The farthest coordinate in ``direction`` (+-1) at which every parameter is within its bounds.

    Raises
    ------
    ConfigError
        No step in that direction is allowed.
    """
    bound = math.inf * direction
    for p, r in zip(effect.params, ray_ratios(effect)):
        if r != 0:
            edge = (p.upper if direction * r > 0 else p.lower) / r
            bound = edge if direction * edge < direction * bound else bound
    if direction * bound <= 0:
        sign = "negative" if direction < 0 else "positive"
        limits = ", ".join(f"{p.field} {p.lower:g}..{p.upper:g}" for p in effect.params)
        raise ConfigError(f"effect {effect.name!r} cannot take a {sign} parameter (bounds {limits})")
    return bound


# --- the strength search ----------------------------------------------------------------


def _gap(kind, sample, rig, proto, mods, opts) -> dict[str, np.ndarray]:
    """Effect prediction minus baseline prediction, on the exact inputs the effect makes."""
    inputs = exact_inputs(kind, sample, rig, proto, mods)
    eff = predict(kind, sample, rig, inputs, mods, **opts)
    base = predict(kind, sample, rig, inputs, NO_MODS, **opts)
    return {q: np.asarray(eff[q], float) - np.asarray(base[q], float) for q in get_kind(kind).outputs}


def _normalised_rms(gap: Mapping[str, np.ndarray], sd: Mapping[str, float], quantities) -> float:
    """sqrt of the mean over quantities and rows of (gap / sd)^2."""
    return float(math.sqrt(np.mean(np.concatenate([(gap[q] / sd[q]) ** 2 for q in quantities]))))


def _strength_quantities(kind, gap: Mapping[str, np.ndarray], sd) -> tuple[str, ...]:
    """The kind's strength quantities, else the output this gap moves most (in noise sd)."""
    fixed = get_kind(kind).strength_quantities
    if fixed is not None:
        return fixed
    scores = [(_normalised_rms(gap, sd, (q,)), q) for q in get_kind(kind).outputs]
    return (max(scores, key=lambda s: s[0])[1],)


def _strength_at(kind, sample, rig, proto, sd, also_valid_for) -> Callable[[Mods, tuple], float]:
    """strength(mods, quantities): the normalised RMS gap; raises outside the model's domain on any run."""
    opts = true_options(kind, sample, rig, proto)

    def strength(mods: Mods, quantities) -> float:
        for s_k, r_k, p_k in also_valid_for:
            _gap(kind, s_k, r_k, p_k, mods, true_options(kind, s_k, r_k, p_k))  # raises outside the domain
        return _normalised_rms(_gap(kind, sample, rig, proto, mods, opts), sd, quantities)

    return strength


def _domain_edge(f: Callable[[float], float], ok: float, bad: float) -> float:
    """The largest valid coordinate between ``ok`` and ``bad`` (bisection), backed off by DOMAIN_BACKOFF."""
    for _ in range(60):
        mid = 0.5 * (ok + bad)
        try:
            f(mid)
            ok = mid
        except TcamlabError:
            bad = mid
    # Keep 10 % inside the domain edge, so that the model stays valid on
    # the noisy logged inputs too (static: ~2 K of temperature headroom).
    return ok * DOMAIN_BACKOFF


def _bracket(f: Callable[[float], float], trial: float, bound: float) -> tuple[float, float, str | None]:
    """(lo, hi, limited_by): f(lo) < 0 <= f(hi) (limited_by None), or hi is the reachable end.

    Doubles ``hi`` from ``trial`` up to ``bound`` ("bound"); past the model's
    domain, ``hi`` falls back to the domain edge ("domain").
    """
    lo, hi = 0.0, trial
    while True:
        try:
            f_hi = f(hi)
        except TcamlabError:
            hi = _domain_edge(f, lo, hi)
            f_hi = f(hi)
            if f_hi < 0:
                return lo, hi, "domain"
        if f_hi >= 0:
            return lo, hi, None
        if hi == bound:
            return lo, hi, "bound"
        lo, hi = hi, hi * 2.0
        if abs(hi) >= abs(bound):
            hi = bound


def _search(
    effect: Effect, target: float, direction: float, strength_of, quantities
) -> tuple[float, str | None]:
    """(coordinate, limited_by) on the ray where the strength is ``target``."""
    if target == 0:
        return 0.0, None

    def f(x):
        return strength_of(effect.mods(ray_values(effect, x)), quantities) - target

    bound = ray_bound(effect, direction)
    lo, hi, limited = _bracket(f, direction * min(effect.params[0].scale, abs(bound)), bound)
    if limited is not None:
        return float(hi), limited
    xtol = 1e-14 * abs(effect.params[0].scale)
    return float(brentq(f, lo, hi, xtol=xtol, rtol=1e-10, maxiter=200)), None


def _at_values(kind, effect: Effect, given: Mapping[str, Any], sample, rig, proto, sd):
    """(values, quantities, strength) for parameter values given as ``{"value": x}`` [SI]."""
    if "value" not in given:
        raise ConfigError(f"effect {effect.name!r}: give a strength or {{'value': x}}")
    values = np.atleast_1d(np.asarray(given["value"], float))
    if values.size != len(effect.params):
        raise ConfigError(
            f"effect {effect.name!r}: give one value per parameter ({', '.join(effect.param_names)})"
        )
    gap = _gap(kind, sample, rig, proto, effect.mods(values), true_options(kind, sample, rig, proto))
    quantities = _strength_quantities(kind, gap, sd)
    return values, quantities, _normalised_rms(gap, sd, quantities)


def _quantities_along(kind, effect: Effect, direction: float, sample, rig, proto, sd) -> tuple[str, ...]:
    """The strength quantities, judged one ``scale`` step (or to the bound) along the ray."""
    trial = direction * min(effect.params[0].scale, abs(ray_bound(effect, direction)))
    gap = _gap(
        kind,
        sample,
        rig,
        proto,
        effect.mods(ray_values(effect, trial)),
        true_options(kind, sample, rig, proto),
    )
    return _strength_quantities(kind, gap, sd)


def scale_effect(
    kind: str,
    name: str | Effect,
    strength: float | Mapping[str, Any],
    sample: Sample,
    rig: Rig,
    proto: pd.DataFrame,
    sd: Mapping[str, float],
    *,
    also_valid_for: tuple = (),
) -> dict[str, Any]:
    """Find an effect's parameters for a strength in noise-sd units.

    Parameters
    ----------
    kind : str
        Rig kind.
    name : str or Effect
        The effect (:func:`resolve_effect`: a library name, names joined by
        ``+``, or an Effect).
    strength : float or {"value": x}
        Target RMS gap between the effect's prediction and the baseline
        prediction over ``proto``, in multiples of the noise sd of the
        strength quantities. All parameters move together along their
        ``scale`` vector; the sign picks the direction (+scale or -scale).
        Or ``{"value": x}``: the parameter values themselves [SI], one per
        parameter.
    sample, rig : the template's sample and rig.
    proto : pandas.DataFrame
        The protocol (:func:`protocol`) of the first run.
    sd : mapping
        :func:`noise_sd` of the kind.
    also_valid_for : sequence of (Sample, Rig, DataFrame)
        Further runs (true sample, rig, protocol) on which the model must
        stay in its domain at the chosen values (the other runs' scatter).

    Returns
    -------
    dict
        ``name``, ``requested_strength``, ``parameters`` {Mods field: SI value}
        (every parameter of the effect), ``fixed``, ``achieved_strength``,
        ``quantities`` (those the strength refers to), ``limited_by`` (None,
        ``"bound"`` or ``"domain"``).
    """
    effect = resolve_effect(name, kind)
    if isinstance(strength, Mapping):
        requested, limited = None, None
        values, quantities, achieved = _at_values(kind, effect, strength, sample, rig, proto, sd)
    else:
        requested = float(strength)
        direction = 1.0 if requested >= 0 else -1.0
        strength_of = _strength_at(kind, sample, rig, proto, sd, also_valid_for)
        quantities = _quantities_along(kind, effect, direction, sample, rig, proto, sd)
        x, limited = _search(effect, abs(requested), direction, strength_of, quantities)
        values = ray_values(effect, x)
        achieved = strength_of(effect.mods(values), quantities) if x != 0 else 0.0
    return {
        "name": effect.name,
        "requested_strength": requested,
        "parameters": {p.field: float(v) for p, v in zip(effect.params, values)},
        "fixed": dict(effect.fixed),
        "achieved_strength": float(achieved),
        "quantities": list(quantities),
        "limited_by": limited,
    }
