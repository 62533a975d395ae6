"""Each hypothesis's predicted logs under a protocol, with their spread over its parameters.

The kind's public model (:func:`tcamlab.kinds.predict`, with an effect's
:class:`~tcamlab.effects.Mods`) is evaluated on the protocol's exact inputs at draws of the
hypothesis's parameters, drawn from the Gaussian of the joint fit (its recalibrated
parameters' fitted coordinates and its effect's parameters, :meth:`Hypothesis.joint`), with a
fixed seed: the correlation matters, since on a heating-only run a drift and a shift of rho
trade off, and independent draws would spread predictions the fit has pinned. The first draw is the fit itself. A quantity whose zero each run profiles out
(:attr:`tcamlab.kinds.Kind.nuisance_zeros`) has each run's mean removed, as the diagnosis
scores it: a constant offset per run tells nothing.

The quantities predicted are the kind's outputs, then any the protocol's ``channels`` add (a
voltage-step run's logged current or temperature, :func:`tcamlab.design.protocols.channels`):
``quantities`` below, the kind's outputs when not given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tcamlab.design.hypotheses import Hypothesis
from tcamlab.diagnosis.problem import MODEL_ERRORS
from tcamlab.kinds import get_kind
from tcamlab.models import static as _static
from tcamlab.text import clipped

__all__ = [
    "Prediction",
    "predictive",
    "sensitivity",
    "limits",
    "hottest",
    "run_outputs",
    "anchored",
    "TEMPERATURE_LIMIT_C",
    "N_DRAWS",
]

N_DRAWS = 30
"""Parameter draws per hypothesis and protocol (the first is the fit itself)."""

TEMPERATURE_LIMIT_C = 170.0
"""Highest temperature a protocol may take the coil to [degC] (input or predicted):
:data:`tcamlab.kinds.static.MAX_OVEN_C`, the same for the Joule-heated coil."""


@dataclass
class Prediction:
    """One hypothesis's predictions under one protocol, rows of every run stacked.

    Attributes
    ----------
    mean, var : dict
        Quantity -> the fit's prediction [SI] and the draws' second moment about it [SI^2], per
        row (each run's zero removed as the diagnosis scores it).
    point : dict
        Quantity -> the prediction at the fit itself [SI], per row (no zero removed).
    failed : float
        Share of the draws where the model has no solution on the protocol [-].
    draws : dict
        Quantity -> every successful draw's predictions [SI], shape (draws, rows).
    z : ndarray
        The standard normal deviates behind each successful draw, shape (draws, parameters).
    """

    mean: dict
    var: dict
    point: dict
    failed: float
    draws: dict
    z: np.ndarray


def _draws(h: Hypothesis, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(u, theta, z) of each draw: z the standard normal deviates behind it (0 for the fit)."""
    rng = np.random.default_rng(seed)
    u0, theta0 = h.u(), h.effect_values
    root = covariance_root(h)
    out = [(u0, theta0, np.zeros(root.shape[1]))]
    for _ in range(n - 1):
        z = rng.standard_normal(root.shape[1])
        x = root @ z
        out.append((u0 + x[: u0.size], theta0 + x[u0.size :], z))
    return out


def covariance_root(h: Hypothesis) -> np.ndarray:
    """A square root of the joint covariance of (u, effect parameters) (eigendecomposition;
    rounding's negative eigenvalues clipped)."""
    c = h.joint()
    if c.size == 0:
        return np.zeros((0, 0))
    w, vecs = np.linalg.eigh((c + c.T) / 2.0)
    return vecs * np.sqrt(np.clip(w, 0.0, None))


def run_outputs(kind: str, sample, rig, mods, frames, quantities=None) -> list[dict]:
    """The model's predictions [SI] of each run's exact inputs (raises where the model has no
    solution, or where one of ``quantities``, default the kind's outputs, is not finite)."""
    k = get_kind(kind)
    quantities = k.outputs if quantities is None else quantities
    out = []
    for data in frames:
        opts = dict(k.run_options(sample, rig, data).options)
        opts.update(k.variants[k.primary])
        with np.errstate(all="ignore"):
            pred = k.predict(sample, rig, data, mods, **opts)
        if not all(np.all(np.isfinite(np.asarray(pred[q], float))) for q in quantities):
            raise ValueError("non-finite prediction")
        out.append(pred)
    return out


def _stack(kind: str, preds: list[dict], zero: bool, quantities=None) -> dict:
    """Each of ``quantities`` (default the kind's outputs), rows of every run stacked; with
    ``zero``, each run's mean removed from those the kind profiles out (its ``nuisance_zeros``)."""
    k = get_kind(kind)
    out = {}
    for q in k.outputs if quantities is None else quantities:
        parts = [np.asarray(p[q], float) for p in preds]
        if zero and q in k.nuisance_zeros:
            parts = [x - x.mean() for x in parts]
        out[q] = np.concatenate(parts)
    return out


def predictive(
    kind: str, sample, rig, frames, h: Hypothesis, n_draws: int = N_DRAWS, seed: int = 0, quantities=None
):
    """(:class:`Prediction`, the fit's per-run outputs) of hypothesis ``h`` on ``frames``, or
    (None, reason) when the model has no solution at the fit itself. ``quantities``: those
    predicted (default the kind's outputs)."""
    rows, point = [], None
    zs = []
    for j, (u, theta, z) in enumerate(_draws(h, n_draws, seed)):
        s, r, mods = h.at(u, theta, sample, rig, kind)
        try:
            preds = run_outputs(kind, s, r, mods, frames, quantities)
        except (*MODEL_ERRORS, ValueError) as exc:
            if j == 0:
                return None, f"{h.name}: no solution ({clipped(str(exc).split(';')[0])})"
            continue
        if j == 0:
            point = preds
        rows.append(_stack(kind, preds, True, quantities))
        zs.append(z)
    draws = {q: np.array([r[q] for r in rows]) for q in rows[0]}
    # centred on the fit (the first draw), not on the draws' mean, which drifts where the model bends
    mean = {q: d[0] for q, d in draws.items()}
    var = {
        q: np.sum((d[1:] - d[0]) ** 2, axis=0) / (len(d) - 1) if len(d) > 1 else 0 * d[0]
        for q, d in draws.items()
    }
    failed = 1.0 - len(rows) / n_draws
    return Prediction(mean, var, _stack(kind, point, False, quantities), failed, draws, np.array(zs)), point


SENSITIVITY_STEP = 0.1
"""Step of the central differences of :func:`sensitivity`, in posterior sds of each parameter."""


def sensitivity(
    kind: str, sample, rig, frames, h: Hypothesis, quantities=None, one_sided: bool = False
) -> dict:
    """Quantity -> d(predicted rows) / d(z) [SI per posterior sd], shape (rows, parameters), at
    the fit, by central differences of :data:`SENSITIVITY_STEP` posterior sds along each
    standardised parameter ((u, theta) = (u0, theta0) + root z), for each of ``quantities``
    (default the kind's outputs). Each run's zero removed as in :func:`predictive`. Raises
    where the model has no solution; with ``one_sided``, only where it has none on either side
    of the fit (a fit at the edge of the model's domain: the difference is then taken on the
    side that has one)."""
    u0, root = h.u(), covariance_root(h)
    p, k = u0.size, h.effect_values.size

    def rows(z):
        x = root @ z
        s, r, mods = h.at(u0 + x[:p], h.effect_values + x[p:], sample, rig, kind)
        return _stack(kind, run_outputs(kind, s, r, mods, frames, quantities), True, quantities)

    centre = rows(np.zeros(p + k)) if one_sided else None
    cols: dict = {}
    for m in range(p + k):
        ys, failed = [], 0
        for sgn in (1.0, -1.0):
            z = np.zeros(p + k)
            z[m] = sgn * SENSITIVITY_STEP
            try:
                ys.append(rows(z))
            except (*MODEL_ERRORS, ValueError):
                if not one_sided or failed:
                    raise
                ys.append(centre)  # the fit itself stands for the side without a solution
                failed += 1
        width = (2 - failed) * SENSITIVITY_STEP
        for q in ys[0]:
            cols.setdefault(q, []).append((ys[0][q] - ys[1][q]) / width)
    return {q: np.array(c).T for q, c in cols.items()}


def anchored(kind: str, sample, rig, frames, h: Hypothesis, n_draws: int, seed: int, quantities=None):
    """``h`` where the model has a solution at its fit and beside it under ``frames``; else
    ``h`` moved to the nearest of its parameter draws (smallest |z|) where it has; None when
    none has. For a protocol the sample has already been through: a fit at the edge of the
    model's domain is the fit's shortcoming there, and the draws that keep to the domain stand
    for it."""
    for u, theta, z in sorted(_draws(h, n_draws, seed), key=lambda d: float(d[2] @ d[2])):
        cand = h if not z.any() else h.moved(u, theta)
        try:
            s, r, mods = cand.at(cand.u(), cand.effect_values, sample, rig, kind)
            run_outputs(kind, s, r, mods, frames, quantities)
            sensitivity(kind, sample, rig, frames, cand, quantities, one_sided=True)
        except (*MODEL_ERRORS, ValueError):
            continue
        return cand
    return None


def hottest(frames, point: list[dict]) -> float:
    """The highest temperature [degC] of a protocol's inputs and of a prediction under it
    (-inf where neither has one)."""
    temps = [x for f, p in zip(frames, point) for x in (f.get("temperature"), p.get("temperature"))]
    return max((float(np.max(np.asarray(t, float))) for t in temps if t is not None), default=-np.inf)


def limits(kind: str, sample, frames, point: list[dict], ceiling: float | None = None) -> str | None:
    """Why a protocol is out of bounds for a hypothesis's fit, or None: a temperature above
    :data:`TEMPERATURE_LIMIT_C` (input or predicted), or above ``ceiling`` [degC] where that is
    higher (the hottest the fit predicts for the runs already made, which the sample survived),
    or a static coil contracted shut (its length down to the solid length of its coils, n d0)."""
    top = max(TEMPERATURE_LIMIT_C, -np.inf if ceiling is None else ceiling)
    hot = hottest(frames, point)
    if hot > top + 1e-6:  # the same program again differs from the one run in rounding only
        if top > TEMPERATURE_LIMIT_C:
            return f"{hot:.1f} degC, above the {top:.1f} degC it predicts for the runs already made"
        return f"{hot:.0f} degC, above the {TEMPERATURE_LIMIT_C:.0f} degC limit"
    if kind == "static":
        n = float(_static.n_coils(sample.fiber_length, sample.coil_length, sample.coil_diameter))
        room = sample.coil_length - n * sample.fiber_diameter
        squeeze = max(float(np.max(np.abs(np.asarray(p["displacement"], float)))) for p in point)
        if squeeze >= room:
            return f"the coil closes ({squeeze * 1e3:.2f} mm of {room * 1e3:.2f} mm)"
    return None
