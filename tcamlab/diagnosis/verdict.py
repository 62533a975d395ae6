"""The verdict: none, attributed, aliased or unexplained, and the one-step pair search.

Constants below, with the reasons for their values in their docstrings.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from tcamlab.diagnosis.candidates import CandidateFit, FoldScores, ci, fit_candidates
from tcamlab.diagnosis.noise import BaselineFit
from tcamlab.diagnosis.problem import Problem
from tcamlab.diagnosis.result import CandidateResult, Gap
from tcamlab.effects import combine

__all__ = [
    "MIN_FRACTION_CLOSED",
    "MIN_PARTIAL_FRACTION",
    "PAIR_POOL",
    "Decision",
    "decide",
    "verdict",
    "pair_verdict",
    "pct",
]


MIN_FRACTION_CLOSED = 0.5
"""Share of the excess squared error (above the noise floor) a candidate must
remove on withheld data to count as an explanation: it must explain the
majority of the gap, not just part of it."""


MIN_PARTIAL_FRACTION = 0.05
"""When no single candidate explains the gap, candidates that alone close at
least this share of it (and improve the withheld runs) are paired."""


PAIR_POOL = 4
"""At most this many of the best single candidates enter the pair search
(6 pairs), which bounds its cost."""


def verdict(ranking, gap_significant, after_folds, boot_idx, b_n, base_rms, limit):
    """(verdict, effect, aliased_with, reason) from the single candidates (see the package docstring)."""
    if not gap_significant:
        return (
            "none",
            None,
            [],
            f"the baseline RMSE is {base_rms:.2f} x the noise floor, within the "
            f"no-gap limit {limit:.2f}: the thesis model explains the data to within noise",
        )
    if not ranking:
        return "unexplained", None, [], "the gap is significant and there are no candidates"
    best = ranking[0]
    ok = (
        np.isfinite(best.fraction_closed)
        and best.fraction_closed >= MIN_FRACTION_CLOSED
        and best.shrinkage_ci95[0] > 0
    )
    if not ok:
        return (
            "unexplained",
            None,
            [],
            f"the baseline RMSE is {base_rms:.2f} x the noise floor (limit {limit:.2f}); the best "
            f"candidate, {best.effect}, closes {pct(best.fraction_closed)} of the gap on withheld "
            f"data (needs {MIN_FRACTION_CLOSED:.0%} and a shrinkage interval above 0)",
        )
    aliased = []
    a_best = after_folds[best.effect][boot_idx].sum(axis=1)
    for c in ranking[1:]:
        if not (np.isfinite(c.fraction_closed) and c.fraction_closed >= MIN_FRACTION_CLOSED):
            continue
        diff = (after_folds[c.effect][boot_idx].sum(axis=1) - a_best) / b_n
        lo, hi = ci(diff)
        if lo <= 0.0:
            aliased.append(c.effect)
    if aliased:
        return (
            "aliased",
            best.effect,
            aliased,
            f"{best.effect} closes {pct(best.fraction_closed)} of the gap on withheld data, but "
            f"{', '.join(aliased)} fit{'s' if len(aliased) == 1 else ''} the withheld runs "
            "indistinguishably well",
        )
    return (
        "attributed",
        best.effect,
        [],
        f"{best.effect} closes {pct(best.fraction_closed)} of the gap above the noise floor on "
        f"withheld data (held-out RMSE shrinks by {best.shrinkage:.0%}) and every other candidate "
        "is clearly worse",
    )


def pair_verdict(combos, after_folds, boot_idx, b_n, order):
    """Verdict from pairs of effects, or None when no pair qualifies.

    A pair qualifies when it closes at least :data:`MIN_FRACTION_CLOSED` of the
    gap on withheld data with a shrinkage interval above 0 and is clearly
    better than each of its members alone (paired bootstrap of the held-out
    MSE difference above 0): both effects are needed. The best qualifying pair
    names the effect (the member that ranks higher alone); other qualifying
    pairs that fit the withheld runs indistinguishably well make it ``aliased``.
    """

    def boot(name):
        return after_folds[name][boot_idx].sum(axis=1)

    qualified = []
    for c in combos:
        if not (
            np.isfinite(c.fraction_closed)
            and c.fraction_closed >= MIN_FRACTION_CLOSED
            and c.shrinkage_ci95[0] > 0
        ):
            continue
        a_pair = boot(c.effect)
        if all(ci((boot(m) - a_pair) / b_n)[0] > 0 for m in c.members):
            qualified.append(c)
    if not qualified:
        return None
    best = qualified[0]
    members = sorted(best.members, key=lambda m: order.get(m, len(order)))
    primary, second = members[0], members[1:]
    a_best = boot(best.effect)
    rivals = [c for c in qualified[1:] if ci((boot(c.effect) - a_best) / b_n)[0] <= 0]
    combination = {"effects": members, **best.to_dict()}
    both = " and ".join(members)
    closes = (
        f"no single candidate closes {MIN_FRACTION_CLOSED:.0%} of the gap; {both} together "
        f"close {pct(best.fraction_closed)} of it on withheld data (held-out RMSE shrinks "
        f"by {best.shrinkage:.0%}), and the pair beats either alone"
    )
    if rivals:
        others = sorted(
            ({m for c in rivals for m in c.members} | set(second)) - {primary},
            key=lambda m: order.get(m, len(order)),
        )
        return (
            "aliased",
            primary,
            others,
            closes
            + "; but "
            + ", ".join(c.effect for c in rivals)
            + " fit the withheld runs indistinguishably well",
            combination,
        )
    return "attributed", primary, [], closes, combination


def pct(x) -> str:
    """A fraction as a percentage, or n/a."""
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.0%}"


@dataclass
class Decision:
    """The verdict and the candidate behind it."""

    verdict: str
    effect: str | None
    aliased_with: list
    reason: str
    combination: dict | None
    """The pair of effects that explains the gap together, or None."""
    best: CandidateResult | None
    """The best candidate (single, or the pair when a pair is the answer)."""
    best_fit: CandidateFit | None
    separate_by: dict
    """Aliased candidates -> the experiment that tells them apart."""


def _pair_pool(ranking) -> list[str]:
    """The best candidates that each close part of the gap on withheld data."""
    return [
        c.effect
        for c in ranking
        if np.isfinite(c.fraction_closed)
        and c.fraction_closed >= MIN_PARTIAL_FRACTION
        and c.shrinkage_ci95[0] > 0
    ][:PAIR_POOL]


def _search_pairs(problem, effects, ranking, fits, scores, baseline, workers):
    """Fit pairs of partial explanations (forward selection, one step); the pair verdict or None."""
    by_name = {e.name: e for e in effects}
    pairs = [combine(by_name[a], by_name[b]) for a, b in itertools.combinations(_pair_pool(ranking), 2)]
    pairs = [e for e in pairs if e is not None]
    if not pairs:
        return None, []
    combos, pair_fits = fit_candidates(problem, pairs, scores, baseline, workers)
    fits.update(pair_fits)
    after = {name: f.after for name, f in fits.items()}
    order = {c.effect: i for i, c in enumerate(ranking)}
    return pair_verdict(combos, after, scores.boot_idx, scores.boot_n, order), combos


def decide(
    problem: Problem,
    effects,
    ranking,
    fits,
    scores: FoldScores,
    baseline: BaselineFit,
    gap: Gap,
    workers=None,
) -> Decision:
    """The verdict from the single candidates, then from pairs when no single one explains the gap."""
    after = {name: f.after for name, f in fits.items()}
    v, effect, aliased, reason = verdict(
        ranking, gap.significant, after, scores.boot_idx, scores.boot_n, gap.rmse_over_noise, gap.limit
    )
    combination = None
    best = ranking[0] if ranking else None
    if v == "unexplained" and gap.significant:
        picked, combos = _search_pairs(problem, effects, ranking, fits, scores, baseline, workers)
        if picked is not None:
            v, effect, aliased, reason, combination = picked
            best = next(c for c in combos if c.effect == combination["effect"])
    separate = (
        {c.effect: c.separate_by for c in ranking if c.effect in [effect, *aliased]} if v == "aliased" else {}
    )
    best_fit = fits.get(best.effect) if best is not None else None
    return Decision(v, effect, aliased, reason, combination, best, best_fit, separate)
