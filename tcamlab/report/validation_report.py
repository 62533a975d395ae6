"""Turn a :class:`~tcamlab.validation.ValidationResult` into a report Document.

Renders only: every number comes from the result object.
"""

from __future__ import annotations

import numpy as np

from tcamlab.config import EXPERIMENT_FILE
from tcamlab.io import input_files, sha256_file
from tcamlab.kinds import get_kind
from tcamlab.metrics import METRIC_LABELS, METRIC_NAMES, SANITY_CHECKS
from tcamlab.numbers import bare_name, fmt, fmt_r2, unit_label
from tcamlab.report.document import Cell, Document, Figure, Section, Table
from tcamlab.report.figures import legend_label, new_figure
from tcamlab.units import parameter_unit, quantity
from tcamlab.validation import relative_to

__all__ = ["validation_document", "parameter_table", "synthetic_banner", "input_table"]


def _fmt_value(value, factor):
    if value is None:
        return "–"
    if isinstance(value, (tuple, list)):
        return ", ".join(fmt(v * factor) for v in value)
    return fmt(value * factor, 6)


def parameter_source(experiment, name: str, run_sources: dict | None = None) -> str:
    """Where a parameter's value comes from, by its real source: the experiment file (named),
    the preset (named, with its reference), a tcamlab default, or the runs (``run_sources``:
    field -> text, e.g. R0 from the rows at rest, S identified) when no value is stated."""
    prov = experiment.provenance.get(name)
    if run_sources and name in run_sources and getattr(experiment.rig, name, 0) is None:
        return run_sources[name]
    if prov is None:
        return "–"
    if prov == EXPERIMENT_FILE:
        return f"experiment file {experiment.path.name}"
    if prov.startswith("tcamlab default") or experiment.preset is None:
        return prov
    return f"preset {experiment.preset}: {prov}"


def _run_sources(result) -> dict:
    """Field -> where each run took its value from, for rig fields not stated (R0, S)."""
    keys = {
        "initial_resistance": ("initial_resistance_source", "initial_resistances_source"),
        "spring_constant": ("spring_constant_source",),
    }
    out = {}
    for name, info_keys in keys.items():
        seen = {p.info[k] for p in result.predictions for k in info_keys if k in p.info}
        if seen:
            out[name] = "per run, " + "; ".join(sorted(str(x) for x in seen))
    return out


def parameter_table(experiment, result=None) -> Table:
    """Sample and rig parameters in lab units with the real source of each value."""
    run_sources = _run_sources(result) if result is not None else {}
    rows = []
    for name, value in experiment.sample.model_kwargs().items():
        unit, factor = parameter_unit(name)
        rows.append(["sample", name, _fmt_value(value, factor), unit, parameter_source(experiment, name)])
    for name in get_kind(experiment.kind).report_rig_fields:
        unit, factor = parameter_unit(name)
        value = getattr(experiment.rig, name)
        sd = experiment.rig.uncertainty.get(name)
        text = _fmt_value(value, factor)
        if sd is not None:
            text += f" ± {fmt(sd * factor, 3)}"
        rows.append(["rig", name, text, unit, parameter_source(experiment, name, run_sources)])
    return Table(
        ["group", "parameter", "value", "unit", "provenance"],
        rows,
        caption="Parameters (lab units) and where each value comes from",
    )


def input_table(runs, start=None) -> Table:
    """The run files (relative to ``start``, the experiment file's folder), rows and SHA-256."""

    def shown(path):
        return path.name if start is None else relative_to(path, start)

    return Table(
        ["file", "rows", "dropped rows", "SHA-256"],
        [
            [
                shown(path),
                len(r.data) if role == "run" else f"joined to {shown(r.path)}",
                _dropped(r, role),
                sha,
            ]
            for r in runs
            for role, path, sha in input_files(r)
        ],
        caption="Input files, relative to the experiment file (raw data is never modified)",
    )


def _dropped(run, role: str) -> str:
    """A run's dropped rows with why (blank cells, outside a joined file's span); '' on a joined file's line."""
    if role != "run":
        return ""
    why = ", ".join(f"{n} {reason}" for reason, n in run.dropped.items())
    return f"{run.n_dropped_total} ({why})" if why else "0"


