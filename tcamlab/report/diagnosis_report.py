"""Report section and document of a gap diagnosis (:class:`tcamlab.diagnosis.DiagnosisResult`)."""

from __future__ import annotations

import math

from tcamlab.numbers import (
    MISSING,
    fmt,
    fmt_column,
    fmt_interval,
    fmt_percent,
    fmt_percent_range,
    lab_unit,
    percent_decimals,
    reading_text,
    rmse_unit,
    shift_text,
    stated_label,
)

from .diagnosis_figures import MIN_REGIME_POINTS, forest_figure, regime_figure, residual_figure
from .diagnosis_tests import paired_lines, paired_sentence, paired_table, stored_tests
from .document import Document, Section, Table
from .validation_report import synthetic_banner

__all__ = [
    "diagnosis_section",
    "diagnosis_document",
    "next_experiment_section",
    "verdict_text",
    "diagnosis_lines",
]


def _pct(x, decimals: int = 0) -> str:
    return MISSING if x is None or not math.isfinite(x) else fmt_percent(x, decimals)


def _num(x, fmt="{:.3g}") -> str:
    """``x`` in ``fmt``; a value that rounds to zero loses its sign (never ``-0.00``)."""
    if x is None or not math.isfinite(x):
        return MISSING
    text = fmt.format(x)
    return text.lstrip("+-") if float(text) == 0.0 else text


def verdict_text(result) -> str:
    """The verdict in plain words."""
    g = result.gap
    lead = (
        f"The thesis model misses the measurements by {g['rmse_over_noise']:.2f} times the "
        f"noise floor (RMS); without a model gap this would stay below {g['limit']:.2f} "
        f"({g['level']:.0%} of the time)."
    )
    if result.verdict == "none":
        return lead + " There is no gap to explain: the thesis model fits these runs to within noise."
    best = next((c for c in result.ranking if c.effect == result.effect), None) or (
        result.ranking[0] if result.ranking else None
    )
    if result.verdict == "miscalibrated":
        return lead + _miscalibrated_text(result.recalibration or {}) + _stand_ins_text(result)
    if result.verdict == "unexplained":
        tail = " The gap is real, but none of the candidate effects explains most of it on withheld runs"
        if best is not None:
            tail += (
                f" (the best, {best.effect}, closes {_pct(best.fraction_closed)} of the gap above "
                f"the noise floor)"
            )
        return lead + tail + ". Look for a cause outside the effect library."
    combo = getattr(result, "combination", None)
    if combo is not None:
        a, b = combo["effects"][0], " and ".join(combo["effects"][1:])
        text = (
            f" No single candidate explains it, but two together do: {a} and {b}. Fitted "
            f"together on the other runs and tested on the withheld one, they cut the RMSE by "
            f"{_pct(combo['shrinkage'], percent_decimals(*combo['shrinkage_ci95']))} (95 % interval "
            f"{fmt_percent_range(*combo['shrinkage_ci95'])}) and close {_pct(combo['fraction_closed'])} of "
            f"the gap above the noise floor; the pair beats either effect alone."
        )
        if result.verdict == "aliased":
            text += (
                " Other pairs fit the withheld data just as well (with "
                + ", ".join(result.aliased_with)
                + "); these data cannot tell them apart."
            )
        return lead + text
    text = (
        f" The most likely cause is {best.effect}: {best.cause}. Fitted on the other runs and "
        f"tested on the withheld one, it cuts the RMSE by {_pct(best.shrinkage, percent_decimals(*best.shrinkage_ci95))} (95 % interval "
        f"{fmt_percent_range(*best.shrinkage_ci95)}) and closes "
        f"{_pct(best.fraction_closed)} of the gap above the noise floor."
    )
    if result.verdict == "aliased":
        text += (
            " However, "
            + ", ".join(result.aliased_with)
            + " explain"
            + ("s" if len(result.aliased_with) == 1 else "")
            + " the withheld data just as well; "
            "these data cannot tell them apart. Experiments that would: "
            + "; ".join(f"{k}: {v}" for k, v in result.separate_by.items())
            + "."
        )
    else:
        text += " " + paired_sentence(result)
    return lead + text


