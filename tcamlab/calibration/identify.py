"""Identifiability in words: which parameters and combinations the logs pin down.

Work in prior-whitened coordinates ``w = (u - u0) / sd_u``, where the prior is
the identity. An eigenvector ``v`` of the posterior covariance of ``w`` with
eigenvalue ``lam`` is a combination whose posterior sd is ``sqrt(lam)`` of its
prior sd; in log space it is ``sum(a_k log theta_k)`` with ``a_k = v_k / sd_u_k``,
i.e. the product ``prod(theta_k ** a_k)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "PINNED_REL_SD",
    "PINNED_PROMISE",
    "PINNED_RATIO",
    "closer_probability",
    "CONSTRAINED_RATIO",
    "Direction",
    "directions",
    "tier",
    "identifiability_text",
]

PINNED_REL_SD = 0.10
"""A parameter or combination is pinned only if its posterior sd is at most 10 % of its value
(in log space) ..."""

PINNED_PROMISE = 0.90
"""What "pinned" promises: the calibrated value is closer to the truth than the stated one in
at least this fraction of cases where the truth is drawn from the prior."""

# Derivation: the stated value errs by e0 ~ N(0, s_prior) and the calibrated one, given the
# truth, by e1 ~ N(0, s_post), independently (the posterior error is orthogonal to the data).
# P(|e1| < |e0|) = (2/pi) atan(s_prior/s_post) (the angle of the wedge |y| > |x| in the
# whitened plane), so P >= PINNED_PROMISE needs s_post / s_prior <= tan(pi/2 (1 - promise)):
# tan(0.05 pi) = 0.158 for 90 %, i.e. the logs shrink the prior sd at least 6.31-fold.
PINNED_RATIO = math.tan(0.5 * math.pi * (1.0 - PINNED_PROMISE))
"""... and at most tan(pi/2 (1 - PINNED_PROMISE)) = 0.158 of its prior sd, so that the
calibrated value is closer to the truth than the stated one with probability
(2/pi) atan(prior/posterior) >= PINNED_PROMISE (see the derivation above)."""


def closer_probability(ratio: float) -> float:
    """P(calibrated closer to the truth than stated) = (2/pi) atan(1 / ratio) [-], for
    posterior sd / prior sd ``ratio`` [-] and a truth drawn from the prior."""
    return 1.0 if ratio <= 0 else 2.0 / math.pi * math.atan(1.0 / ratio)


CONSTRAINED_RATIO = 0.5
"""Otherwise it is constrained when the logs at least halve its prior sd, and rests on its
prior when they do not."""

COMPONENT_SHARE = 0.3
"""Exponents below this fraction of the largest are left out of a combination's name."""


@dataclass(frozen=True)
class Direction:
    """One eigen-combination of the posterior.

    Attributes
    ----------
    exponents : dict of str to float
        Parameter name -> exponent a_k of ``prod(theta_k ** a_k)``, largest magnitude 1 [-].
    ratio : float
        Posterior sd / prior sd along the combination [-].
    relative_sd : float
        Posterior sd of ``log(prod(theta_k ** a_k))`` [-] (about its relative sd).
    pinned : bool
        ``relative_sd <= PINNED_REL_SD`` and ``ratio <= PINNED_RATIO``.
    """

    exponents: dict[str, float]
    ratio: float
    relative_sd: float
    pinned: bool

    def name(self, symbols: dict[str, str]) -> str:
        """``C_th^1 lambda^-1``-style name; ratios and products named as such."""
        terms = [(symbols[k], a) for k, a in self.exponents.items()]
        text = " ".join(f"{s}^{a:+.2f}".replace("+", "") for s, a in terms)
        if len(terms) == 2 and abs(abs(terms[0][1]) - abs(terms[1][1])) < 0.35:
            (s1, a1), (s2, a2) = terms
            about = "" if abs(abs(a1) - abs(a2)) < 0.15 else "about "
            word = about + (f"the ratio {s1}/{s2}" if a1 * a2 < 0 else f"the product {s1}*{s2}")
            if {s1, s2} == {"C_th", "lambda"} and a1 * a2 < 0:
                word += " (the thermal time constant tau)"
            text += f", i.e. {word}"
        return text


