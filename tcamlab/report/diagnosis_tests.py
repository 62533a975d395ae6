"""The paired tests behind "every other candidate is clearly worse", shown.

The diagnosis computes them (:mod:`tcamlab.diagnosis.paired`) and stores them in its result
(``paired_tests``: for every other candidate against the best, the paired bootstrap over
withheld folds the verdict uses, with its 95 % interval and one-sided p, and a sign test over
folds); this module only prints what is stored, from a
:class:`tcamlab.diagnosis.DiagnosisResult` or from its ``diagnosis.json`` mapping.

"Clearly worse" is printed only when every other candidate's bootstrap interval lies above
0 *and* its shrinkage interval does not overlap the best's; otherwise the text says which
candidates the withheld data cannot tell apart from the best.
"""

from __future__ import annotations

from collections.abc import Mapping

from tcamlab.numbers import fmt

from .document import Table

__all__ = ["stored_tests", "paired_sentence", "paired_lines", "paired_table"]


def stored_tests(result) -> list[dict]:
    """The paired tests stored in a diagnosis result (its ``paired_tests``), or [].

    Parameters
    ----------
    result
        A :class:`tcamlab.diagnosis.DiagnosisResult`, or its ``diagnosis.json`` mapping.

    Returns
    -------
    list of dict
        The stored tests (keys as :attr:`tcamlab.diagnosis.DiagnosisResult.paired_tests`);
        [] when the result has none.
    """
    tests = (
        result.get("paired_tests") if isinstance(result, Mapping) else getattr(result, "paired_tests", None)
    )
    return list(tests or [])


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
    tests = stored_tests(result)
    if not tests:
        return (
            "The paired test against the other candidates cannot be computed from this result "
            "(no per-fold scores), so no candidate is called clearly worse."
        )
    how = (
        f"in a paired bootstrap over the {tests[0]['folds']} withheld folds ({tests[0]['n_boot']} "
        f"resamples, seed {tests[0]['seed']}), the held-out mean squared residual minus the best's"
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
    tests = stored_tests(result)
    if not tests:
        return []
    head = (
        f"held-out mean squared residual minus the best's [noise sd²], paired bootstrap over "
        f"{tests[0]['folds']} folds ({tests[0]['n_boot']} resamples, seed {tests[0]['seed']}):"
    )
    return [head] + [_one(t) + _not_clearly(t) for t in tests]


def _not_clearly(t: dict) -> str:
    """Why a candidate is not clearly worse, in words ("" when it is): a significant paired
    test alone is not enough, the shrinkage intervals must not overlap either."""
    if t["clearly_worse"]:
        return ""
    if t["ci95"][0] <= 0.0:
        return " - NOT clearly worse: the interval includes 0"
    return " - NOT clearly worse: worse by the paired test, but its shrinkage interval overlaps the best's"


def paired_table(result) -> Table | None:
    """The paired tests as a table, or None without them."""
    tests = stored_tests(result)
    if not tests:
        return None
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
        caption=f"Paired tests against {tests[0]['best']} on the withheld folds (paired bootstrap as "
        "the verdict uses, one-sided; computed from the per-fold scores)",
    )
