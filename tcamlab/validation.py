"""Validation: run the thesis model on each run's inputs and measure the error.

``validate(experiment)`` returns a :class:`ValidationResult` holding, per run,
the measured and predicted columns, error metrics per model variant and
quantity (per run and pooled), threshold checks, and kind-specific extras
(spring constants used for sensing, the Monte Carlo band for dynamic runs).
Each run's zero of every zero-referenced channel (:attr:`Kind.nuisance_zeros`)
is estimated and subtracted before the metrics and the kind's extras
(:data:`tcamlab.metrics.ZERO_METHOD_NOTE`).
No file is written here: see :mod:`tcamlab.pipeline`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from tcamlab.config import Experiment
from tcamlab.errors import ConvergenceError, IntegrationError, ModelDomainError
from tcamlab.io import RunData, input_files, sha256_file
from tcamlab.kinds import Kind, get_kind, rest_rows
from tcamlab.metrics import (
    MIN_REST_ROWS,
    SANITY_CHECKS,
    STATUS_FAILED,
    STATUS_PASSED,
    check_thresholds,
    domain_warning,
    error_metrics,
    estimate_zero,
    flat_prediction_warning,
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

__all__ = ["ValidationResult", "RunPrediction", "validate", "MC_DRAWS"]

MC_DRAWS = 1000
"""Monte Carlo draws for the dynamic prediction band."""


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
        nuisance zero (its ``stderr`` is the zero's sd, e.g. for a prediction band).
    """

    name: str
    data: pd.DataFrame
    predicted: dict
    band: dict | None = None
    info: dict = field(default_factory=dict)
    zeros: dict = field(default_factory=dict)


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

    def zeros_dict(self) -> dict:
        """The ``zeros`` block of metrics.json: per run and quantity, in lab units."""
        runs = {}
        for p in self.predictions:
            if p.zeros:
                runs[p.name] = {
                    quantity(q).column: z.scaled(quantity(q).factor).to_dict() for q, z in p.zeros.items()
                }
        return {"min_rest_rows": MIN_REST_ROWS, "runs": runs}

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
                    "dropped_rows": int(r.n_dropped),
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


def _metrics(predictions, variants, quantities) -> dict:
    """Metrics per variant, quantity, run and pooled; ``n_zeros`` counts the zeros subtracted."""
    out = {}
    for v in variants:
        out[v] = {}
        for q in quantities:
            name, factor = quantity(q).column, quantity(q).factor
            pairs = [(p.data[q].to_numpy() * factor, p.predicted[v][q] * factor) for p in predictions]
            runs = {}
            for p, (m, pr) in zip(predictions, pairs):
                runs[p.name] = {**error_metrics(m, pr), "n_zeros": int(q in p.zeros)}
            pooled = {**pooled_metrics(pairs), "n_zeros": sum(int(q in p.zeros) for p in predictions)}
            out[v][name] = {"runs": runs, "pooled": pooled}
    return out


def _own_zeros(kind: Kind, p: RunPrediction, q: str, raw: np.ndarray, rest, primary_zero: float) -> None:
    """Give every other variant its own nuisance zero: the zero is profiled per model, as in
    calibration, so a variant referenced to its own rest (the self-sensing EKF, tared at rest
    like the laser) is not charged the primary model's rest offset. The measurement keeps the
    primary's zero; the variant's prediction moves by the difference of the two zeros. Only
    for a zero from the rows at rest: a whole-run zero would take each model's bias away."""
    for v in kind.variants:
        if v == kind.primary or q not in p.predicted.get(v, {}):
            continue
        own = estimate_zero(raw, p.predicted[v][q], rest).value
        if np.isfinite(own):
            p.predicted[v] = {
                **p.predicted[v],
                q: np.asarray(p.predicted[v][q], float) + (own - primary_zero),
            }