def _miscalibrated_text(rec: dict) -> str:
    """The ``miscalibrated`` verdict: the recalibrated parameters, their intervals and shifts."""
    parts = []
    for name in rec.get("named", []):
        p = rec["parameters"][name]
        sds = shift_text(p)
        unit, fac = _parameter_unit(name, p["unit"])
        value, lo, hi = fmt_interval(p["value"] * fac, p["ci95"][0] * fac, p["ci95"][1] * fac)
        interval = (
            "at the edge of the model's domain on these runs, so no posterior interval"
            if p.get("at_domain_edge")
            else f"95 % interval {lo} to {hi}"
        )
        parts.append(
            f"{p['symbol']} = {value} {unit} ({interval}; stated "
            f"{fmt(p['stated'] * fac)}, {sds}{reading_text(p, fac, unit)})"
        )
    if rec.get("via_effect"):
        # the parameter's own error, fitted as an effect (no prior), explained the gap
        return (
            " The gap is a wrong parameter, not missing physics: fitted as its own error "
            f"({rec['via_effect']}), "
            + "; ".join(parts)
            + f". Fitted on the other runs and tested on the withheld one, that closes "
            f"{_pct(rec.get('fraction_closed'))} of the gap above the noise floor; recalibration "
            "under the stated uncertainty does not move it that far."
        )
    return (
        " The gap closes by recalibrating the stated parameters, not by adding physics: "
        + "; ".join(parts)
        + f". Fitted on the other runs and tested on the withheld one, recalibration closes "
        f"{_pct(rec.get('fraction_closed'))} of the gap above the noise floor, and no candidate "
        "effect fitted together with it does clearly better."
    )


def _stand_ins_text(result) -> str:
    """The effects that fit the withheld runs as well as a ``miscalibrated`` shift (the
    result's ``stand_ins_words``), with the experiments that tell them apart (empty without
    any)."""
    words = getattr(result, "stand_ins_words", None)
    if not result.aliased_with or not words:
        return ""
    many = len(result.aliased_with) > 1
    return (
        " But "
        + words
        + (" fit" if many else " fits")
        + " the withheld runs as well; these data cannot tell the shift from "
        + ("them" if many else "it")
        + ". Experiments that would: "
        + "; ".join(f"{k}: {v}" for k, v in result.separate_by.items())
        + "."
    )


def _params_text(parameters: dict) -> str:
    """Fitted parameters in lab units: ``slack = 0.6884 mm (95 % 0.6822 to 0.6947)``."""
    out = []
    for name, p in parameters.items():
        unit, fac = lab_unit(p.get("unit", ""))
        lo, hi = p["ci95"]
        u = f" {unit}" if unit else ""
        v, a, b = fmt_column([_scaled(x, fac) for x in (p["value"], lo, hi)])
        # at a bound of its fit the Laplace interval is no interval ("3.6e-06 to 3.6e-06")
        where = "at a bound of its fitted range, so no interval" if p.get("at_bound") else f"95 % {a} to {b}"
        out.append(f"{name} = {v}{u} ({where})")
    return "; ".join(out)


def _scaled(x, fac):
    return None if x is None else float(x) * fac


def _candidate_row(c, baseline, fac: float) -> list:
    get = (lambda k: c[k]) if isinstance(c, dict) else (lambda k: getattr(c, k))
    name = " + ".join(c["effects"]) + " (pair)" if isinstance(c, dict) else c.effect
    lo, hi = get("shrinkage_ci95")
    return [
        name,
        _scaled(get("heldout_rmse_before"), fac),
        _scaled(get("heldout_rmse_after"), fac),
        # the estimate with its interval's decimals (never 0% beside 0.2% to 0.3%)
        _pct(get("shrinkage"), percent_decimals(lo, hi)),
        fmt_percent_range(lo, hi),
        _pct(get("fraction_closed")),
        _num(get("aic") - baseline["aic"], "{:.1f}"),
        _num(get("bic") - baseline["bic"], "{:.1f}"),
        _params_text(get("parameters")) or MISSING,
    ]


