"""Turn a :class:`~tcamlab.validation.ValidationResult` into a report Document.

Renders only: every number comes from the result object.
"""

from __future__ import annotations

import numpy as np

from tcamlab.kinds import get_kind
from tcamlab.metrics import METRIC_LABELS, METRIC_NAMES
from tcamlab.report.document import Cell, Document, Figure, Section, Table
from tcamlab.report.figures import legend_label, new_figure
from tcamlab.units import parameter_unit, quantity

__all__ = ["validation_document", "parameter_table", "synthetic_banner", "input_table"]


def _fmt_value(value, factor):
    if value is None:
        return "–"
    if isinstance(value, (tuple, list)):
        return ", ".join(f"{v * factor:.4g}" for v in value)
    return f"{value * factor:.6g}"


def parameter_table(experiment) -> Table:
    """Sample and rig parameters in lab units with their provenance."""
    rows = []
    for name, value in experiment.sample.model_kwargs().items():
        unit, factor = parameter_unit(name)
        rows.append(["sample", name, _fmt_value(value, factor), unit, experiment.provenance.get(name, "–")])
    for name in get_kind(experiment.kind).report_rig_fields:
        unit, factor = parameter_unit(name)
        value = getattr(experiment.rig, name)
        sd = experiment.rig.uncertainty.get(name)
        text = _fmt_value(value, factor)
        if sd is not None:
            text += f" ± {sd * factor:.3g}"
        rows.append(["rig", name, text, unit, experiment.provenance.get(name, "–")])
    return Table(
        ["group", "parameter", "value", "unit", "provenance"],
        rows,
        caption="Parameters (lab units) and where each value comes from",
    )


def input_table(runs) -> Table:
    return Table(
        ["file", "rows", "dropped rows", "SHA-256"],
        [[r.path.name, len(r.data), r.n_dropped, r.sha256] for r in runs],
        caption="Input files (raw data is never modified)",
    )


def synthetic_banner(experiment) -> str | None:
    syn = experiment.synthetic
    if not syn:
        return None
    text = (
        f"SYNTHETIC DATA: made by {syn.get('generator', '?')} with seed "
        f"{syn.get('seed', '?')}; not a measurement."
    )
    if syn.get("command"):
        text += f" Command: {syn['command']}"
    return text


def _metrics_table(result) -> Table:
    rows = []
    for variant in result.variants:
        for q, block in result.metrics[variant].items():
            for run, m in list(block["runs"].items()) + [("pooled", block["pooled"])]:
                rows.append(
                    [
                        variant + (" (primary)" if variant == result.primary else ""),
                        q,
                        run,
                        *(m[k] for k in METRIC_NAMES),
                        m["n"],
                    ]
                )
    return Table(
        ["model", "quantity", "run", *(METRIC_LABELS[k] for k in METRIC_NAMES), "n"],
        rows,
        caption="Error metrics (predicted − measured) in the quantity's unit",
    )


def _zeros_table(result) -> Table | None:
    """Each run's estimated nuisance zero, with its standard error and 95% interval."""
    rows = []
    for run, zeros in result.zeros_dict()["runs"].items():
        for q, z in zeros.items():
            lo, hi = z["ci95"]
            ci = "–" if lo is None else f"{lo:.3g} to {hi:.3g}"
            where = (
                f"{z['rows']} rows at rest" if z["source"] == "rest rows" else f"whole run ({z['rows']} rows)"
            )
            rows.append([run, q, z["value"], z["stderr"], ci, where])
    if not rows:
        return None
    return Table(
        ["run", "quantity", "zero", "standard error", "95% CI", "estimated from"],
        rows,
        caption="Nuisance zeros (quantity's unit): each run's zero, the mean of measured − predicted "
        "at rest (else over the run), subtracted from the measurement before the metrics",
    )


def _threshold_table(result) -> Table | None:
    if not result.checks:
        return None
    rows = [
        [
            c.key,
            c.quantity,
            c.value,
            f"{c.comparison} {c.limit:g}",
            Cell("pass", "pass") if c.passed else Cell("FAIL", "fail"),
        ]
        for c in result.checks
    ]
    return Table(
        ["threshold", "quantity", "value", "limit", "result"],
        rows,
        caption=f"Acceptance thresholds on the pooled metrics of the {result.primary} model",
    )


def _figures(result) -> list[Figure]:
    """The report's figures, drawn with mathtext off: run names are file names and a
    '$' in one must be shown as it is, not parsed (or fail to parse) as TeX."""
    import matplotlib

    with matplotlib.rc_context({"text.parse_math": False}):
        return _draw_figures(result)


def _draw_figures(result) -> list[Figure]:
    figs = get_kind(result.kind).figures(result)
    # residuals of the primary model
    fig, ax = new_figure(6.4, 2.8)
    for q in result.quantities:
        name, factor = quantity(q).column, quantity(q).factor
        for p in result.predictions:
            res = (p.predicted[result.primary][q] - p.data[q].to_numpy()) * factor
            ax.plot(np.arange(res.size), res, ".", ms=2, label=f"{legend_label(p.name)} {name}")
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set_xlabel("row")
    ax.set_ylabel("predicted − measured")
    ax.legend(fontsize=6, ncol=2)
    figs.append(Figure(fig, f"Residuals of the {result.primary} model by row.", alt="residual plot"))
    return figs


def validation_document(result, *, command: str | None = None) -> Document:
    """The validation report of one experiment as a :class:`Document`."""
    from tcamlab import __version__

    exp = result.experiment
    summary_tables = [
        t for t in (_threshold_table(result), _metrics_table(result), _zeros_table(result)) if t
    ]
    verdict = (
        ("all thresholds pass" if result.passed else "some thresholds FAIL")
        if result.checks
        else "no thresholds set"
    )
    summary = Section(
        "Summary",
        paragraphs=[f"Kind: {get_kind(exp.kind).description}.", f"{len(result.runs)} run(s); {verdict}."]
        + ([f"Notes: {exp.notes}"] if exp.notes else []),
        tables=summary_tables,
        notes=list(result.notes),
    )
    sections = [summary, Section("Model against measurement", figures=_figures(result))]
    extra = get_kind(result.kind).extras_section(result)
    if extra:
        sections.append(extra)
    sections.append(Section("Parameters", tables=[parameter_table(exp)]))
    sections.append(Section("Inputs", tables=[input_table(result.runs)]))
    metadata = {"tool": f"tcamlab {__version__}", "experiment file": exp.path.name, "kind": exp.kind}
    if command:
        metadata["command"] = command
    for r in result.runs:
        metadata[f"sha256 {r.path.name}"] = r.sha256
    return Document(
        title=exp.title,
        subtitle=f"Validation report: {exp.name}",
        sections=sections,
        metadata=metadata,
        synthetic_banner=synthetic_banner(exp),
    )
