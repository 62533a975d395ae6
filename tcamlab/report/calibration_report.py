"""The calibration report (``calibration.html`` / ``calibration.pdf``) as a :class:`Document`.

Renders only: every number comes from the :class:`~tcamlab.calibration.CalibrationResult`
(its per-run :attr:`~tcamlab.calibration.CalibrationResult.curves` for the overlays
and residuals, each estimate's ``profile_points`` for the profile plots). The
first section is the provenance (tool version, command, every input file with
its path relative to the first experiment file's folder and its SHA-256), so a
reader sees where the numbers come from before the numbers.

Numbers: each parameter row is printed in the experiment file's lab unit (a
power of ten moved into the unit when the value is far from 1) with the
decimals that show two significant digits of its posterior sd.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

from tcamlab.report.calibration_figures import (
    correlation_figure,
    overlay_figure,
    parameter_display,
    quantity_display,
    residual_figure,
    stride,
)
from tcamlab.report.document import Document, Figure, Section, Table
from tcamlab.report.validation_report import synthetic_banner

__all__ = ["calibration_document", "parameter_rows", "figure_files", "stated_shift_warnings"]

DASH = "\u2013"


def _decimals(sd: float) -> int:
    """Decimals that show two significant digits of ``sd`` (0 to 10)."""
    if not (sd > 0 and math.isfinite(sd)):
        return 4
    return int(min(max(1 - math.floor(math.log10(sd)), 0), 10))


def _fixed(x: float | None, d: int) -> str:
    if x is None or not math.isfinite(x):
        return DASH
    text = f"{x:.{d}f}"
    return "0" if float(text) == 0 else text.replace("-", "\u2212")


def _signed(x: float | None) -> str:
    """``+0.12`` / ``−1.50``; a value that rounds to zero is ``0.00``, never ``−0.00``."""
    if x is None or not math.isfinite(x):
        return DASH
    text = f"{x:+.2f}"
    return "0.00" if float(text) == 0 else text.replace("-", "\u2212")


def _interval(lo: float, hi: float, d: int, open_=(False, False), unsure=(False, False)) -> str:
    left = ("\u2264 " if open_[0] else "") + _fixed(lo, d) + (" ?" if unsure[0] else "")
    right = _fixed(hi, d) + (" \u2191" if open_[1] else "") + (" ?" if unsure[1] else "")
    return f"{left} to {right}"


UNSURE_Z = 0.1
"""A profile bound whose signed root is further than this from 1.96 was not reached."""


def unsure_bounds(p) -> tuple[bool, bool]:
    """Whether each profile bound is not where z = -1.96 / +1.96: the search stopped
    (its step limit) before reaching it, and the box edge was not reached either."""
    from tcamlab.calibration.fit import Z95

    out = []
    for bound, is_open in zip(p.profile_95, p.profile_open):
        zs = [abs(z) for v, z in p.profile_points if v == bound]
        out.append(bool(zs) and not is_open and min(abs(z - Z95) for z in zs) > UNSURE_Z)
    return out[0], out[1]


def _prior(p) -> str:
    source = "stated" if p.stated_sd is not None else "default"
    shape = "log-normal" if p.positive else "normal"
    return f"{shape} {100 * p.prior_sd_rel:.3g}\u00a0% ({source})"


def _name(p) -> str:
    """``thermal mass``, or ``thermal mass (EXP)`` for a rig parameter of several experiments."""
    exp, _, _ = p.name.rpartition(".")
    return p.field.replace("_", " ") + (f" ({exp})" if exp else "")


def parameter_rows(result) -> list[list[str]]:
    """Rows of the parameter table, lab units, one per calibrated parameter."""
    rows = []
    for p in result.parameters:
        unit, f = parameter_display(p)
        d = _decimals(p.posterior_sd * f)
        stated = f"{p.stated * f:.6g}" + ("" if p.stated_in_file else " (from the logs)")
        rows.append(
            [
                p.symbol,
                _name(p),
                unit,
                stated.replace("-", "\u2212"),
                DASH if p.stated_sd is None else f"{p.stated_sd * f:.6g}",
                _prior(p),
                _fixed(p.value * f, d),
                _interval(p.laplace_95[0] * f, p.laplace_95[1] * f, d),
                _interval(p.profile_95[0] * f, p.profile_95[1] * f, d, p.profile_open, unsure_bounds(p)),
                _signed(p.shift_in_stated_sds),
                p.identification,
            ]
        )
    return rows


def _parameter_table(result) -> Table:
    return Table(
        [
            "symbol",
            "parameter",
            "unit",
            "stated",
            "stated sd",
            "prior used",
            "calibrated",
            "Laplace 95 %",
            "profile 95 %",
            "shift [stated sds]",
            "identified",
        ],
        parameter_rows(result),
        caption=(
            "Calibrated parameters in lab units. Shift = (calibrated \u2212 stated) / stated sd. "
            "Identified: pinned (relative posterior sd at most 10 % and at most 0.158 of the prior's, "
            "so the calibrated value beats the stated one in at least 90 % of cases), "
            "constrained (the logs at least halve the prior sd) or prior (rests on its prior). \u2264 or \u2191 marks a profile bound "
            "at the edge of the search box (the data never raised chi-square by 3.84 there); ? a "
            "bound where the profile search stopped before |z| reached 1.96 (see the notes)."
        ),
    )


def stated_shift_warnings(result) -> list[str]:
    """A warning for each parameter calibrated more than 3 stated sds from its stated value
    (:func:`tcamlab.metrics.stated_shift_warning`), with the numbers in lab units."""
    from tcamlab.metrics import stated_shift_warning
    from tcamlab.units import PARAMETER_UNITS

    out = []
    for p in result.parameters:
        unit, fac = PARAMETER_UNITS.get(p.field, (p.unit, 1.0))
        sd = None if p.stated_sd is None else p.stated_sd * fac
        w = stated_shift_warning(
            f"{p.where}.{p.key} ({p.symbol})", p.value * fac, p.stated * fac, sd, unit, "calibrated"
        )
        if w is not None:
            out.append(w.message)
    return out


def _unsure_notes(result) -> list[str]:
    """A warning for each profile bound the search did not reach."""
    out = []
    for p in result.parameters:
        for side, unsure, bound in zip(("lower", "upper"), unsure_bounds(p), p.profile_95):
            if unsure:
                z = min((z for v, z in p.profile_points if v == bound), key=lambda z: abs(abs(z) - 1.96))
                out.append(
                    f"The {side} profile bound of {p.symbol} is not a 95 % bound: the search stopped "
                    f"where z = {z:+.2f}, not \u00b11.96 (see its profile plot); the 95 % bound lies "
                    "further out."
                )
    return out


def _quality_table(result) -> Table:
    rows = []
    for q in result.fit:
        unit, f = quantity_display(q.quantity)
        rows.append(
            [
                q.experiment,
                q.quantity,
                f"{q.sigma * f:.3g} {unit}",
                f"{q.rmse_over_sigma_stated:.2f}",
                f"{q.rmse_over_sigma_calibrated:.2f}",
                q.n,
            ]
        )
    return Table(
        ["experiment", "quantity", "noise sd", "RMS / noise, stated", "RMS / noise, calibrated", "n"],
        rows,
        caption=(
            "Fit quality: RMS of measured \u2212 predicted over the noise floor (second "
            "differences); stated with the logged zeros, calibrated with the fitted zeros. "
            "About 1 is a fit to within noise."
        ),
    )


def _zeros_table(result) -> Table | None:
    if not result.zeros:
        return None
    rows = []
    for z in result.zeros:
        unit, f = quantity_display(z.quantity)
        d = _decimals(z.sd * f)
        rows.append(
            [
                z.experiment,
                z.run,
                z.quantity,
                unit,
                _fixed(z.value * f, d),
                _fixed(z.sd * f, d),
                _interval(z.interval_95[0] * f, z.interval_95[1] * f, d),
            ]
        )
    return Table(
        ["experiment", "run", "quantity", "unit", "zero", "sd", "95 % interval"],
        rows,
        caption=(
            "Nuisance zeros: each run's offset of measured \u2212 predicted at the calibrated "
            "values (the logged zero's error), with its interval."
        ),
    )


def _relative(path: str, base: Path) -> str:
    p = Path(path)
    try:
        return Path(os.path.relpath(p.resolve(), base.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        return p.name


def _provenance_section(result, command: str | None) -> Section:
    from tcamlab import __version__

    base = Path(result.experiments[0]).parent
    lines = [f"Tool: tcamlab {__version__}."]
    if command:
        lines.append(f"Command: {command}")
    lines.append(
        f"Input files (paths relative to the folder of {Path(result.experiments[0]).name}) and their SHA-256:"
    )
    for entry in result.inputs:
        lines.append(f"{entry['role']} {_relative(entry['path'], base)}: {entry['sha256']}")
    return Section("Provenance", paragraphs=lines)


def _figure(fig, caption: str) -> Figure:
    return Figure(fig, caption, alt=caption)


def _thinned(curves) -> str:
    k = max(stride(len(next(iter(c.measured.values())))) for c in curves)
    if k == 1:
        return ""
    return (
        f" Long log: measured points drawn as the lowest and highest of each {2 * k}-row bin, model "
        f"curves every {k}th row (figure only)."
    )


def _experiment_figures(result, name: str) -> list[Figure]:
    curves = [c for c in result.curves if c.experiment == name]
    if not curves:
        return []
    quantities = [q.quantity for q in result.fit if q.experiment == name]
    sigma = {q.quantity: q.sigma for q in result.fit if q.experiment == name}
    x = curves[0].x
    zeroed = any(c.zero for c in curves)
    figs = []
    for q in quantities:
        zero = " plus each run's fitted zero" if any(q in c.zero for c in curves) else ""
        figs.append(
            _figure(
                overlay_figure([c for c in curves if q in c.measured], q),
                f"{name}: measured {q} (points) against the model at the stated values (dashed) "
                f"and at the calibrated values{zero} (solid), every run that logs it." + _thinned(curves),
            )
        )
    figs.append(
        _figure(
            residual_figure(curves, quantities, sigma),
            f"{name}: residuals (measured \u2212 predicted) against {x}, all runs; left at the "
            "stated values"
            + (" with the logged zeros" if zeroed else "")
            + ", right at the calibrated values"
            + (" with the fitted zeros" if zeroed else "")
            + ". Grey band: \u00b12 noise sd."
            + _thinned(curves),
        )
    )
    return figs


def _labels(result) -> list[str]:
    several = len(result.experiments) > 1
    out = []
    for p in result.parameters:
        exp = p.name.split(".")[0] if several and "." in p.name else ""
        out.append(f"{p.symbol} ({exp})" if exp else p.symbol)
    return out


def _title(experiments) -> str:
    return "; ".join(dict.fromkeys(e.title for e in experiments))


def _profile_section(result) -> Section:
    from tcamlab.report.calibration_figures import profile_figure

    return Section(
        "Profile likelihood",
        paragraphs=[
            "Where a profile follows the dotted Laplace line the Jacobian interval can be "
            "trusted; a bend, a flat stretch or a jump means the data constrain the parameter "
            "unevenly and only the profile interval holds."
        ],
        figures=[
            _figure(
                profile_figure(result.parameters, _labels(result)),
                "Signed root of the profile likelihood, z = \u00b1sqrt(chi-square rise), "
                "each parameter re-optimising the others (points: evaluated). Shaded: the 95 % "
                "profile interval, where |z| < 1.96; dotted: the Laplace (Jacobian) "
                "approximation; dash-dotted: the stated value.",
            )
        ],
    )


def _correlation_section(result) -> Section:
    return Section(
        "Correlation",
        paragraphs=[
            "Two parameters correlated near \u00b11 are fixed by these logs only as a "
            "combination (see Identifiability)."
        ],
        figures=[
            _figure(
                correlation_figure(_labels(result), result.correlation["matrix"]),
                "Posterior correlation of the calibrated parameters (in fitted coordinates: "
                "logarithms of positive parameters). Near \u00b11: the logs fix only a "
                "combination.",
            )
        ],
    )


def _measurement_section(result, name: str) -> Section:
    return Section(
        f"Model against measurement: {name}",
        paragraphs=[
            "The overlays show each whole run; the residual panels show the difference at the "
            "scale of the noise, where stated and calibrated values can be told apart."
        ],
        figures=_experiment_figures(result, name),
    )


def estimator_section(result) -> Section | None:
    """Both fits of a self-sensing experiment (open-loop, then the EKF refit) and which figure
    uses which; None without a second stage."""
    fits = getattr(result, "estimator", None) or []
    if not fits:
        return None
    from tcamlab.calibration.estimator import SYMBOLS

    rows = []
    for fit in fits:
        for name, symbol in SYMBOLS.items():
            if name not in fit.open_loop:
                continue
            before, after = fit.open_loop[name], fit.values[name]
            if name in fit.fitted:
                status = f"refitted, sd {fit.sd[name]:.3g}{(getattr(fit, 'disagreements', None) or {}).get(name, '')}"
            else:
                status = fit.held.get(name, "held at its stated value")
            rows.append([fit.experiment, symbol, f"{before:.6g}", f"{after:.6g}", status])
    paragraphs = [
        "Second stage: the open-loop fit above leaves R0, the TCR, C_th and lambda off together "
        "(the inversion cannot tell them apart), which the causal EKF with the load unknown reads as a "
        "load drift, and it does not use the mechanics, whose thermal stroke the EKF follows. R0 and "
        "the TCR, and the lead resistance R_lead (bounded at 0), the stretch factor k_s, the quadratic "
        "TCR tcr2 and the fiber's radial expansion rho (the mechanics' stroke per kelvin) where the runs "
        "identify them, are refitted through the EKF against the laser "
        "("
        + "; ".join(
            f"{f.experiment}: {', '.join(f.cases)}, weighted error rms {f.rms_before_um:.1f} um -> "
            f"{f.rms_after_um:.1f} um"
            if f.fitted
            else f"{f.experiment}: not refitted"
            for f in fits
        )
        + "); C_th, lambda and b stay at the open-loop fit."
    ]
    paragraphs += [f"The {k} is used by {v}." for k, v in fits[0].used_by.items()]
    head = ["experiment", "parameter", "open-loop fit", "EKF refit (written)", "status"]
    return Section(
        "Fit for the estimator",
        paragraphs=paragraphs,
        tables=[Table(head, rows, caption="R0, TCR, R_lead, k_s, tcr2, rho, E and b after each stage (SI)")],
    )


def calibration_document(result, experiments: Sequence, *, command: str | None = None) -> Document:
    """The calibration report.

    Parameters
    ----------
    result : CalibrationResult
        The calibration (with its curves).
    experiments : sequence of Experiment
        The calibrated experiments (titles, synthetic banners).
    command : str, optional
        The command line shown in the provenance.
    """
    names = [e.name for e in experiments]
    zeros = _zeros_table(result)
    sections = [
        _provenance_section(result, command),
        Section(
            "Parameters",
            paragraphs=[
                f"{len(result.parameters)} parameters calibrated jointly over every run of "
                + ", ".join(names)
                + f" ({result.n_points} data points; penalised chi-square {result.chi2:.1f})."
            ],
            tables=[_parameter_table(result)],
            notes=list(result.notes) + _unsure_notes(result),
            warnings=stated_shift_warnings(result),
        ),
        Section("Identifiability", paragraphs=list(result.identifiability)),
        Section("Fit quality", tables=[_quality_table(result)]),
    ]
    sections += [s for s in (estimator_section(result),) if s is not None]
    if zeros is not None:
        sections.append(Section("Nuisance zeros", tables=[zeros]))
    sections += [_measurement_section(result, name) for name in names]
    sections += [_profile_section(result), _correlation_section(result)]
    banners = [b for b in (synthetic_banner(e) for e in experiments) if b]
    return Document(
        title=f"Calibration: {_title(experiments)}",
        subtitle="Calibration report: " + "+".join(names),
        sections=sections,
        metadata={},
        synthetic_banner=" ".join(dict.fromkeys(banners)) or None,
    )


def figure_files(doc: Document, html: str | None = None, stem: str = "calibration") -> dict[str, bytes]:
    """Each figure of ``doc`` as standalone PNG (150 dpi) and SVG: ``STEM-figN.png`` / ``.svg``.

    With ``html`` (``render_html(doc)``), the SVGs are the ones inlined there (the same
    bytes ``figure_to_svg`` gives, taken instead of drawn a second time).
    """
    from tcamlab.report.figures import figure_to_png, figure_to_svg

    figures = [fig for section in doc.sections for fig in section.figures]
    inlined = re.findall(r"<svg\b.*?</svg>\n?", html or "", flags=re.S)
    out: dict[str, bytes] = {}
    for n, fig in enumerate(figures, start=1):
        out[f"{stem}-fig{n}.png"] = figure_to_png(fig.figure)
        svg = inlined[n - 1] if len(inlined) == len(figures) else figure_to_svg(fig.figure, index=n)
        out[f"{stem}-fig{n}.svg"] = svg.encode()
    return out