def directions(names: list[str], sd_u: np.ndarray, cov: np.ndarray) -> list[Direction]:
    """Eigen-combinations of the posterior covariance ``cov`` of ``u``, best pinned first."""
    d = np.asarray(sd_u, float)
    cw = cov / np.outer(d, d)
    lam, vec = np.linalg.eigh((cw + cw.T) / 2)
    out = []
    for k in range(len(lam)):
        a = vec[:, k] / d
        a = a / a[np.argmax(np.abs(a))]
        keep = np.abs(a) >= COMPONENT_SHARE
        ratio = float(np.sqrt(max(lam[k], 0.0)))
        rel = float(np.sqrt(max(a @ cov @ a, 0.0)))
        exps = {n: float(x) for n, x, kp in zip(names, a, keep) if kp}
        out.append(Direction(exps, ratio, rel, tier(rel, rel / ratio if ratio > 0 else np.inf) == "pinned"))
    return sorted(out, key=lambda x: x.ratio)


def tier(posterior_sd_rel: float, prior_sd_rel: float) -> str:
    """``"pinned"``, ``"constrained"`` or ``"prior"`` (rests on its prior), from the relative
    posterior and prior sds [-] (see :data:`PINNED_REL_SD`, :data:`PINNED_RATIO`,
    :data:`CONSTRAINED_RATIO`)."""
    ratio = posterior_sd_rel / prior_sd_rel if prior_sd_rel > 0 else np.inf
    if posterior_sd_rel <= PINNED_REL_SD and ratio <= PINNED_RATIO:
        return "pinned"
    return "constrained" if ratio <= CONSTRAINED_RATIO else "prior"


def _short_of_pinned(p) -> str:
    """Why a constrained parameter is not pinned: too wide, or not narrowed enough."""
    if p.posterior_sd_rel > PINNED_REL_SD:
        return f"not to {100 * PINNED_REL_SD:.0f}%"
    return f"less than the {1 / PINNED_RATIO:.3g}-fold a {100 * PINNED_PROMISE:.0f}% chance of beating the stated value needs"


def _sds(p) -> str:
    if p.stated == 0 and not p.positive:  # a percent of 0 means nothing: absolute sds
        return f"posterior sd {p.posterior_sd:.3g} {p.unit} vs prior {p.prior_sd:.3g} {p.unit}"
    return f"posterior sd {100 * p.posterior_sd_rel:.3g}% vs prior {100 * p.prior_sd_rel:.3g}%"


def identifiability_text(params: list, dirs: list[Direction], experiments: str) -> list[str]:
    """Sentences: what the logs pin, what they only constrain, what rests on the prior, and
    the experiment that would pin the rest.

    ``params`` are :class:`~tcamlab.calibration.result.ParameterEstimate`; ``experiments``
    names the logs (e.g. "dynamic (5 runs; displacement)").
    """
    symbols = {p.name: p.symbol for p in params}
    tiers = {p.name: tier(p.posterior_sd_rel, p.prior_sd_rel) for p in params}
    pinned = [p for p in params if tiers[p.name] == "pinned"]
    lines = []
    if pinned:
        lines.append(
            f"Pinned by {experiments}: " + "; ".join(f"{p.symbol} ({_sds(p)})" for p in pinned) + "."
        )
    for dvec in dirs:
        # a pinned combination says something only about parameters not pinned on their own
        involved = [n for n in dvec.exponents if tiers[n] != "pinned"]
        if dvec.pinned and len(involved) > 1:
            lines.append(
                f"Not fixed separately: {', '.join(symbols[n] for n in involved)}; the data pin "
                f"only {dvec.name(symbols)} (to {100 * dvec.relative_sd:.3g}%)."
            )
    for p in params:
        if tiers[p.name] == "constrained":
            lines.append(
                f"Constrained, not pinned: {p.symbol} ({_sds(p)}: the logs narrow it "
                f"{p.prior_sd_rel / p.posterior_sd_rel:.3g}-fold, {_short_of_pinned(p)}); "
                f"to pin it: {p.pinned_by}."
            )
    for p in params:
        if tiers[p.name] == "prior":
            lines.append(f"Rests on its prior: {p.symbol} ({_sds(p)}); to pin it: {p.pinned_by}.")
    if len(pinned) == len(params) and len(params) > 1:
        lines.append(
            f"Every calibrated parameter is fixed separately by these logs; the tightest combination "
            f"is {dirs[0].name(symbols)} ({100 * dirs[0].relative_sd:.3g}%), the loosest "
            f"{dirs[-1].name(symbols)} ({100 * dirs[-1].relative_sd:.3g}%)."
        )
    return lines