def _ranking_table(result) -> Table:
    unit = result.ranking[0].unit if result.ranking else ""
    shown, fac = ("x noise sd", 1.0) if unit == "noise" else rmse_unit(unit)
    rows = [_candidate_row(c, result.baseline, fac) for c in result.ranking]
    combo = getattr(result, "combination", None)
    if combo is not None:
        rows.insert(0, _candidate_row(combo, result.baseline, fac))
    return Table(
        [
            "effect",
            f"held-out RMSE before [{shown}]",
            f"held-out RMSE after [{shown}]",
            "shrinkage",
            "95 % interval",
            "gap closed",
            "dAIC",
            "dBIC",
            "fitted parameters, lab units (95 % CI)",
        ],
        rows,
        caption="Candidate effects, best first (held-out = leave one run out)",
    )


def _regime_table(result) -> Table:
    rows = [
        [
            r["group"],
            r["regime"],
            r["n"],
            _num(r["rmse_over_noise"], "{:.2f}"),
            _num(r["bias_over_noise"], "{:+.2f}"),
            fmt_percent(r["share"]),
        ]
        for r in result.regimes
    ]
    return Table(
        ["grouping", "regime", "n", "RMSE / noise", "bias / noise", "share of sq. error"],
        rows,
        caption="Where the baseline misses (residuals in noise-floor units; regimes with fewer "
        f"than {MIN_REGIME_POINTS} points are listed but not drawn)",
    )


def _noise_table(result) -> Table:
    rows = []
    between = result.noise_floor["between_runs"]
    for q, v in result.noise_floor["by_quantity"].items():
        btw = between.get(q, {}) if between.get("available") else {}
        unit, fac = rmse_unit(v["unit"])
        rows.append(
            [
                q,
                unit,
                _scaled(v["sigma"], fac),
                _scaled(v.get("quantisation_step"), fac),
                _scaled(btw.get("sd"), fac),
                _scaled(result.baseline["by_quantity"][q]["rmse"], fac),
            ]
        )
    return Table(
        ["quantity", "unit", "noise floor", "quantisation step", "between-run sd", "baseline RMSE"],
        rows,
        caption="Noise floor estimated from the data",
    )


def _figures(result) -> list:
    figures = []
    for q in result.noise_floor["quantities"]:
        fig = residual_figure(result, q)
        if fig is not None:
            figures.append(fig)
    for group in result._series.get("regime_groups", []):
        fig = regime_figure(result, group)
        if fig is not None:
            figures.append(fig)
    forest = forest_figure(result)
    if forest is not None:
        figures.append(forest)
    return figures


def diagnosis_section(result) -> Section:
    """A report section: verdict, paired tests, ranking, residuals before and after the best
    candidate, residuals by regime, forest plot."""
    tables = [_ranking_table(result)]
    tests = paired_table(result)
    if tests is not None:
        tables.append(tests)
    tables += [_regime_table(result), _noise_table(result)]
    notes = (
        []
        if result.verdict in ("none", "attributed")
        else [f"Verdict: {result.verdict}" + (f" ({result.effect})" if result.effect else "")]
    )
    return Section(
        heading="Sim-to-real gap diagnosis",
        paragraphs=[
            verdict_text(result),
            "Method: residual = measured - thesis model; noise floor from second differences "
            "of the residuals, plus the quantisation error they cannot see where a reading moves "
            "by less than its step between rows; each candidate effect fitted on all runs but one "
            "and scored on the withheld run; intervals from a bootstrap over withheld runs.",
        ],
        tables=tables,
        figures=_figures(result),
        notes=notes,
        warnings=list(getattr(result, "warnings", None) or []),
    )


def _finite(x):
    """``x`` as a float, or None (shown as a dash) when missing or not finite."""
    return float(x) if isinstance(x, (int, float)) and math.isfinite(x) else None


