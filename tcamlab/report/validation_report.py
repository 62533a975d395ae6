"""Turn a :class:`~tcamlab.validation.ValidationResult` into a report Document.

Renders only: every number comes from the result object.
"""

from __future__ import annotations

import numpy as np

from tcamlab.report.document import Cell, Document, Figure, Section, Table
from tcamlab.report.figures import new_figure

__all__ = ["validation_document", "parameter_table", "synthetic_banner", "input_table"]

_KIND_TEXT = {
    "static": "static oven test (thesis section 2.5.1): displacement against temperature, "
    "constant-G model (2.12) and G(T) model (2.13)",
    "dynamic": "voltage-step test (thesis section 2.5.2): displacement against time, "
    "model (2.14)-(2.19) with a Monte Carlo band from the parameter uncertainties",
    "sensing": "sensing pull test (thesis section 3.3): displacement and force predicted from "
    "resistance, (3.1)-(3.7) with F = S delta",
    "curvature": "camera curvature test (thesis section 4.3): segment curvatures predicted "
    "from R1, R2 by (4.1)",
}

_SI_UNITS = {
    "fiber_diameter": ("mm", 1e3),
    "fiber_length": ("mm", 1e3),
    "coil_length": ("mm", 1e3),
    "coil_diameter": ("mm", 1e3),
    "twists": ("turns", 1),
    "youngs_modulus": ("GPa", 1e-9),
    "thread_plies": ("-", 1),
    "max_volume_fraction": ("-", 1),
    "radial_cte": ("1/K", 1),
    "shear_modulus_slope": ("MPa/K", 1e-6),
    "load": ("g", 1e3),
    "ambient": ("degC", 1),
    "voltage": ("V", 1),
    "pulse": ("s", 1),
    "resistance": ("ohm", 1),
    "thermal_mass": ("J/K", 1),
    "heat_loss": ("W/K", 1),
    "damping": ("N s/m", 1),
    "initial_resistance": ("ohm", 1),
    "spring_constant": ("N/m", 1),
    "sensor_offset": ("mm", 1e3),
    "segment_lengths": ("mm", 1e3),
}

