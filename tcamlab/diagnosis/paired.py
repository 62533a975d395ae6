"""The paired tests behind "every other candidate is clearly worse".

From each candidate's held-out score per fold (``folds``: ``rmse_after_noise``) and each
fold's held-out rows (``settings.fold_details``), for the best candidate B and every other
candidate C:

- the paired bootstrap over folds the verdict uses: resample the folds (``n_boot``
  resamples, the diagnosis's ``seed``), and take the pooled held-out mean squared
  normalised residual of C minus B's (each fold weighted by its held-out rows); its 95 %
  percentile interval, and p = the share of resamples where C is not worse (one-sided);
- a sign test: on how many withheld folds C is worse, and its one-sided binomial p.

C is *clearly worse* when its bootstrap interval lies above 0 *and* its shrinkage interval
does not overlap B's. :class:`tcamlab.diagnosis.result.DiagnosisResult` stores the tests
(``paired_tests``); the report only prints them.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

__all__ = ["paired_tests", "best_candidate", "candidate_name"]


def _get(c, key):
    return c[key] if isinstance(c, dict) else getattr(c, key)


def best_candidate(result):
    """The named candidate's scores, or None.

    Parameters
    ----------
    result
        A diagnosis result (anything with ``combination``, ``ranking`` and ``effect``).

    Returns
    -------
    dict or CandidateResult or None
        The pair (``combination``, a dict) for a pair verdict, else the ranking entry of
        ``result.effect``; None when no candidate is named.
    """
    combo = getattr(result, "combination", None)
    if combo is not None:
        return combo
    return next((c for c in result.ranking if c.effect == result.effect), None)


def candidate_name(c) -> str:
    """A candidate's name: its effect, or ``"A + B"`` for a pair (a dict with ``effects``)."""
    return " + ".join(c["effects"]) if isinstance(c, dict) and "effects" in c else _get(c, "effect")


def _fold_rows(settings) -> np.ndarray:
    """Held-out rows of each fold (contiguous row ranges, ``settings.fold_details``)."""
    details = settings["fold_details"]
    return np.array([sum(h["rows"][1] - h["rows"][0] + 1 for h in d["held_out"]) for d in details], float)


def _fold_mse(c) -> np.ndarray:
    """Held-out mean squared normalised residual of each fold [noise sd²]."""
    return np.array([f["rmse_after_noise"] ** 2 for f in _get(c, "folds")], float)


def _overlap(a, b) -> bool:
    (alo, ahi), (blo, bhi) = _get(a, "shrinkage_ci95"), _get(b, "shrinkage_ci95")
    return bool(alo <= bhi and blo <= ahi)


def _one_test(c, best, n: np.ndarray, mse_b: np.ndarray, boot: np.ndarray, seed: int) -> dict:
    """The paired bootstrap and sign test of candidate ``c`` against ``best``."""
    mse_c = _fold_mse(c)
    d = (mse_c - mse_b) * n
    samples = d[boot].sum(axis=1) / n[boot].sum(axis=1)
    lo, hi = (float(v) for v in np.quantile(samples, [0.025, 0.975]))
    worse = int(np.sum(mse_c > mse_b))
    overlap = _overlap(c, best)
    return {
        "candidate": candidate_name(c),
        "best": candidate_name(best),
        "diff": float(d.sum() / n.sum()),
        "ci95": [lo, hi],
        "p_boot": float(np.mean(samples <= 0.0)),
        "n_boot": int(boot.shape[0]),
        "seed": int(seed),
        "worse_folds": worse,
        "folds": int(n.size),
        "p_sign": float(stats.binomtest(worse, int(n.size), 0.5, alternative="greater").pvalue),
        "intervals_overlap": overlap,
        "clearly_worse": bool(lo > 0.0 and not overlap),
    }


def paired_tests(result) -> list[dict]:
    """Paired tests of every other candidate against the best (module docstring).

    Parameters
    ----------
    result
        A diagnosis result: ``ranking`` (candidates with ``effect``, ``folds`` and
        ``shrinkage_ci95``), ``effect``, ``combination`` and ``settings`` (``seed``,
        ``n_boot``, ``fold_details``).

    Returns
    -------
    list of dict
        One per other candidate of the ranking, in its order: ``candidate``, ``best`` (the
        candidate tested against), ``diff`` (pooled held-out mean squared residual of it
        minus the best's [noise sd²]), ``ci95`` ([lo, hi] of ``diff``, paired bootstrap),
        ``p_boot`` (share of resamples with ``diff`` <= 0), ``n_boot``, ``seed``,
        ``worse_folds`` (folds where it is worse), ``folds``, ``p_sign`` (one-sided sign
        test), ``intervals_overlap`` (its shrinkage interval overlaps the best's) and
        ``clearly_worse`` (interval above 0 and no overlap). Empty when no candidate is
        named or the per-fold scores are missing; a candidate with another number of folds
        is left out.
    """
    best = best_candidate(result)
    try:
        settings = result.settings
        n, mse_b = _fold_rows(settings), _fold_mse(best)
    except (AttributeError, KeyError, TypeError):  # no best, or a result without per-fold scores
        return []
    if n.size == 0 or n.size != mse_b.size:
        return []
    seed = int(settings["seed"])
    boot = np.random.default_rng(seed).integers(0, n.size, size=(max(int(settings["n_boot"]), 1), n.size))
    return [
        _one_test(c, best, n, mse_b, boot, seed)
        for c in result.ranking
        if candidate_name(c) != candidate_name(best) and _fold_mse(c).size == n.size
    ]