def _subtract_zeros(kind: Kind, preds: list[RunPrediction]) -> list[str]:
    """Estimate each run's nuisance zeros with the primary model, subtract them (every other
    variant is shifted to its own zero, :func:`_own_zeros`); the notes."""
    sources: dict[str, set] = {}
    for p in preds:
        rest = rest_rows(kind, p.data)
        for q in kind.nuisance_zeros:
            if q not in kind.outputs or q not in p.data:
                continue
            raw = p.data[q].to_numpy(float)
            est = estimate_zero(raw, p.predicted[kind.primary][q], rest)
            if not np.isfinite(est.value):
                continue
            if "whole run" not in est.source:  # a whole-run zero would hide each model's bias
                _own_zeros(kind, p, q, raw, rest, est.value)
            p.data = p.data.assign(**{q: raw - est.value})
            p.zeros[q] = est
            sources.setdefault(q, set()).add(est.source)
    notes = []
    for q, src in sources.items():
        how = " or ".join(sorted(src))
        notes.append(
            f"the zero of {quantity(q).column} was estimated per run ({how}, with the {kind.primary} "
            f"model) and subtracted before the metrics; see the table of nuisance zeros"
            + ("; each other model is scored after its own zero" if len(kind.variants) > 1 else "")
            + (
                f" (fewer than {MIN_REST_ROWS} rows at rest: whole-run zeros make those runs' bias 0)"
                if "whole run" in src
                else ""
            )
        )
    return notes


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


def sanity_warnings(kind: Kind, preds: list[RunPrediction], metrics: dict) -> list:
    """Every sanity check of :data:`tcamlab.metrics.SANITY_CHECKS` on the primary model;
    a wrong reference (R0) first, as it explains the others."""
    out = _reference_warnings(kind, preds)
    for q in kind.outputs:
        col, factor = quantity(q).column, quantity(q).factor
        unit = unit_label(col)
        out += r2_warnings(col, metrics[kind.primary][col])
        measured = np.concatenate([p.data[q].to_numpy(float) for p in preds]) * factor
        predicted = np.concatenate([np.asarray(p.predicted[kind.primary][q], float) for p in preds]) * factor
        out.append(flat_prediction_warning(col, unit, measured, predicted))
        for p in preds:
            m, pr = p.data[q].to_numpy(float), np.asarray(p.predicted[kind.primary][q], float)
            out.append(domain_warning(p.name, col, int(np.sum(np.isfinite(m) & ~np.isfinite(pr))), m.size))
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
    except _MODEL_ERRORS as exc:
        prefix = f"{exp.path.name}, run {name}: "
        if exc.message.startswith(prefix):
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
    for i, (r, name) in enumerate(zip(runs, names)):
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
        preds.append(RunPrediction(name, r.data, predicted, info=dict(ro.info)))
    return preds


def validate(
    experiment: Experiment,
    runs: list[RunData] | None = None,
    *,
    mc_draws: int = MC_DRAWS,
    seed: int = 0,
    drop_na: bool = False,
    max_bytes: int | None = None,
    zeros: bool = True,
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

    Returns
    -------
    ValidationResult
    """
    if runs is None:
        kw = {} if max_bytes is None else {"max_bytes": max_bytes}
        runs = experiment.read_runs(drop_na=drop_na, **kw)
    names = _run_names(runs)
    kind = get_kind(experiment.kind)
    preds = _predict_runs(experiment, kind, runs, names)
    zero_notes = _subtract_zeros(kind, preds) if zeros else []
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
    notes = zero_notes + notes
    dropped = sum(r.n_dropped for r in runs)
    if dropped:
        notes.append(f"{dropped} rows with blank cells were dropped (--drop-na)")
    warnings = sanity_warnings(kind, preds, metrics)
    warnings += unused_threshold_warnings(experiment.thresholds, checks, list(metrics[primary]))
    warnings += [
        w
        for w in calibrated_parameter_warnings(experiment) + identified_parameter_warnings(experiment, runs)
        if w is not None
    ]
    return ValidationResult(
        experiment, runs, preds, variants, primary, metrics, checks, notes, extras, warnings
    )
