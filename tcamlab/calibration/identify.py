"""Identifiability in words: which parameters and combinations the logs pin down.

Work in prior-whitened coordinates ``w = (u - u0) / sd_u``, where the prior is
the identity. An eigenvector ``v`` of the posterior covariance of ``w`` with
eigenvalue ``lam`` is a combination whose posterior sd is ``sqrt(lam)`` of its
prior sd; in log space it is ``sum(a_k log theta_k)`` with ``a_k = v_k / sd_u_k``,
i.e. the product ``prod(theta_k ** a_k)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PINNED_RATIO", "Direction", "directions", "identifiability_text"]

PINNED_RATIO = 0.5
"""A parameter or combination is pinned when its posterior sd is below this fraction of
its prior sd."""

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
        ``ratio < PINNED_RATIO``.
    """

    exponents: dict[str, float]
    ratio: float
    relative_sd: float
    pinned: bool

    def name(self, symbols: dict[str, str]) -> str:
        """``C_th^1 lambda^-1``-style name; ratios and products named as such."""
        terms = [(symbols[k], a) for k, a in self.exponents.items()]
        text = " ".join(f"{s}^{a:+.2f}".replace("+", "") for s, a in terms)
        if len(terms) == 2 and abs(abs(terms[0][1]) - abs(terms[1][1])) < 0.25:
            (s1, a1), (s2, a2) = terms
            word = f"the ratio {s1}/{s2}" if a1 * a2 < 0 else f"the product {s1}*{s2}"
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
        out.append(Direction(exps, ratio, rel, ratio < PINNED_RATIO))
    return sorted(out, key=lambda x: x.ratio)


def identifiability_text(params: list, dirs: list[Direction], experiments: str) -> list[str]:
    """Sentences: what the logs pin, what rests on the prior and what would pin it.

    ``params`` are :class:`~tcamlab.calibration.result.ParameterEstimate`; ``experiments``
    names the logs (e.g. "dynamic (5 runs; displacement)").
    """
    symbols = {p.name: p.symbol for p in params}
    pinned = [p for p in params if p.pinned]
    loose = [p for p in params if not p.pinned]
    lines = []
    if pinned:
        lines.append(
            f"Pinned by {experiments}: "
            + "; ".join(
                f"{p.symbol} (posterior sd {100 * p.posterior_sd_rel:.3g}% vs prior "
                f"{100 * p.prior_sd_rel:.3g}%)"
                for p in pinned
            )
            + "."
        )
    for dvec in dirs:
        involved = [n for n in dvec.exponents if not next(p for p in params if p.name == n).pinned]
        if dvec.pinned and len(dvec.exponents) > 1 and involved:
            lines.append(
                f"Not fixed separately: {', '.join(symbols[n] for n in dvec.exponents)}; the data pin "
                f"only {dvec.name(symbols)} (to {100 * dvec.relative_sd:.3g}%)."
            )
    for p in loose:
        lines.append(
            f"Rests on its prior: {p.symbol} (posterior sd {100 * p.posterior_sd_rel:.3g}% vs prior "
            f"{100 * p.prior_sd_rel:.3g}%); to pin it: {p.pinned_by}."
        )
    if not loose and len(params) > 1:
        lines.append(
            f"Every calibrated parameter is fixed separately by these logs; the tightest combination "
            f"is {dirs[0].name(symbols)} ({100 * dirs[0].relative_sd:.3g}%), the loosest "
            f"{dirs[-1].name(symbols)} ({100 * dirs[-1].relative_sd:.3g}%)."
        )
    return lines