_RIG_FIELDS_BY_KIND = {
    "static": ("load", "ambient"),
    "dynamic": ("load", "ambient", "voltage", "pulse", "resistance", "thermal_mass", "heat_loss", "damping"),
    "sensing": ("ambient", "initial_resistance", "spring_constant"),
    "curvature": ("ambient", "spring_constant", "sensor_offset", "segment_lengths"),
}


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
        unit, factor = _SI_UNITS[name]
        rows.append(["sample", name, _fmt_value(value, factor), unit, experiment.provenance.get(name, "–")])
    for name in _RIG_FIELDS_BY_KIND[experiment.kind]:
        unit, factor = _SI_UNITS[name]
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
                        m["rmse"],
                        m["mae"],
                        m["max_abs"],
                        m["bias"],
                        m["nrmse"],
                        m["r2"],
                        m["n"],
                    ]
                )
    return Table(
        ["model", "quantity", "run", "RMSE", "MAE", "max |err|", "bias", "NRMSE", "R²", "n"],
        rows,
        caption="Error metrics (predicted − measured) in the quantity's unit",
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


def _run_label(name: str) -> str:
    """A run name (a file stem, so user text) made safe as a matplotlib legend label.

    matplotlib hides artists whose label starts with '_' from the legend; a
    leading space keeps such runs visible. Mathtext ('$...$') is switched off
    where the figures are drawn (see :func:`_figures`).
    """
    return " " + name if name.startswith("_") else name


def _figures(result) -> list[Figure]:
    """The report's figures, drawn with mathtext off: run names are file names and a
    '$' in one must be shown as it is, not parsed (or fail to parse) as TeX."""
    import matplotlib

    with matplotlib.rc_context({"text.parse_math": False}):
        return _draw_figures(result)


def _draw_figures(result) -> list[Figure]:
    kind = result.kind
    figs = []
    if kind == "static":
        fig, ax = new_figure()
        for p in result.predictions:
            t = p.data["temperature"].to_numpy()
            (line,) = ax.plot(
                t, p.data["displacement"] * 1e3, "o", ms=3, label=f"{_run_label(p.name)} measured"
            )
            ax.plot(
                t,
                p.predicted["G(T)"]["displacement"] * 1e3,
                "-",
                color=line.get_color(),
                label=f"{_run_label(p.name)} G(T) model",
            )
            ax.plot(
                t,
                p.predicted["constant-G"]["displacement"] * 1e3,
                "--",
                color=line.get_color(),
                alpha=0.7,
                label=f"{_run_label(p.name)} constant-G model",
            )
        ax.set_xlabel("temperature [°C]")
        ax.set_ylabel("displacement [mm]")
        ax.legend(fontsize=6, ncol=2)
        figs.append(
            Figure(
                fig,
                "Displacement against temperature: measured (points), G(T) "
                "model (solid) and constant-G model (dashed), as in thesis "
                "figure 2.7.",
                alt="static validation plot",
            )
        )
    elif kind == "dynamic":
        fig, ax = new_figure()
        for p in result.predictions:
            t = p.data["time"].to_numpy()
            if p.band is not None:
                ax.fill_between(t, p.band["lower"] * 1e3, p.band["upper"] * 1e3, alpha=0.15)
            (line,) = ax.plot(
                t, p.data["displacement"] * 1e3, ".", ms=1.5, label=f"{_run_label(p.name)} measured"
            )
            ax.plot(
                t,
                p.predicted["G(T)"]["displacement"] * 1e3,
                "-",
                color=line.get_color(),
                lw=1,
                label=f"{_run_label(p.name)} model",
            )
        ax.set_xlabel("time [s]")
        ax.set_ylabel("displacement [mm]")
        ax.legend(fontsize=6, ncol=2)
        figs.append(
            Figure(
                fig,
                "Displacement against time under the voltage pulse: "
                "measured (points), model (line) and 95% Monte Carlo band "
                "(shaded), as in thesis figure 2.9.",
                alt="dynamic plot",
            )
        )
    elif kind == "sensing":
        for q, unit, factor, label in (
            ("force", "N", 1.0, "Force"),
            ("displacement", "mm", 1e3, "Displacement"),
        ):
            fig, ax = new_figure()
            for p in result.predictions:
                r = p.data["resistance"].to_numpy()
                (line,) = ax.plot(r, p.data[q] * factor, "o", ms=2, label=f"{_run_label(p.name)} measured")
                ax.plot(
                    r,
                    p.predicted["thesis"][q] * factor,
                    "-",
                    color=line.get_color(),
                    lw=1,
                    label=f"{_run_label(p.name)} model",
                )
            ax.set_xlabel("resistance [ohm]")
            ax.set_ylabel(f"{q} [{unit}]")
            ax.legend(fontsize=6, ncol=2)
            figs.append(
                Figure(
                    fig,
                    f"{label} against resistance: measured and predicted (thesis figures 3.3/3.4).",
                    alt=f"sensing {q} plot",
                )
            )
    else:
        fig, ax = new_figure()
        for p in result.predictions:
            c = p.data["cable"].to_numpy() * 1e3
            for q, marker in (("kappa1", "o"), ("kappa2", "s")):
                (line,) = ax.plot(c, p.data[q] * 1e-3, marker, ms=3, label=f"{_run_label(p.name)} {q} camera")
                ax.plot(
                    c,
                    p.predicted["thesis"][q] * 1e-3,
                    "-",
                    color=line.get_color(),
                    lw=1,
                    label=f"{_run_label(p.name)} {q} model",
                )
        ax.set_xlabel("cable pull [mm]")
        ax.set_ylabel("curvature [1/mm]")
        ax.legend(fontsize=6, ncol=2)
        figs.append(
            Figure(
                fig,
                "Segment curvatures against cable pull: camera (markers) and "
                "model from R1, R2 (lines), as in thesis figure 4.8.",
                alt="curvature plot",
            )
        )
    # residuals of the primary model
    fig, ax = new_figure(6.4, 2.8)
    from tcamlab.validation import DISPLAY

    for q in result.quantities:
        name, factor = DISPLAY[q]
        for p in result.predictions:
            res = (p.predicted[result.primary][q] - p.data[q].to_numpy()) * factor
            ax.plot(np.arange(res.size), res, ".", ms=2, label=f"{_run_label(p.name)} {name}")
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set_xlabel("row")
    ax.set_ylabel("predicted − measured")
    ax.legend(fontsize=6, ncol=2)
    figs.append(Figure(fig, f"Residuals of the {result.primary} model by row.", alt="residual plot"))
    return figs


def _extras_section(result) -> Section | None:
    if result.kind == "sensing":
        rows = [
            [
                name,
                i["spring_constant_N_per_m"],
                i["spring_constant_source"],
                i["initial_resistance_ohm"],
                i["initial_resistance_source"],
                Cell(i["conditioning"], "pass" if i["conditioning"] == "ok" else "warn"),
                i["margin_1_minus_S_f11"],
            ]
            for name, i in result.extras["spring_constant"].items()
        ]
        return Section(
            "Spring constant and conditioning",
            tables=[
                Table(
                    ["run", "S [N/m]", "S from", "R0 [ohm]", "R0 from", "conditioning", "1 − S f11"],
                    rows,
                    caption="Spring constant used for each run (never identified on the run "
                    "it validates) and the margin of the sensing equation",
                )
            ],
        )
    if result.kind == "dynamic" and result.extras.get("monte_carlo"):
        mc = result.extras["monte_carlo"]
        rows = [[name, s["draws"], s["out_of_range"], s["coverage_95"]] for name, s in mc["runs"].items()]
        return Section(
            "Monte Carlo prediction band",
            paragraphs=[
                f"Parameters drawn: {', '.join(mc['parameters'])}; distribution: "
                f"{mc['distribution']} (keeps every parameter positive although the stated sd "
                f"of lambda exceeds its value)."
            ],
            tables=[
                Table(
                    ["run", "draws", "out of range", "coverage of the 95% band"],
                    rows,
                    caption="Monte Carlo band per run",
                )
            ],
        )
    return None


def validation_document(result, *, command: str | None = None) -> Document:
    """The validation report of one experiment as a :class:`Document`."""
    from tcamlab import __version__

    exp = result.experiment
    summary_tables = [t for t in (_threshold_table(result), _metrics_table(result)) if t]
    verdict = (
        ("all thresholds pass" if result.passed else "some thresholds FAIL")
        if result.checks
        else "no thresholds set"
    )
    summary = Section(
        "Summary",
        paragraphs=[f"Kind: {_KIND_TEXT[exp.kind]}.", f"{len(result.runs)} run(s); {verdict}."]
        + ([f"Notes: {exp.notes}"] if exp.notes else []),
        tables=summary_tables,
        notes=list(result.notes),
    )
    sections = [summary, Section("Model against measurement", figures=_figures(result))]
    extra = _extras_section(result)
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
