"""Validation: run the thesis model on each run's inputs and measure the error.

``validate(experiment)`` returns a :class:`ValidationResult` holding, per run,
the measured and predicted columns, error metrics per model variant and
quantity (per run and pooled), threshold checks, and kind-specific extras
(spring constants used for sensing, the Monte Carlo band for dynamic runs).
Each run's zero of every zero-referenced channel (:attr:`Kind.nuisance_zeros`)
is estimated for every model under one rule (rows at rest, else the logged zero;
the whole run on request) and subtracted before the metrics and the kind's extras
(:data:`tcamlab.metrics.ZERO_METHOD_NOTE`).
No file is written here: see :mod:`tcamlab.pipeline`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from tcamlab import progress
from tcamlab.config import Experiment
from tcamlab.errors import ConfigError, ConvergenceError, InputError, IntegrationError, ModelDomainError
from tcamlab.io import VARIABLE_MAP, RunData, input_files, sha256_file
from tcamlab.kinds import Kind, get_kind, rest_rows
from tcamlab.metrics import (
    LOGGED_ZERO,
    MIN_REST_ROWS,
    SANITY_CHECKS,
    STATUS_FAILED,
    STATUS_PASSED,
    ZERO_REST,
    ZERO_WHOLE_RUN,
    check_thresholds,
    dead_channel_warning,
    domain_warning,
    error_metrics,
    estimate_zero,
    flat_prediction_warning,
    implausible_value_warnings,
    opposite_direction_warning,
    pooled_metrics,
    r2_warnings,
    reference_warning,
    stated_shift_warning,
    threshold_status,
    unused_threshold_warnings,
    zero_offset_warning,
)
from tcamlab.numbers import unit_label
from tcamlab.text import shown_path
from tcamlab.units import quantity

__all__ = ["ValidationResult", "RunPrediction", "validate", "ignored_columns", "without_columns", "MC_DRAWS"]

MC_DRAWS = 1000
"""Monte Carlo draws for the dynamic prediction band."""

FIRST_ROW_ZEROS = ("displacement",)
"""Quantities logged from their first row (the laser zeroed on the run; the static, dynamic
and self-sensing displacement models read 0 there): their logged zero is the first row's
residual. Any other zero-referenced channel (the load cell) stands as logged."""


@dataclass
class RunPrediction:
    """Measured and predicted values of one run (SI).

    Attributes
    ----------
    name : str
        Run name (CSV file stem).
    data : DataFrame
        The run's canonical SI columns as ingested, each estimated zero of
        ``zeros`` subtracted (the logged values are in ``ValidationResult.runs``).
    predicted : dict
        Model variant -> {quantity -> ndarray} [SI].
    band : dict or None
        Dynamic runs: {"lower", "upper", "median"} displacement [m].
    info : dict
        Per-run facts shown in the report (spring constant and its source...).
    zeros : dict
        Quantity -> :class:`tcamlab.metrics.ZeroEstimate` [SI] of the run's
        nuisance zero under the primary model (its ``stderr`` is the zero's sd, e.g.
        for a prediction band); subtracted from ``data``.
    variant_zeros : dict
        Model variant -> {quantity -> ZeroEstimate [SI]}: each model's own zero under
        the same rule (the primary's is ``zeros``). Another model's prediction is moved
        by the difference of its zero and the primary's, so that its residuals are
        those against the logged measurement minus its own zero.
    """

    name: str
    data: pd.DataFrame
    predicted: dict
    band: dict | None = None
    info: dict = field(default_factory=dict)
    zeros: dict = field(default_factory=dict)
    variant_zeros: dict = field(default_factory=dict)


@dataclass
class ValidationResult:
    """Outcome of validating one experiment.

    Attributes
    ----------
    experiment : Experiment
    runs : list of RunData
    predictions : list of RunPrediction
    variants : list of str
        Model variants compared; ``primary`` is the one thresholds apply to.
    primary : str
    metrics : dict
        variant -> display quantity -> {"runs": {run: metrics}, "pooled": metrics}.
    checks : list of ThresholdCheck
    notes : list of str
        Facts the reader must see (conditioning, draws out of range).
    extras : dict
        Kind-specific results (spring fits, conditioning, Monte Carlo summary).
    warnings : list of SanityWarning
        The sanity checks that failed (:data:`tcamlab.metrics.SANITY_CHECKS`); they
        never change the status, ``--strict`` turns them into exit status 1.
    zero_rule : str
        ``"rest"`` (zeros from rows at rest, else as logged) or ``"whole-run"``.
    unadjusted : dict or None
        With the whole-run rule: the metrics (shape of ``metrics``) under the rest
        rule, i.e. without each model's mean error taken away; else None.
    ignored : tuple of str
        Canonical columns treated as not logged (``validate --ignore``).
    """

    experiment: Experiment
    runs: list
    predictions: list
    variants: list
    primary: str
    metrics: dict
    checks: list
    notes: list = field(default_factory=list)
    extras: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    zero_rule: str = ZERO_REST
    unadjusted: dict | None = None
    ignored: tuple[str, ...] = ()

    @property
    def kind(self) -> str:
        return self.experiment.kind

    @property
    def status(self) -> str:
        """``"passed"``, ``"failed"`` or ``"no limits set"`` (:func:`tcamlab.metrics.threshold_status`)."""
        return threshold_status(self.checks)

    @property
    def passed(self) -> bool | None:
        """True when every threshold passed, False when one failed, None when none was checked."""
        return {STATUS_PASSED: True, STATUS_FAILED: False}.get(self.status)

    @property
    def failed(self) -> bool:
        """A threshold failed (exit status 1)."""
        return self.status == STATUS_FAILED

    @property
    def quantities(self) -> tuple[str, ...]:
        return get_kind(self.kind).outputs

    @property
    def zeros(self) -> dict:
        """Run -> {quantity -> ZeroEstimate [SI]}: the nuisance zeros subtracted."""
        return {p.name: dict(p.zeros) for p in self.predictions if p.zeros}

    def variant_zeros(self, variant: str) -> dict:
        """Run -> {quantity -> ZeroEstimate [SI]}: one model's own zeros."""
        return {
            p.name: dict(p.variant_zeros[variant]) for p in self.predictions if variant in p.variant_zeros
        }

    def zeros_dict(self) -> dict:
        """The ``zeros`` block of metrics.json: the rule, and per run and quantity in lab
        units the primary model's zeros (``runs``) and every model's (``by_model``)."""

        def block(zeros: dict) -> dict:
            return {quantity(q).column: z.scaled(quantity(q).factor).to_dict() for q, z in zeros.items()}

        runs = {p.name: block(p.zeros) for p in self.predictions if p.zeros}
        by_model = {v: {run: block(z) for run, z in self.variant_zeros(v).items()} for v in self.variants}
        return {"rule": self.zero_rule, "min_rest_rows": MIN_REST_ROWS, "runs": runs, "by_model": by_model}

    def to_pandas(self) -> pd.DataFrame:
        """One row per logged sample: run, inputs, measured (as logged), the run's estimated
        zero where there is one, and predicted (lab units); residual = predicted - (measured - zero)."""
        frames = []
        inputs = [c for c in get_kind(self.kind).inputs if c != "time"]
        for p, r in zip(self.predictions, self.runs):
            out = {"run": p.name, "row": np.arange(1, len(p.data) + 1)}
            if "time" in p.data:
                out["time_s"] = p.data["time"].to_numpy()
            for c in inputs:
                name, factor = quantity(c).column, quantity(c).factor
                out[name] = p.data[c].to_numpy() * factor
            for q in self.quantities:
                name, factor = quantity(q).column, quantity(q).factor
                out[f"measured_{name}"] = r.data[q].to_numpy() * factor
                if q in p.zeros:
                    out[f"zero_{name}"] = np.full(len(p.data), p.zeros[q].value * factor)
                for v in self.variants:
                    out[f"predicted_{name}__{_slug(v)}"] = p.predicted[v][q] * factor
            if p.band is not None:
                out["band_lower_displacement_mm"] = p.band["lower"] * 1e3
                out["band_upper_displacement_mm"] = p.band["upper"] * 1e3
            frames.append(pd.DataFrame(out))
        return pd.concat(frames, ignore_index=True)

    def metrics_table(self, variant: str | None = None) -> pd.DataFrame:
        """Metrics per run and pooled for one variant (default: primary)."""
        variant = self.primary if variant is None else variant
        rows = []
        for q, block in self.metrics[variant].items():
            for run, m in list(block["runs"].items()) + [("pooled", block["pooled"])]:
                rows.append({"quantity": q, "run": run, **m})
        return pd.DataFrame(rows)

    def to_dict(self) -> dict:
        """The metrics.json document (schema in README)."""
        from tcamlab import __version__

        exp = self.experiment
        return {
            "schema_version": 2,
            "tool": f"tcamlab {__version__}",
            "experiment": exp.name,
            "title": exp.title,
            "kind": exp.kind,
            "synthetic": exp.synthetic,
            "experiment_file": {
                "file": exp.path.name,
                "path": shown_path(exp.path),
                "sha256": sha256_file(exp.path),
            },
            "inputs": [
                {
                    "file": r.path.name,
                    "path": relative_to(r.path, exp.path.parent),
                    "sha256": r.sha256,
                    "rows": int(len(r.data)),
                    "dropped_rows": r.n_dropped_total,
                    "dropped": dict(r.dropped),
                    "columns": r.columns,
                }
                | _joined_input(r, exp.path.parent)
                for r in self.runs
            ],
            "primary_model": self.primary,
            "models": {
                v: {
                    q: {"runs": {k: _json(m) for k, m in b["runs"].items()}, "pooled": _json(b["pooled"])}
                    for q, b in self.metrics[v].items()
                }
                for v in self.variants
            },
            **({"models_unadjusted": _json(self.unadjusted)} if self.unadjusted is not None else {}),
            "ignored_columns": list(self.ignored),
            "zero_rule": self.zero_rule,
            "zeros": self.zeros_dict(),
            "thresholds": [c.to_dict() for c in self.checks],
            "status": self.status,
            "passed": self.passed,
            "sanity_checks": dict(SANITY_CHECKS),
            "warnings": [w.to_dict() for w in self.warnings],
            "notes": list(self.notes),
            "extras": _json(self.extras),
        }

    def plot(self, ax=None, quantity: str | None = None):
        """Measured against predicted (primary variant) for all runs, on one axes."""
        if ax is None:
            from matplotlib.figure import Figure

            ax = Figure().add_subplot()
        q = quantity or self.quantities[0]
        name, factor = quantity(q).column, quantity(q).factor
        for p in self.predictions:
            ax.plot(p.data[q] * factor, p.predicted[self.primary][q] * factor, ".", label=p.name)
        ax.set_xlabel(f"measured {name}")
        ax.set_ylabel(f"predicted {name}")
        return ax


def _joined_input(run: RunData, start) -> dict:
    """``{"joined": {...}}``: the second instrument's file of a run joined on time (its path
    relative to the experiment file's folder and SHA-256), or {} for a run of one file."""
    joined = [(p, h) for role, p, h in input_files(run) if role == "joined"]
    if not joined:
        return {}
    (path, sha), join = joined[0], run.join
    return {
        "joined": {
            "file": path.name,
            "path": relative_to(path, start),
            "sha256": sha,
            "offset_s": join["offset_s"],
        }
    }


def smoothed_notes(run: RunData) -> list[str]:
    """One line per input of ``run`` that a slower instrument logged and the models read
    averaged over its frames (:attr:`tcamlab.io.RunData.smoothed`)."""
    out = []
    for col, s in run.smoothed.items():
        unit = run.units.get(col, "")
        out.append(
            f"{run.path.name}: {col} comes from a slower instrument (a frame every "
            f"{s['rows_per_frame']} rows, noise {s['frame_sd']:.3g} {unit} per frame); the models read "
            f"its average over {s['frames']} frames ({s['window_rows']} rows), centred, so its "
            f"noise does not pass to the outputs as a misfit (tcamlab.signals.smooth_slow_input)"
        )
    return out


def relative_to(path, start) -> str:
    """``path`` relative to the folder ``start`` in POSIX form (``../raw/run1.csv``), as an
    experiment file names its runs; the bare name on another drive. Never absolute."""
    import os
    from pathlib import Path

    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()
    except ValueError:
        return Path(path).name


def _slug(variant: str) -> str:
    return variant.replace("(", "").replace(")", "").replace(" ", "_").replace("-", "_")


def _json(obj):
    """JSON-safe copy: NaN/inf -> None, numpy scalars -> Python."""
    if isinstance(obj, dict):
        return {str(k): _json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        x = float(obj)
        return x if np.isfinite(x) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return _json(obj.tolist())
    return obj


def _fitted(z) -> int:
    """1 for a zero estimated from the data (rows at rest, whole run), 0 for a logged zero."""
    return int(z is not None and z.source != LOGGED_ZERO)


def _bias_sd(zeros, counts) -> float:
    """Sd of a bias from the zeros' standard errors [the zeros' unit]: the bias over rows
    sum(n_i z_i) / sum(n_i) with independent zeros. NaN when a run has no zero."""
    se = np.array([np.nan if z is None else z.stderr for z in zeros], float)
    n = np.asarray(counts, float)
    if n.sum() <= 0:
        return float("nan")
    return float(np.sqrt(np.sum((n * se) ** 2)) / n.sum())


def _metrics(predictions, variants, quantities) -> dict:
    """Metrics per variant, quantity, run and pooled; ``n_zeros`` counts the zeros estimated
    from the data, ``bias_sd`` is the bias's sd from the model's own zeros [lab unit]."""
    out = {}
    for v in variants:
        out[v] = {}
        for q in quantities:
            name, factor = quantity(q).column, quantity(q).factor
            pairs = [(p.data[q].to_numpy() * factor, p.predicted[v][q] * factor) for p in predictions]
            zeros = [p.variant_zeros.get(v, {}).get(q) for p in predictions]
            runs, counts = {}, []
            for p, (m, pr), z in zip(predictions, pairs, zeros):
                m_run = error_metrics(m, pr)
                counts.append(m_run["n"])
                runs[p.name] = {**m_run, "bias_sd": _bias_sd([z], [1]) * factor, "n_zeros": _fitted(z)}
            pooled = {
                **pooled_metrics(pairs),
                "bias_sd": _bias_sd(zeros, counts) * factor,
                "n_zeros": sum(_fitted(z) for z in zeros),
            }
            out[v][name] = {"runs": runs, "pooled": pooled}
    return out


def _zeros_of_run(kind: Kind, p: RunPrediction, q: str, rule: str) -> dict:
    """Variant -> ZeroEstimate [SI] of one run and quantity: every model under the same rule,
    against the same logged measurement."""
    raw, rest = p.data[q].to_numpy(float), rest_rows(kind, p.data)
    first = q in FIRST_ROW_ZEROS
    return {
        v: estimate_zero(raw, p.predicted[v][q], rest, rule=rule, first_row=first)
        for v in kind.variants
        if q in p.predicted.get(v, {})
    }


def _subtract_zeros(kind: Kind, preds: list[RunPrediction], rule: str = ZERO_REST) -> list[str]:
    """Estimate each run's nuisance zeros for every model under ``rule``; subtract the primary
    model's from the measurement and move every other model's prediction by the difference of
    its own zero and the primary's (its residuals are then those against the logged
    measurement minus its own zero); the notes."""
    sources: dict[str, set] = {}
    for p in preds:
        for q in kind.nuisance_zeros:
            if q not in kind.outputs or q not in p.data:
                continue
            own = _zeros_of_run(kind, p, q, rule)
            est = own.get(kind.primary)
            if est is None or not np.isfinite(est.value):
                continue
            for v, z in own.items():
                if v != kind.primary and np.isfinite(z.value):
                    shift = z.value - est.value
                    p.predicted[v] = {**p.predicted[v], q: np.asarray(p.predicted[v][q], float) + shift}
                p.variant_zeros.setdefault(v, {})[q] = z
            p.data = p.data.assign(**{q: p.data[q].to_numpy(float) - est.value})
            p.zeros[q] = est
            sources.setdefault(q, set()).add(est.source)
    return [_zero_note(kind, q, src, rule) for q, src in sources.items()]


def _zero_note(kind: Kind, q: str, sources: set, rule: str) -> str:
    """The report's note on how the zeros of quantity ``q`` were taken."""
    col = quantity(q).column
    each = (
        "; every model is scored after its own zero under the same rule (the figures draw the "
        f"measurement minus the {kind.primary} model's zero and move each other model's prediction "
        "by the difference of its zero and that one)"
        if len(kind.variants) > 1
        else ""
    )
    if rule == ZERO_WHOLE_RUN:
        return (
            f'[validation] zero = "whole-run": the zero of {col} was fitted over each whole run, for '
            "each model its own, and subtracted: bias and R² exclude the mean error (the bias is 0 "
            "by construction); the unadjusted metrics (zeros from the rows at rest, else as logged) "
            "are given beside" + each
        )
    how = []
    if "rest rows" in sources:
        how.append(f"the mean residual of its rows at rest (at least {MIN_REST_ROWS} of them)")
    if LOGGED_ZERO in sources:
        ref = "its first row" if q in FIRST_ROW_ZEROS else "the log as it is"
        how.append(
            f"the logged zero ({ref}) where fewer than {MIN_REST_ROWS} rows are at rest; its "
            "uncertainty (the noise sd over the square root of the rest rows used) is given beside "
            "the bias, which keeps the model's mean error"
        )
    return (
        f"the zero of {col} was taken per run as "
        + ", or ".join(how)
        + each
        + "; see the table of nuisance zeros"
    )


_REFERENCES = {
    "initial_resistance_ohm": ("R0", ("resistance",)),
    "initial_resistances_ohm": ("R0", ("r1", "r2")),
}
"""Per-run info key of a resistance reference -> (name, logged channels it refers to)."""


def _reference_warnings(kind: Kind, preds: list[RunPrediction]) -> list:
    """Each run's resistance reference (R0) against the mean of its logged rows at rest."""
    out = []
    for p in preds:
        rest = rest_rows(kind, p.data)
        for key, (name, channels) in _REFERENCES.items():
            if key not in p.info:
                continue
            used = np.atleast_1d(np.asarray(p.info[key], float))
            source = str(p.info.get(key.replace("_ohm", "_source"), "?"))
            for j, ch in enumerate(channels):
                label = name if len(channels) == 1 else f"{name} of {ch}"
                value = float(used[min(j, used.size - 1)])
                out.append(reference_warning(p.name, label, value, source, p.data[ch].to_numpy(float)[rest]))
    return out


def _pair(kind: Kind, p: RunPrediction, q: str, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """A run's measured and primary-model values of ``q``, times ``factor`` (lab units)."""
    return p.data[q].to_numpy(float) * factor, np.asarray(p.predicted[kind.primary][q], float) * factor


def sanity_warnings(kind: Kind, preds: list[RunPrediction], metrics: dict) -> list:
    """Every sanity check of :data:`tcamlab.metrics.SANITY_CHECKS` on the primary model;
    a channel in an implausible unit first, then a wrong reference (R0), as they explain the
    others."""
    out = [w for p in preds for w in implausible_value_warnings(p.name, p.data)]
    out += _reference_warnings(kind, preds)
    for q in kind.outputs:
        col, factor = quantity(q).column, quantity(q).factor
        unit = unit_label(col)
        out += r2_warnings(col, metrics[kind.primary][col])
        measured = np.concatenate([p.data[q].to_numpy(float) for p in preds]) * factor
        predicted = np.concatenate([np.asarray(p.predicted[kind.primary][q], float) for p in preds]) * factor
        flat = flat_prediction_warning(col, unit, measured, predicted)
        out += [flat, opposite_direction_warning(col, measured, predicted)]
        if flat is None or flat.values["measured_range"] > 0:  # else the pooled one says it
            out += [dead_channel_warning(p.name, col, unit, *_pair(kind, p, q, factor)) for p in preds]
        for p in preds:
            m = p.data[q].to_numpy(float)
            # every model's rows with no finite prediction: an estimator that diverged is scored
            # on the few rows before it did, and must not look like a fit
            for model, pred in p.predicted.items():
                if q in pred:
                    outside = int(np.sum(np.isfinite(m) & ~np.isfinite(np.asarray(pred[q], float))))
                    out.append(
                        domain_warning(p.name, col, outside, m.size, None if model == kind.primary else model)
                    )
            if q in p.zeros:
                out.append(zero_offset_warning(p.name, col, unit, p.zeros[q].scaled(factor)))
    return [w for w in out if w is not None]


CALIBRATED_SUFFIX = ".calibrated"
"""Stem suffix of a calibrated experiment file (``NAME.calibrated.toml`` beside ``NAME.toml``)."""


def _stated(holder_name: str, experiment: Experiment, field_name: str) -> tuple[float | None, float | None]:
    """(stated value, stated sd) [SI] of a sample or rig field of ``experiment``."""
    holder = experiment.sample if holder_name == "sample" else experiment.rig
    unc = experiment.sample_uncertainty if holder_name == "sample" else experiment.rig.uncertainty
    value = getattr(holder, field_name, None)
    sd = unc.get(field_name)
    return (None if value is None else float(np.atleast_1d(value)[0])), (None if sd is None else float(sd))


def calibrated_parameter_warnings(experiment: Experiment) -> list:
    """Each parameter of a ``NAME.calibrated.toml`` (its ``[calibration]`` table) against the
    stated value and sd of ``NAME.toml`` beside it (none when that file is not there)."""
    from tcamlab.config import load_experiment
    from tcamlab.units import PARAMETER_UNITS

    joint = getattr(experiment, "calibration", None)
    path = experiment.path
    if joint is None or not path.stem.endswith(CALIBRATED_SUFFIX):
        return []
    original = path.with_name(path.stem[: -len(CALIBRATED_SUFFIX)] + path.suffix)
    if not original.is_file():
        return []
    stated_exp = load_experiment(original, require_runs=False)
    out = []
    for key, (where, field_name) in zip(joint.keys, joint.fields):
        value, _ = _stated(where, experiment, field_name)
        stated, sd = _stated(where, stated_exp, field_name)
        if value is None or stated is None:
            continue
        unit, fac = PARAMETER_UNITS.get(field_name, ("", 1.0))
        out.append(
            stated_shift_warning(
                key,
                value * fac,
                stated * fac,
                None if sd is None else sd * fac,
                unit,
                f"calibrated, {path.name}; stated in {original.name}",
            )
        )
    return out


def identified_parameter_warnings(experiment: Experiment, runs: list[RunData]) -> list:
    """Sensing: a stated spring constant with a stated sd against S identified from the logs
    (force on displacement through the origin, every run)."""
    from tcamlab.kinds.sensing import identify_spring

    rig = experiment.rig
    sd = rig.uncertainty.get("spring_constant")
    if experiment.kind != "sensing" or rig.spring_constant is None or sd is None or len(runs) == 0:
        return []
    try:
        s_id = identify_spring([(r.data, np.ones(len(r.data), bool)) for r in runs])
    except (ValueError, ArithmeticError, *_MODEL_ERRORS):
        return []
    return [
        stated_shift_warning(
            "rig.spring_constant_N_per_m (S)",
            s_id,
            float(rig.spring_constant),
            float(sd),
            "N/m",
            "identified from the logs, force on displacement through the origin, every run",
        )
    ]


def ignored_columns(kind_name: str, names) -> tuple[str, ...]:
    """The canonical columns ``validate --ignore`` names, checked against the kind's data contract.

    Parameters
    ----------
    kind_name : str
        The experiment's kind.
    names : iterable of str
        Canonical column names (``load_N``), in the order given; repeats count once.

    Returns
    -------
    tuple of str
        The names, each an optional column of the kind.

    Raises
    ------
    ConfigError
        A name that is a required column of the kind, or not one of its columns at all
        (with a did-you-mean hint).
    """
    from tcamlab.text import did_you_mean

    kind = get_kind(kind_name)
    optional = ", ".join(kind.optional_columns) or "none"
    out: list[str] = []
    for name in names:
        if name in kind.required_columns:
            raise ConfigError(
                f"--ignore {name}: a required column of a {kind.name} run cannot be ignored",
                hint=f"optional columns of a {kind.name} run: {optional}",
            )
        if name not in kind.optional_columns:
            known = kind.optional_columns + kind.required_columns
            raise ConfigError(
                f"--ignore {name}: not a column of a {kind.name} run{did_you_mean(name, known)}",
                hint=f"optional columns of a {kind.name} run: {optional}",
            )
        if name not in out:
            out.append(name)
    return tuple(out)


def without_columns(runs: list[RunData], ignored: tuple[str, ...]) -> list[RunData]:
    """The runs with the internal columns of ``ignored`` (canonical names) dropped from their data,
    as if not logged; the files and the ``[columns]`` mapping they were read with are kept."""
    from dataclasses import replace

    internal = [VARIABLE_MAP[c][0] for c in ignored]
    out = []
    for r in runs:
        gone = [c for c in internal if c in r.data]
        out.append(replace(r, data=r.data.drop(columns=gone)) if gone else r)
    return out


def _ignored_note(runs: list[RunData], ignored: tuple[str, ...]) -> str:
    """The report's note on the columns treated as not logged."""
    internal = {c: VARIABLE_MAP[c][0] for c in ignored}
    had = [c for c in ignored if any(internal[c] in getattr(r, "source_columns", {}) for r in runs)]
    text = f"--ignore {', '.join(ignored)}: treated as not logged (the raw files are not modified)"
    missing = [c for c in ignored if c not in had]
    return text + (f"; {', '.join(missing)} not logged anyway" if missing else "")


def _run_names(runs: list[RunData]) -> list[str]:
    names = [r.path.stem for r in runs]
    if len(set(names)) != len(names):
        names = [f"{i + 1}:{n}" for i, n in enumerate(names)]
    return names


# -- per kind -----------------------------------------------------------------------

_MODEL_ERRORS = (ModelDomainError, ConvergenceError, IntegrationError)


def _in_run(exp: Experiment, name: str, fn, *args, **kwargs):
    """Call a model; name the experiment file and the run in any model error.

    A parameter set with no physical solution (G_t' <= 0 in the run's
    temperature range, S f11 >= 1 ...) then reads, on one line,
    ``static.toml, run static_run1: <reason> (hint: ...)``.
    """
    try:
        return fn(*args, **kwargs)
    except (*_MODEL_ERRORS, InputError) as exc:
        # an input error that names its file already (a column, a row) keeps its own words
        prefix = f"{exp.path.name}, run {name}: "
        if exc.message.startswith(prefix) or (isinstance(exc, InputError) and exp.path.name in exc.message):
            raise
        raise type(exc)(prefix + exc.message, exc.hint) from None


def _training(runs, names, i):
    """The other runs, all rows: what a run's spring constant may be identified on."""
    others = [j for j in range(len(runs)) if j != i]
    data = [(runs[j].data, np.ones(len(runs[j].data), dtype=bool)) for j in others]
    return data, [names[j] for j in others]


def _predict_runs(exp: Experiment, kind: Kind, runs, names) -> list[RunPrediction]:
    """Every model variant of the kind on every run, with the kind's per-run constants."""
    preds = []
    with progress.task(f"{exp.path.name}: model on each run", total=len(runs)) as step:
        for i, name in enumerate(names):
            preds.append(_predict_run(exp, kind, runs, names, i))
            step(description=f"{exp.path.name}: model on {name}")
    return preds


def _predict_run(exp: Experiment, kind: Kind, runs, names, i: int) -> RunPrediction:
    """Every model variant of the kind on run ``i``, with its per-run constants."""
    r, name = runs[i], names[i]
    training, training_runs = _training(runs, names, i)
    ro = _in_run(
        exp,
        name,
        kind.run_options,
        exp.sample,
        exp.rig,
        r.data,
        training=training,
        training_runs=training_runs,
        where=exp.path.name,
        provenance=exp.provenance,
        for_report=True,
    )
    predicted = {
        v: _in_run(exp, name, kind.predict, exp.sample, exp.rig, r.data, **ro.options, **extra)
        for v, extra in kind.variants.items()
    }
    return RunPrediction(name, r.data, predicted, info=dict(ro.info))


def validate(
    experiment: Experiment,
    runs: list[RunData] | None = None,
    *,
    mc_draws: int = MC_DRAWS,
    seed: int = 0,
    drop_na: bool = False,
    max_bytes: int | None = None,
    zeros: bool = True,
    zero_rule: str | None = None,
    ignore=(),
) -> ValidationResult:
    """Validate the thesis model of ``experiment.kind`` against its runs.

    Parameters
    ----------
    experiment : Experiment
    runs : list of RunData, optional
        Default: read the experiment's runs.
    mc_draws : int
        Monte Carlo draws for the dynamic band (0: none).
    seed : int
        Seed of the Monte Carlo draws.
    drop_na : bool
        Drop blank cells on reading (counted in the report).
    max_bytes : int, optional
        Refuse run files larger than this [bytes] (default
        :data:`tcamlab.io.DEFAULT_MAX_BYTES`).
    zeros : bool
        Estimate and subtract each run's nuisance zeros
        (:data:`tcamlab.metrics.ZERO_METHOD_NOTE`); False compares the log as
        it is (a re-zeroed first row is then an exact, zero residual).
    zero_rule : {"rest", "whole-run"}, optional
        Default: the experiment file's ``[validation] zero`` (else ``"rest"``). With
        ``"whole-run"`` the metrics under ``"rest"`` are kept as ``unadjusted``.
    ignore : iterable of str
        Canonical optional columns treated as not logged (:func:`ignored_columns`).

    Returns
    -------
    ValidationResult
    """
    ignored = ignored_columns(experiment.kind, ignore)
    if runs is None:
        kw = {} if max_bytes is None else {"max_bytes": max_bytes}
        runs = experiment.read_runs(drop_na=drop_na, **kw)
    logged, runs = runs, without_columns(runs, ignored)
    names = _run_names(runs)
    kind = get_kind(experiment.kind)
    preds = _predict_runs(experiment, kind, runs, names)
    rule = (zero_rule or getattr(experiment, "zero_rule", ZERO_REST)) if zeros else ZERO_REST
    zero_notes, unadjusted = _apply_zeros(kind, preds, rule) if zeros else ([], None)
    notes, extras = kind.validation_extras(
        experiment,
        preds,
        mc_draws=mc_draws,
        seed=seed,
        call=lambda name, fn, *a, **k: _in_run(experiment, name, fn, *a, **k),
    )
    variants, primary = list(kind.variants), kind.primary
    metrics = _metrics(preds, variants, kind.outputs)
    pooled = {q: b["pooled"] for q, b in metrics[primary].items()}
    checks = check_thresholds(pooled, experiment.thresholds)
    notes = zero_notes + notes + ([_ignored_note(logged, ignored)] if ignored else [])
    dropped = sum(r.n_dropped for r in runs)
    if dropped:
        notes.append(f"{dropped} rows with blank cells were dropped (--drop-na)")
    notes += [n for r in runs for n in smoothed_notes(r)]
    warnings = sanity_warnings(kind, preds, metrics) + list(extras.pop("warnings", []))
    warnings += unused_threshold_warnings(experiment.thresholds, checks, list(metrics[primary]))
    warnings += [
        w
        for w in calibrated_parameter_warnings(experiment) + identified_parameter_warnings(experiment, runs)
        if w is not None
    ]
    result = ValidationResult(experiment, runs, preds, variants, primary, metrics, checks, notes, extras)
    result.warnings, result.zero_rule, result.unadjusted = warnings, rule, unadjusted
    result.ignored = ignored
    return result


def _apply_zeros(kind: Kind, preds: list[RunPrediction], rule: str) -> tuple[list[str], dict | None]:
    """Subtract the zeros under ``rule`` (:func:`_subtract_zeros`); the notes, and with the
    whole-run rule the metrics under the rest rule (unadjusted), else None."""
    unadjusted = None
    if rule == ZERO_WHOLE_RUN:
        logged = [_copy_prediction(p) for p in preds]
        _subtract_zeros(kind, logged, ZERO_REST)
        unadjusted = _metrics(logged, list(kind.variants), kind.outputs)
    return _subtract_zeros(kind, preds, rule), unadjusted


def _copy_prediction(p: RunPrediction) -> RunPrediction:
    """A copy of a run's prediction that zeros can be subtracted from independently."""
    predicted = {v: dict(d) for v, d in p.predicted.items()}
    return RunPrediction(p.name, p.data.copy(), predicted, p.band, dict(p.info))
