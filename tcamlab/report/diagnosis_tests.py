"""The paired test behind "every other candidate is clearly worse", recomputed and shown.

The diagnosis result carries each candidate's held-out score per fold (``folds``:
``rmse_after_noise``) and each fold's held-out rows (``settings.fold_details``), not the
test itself. From them, for the best candidate B and every other candidate C:

- the paired bootstrap over folds the verdict uses: resample the folds (``n_boot``
  resamples, the diagnosis's ``seed``), and take the pooled held-out mean squared
  normalised residual of C minus B's; its 95 % percentile interval, and p = the share of
  resamples where C is not worse (one-sided);
- a sign test: on how many withheld folds C is worse, and its one-sided binomial p.

"Clearly worse" is printed only when every other candidate's bootstrap interval lies above
0 *and* its shrinkage interval does not overlap the best's; otherwise the text says which
candidates the withheld data cannot tell apart from the best.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from tcamlab.numbers import fmt

from .document import Table

__all__ = ["paired_tests", "paired_sentence", "paired_lines", "paired_table", "best_candidate"]


def best_candidate(result):
    """The named candidate's scores (the pair for a pair verdict), or None."""
    combo = getattr(result, "combination", None)
    if combo is not None:
        return combo
    return next((c for c in result.ranking if c.effect == result.effect), None)


def _get(c, key):
    return c[key] if isinstance(c, dict) else getattr(c, key)


def _name(c) -> str:
    return " + ".join(c["effects"]) if isinstance(c, dict) and "effects" in c else _get(c, "effect")


def _fold_rows(result) -> np.ndarray:
    """Held-out rows of each fold (contiguous row ranges, ``settings.fold_details``)."""
    details = result.settings["fold_details"]
    return np.array([sum(h["rows"][1] - h["rows"][0] + 1 for h in d["held_out"]) for d in details], float)


def _fold_mse(c) -> np.ndarray:
    return np.array([f["rmse_after_noise"] ** 2 for f in _get(c, "folds")], float)


def _overlap(a, b) -> bool:
    (alo, ahi), (blo, bhi) = _get(a, "shrinkage_ci95"), _get(b, "shrinkage_ci95")
    return bool(alo <= bhi and blo <= ahi)


def paired_tests(result) -> list[dict]:
    """Paired tests of every other candidate against the best (module docstring); [] when
    there is no best or the folds are missing.

    Returns
    -------
    list of dict
        ``candidate``, ``diff`` (pooled held-out MSE of it minus the best's [noise sd²]),
        ``ci95``, ``p_boot``, ``worse_folds``, ``folds``, ``p_sign``, ``intervals_overlap``,
        ``clearly_worse``.
    """
    best = best_candidate(result)
    try:
        n, mse_b = _fold_rows(result), _fold_mse(best)
    except (AttributeError, KeyError, TypeError):  # no best, or a result without per-fold scores
        return []
    if n.size != mse_b.size:
        return []
    s = result.settings
    boot = np.random.default_rng(s["seed"]).integers(0, n.size, size=(max(int(s["n_boot"]), 1), n.size))
    out = []
    for c in result.ranking:
        if _name(c) == _name(best):
            continue
        mse_c = _fold_mse(c)
        if mse_c.size != n.size:
            continue
        d = (mse_c - mse_b) * n
        samples = d[boot].sum(axis=1) / n[boot].sum(axis=1)
        lo, hi = (float(v) for v in np.quantile(samples, [0.025, 0.975]))
        worse = int(np.sum(mse_c > mse_b))
        overlap = _overlap(c, best)
        out.append(
            {
                "candidate": _name(c),
                "diff": float(d.sum() / n.sum()),
                "ci95": [lo, hi],
                "p_boot": float(np.mean(samples <= 0.0)),
                "n_boot": int(boot.shape[0]),
                "worse_folds": worse,
                "folds": int(n.size),
                "p_sign": float(stats.binomtest(worse, int(n.size), 0.5, alternative="greater").pvalue),
                "intervals_overlap": overlap,
                "clearly_worse": bool(lo > 0.0 and not overlap),
            }
        )
    return out


def _p(p: float, n_boot: int) -> str:
    return f"p < {fmt(1.0 / n_boot)}" if p <= 0.0 else f"p = {fmt(p, 2)}"


