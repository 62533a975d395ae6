"""Report section and document of a gap diagnosis (:class:`tcamlab.diagnosis.DiagnosisResult`)."""

from __future__ import annotations

import math

from .document import Document, Figure, Section, Table
from .figures import new_figure

__all__ = ["diagnosis_section", "diagnosis_document", "verdict_text"]


def _pct(x) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{100 * x:.0f} %"


def _num(x, fmt="{:.3g}") -> str:
    return "–" if x is None or not math.isfinite(x) else fmt.format(x)


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
        return lead + _miscalibrated_text(result.recalibration or {})
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
            f"{_pct(combo['shrinkage'])} (95 % interval {_pct(combo['shrinkage_ci95'][0])} to "
            f"{_pct(combo['shrinkage_ci95'][1])}) and close {_pct(combo['fraction_closed'])} of "
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
        f"tested on the withheld one, it cuts the RMSE by {_pct(best.shrinkage)} (95 % interval "
        f"{_pct(best.shrinkage_ci95[0])} to {_pct(best.shrinkage_ci95[1])}) and closes "
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
        text += " Every other candidate is clearly worse on withheld data."
    return lead + text


def _miscalibrated_text(rec: dict) -> str:
    """The ``miscalibrated`` verdict: the recalibrated parameters, their intervals and shifts."""
    parts = []
    for name in rec.get("named", []):
        p = rec["parameters"][name]
        shift = p["shift_in_stated_sds"]
        sds = f"{shift:+.1f} stated sds" if shift is not None else f"{p['shift_in_prior_sds']:+.1f} prior sds"
        parts.append(
            f"{p['symbol']} = {p['value']:.4g} {p['unit']} (95 % interval {p['ci95'][0]:.4g} to "
            f"{p['ci95'][1]:.4g}; stated {p['stated']:.4g}, {sds})"
        )
    return (
        " The gap closes by recalibrating the stated parameters, not by adding physics: "
        + "; ".join(parts)
        + f". Fitted on the other runs and tested on the withheld one, recalibration closes "
        f"{_pct(rec.get('fraction_closed'))} of the gap above the noise floor, and no candidate "
        "effect fitted together with it does clearly better."
    )


def _figure(draw, caption, w=6.4, h=3.4, **kw):
    fig, ax = new_figure(w, h)
    draw(ax, **kw)
    return Figure(fig, caption, alt=caption)


def diagnosis_section(result) -> Section:
    """A report section: verdict, ranking, forest plot, residuals by regime, overlays."""
    unit = result.ranking[0].unit if result.ranking else ""
    rows = []
    for c in result.ranking:
        params = "; ".join(
            f"{name} = {_num(p['value'])} [{_num(p['ci95'][0])}, {_num(p['ci95'][1])}] {p['unit']}"
            for name, p in c.parameters.items()
        )
        rows.append(
            [
                c.effect,
                _num(c.heldout_rmse_before, "{:.4g}"),
                _num(c.heldout_rmse_after, "{:.4g}"),
                _pct(c.shrinkage),
                f"{_pct(c.shrinkage_ci95[0])} to {_pct(c.shrinkage_ci95[1])}",
                _pct(c.fraction_closed),
                _num(c.aic - result.baseline["aic"], "{:.1f}"),
                _num(c.bic - result.baseline["bic"], "{:.1f}"),
                params,
            ]
        )
    combo = getattr(result, "combination", None)
    if combo is not None:
        params = "; ".join(
            f"{name} = {_num(p['value'])} [{_num(p['ci95'][0])}, {_num(p['ci95'][1])}] {p['unit']}"
            for name, p in combo["parameters"].items()
        )
        rows.insert(
            0,
            [
                " + ".join(combo["effects"]) + " (pair)",
                _num(combo["heldout_rmse_before"], "{:.4g}"),
                _num(combo["heldout_rmse_after"], "{:.4g}"),
                _pct(combo["shrinkage"]),
                f"{_pct(combo['shrinkage_ci95'][0])} to {_pct(combo['shrinkage_ci95'][1])}",
                _pct(combo["fraction_closed"]),
                _num(combo["aic"] - result.baseline["aic"], "{:.1f}"),
                _num(combo["bic"] - result.baseline["bic"], "{:.1f}"),
                params,
            ],
        )
    ranking = Table(
        [
            "effect",
            f"held-out RMSE before [{unit}]",
            f"held-out RMSE after [{unit}]",
            "shrinkage",
            "95 % interval",
            "gap closed",
            "dAIC",
            "dBIC",
            "fitted parameters (95 % CI)",
        ],
        rows,
        caption="Candidate effects, best first (held-out = leave one run out)",
    )
    reg_rows = [
        [
            r["group"],
            r["regime"],
            r["n"],
            _num(r["rmse_over_noise"], "{:.2f}"),
            _num(r["bias_over_noise"], "{:+.2f}"),
            _pct(r["share"]),
        ]
        for r in result.regimes
    ]
    regimes = Table(
        ["grouping", "regime", "n", "RMSE / noise", "bias / noise", "share of sq. error"],
        reg_rows,
        caption="Where the baseline misses (residuals in noise-floor units)",
    )
    nf_rows = []
    for q, v in result.noise_floor["by_quantity"].items():
        btw = (
            result.noise_floor["between_runs"].get(q, {})
            if result.noise_floor["between_runs"].get("available")
            else {}
        )
        nf_rows.append(
            [
                q,
                v["unit"],
                _num(v["sigma"], "{:.3g}"),
                _num(btw.get("sd"), "{:.3g}"),
                _num(result.baseline["by_quantity"][q]["rmse"], "{:.3g}"),
            ]
        )
    noise = Table(
        ["quantity", "unit", "noise floor (2nd difference)", "between-run sd", "baseline RMSE"],
        nf_rows,
        caption="Noise floor estimated from the data",
    )
    figures = []
    for group in result._series.get("regime_groups", []):
        figures.append(_figure(result.plot_residuals, f"Baseline residuals by {group}", group=group))
    if result.ranking:
        figures.append(
            _figure(
                result.plot_forest,
                "Held-out RMSE shrinkage per candidate",
                h=0.5 + 0.45 * len(result.ranking),
            )
        )
    n_runs = len(result._series.get("runs", []))
    for i in range(min(n_runs, 2)):
        for q in result.noise_floor["quantities"]:
            figures.append(
                _figure(
                    result.plot_overlay,
                    f"Run {i + 1}: {q}, measured, thesis model and best candidate (fitted on all runs)",
                    run=i,
                    quantity=q,
                )
            )
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
            "of the residuals; each candidate effect fitted on all runs but one and scored on "
            "the withheld run; intervals from a bootstrap over withheld runs.",
        ],
        tables=[ranking, regimes, noise],
        figures=figures,
        notes=notes,
    )


def diagnosis_document(result, experiment=None) -> Document:
    """A full report Document of a diagnosis."""
    title = getattr(experiment, "title", None) or result.experiment.get("title") or "Experiment"
    synthetic = getattr(experiment, "synthetic", None)
    meta = {
        "kind": result.kind,
        "experiment": str(result.experiment.get("path", "")),
        "runs": str(result.experiment.get("n_runs")),
        "verdict": result.verdict,
        "folds": str(result.settings.get("fold_scheme")),
        "bootstrap": f"{result.settings.get('n_boot')} resamples, seed {result.settings.get('seed')}",
    }
    return Document(
        title=f"Gap diagnosis: {title}",
        subtitle=result.kind,
        sections=[diagnosis_section(result)],
        metadata=meta,
        synthetic_banner="Synthetic data (virtual rig)." if synthetic else None,
    )
