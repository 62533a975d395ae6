"""Where the baseline misses: residuals by regime, per-run statistics, and the plot series.

The regimes are the kind's own (:attr:`tcamlab.kinds.Kind.regimes`: temperature
bands, heating and cooling phases, force bands, loading and unloading ...).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tcamlab.diagnosis.noise import BaselineFit
from tcamlab.diagnosis.problem import MODEL_ERRORS, Problem
from tcamlab.diagnosis.result import Regime, RunStatistics
from tcamlab.units import display

__all__ = [
    "Labels",
    "label_rows",
    "regime_table",
    "run_statistics",
    "plot_series",
    "autocorr1",
    "durbin_watson",
    "corr",
]


def autocorr1(r: np.ndarray) -> float:
    r = r - r.mean()
    den = float(np.sum(r * r))
    return float(np.sum(r[1:] * r[:-1]) / den) if den > 0 and r.size > 2 else float("nan")


def durbin_watson(r: np.ndarray) -> float:
    den = float(np.sum(r * r))
    return float(np.sum(np.diff(r) ** 2) / den) if den > 0 else float("nan")


def corr(a: np.ndarray, b: np.ndarray) -> float:
    if a.size < 3 or np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


@dataclass
class Labels:
    """Normalised baseline residuals of all runs and quantities, stacked, with their labels."""

    z: np.ndarray
    """Residual / noise floor, runs then quantities in order [-]."""
    quantity: np.ndarray
    """The quantity of each entry."""
    groups: dict
    """Regime group -> label of each entry (None where a run lacks the group)."""


def label_rows(problem: Problem, baseline: BaselineFit) -> Labels:
    """Stack the normalised baseline residuals with the kind's regime labels."""
    labels: dict[str, list] = {}
    zs, qlab = [], []
    for i, d in enumerate(problem.frames):
        for q in (q for q in problem.quantities if problem.logs(i, q)):
            zs.append(baseline.residuals[i][q] / problem.sigma[q])
            qlab.append(np.full(len(d), q, dtype=object))
            for g, v in problem.k.regimes(d, q, problem.frames).items():
                labels.setdefault(g, []).append(v)
    groups = {g: np.concatenate(v) if len(v) == len(zs) else None for g, v in labels.items()}
    return Labels(np.concatenate(zs), np.concatenate(qlab), groups)


def _regime(problem: Problem, labels: Labels, group: str, name: str, total: float) -> Regime:
    m = labels.groups[group] == name
    zz = labels.z[m]
    by_q = {}
    for q in problem.quantities:
        mq = m & (labels.quantity == q)
        if mq.any():
            unit, fac = display(q)
            zq = labels.z[mq] * problem.sigma[q] * fac
            by_q[q] = {
                "n": int(mq.sum()),
                "rmse": float(np.sqrt(np.mean(zq**2))),
                "bias": float(np.mean(zq)),
                "unit": unit,
            }
    return Regime(
        group=group,
        regime=str(name),
        n=int(m.sum()),
        rmse_over_noise=float(np.sqrt(np.mean(zz**2))),
        bias_over_noise=float(np.mean(zz)),
        share=float(np.sum(zz**2) / total),
        by_quantity=by_q,
    )


def regime_table(problem: Problem, labels: Labels) -> list[Regime]:
    """RMSE, bias and share of the squared residual in every regime of every group."""
    out = []
    total = float(np.sum(labels.z**2)) or 1.0
    for g, lab in labels.groups.items():
        if lab is None:
            continue
        out += [_regime(problem, labels, g, name, total) for name in dict.fromkeys(lab) if name]
    return out


def run_statistics(problem: Problem, baseline: BaselineFit, noise, names) -> list[RunStatistics]:
    """Per run: residual RMSE and bias, noise, autocorrelation, Durbin-Watson, input correlations."""
    inputs = list(problem.k.inputs)
    if "time" not in inputs and any("time" in d for d in problem.frames):
        inputs.append("time")
    out = []
    for i, d in enumerate(problem.frames):
        by_q = {}
        for q in (q for q in problem.quantities if problem.logs(i, q)):
            unit, fac = display(q)
            r = baseline.residuals[i][q]
            by_q[q] = {
                "rmse": float(np.sqrt(np.mean(r**2))) * fac,
                "bias": float(np.mean(r)) * fac,
                "unit": unit,
                "noise_sigma": noise.by_quantity[q].per_run[i],
                "lag1_autocorrelation": autocorr1(r),
                "durbin_watson": durbin_watson(r),
                "correlation_with_inputs": {c: corr(r, d[c].to_numpy(float)) for c in inputs if c in d},
            }
        out.append(RunStatistics(index=i, name=names[i], n=int(len(d)), by_quantity=by_q))
    return out


def _with_zero(problem: Problem, i: int, pred: dict) -> dict:
    """Predictions plus the run's profiled zero: measured - residual [SI]."""
    res = problem.resid(i, pred)
    return {q: problem.measured(i, q) - res[q] for q in problem.quantities if problem.logs(i, q)}


def plot_series(problem: Problem, baseline: BaselineFit, labels: Labels, best) -> dict:
    """Arrays for the result's plots: each run's measured, baseline and best-candidate curves.

    ``best`` maps a run index to the best candidate's predictions [SI], or is None. Curves
    carry each run's profiled zero, so they overlay the logged data.
    """
    xcol = problem.k.x_column
    runs = []
    for i, d in enumerate(problem.frames):
        if xcol not in d:
            x, xlabel = np.arange(len(d)), "row"
        else:
            unit, fac = display(xcol)
            x, xlabel = d[xcol].to_numpy(float) * fac, f"{xcol} [{unit}]"
        best_pred = None
        if best is not None:
            try:
                best_pred = _with_zero(problem, i, best(i))
            except MODEL_ERRORS:
                best_pred = None
        measured = {q: problem.measured(i, q) for q in problem.quantities if problem.logs(i, q)}
        runs.append(
            {
                "x": x,
                "xlabel": xlabel,
                "measured": measured,
                "baseline": _with_zero(problem, i, baseline.predictions[i]),
                "best": best_pred,
            }
        )
    groups = {g: v for g, v in labels.groups.items() if v is not None}
    return {"runs": runs, "z": labels.z, "labels": groups, "regime_groups": list(groups)}