def _separation_cells(c: dict, out_of_reach: dict) -> list:
    """J, J beyond the repeat, the weakest within-reach effect's Wald statistic at its fit (None
    without one, or when one has none: a hypothesis without a solution near its fit, stored
    as null) and whether the protocol decides."""
    at_fit = [_finite(v) for n, v in (c.get("at_fit") or {}).items() if n not in out_of_reach]
    weakest = min(at_fit) if at_fit and None not in at_fit else None
    return [
        _finite(c.get("separation_refit")),
        _finite(c.get("beyond_repeat")),
        weakest,
        "yes" if c.get("decisive") else "no",
    ]


def next_experiment_section(design) -> Section | None:
    """The "Next experiment" section of a diagnosis's ``next_experiment``, or None.

    Parameters
    ----------
    design : dict or None
        :meth:`tcamlab.design.DesignResult.to_dict` of the design run on the diagnosis
        (``message``, ``best``, ``candidates`` with ``name``, ``separation``,
        ``separation_refit``, ``runs``, ``minutes``, ``feasible``, ``limit``).

    Returns
    -------
    Section or None
        The message and a table of the candidate protocols, the best one marked; None
        without a design.
    """
    if not design:
        return None
    best = design.get("best")
    precision = design.get("status") == "clear"
    reach = design.get("out_of_reach") or {}
    rows = [
        [c.get("name", "") + (" (best)" if best is not None and c.get("name") == best else "")]
        + ([_finite(c.get("information_gain"))] if precision else _separation_cells(c, reach))
        + [
            c.get("runs"),
            _finite(c.get("minutes")),
            "yes" if c.get("feasible", True) else (c.get("limit") or "no"),
        ]
        for c in design.get("candidates") or []
    ]
    if precision:
        columns = ["protocol", "information gain [nats]", "runs", "minutes", "feasible"]
        caption = (
            "Candidate protocols, best first: what each adds to the precision of the explanation's "
            "parameters (expected information gain); feasible, or the limit it breaks"
        )
    else:
        columns = [
            "protocol",
            "separation J",
            "J beyond the repeat",
            "weakest effect at its fit",
            "decides",
            "runs",
            "minutes",
            "feasible",
        ]
        caption = (
            "Candidate protocols, best first: separation J of the hardest pair of hypotheses (symmetric "
            "KL divergence of their predictive distributions, J/2 the expected log Bayes factor), "
            "what it adds beyond a repeat of the protocol run (decisive from 9.2: a Bayes factor of "
            "100), the Wald statistic of the weakest effect within the menu's reach if it is as "
            "large as fitted (from 15: a probability of 0.8 of reaching 9.2), whether it decides "
            "(both), and whether the sample's limits allow it"
        )
    return Section(
        heading="Next experiment",
        paragraphs=[str(design["message"])] if design.get("message") else [],
        tables=[Table(columns, rows, caption=caption)] if rows else [],
    )


def diagnosis_document(result, experiment=None, next_experiment=None) -> Document:
    """A full report Document of a diagnosis.

    Parameters
    ----------
    result : DiagnosisResult
        The diagnosis.
    experiment : Experiment, optional
        Its experiment (title, synthetic banner).
    next_experiment : dict, optional
        The design's :meth:`~tcamlab.design.DesignResult.to_dict`; by default the result's
        ``next_experiment``. Rendered as a "Next experiment" section when present.
    """
    title = getattr(experiment, "title", None) or result.experiment.get("title") or "Experiment"
    synthetic = getattr(experiment, "synthetic", None)
    meta = {
        "tool": str(result.experiment.get("tool", "")),
        "kind": result.kind,
        "experiment": str(result.experiment.get("path", "")),
        "runs": str(result.experiment.get("n_runs")),
        "verdict": result.verdict,
        "folds": str(result.settings.get("fold_scheme")),
        "bootstrap": f"{result.settings.get('n_boot')} resamples, seed {result.settings.get('seed')}",
    }
    for entry in result.experiment.get("inputs", []):
        meta[f"sha256 {entry['path']}"] = entry["sha256"]
    if next_experiment is None:
        next_experiment = getattr(result, "next_experiment", None)
    following = next_experiment_section(next_experiment)
    return Document(
        title=f"Gap diagnosis: {title}",
        subtitle=result.kind,
        sections=[diagnosis_section(result)] + ([following] if following is not None else []),
        metadata=meta,
        synthetic_banner=synthetic_banner(experiment) if synthetic else None,
    )