def mapping_table(runs, start=None) -> Table:
    """The ``[columns]`` mapping each run was read with: file header -> canonical column, unit, scale, offset."""
    rows = []
    for r in runs:
        name = r.path.name if start is None else relative_to(r.path, start)
        for canon, e in r.columns.items():
            source = f"{e['file']}: {e['from']}" if "file" in e else str(e["from"])
            rows.append([name, canon, source, e["unit"], f"{e['scale']:g}", f"{e['offset']:g}"])
    return Table(
        ["run", "column", "from", "unit", "scale", "offset"],
        rows,
        caption="[columns] mapping: value = convert(raw * scale + offset, unit)",
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
    # the experiment file's command leaves out what a diagnosis must not see; say so, and
    # where the rest is, without saying whether anything was left out (that would tell)
    text += (
        " The command leaves out any withheld options (--effect, --parameter-error,"
        " --noisy-zero); the virtual rig keeps the full command in its truth file"
        " (truth/NAME.truth.json), which this report does not read."
    )
    return text


def _shown(m: dict, key: str):
    """A metric as the table shows it: a bias below 1e-9 of the RMSE is rounding (a whole-run
    zero, ``[validation] zero = "whole-run"``, makes the bias 0 by construction), shown as 0,
    not as -1.8e-17."""
    v = m[key]
    if key == "bias" and v is not None and abs(v) <= 1e-9 * abs(m.get("rmse") or 0.0):
        return 0.0
    return v


UNADJUSTED = ("rmse", "bias", "r2")
"""Metrics shown again without the whole-run zeros (under the rest rule), each beside its own."""


def _metric_columns(result) -> list[tuple[str, str]]:
    """(key, source) of the metric columns: ``"m"`` the metric, ``"u"`` its unadjusted value
    (whole-run zeros only, right after it), ``"sd"`` the bias's sd from the zeros."""
    cols = []
    for k in METRIC_NAMES:
        cols.append((k, "m"))
        if result.unadjusted is not None and k in UNADJUSTED:
            cols.append((k, "u"))
        if k == "bias":
            cols.append(("bias_sd", "sd"))
    return cols


def _metrics_row(result, variant: str, q: str, run: str, m: dict) -> list:
    """One row of the metrics table: the metrics (each unadjusted one beside it with a
    whole-run zero), the bias's sd from the zero, n."""
    raw = {}
    if result.unadjusted is not None:
        block = result.unadjusted[variant][q]
        raw = block["pooled"] if run == "pooled" else block["runs"][run]
    cells = []
    for k, src in _metric_columns(result):
        if src == "sd":
            cells.append(m.get("bias_sd"))
        else:
            d = m if src == "m" else raw
            cells.append(fmt_r2(d[k]) if k == "r2" else (_shown(d, k) if src == "m" else d[k]))
    label = variant + (" (primary)" if variant == result.primary else "")
    return [label, _quantity_label(q), run, *cells, m["n"]]


def _metrics_table(result) -> Table:
    rows = []
    for variant in result.variants:
        for q, block in result.metrics[variant].items():
            for run, m in list(block["runs"].items()) + [("pooled", block["pooled"])]:
                rows.append(_metrics_row(result, variant, q, run, m))
    names = {"m": "{}", "u": "{} unadjusted", "sd": "bias sd (zero)"}
    labels = [names[src].format(METRIC_LABELS.get(k, k)) for k, src in _metric_columns(result)]
    caption = (
        "Error metrics (predicted − measured) in the quantity's unit, each model after its own zero; "
        "bias sd (zero): the bias's standard deviation from the zeros' uncertainty"
    )
    if result.unadjusted is not None:
        caption += (
            '. [validation] zero = "whole-run": bias and R² exclude each model\'s mean error (the '
            "bias is 0 by construction); each unadjusted column, beside its metric, takes the zeros "
            "from the rows at rest, else as logged"
        )
    return Table(["model", "quantity", "run", *labels, "n"], rows, caption=caption)


def _quantity_label(q: str) -> str:
    """``displacement_mm`` -> ``displacement [mm]``: the unit of RMSE, MAE, max |err| and bias."""
    unit = unit_label(q)
    return f"{bare_name(q)} [{unit}]" if unit else q


STATUS_TEXT = {
    "passed": "PASSED: every acceptance threshold of the experiment file is met",
    "failed": "FAILED: at least one acceptance threshold is exceeded (table below)",
    "no limits set": "NO LIMITS SET: the experiment file has no [thresholds] that apply, so nothing "
    "was checked against a limit (neutral; not a pass)",
}
"""The status line of a report's first section."""


def status_section(result) -> Section:
    """The report's first screen: the status, every sanity warning with its numbers, and
    which sanity checks ran."""
    warned = {w.check for w in result.warnings}
    rows = [
        [key, text, Cell(f"WARNING ({sum(w.check == key for w in result.warnings)})", "warn")]
        if key in warned
        else [key, text, Cell("ok", "pass")]
        for key, text in SANITY_CHECKS.items()
    ]
    table = Table(
        ["check", "requires", "result"],
        rows,
        caption="Sanity checks run on every validation (primary model); a warning never changes the "
        "status, --strict turns it into exit status 1",
    )
    n = len(result.warnings)
    heading = f"Status: {result.status}; " + (
        f"{n} sanity warning{'s' if n > 1 else ''}" if n else "no sanity warning"
    )
    return Section(
        heading,
        paragraphs=[f"{STATUS_TEXT[result.status]}."],
        warnings=[w.message for w in result.warnings],
        tables=[table] + ([t] if (t := _threshold_table(result)) else []),
    )


ZERO_SOURCES = {
    "rest rows": "{rows} rows at rest",
    "logged zero": "logged zero (sd over {rows} row(s))",
    "whole run": "whole run ({rows} rows)",
}
"""How the zeros table says where a zero comes from."""


def _zeros_table(result) -> Table | None:
    """Each model's nuisance zero per run, with its standard error and 95% interval."""
    rows = []
    by_model = result.zeros_dict()["by_model"]
    for variant in result.variants:
        for run, zeros in by_model.get(variant, {}).items():
            for q, z in zeros.items():
                lo, hi = z["ci95"]
                ci = "–" if lo is None else f"{fmt(lo, 3)} to {fmt(hi, 3)}"
                where = ZERO_SOURCES.get(z["source"], z["source"]).format(rows=z["rows"])
                rows.append([variant, run, _quantity_label(q), z["value"], z["stderr"], ci, where])
    if not rows:
        return None
    return Table(
        ["model", "run", "quantity", "zero", "standard error", "95% CI", "estimated from"],
        rows,
        caption="Nuisance zeros (quantity's unit), each model its own under one rule: the mean of "
        "measured − predicted over the rows at rest, else the logged zero (standard error: the noise "
        "sd over the square root of the rest rows used), or over the whole run on request",
    )


def _threshold_table(result) -> Table | None:
    if not result.checks:
        return None
    rows = [
        [
            c.key,
            c.quantity,
            fmt_r2(c.value) if c.metric == "r2" else c.value,
            f"{c.comparison} {fmt(c.limit)}",
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


def _residual_x(result) -> str:
    """The physical input residuals are drawn against: the kind's ``x_column`` where every run
    logs it, else the first other input (e.g. resistance for a pull test without time)."""
    kind = get_kind(result.kind)
    if all(kind.x_column in p.data for p in result.predictions):
        return kind.x_column
    return next(c for c in kind.inputs if all(c in p.data for p in result.predictions))


def _draw_figures(result) -> list[Figure]:
    figs = get_kind(result.kind).figures(result)
    figs.append(_residual_figure(result))
    return figs


def _residual_figure(result) -> Figure:
    """Residuals of the primary model against the physical input, one panel per quantity with
    its unit (a force in N and a displacement in mm never share an axis)."""
    from tcamlab.report.figures import report_style

    x = _residual_x(result)
    xq = quantity(x)
    n = len(result.quantities)
    fig, _ = new_figure(6.4, 1.2 + 1.7 * n)
    fig.clear()
    with report_style():
        axes = np.atleast_1d(fig.subplots(n, 1, sharex=True))
    for ax, q in zip(axes, result.quantities):
        name, factor = quantity(q).column, quantity(q).factor
        for p in result.predictions:
            res = (p.predicted[result.primary][q] - p.data[q].to_numpy()) * factor
            ax.plot(p.data[x].to_numpy() * xq.factor, res, ".", ms=3, label=legend_label(p.name))
        ax.axhline(0.0, color="0.3", lw=0.8)
        unit = unit_label(name)
        ax.set_ylabel(f"{bare_name(name)} residual" + (f" [{unit}]" if unit else ""))
    axes[-1].set_xlabel(f"{xq.name} [{unit_label(xq.column) or xq.column_unit}]")
    if len(result.predictions) <= 6:
        axes[0].legend(
            fontsize=7,
            ncol=min(3, len(result.predictions)),
            loc="lower center",
            bbox_to_anchor=(0.5, 1.0),
            frameon=False,
        )
    caption = (
        f"Residuals (predicted − measured, after each run's zero) of the {result.primary} model "
        f"against {xq.name}, one panel per quantity."
    )
    return Figure(fig, caption, alt="residual plot")


def validation_document(result, *, command: str | None = None) -> Document:
    """The validation report of one experiment as a :class:`Document`."""
    from tcamlab import __version__

    exp = result.experiment
    summary_tables = [t for t in (_metrics_table(result), _zeros_table(result)) if t]
    summary = Section(
        "Summary",
        paragraphs=[f"Kind: {get_kind(exp.kind).description}.", f"{len(result.runs)} run(s)."]
        + ([f"Notes: {exp.notes}"] if exp.notes else []),
        tables=summary_tables,
        notes=list(result.notes),
    )
    sections = [
        status_section(result),
        summary,
        Section("Model against measurement", figures=_figures(result)),
    ]
    extra = get_kind(result.kind).extras_section(result)
    if extra:
        sections.append(extra)
    sections.append(Section("Parameters", tables=[parameter_table(exp, result)]))
    sections.append(
        Section(
            "Inputs",
            tables=[input_table(result.runs, exp.path.parent), mapping_table(result.runs, exp.path.parent)],
        )
    )
    metadata = {"tool": f"tcamlab {__version__}", "experiment file": exp.path.name, "kind": exp.kind}
    metadata["sha256 " + exp.path.name] = sha256_file(exp.path)
    if command:
        metadata["command"] = command
    for r in result.runs:
        for _, path, sha in input_files(r):
            metadata[f"sha256 {relative_to(path, exp.path.parent)}"] = sha
    return Document(
        title=exp.title,
        subtitle=f"Validation report: {exp.name}",
        sections=sections,
        metadata=metadata,
        synthetic_banner=synthetic_banner(exp),
    )