def _one(t: dict) -> str:
    lo, hi = t["ci95"]
    return (
        f"{t['candidate']} {fmt(t['diff'], 3)} (95 % {fmt(lo, 3)} to {fmt(hi, 3)}, "
        f"{_p(t['p_boot'], t['n_boot'])}; worse on {t['worse_folds']} of {t['folds']} withheld "
        f"folds, sign test p = {fmt(t['p_sign'], 2)})"
    )


def _closest(tests: list[dict]) -> str:
    t = min(tests, key=lambda t: t["ci95"][0])
    lo, hi = t["ci95"]
    return (
        f"{t['candidate']}, {fmt(t['diff'], 3)} noise sd² (95 % {fmt(lo, 3)} to {fmt(hi, 3)}, "
        f"{_p(t['p_boot'], t['n_boot'])}; worse on {t['worse_folds']} of {t['folds']} folds)"
    )


def paired_sentence(result) -> str:
    """The claim about the other candidates, with the test that supports it (the table of
    :func:`paired_table` gives every candidate's)."""
    tests = paired_tests(result)
    if not tests:
        return (
            "The paired test against the other candidates cannot be recomputed from this result "
            "(no per-fold scores), so no candidate is called clearly worse."
        )
    how = (
        f"in a paired bootstrap over the {tests[0]['folds']} withheld folds ({tests[0]['n_boot']} "
        f"resamples, seed {result.settings['seed']}), the held-out mean squared residual minus the best's"
    )
    if all(t["clearly_worse"] for t in tests):
        return (
            f"Every other candidate is clearly worse on withheld data: {how} is above 0 for each, "
            f"the closest being {_closest(tests)}, and no shrinkage interval overlaps the best's."
        )
    tied = [t for t in tests if t["ci95"][0] <= 0.0]
    close = [t for t in tests if t["ci95"][0] > 0.0 and t["intervals_overlap"]]
    clear = [t for t in tests if t["clearly_worse"]]
    parts = [f"Not every other candidate is clearly worse ({how}; table of paired tests)."]
    if tied:
        parts.append(
            "The withheld data cannot tell it from " + "; ".join(map(_one, tied)) + " (interval includes 0)."
        )
    if close:
        parts.append(
            ", ".join(t["candidate"] for t in close)
            + f" {'is' if len(close) == 1 else 'are'} worse by the paired test (closest: "
            + _closest(close)
            + "), but their shrinkage intervals overlap the best's."
        )
    if clear:
        parts.append("Clearly worse: " + ", ".join(t["candidate"] for t in clear) + ".")
    return " ".join(parts)


def paired_lines(result) -> list[str]:
    """One line per other candidate for the text output (the test named on the first)."""
    tests = paired_tests(result)
    if not tests:
        return []
    head = (
        f"held-out mean squared residual minus the best's [noise sd²], paired bootstrap over "
        f"{tests[0]['folds']} folds ({tests[0]['n_boot']} resamples, seed {result.settings['seed']}):"
    )
    return [head] + [_one(t) + ("" if t["clearly_worse"] else " - NOT clearly worse") for t in tests]


def paired_table(result) -> Table | None:
    """The paired tests as a table, or None without them."""
    tests = paired_tests(result)
    if not tests:
        return None
    best = best_candidate(result)
    rows = [
        [
            t["candidate"],
            fmt(t["diff"], 3),
            f"{fmt(t['ci95'][0], 3)} to {fmt(t['ci95'][1], 3)}",
            _p(t["p_boot"], t["n_boot"]),
            f"{t['worse_folds']} of {t['folds']}",
            fmt(t["p_sign"], 2),
            "yes" if t["intervals_overlap"] else "no",
            "yes" if t["clearly_worse"] else "no",
        ]
        for t in tests
    ]
    return Table(
        [
            "candidate",
            "MSE minus best's [noise sd²]",
            "95 % interval",
            "bootstrap p",
            "worse on folds",
            "sign test p",
            "shrinkage intervals overlap",
            "clearly worse",
        ],
        rows,
        caption=f"Paired tests against {_name(best)} on the withheld folds (paired bootstrap as "
        "the verdict uses, one-sided; recomputed from the per-fold scores)",
    )