def _rmse_by_quantity(c) -> str:
    """``displacement 0.0123 -> 0.0045 mm, force 1.23 -> 0.45 mN`` (held-out, lab units)."""
    parts = []
    for q, v in (c.get("by_quantity") or {}).items():
        unit, fac = rmse_unit(v.get("unit", ""))
        parts.append(
            f"{q} {fmt(_scaled(v['heldout_rmse_before'], fac))} -> "
            f"{fmt(_scaled(v['heldout_rmse_after'], fac))} {unit}".rstrip()
        )
    return ", ".join(parts)


def _reason(result) -> str:
    """The verdict's reason, with a bare "clearly worse" replaced by the paired tests."""
    reason = result.reason
    phrase = ", and every other candidate is clearly worse"
    cut = reason.find(phrase)
    if cut < 0:
        return reason
    # what the verdict added after the phrase (a gap left, a domain edge) is kept, before the tests
    head, tail = reason[:cut], reason[cut + len(phrase) :]
    tests = stored_tests(result)
    if tests and all(t["clearly_worse"] for t in tests):
        if not tail:
            return (
                head + ", and every other candidate is clearly worse by a paired test on the withheld folds:"
            )
        return (
            head + tail + "; every other candidate is clearly worse by a paired test on the withheld folds:"
        )
    return (
        head
        + tail
        + "; paired tests against it on the withheld folds (not every other candidate is clearly worse):"
    )


def diagnosis_lines(result) -> list[str]:
    """The ``diagnose`` text output: verdict, reason with the paired tests, recalibrated
    parameters and the five best candidates, every RMSE with its unit, parameters in lab
    units."""
    doc = result.to_dict()
    rec = doc.get("recalibration") or {}
    named = doc.get("effect") or ", ".join(rec.get("named", []))
    lines = [f"verdict: {doc['verdict']}" + (f" ({named})" if named else ""), f"  {_reason(result)}"]
    lines += [f"  warning: {w}" for w in doc.get("warnings") or []]
    if "clearly worse" in result.reason:
        lines += [f"    {t}" for t in paired_lines(result)]
    lines += [f"  to tell apart, {k}: {v}" for k, v in (doc.get("separate_by") or {}).items()]
    for name in rec.get("named", []):
        p = rec["parameters"][name]
        unit, fac = _parameter_unit(name, p["unit"])
        sds = shift_text(p)
        value, lo, hi = fmt_interval(p["value"] * fac, p["ci95"][0] * fac, p["ci95"][1] * fac)
        lines.append(
            f"  recalibrated {p['symbol']} = {value} {unit} (95 % {lo} to "
            f"{hi}; {stated_label(p)} {fmt(p['stated'] * fac)}, {sds}{reading_text(p, fac, unit)})"
        )
    rows = ([doc["combination"]] if doc.get("combination") else []) + doc["ranking"][:5]
    for r in rows:
        unit = "x noise sd" if r["unit"] == "noise" else rmse_unit(r["unit"])[0]
        fac = 1.0 if r["unit"] == "noise" else rmse_unit(r["unit"])[1]
        line = (
            f"  {r['effect']:<36s} held-out RMSE {fmt(_scaled(r['heldout_rmse_before'], fac))} -> "
            f"{fmt(_scaled(r['heldout_rmse_after'], fac))} {unit} ({fmt_percent(r['shrinkage'])} shrinkage)"
        )
        if r["unit"] == "noise" and r.get("by_quantity"):
            line += f"; {_rmse_by_quantity(r)}"
        if r.get("parameters"):
            line += f"; {_params_text(r['parameters'])}"
        lines.append(line)
    return lines


def _parameter_unit(name: str, si_unit: str) -> tuple[str, float]:
    """Lab unit of a recalibrated parameter: the experiment file's (``youngs_modulus`` in GPa),
    else by its SI unit."""
    from tcamlab.units import PARAMETER_UNITS

    field = name.rsplit(".", 1)[-1]
    return PARAMETER_UNITS.get(field) or lab_unit(si_unit)
