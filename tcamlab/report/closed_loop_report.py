"""The closed-loop report (``closed_loop.html`` / ``.pdf``) as a :class:`Document`.

Renders only: every number comes from the :class:`~tcamlab.estimation.control.ClosedLoopStudy`
objects (one with the load unknown to the estimator, one with it logged by a
load cell). Displacements are shown in mm, as the rig logs them.
"""

from __future__ import annotations

import numpy as np

from tcamlab.report.document import Document, Figure, Section, Table
from tcamlab.report.figures import new_figure

__all__ = ["closed_loop_document", "estimate_metrics", "COLORS"]

COLORS = {"open-loop": "tab:gray", "laser": "tab:blue", "self-sensing": "tab:red"}
STRIDE = 20
"""Samples per plotted point (1 kHz runs: 50 points a second is enough to see them)."""


def estimate_metrics(result, stroke: float) -> dict:
    """Mean and 95% interval (2.5-97.5 percentile width) of the estimate's error [m], and per stroke."""
    e = result.estimate_error
    width = float(np.percentile(e, 97.5) - np.percentile(e, 2.5))
    mean = float(np.mean(e))
    return {"mean": mean, "interval95": width, "mean_rel": mean / stroke, "interval_rel": width / stroke}


def _tracking_figure(study, title):
    fig, ax = new_figure(6.4, 3.4)
    r0 = next(iter(study.results.values()))
    ax.plot(r0.time[::STRIDE], r0.reference[::STRIDE] * 1e3, "k--", lw=1, label="reference")
    for mode, r in study.results.items():
        ax.plot(
            r.time[::STRIDE], r.displacement[::STRIDE] * 1e3, color=COLORS[mode], lw=1, label=f"true, {mode}"
        )
    ax.axvline(study.scenario.load_change_at, color="k", lw=0.6, alpha=0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement [mm]")
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=2)
    return fig


def _error_figure(study):
    fig, ax = new_figure(6.4, 3.0)
    for mode, r in study.results.items():
        ax.plot(r.time[::STRIDE], r.tracking_error[::STRIDE] * 1e3, color=COLORS[mode], lw=0.8, label=mode)
    ax.axvline(study.scenario.load_change_at, color="k", lw=0.6, alpha=0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("true - reference [mm]")
    ax.legend(fontsize=7)
    return fig


def _estimate_figures(result):
    fig1, ax = new_figure(6.4, 3.0)
    ax.plot(result.time[::STRIDE], result.displacement[::STRIDE] * 1e3, "k", lw=1, label="true")
    ax.plot(result.time[::STRIDE], result.estimate[::STRIDE] * 1e3, "tab:red", lw=0.8, label="self-sensed")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement [mm]")
    ax.legend(fontsize=7)
    fig2, ax2 = new_figure(6.4, 3.0)
    ax2.plot(result.displacement[::STRIDE] * 1e3, result.estimate_error[::STRIDE] * 1e3, ".", ms=1.5)
    ax2.set_xlabel("true displacement [mm]")
    ax2.set_ylabel("estimate - true [mm]")
    return fig1, fig2


def _rms_table(study, label):
    laser = study.rms["laser"]
    rows = [
        [m, study.rms[m] * 1e3, study.rms_after_load_change[m] * 1e3, study.rms[m] / laser]
        for m in study.results
    ]
    return Table(
        ["feedback", "RMS [mm]", "RMS after the load change [mm]", "RMS / laser's"],
        rows,
        caption=f"Tracking error against the TRUE displacement ({label}; from 5 s on)",
    )


def _estimate_table(studies, stroke):
    rows = []
    for label, study in studies.items():
        m = estimate_metrics(study.results["laser"], stroke)
        rows.append(
            [label, m["mean"] * 1e3, m["mean_rel"] * 100, m["interval95"] * 1e3, m["interval_rel"] * 100]
        )
    return Table(
        ["load", "mean error [mm]", "mean [% stroke]", "95% interval [mm]", "95% interval [% stroke]"],
        rows,
        caption=f"Self-sensed displacement against the true one, stroke {stroke * 1e3:.2f} mm "
        "(targets: 2% and 10% of the stroke; van der Weijde et al. 2017: mean -0.27 mm, "
        "95% interval 2.14 mm over a 10-30 mm stroke)",
    )


def _setup_section(study, experiment_name):
    sc = study.scenario
    m, t = study.model_rig, study.truth_rig
    rows = [
        ["C_th [J/K]", m.thermal_mass, t.thermal_mass],
        ["lambda [W/K]", m.heat_loss, t.heat_loss],
        ["b [N s/m]", m.damping, t.damping],
        ["TCR [1/K]", study.model_tcr, study.truth_tcr],
    ]
    return Section(
        "Setup",
        paragraphs=[
            f"Parameters of the controller and the estimator from {experiment_name}; the virtual rig runs "
            f"with the TRUE values below, drawn about them with the sds of a calibration (seed {sc.seed}).",
            f"{sc.duration:g} s at {1 / sc.dt:g} Hz: steps then a sine, largest contraction "
            f"{sc.stroke * 1e3:.2f} mm; the load force steps by {sc.load_change * 1e3:g} mN at "
            f"{sc.load_change_at:g} s, told to nobody. PI gains kp = {study.gains[0]:.4g} W/m, "
            f"ki = {study.gains[1]:.4g} W/(m s) (integral time C_th/lambda, crossover "
            f"{sc.bandwidth:g} rad/s), feedforward from the static model; driver {sc.v_min:g}-{sc.v_max:g} V.",
        ],
        tables=[Table(["parameter", "calibrated (used)", "true (plant)"], rows, caption="Model and truth")],
    )


def closed_loop_document(studies: dict, experiment_name: str, metadata: dict) -> Document:
    """The report of ``{"load unknown": study, "load logged": study}`` on one experiment."""
    first = next(iter(studies.values()))
    stroke = first.scenario.stroke
    sections = [_setup_section(first, experiment_name)]
    for label, study in studies.items():
        est1, est2 = _estimate_figures(study.results["laser"])
        sections.append(
            Section(
                f"Closed loop, {label}",
                tables=[_rms_table(study, label)],
                figures=[
                    Figure(_tracking_figure(study, label), "Reference and TRUE displacement per feedback"),
                    Figure(
                        _error_figure(study), "Tracking error against time (vertical line: the load change)"
                    ),
                    Figure(est1, "Self-sensed and true displacement (the laser-feedback run)"),
                    Figure(est2, "Estimate error against the true displacement"),
                ],
            )
        )
    sections.insert(1, Section("Self-sensing accuracy", tables=[_estimate_table(studies, stroke)]))
    return Document(
        title=f"Closed loop on the self-sensed displacement: {experiment_name}",
        subtitle="virtual rig: open-loop voltage, laser feedback and self-sensing feedback",
        sections=sections,
        metadata=metadata,
        synthetic_banner="SYNTHETIC DATA: virtual rig (tcamlab.estimation.control), seed "
        f"{first.scenario.seed}; not a measurement",
    )
