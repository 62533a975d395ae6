"""Typed results of the diagnosis.

Every stage of :func:`tcamlab.diagnosis.diagnose` returns one of these
dataclasses. Their fields carry units in their docstrings; they also read
like the mappings of the JSON layout (``result.gap["limit"]``), so
:meth:`DiagnosisResult.to_dict` is their plain conversion.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from tcamlab.diagnosis.paired import paired_tests
from tcamlab.jsonutil import to_jsonable
from tcamlab.units import display

__all__ = [
    "SCHEMA_VERSION",
    "Record",
    "QuantityNoise",
    "NoiseFloor",
    "Baseline",
    "Gap",
    "Regime",
    "RunStatistics",
    "Settings",
    "CandidateResult",
    "DiagnosisResult",
    "stand_ins_text",
]


class Record(Mapping):
    """A dataclass that also reads as the mapping of its fields (its JSON object)."""

    def __getitem__(self, key: str) -> Any:
        if key not in self._keys():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())

    def _keys(self) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(self))

    def to_dict(self) -> dict:
        """JSON-safe dict of the fields (non-finite numbers become null)."""
        return to_jsonable(dict(self))


@dataclass(frozen=True, eq=False)
class QuantityNoise(Record):
    """Noise floor of one measured quantity."""

    sigma: float
    """Noise sd [display unit of the quantity, e.g. mm]."""
    unit: str
    """That display unit."""
    per_run: list
    """Second-difference sd of each run, with the quantisation error it cannot see
    (:func:`tcamlab.io.quantisation.unseen_variance`) [display unit]; NaN for a run that
    does not log the quantity."""
    dof: float
    """Effective degrees of freedom of ``sigma**2`` [-]."""
    method: str
    """How it was estimated."""
    quantisation_step: float | None = None
    """The logged column's quantisation step [display unit], None if it has none."""


@dataclass(frozen=True, eq=False)
class NoiseFloor(Record):
    """Noise floor of every quantity, from the data alone."""

    quantities: list
    """The quantities scored (internal names): the kind's outputs, then every other column the
    model predicts that some run logs (a voltage-step test's current), each scored on the runs
    that log it."""
    method: str
    """The estimator, in words."""
    by_quantity: dict
    """Quantity -> :class:`QuantityNoise`."""
    between_runs: dict
    """Between-run spread of the residuals per quantity (``available`` False with a reason)."""


@dataclass(frozen=True, eq=False)
class Baseline(Record):
    """The thesis model's fit to all runs."""

    rmse_over_noise: float
    """Pooled RMSE of the normalised residuals [noise-floor multiples]."""
    n: int
    """Residuals pooled (rows times quantities)."""
    by_quantity: dict
    """Quantity -> {rmse, bias [display unit], rmse_over_noise [-], unit}."""
    aic: float
    """Akaike information criterion of the normalised residuals."""
    bic: float
    """Bayesian information criterion of the normalised residuals."""
    spring_constant_N_per_m: float | None
    """Sensing S used on all runs [N/m] (None: the kind has none to identify)."""
    options: dict
    """Where the per-run constants came from."""


@dataclass(frozen=True, eq=False)
class Gap(Record):
    """Whether the baseline misses the data by more than the noise."""

    rmse_over_noise: float
    """Baseline RMSE [noise-floor multiples], over N - R degrees of freedom (R profiled zeros)."""
    limit: float
    """Largest RMSE consistent with no gap at ``level`` [noise-floor multiples]."""
    level: float
    """Quantile of the no-gap distribution used [-]."""
    expected_rmse_over_noise_without_gap: float
    """Expected RMSE without a gap [noise-floor multiples] (1: the RMSE is over N - R)."""
    nuisance_zeros: list
    """Quantities whose per-run zero is profiled out (each run's mean residual)."""
    n_points: int
    """Residuals pooled."""
    noise_dof: float
    """Smallest degrees of freedom of a quantity's noise estimate."""
    significant: bool
    """``rmse_over_noise > limit``."""
    rule: str
    """The test, in words."""
    run_to_run: dict = field(default_factory=dict)
    """{sample field: relative sd} of each run's departure from the shared sample, profiled
    out of every run before the test (:func:`tcamlab.kinds.run_scatter`)."""


@dataclass(frozen=True, eq=False)
class Regime(Record):
    """Baseline residuals in one regime (a temperature band, a phase ...)."""

    group: str
    regime: str
    n: int
    """Rows times quantities in the regime."""
    rmse_over_noise: float
    """[noise-floor multiples]"""
    bias_over_noise: float
    """[noise-floor multiples]"""
    share: float
    """Share of the total squared normalised residual [-]."""
    by_quantity: dict
    """Quantity -> {n, rmse, bias [display unit], unit}."""


@dataclass(frozen=True, eq=False)
class RunStatistics(Record):
    """Baseline residual statistics of one run."""

    index: int
    name: str
    n: int
    by_quantity: dict
    """Quantity -> {rmse, bias, noise_sigma [display unit], unit, lag1_autocorrelation,
    durbin_watson, correlation_with_inputs}."""


@dataclass(frozen=True, eq=False)
class Settings(Record):
    """How the diagnosis was run."""

    n_boot: int
    seed: int
    folds: int
    fold_scheme: str
    candidates: list
    gap_level: float
    min_fraction_closed: float
    ci_level: float
    fold_details: list
    ignored_columns: list = field(default_factory=list)
    """Canonical logged columns treated as not logged (``diagnose --ignore``)."""


SCHEMA_VERSION = 2
"""Version of the :meth:`DiagnosisResult.to_dict` layout."""


@dataclass
class CandidateResult:
    """One candidate effect's scores.

    RMSEs ``heldout_rmse_before`` / ``heldout_rmse_after`` are pooled over the
    withheld folds, in ``unit`` (the display unit when every quantity of the
    kind shares one, else ``"noise"`` = multiples of the noise floor);
    ``*_noise`` are the same in noise-floor multiples; ``by_quantity`` gives
    each quantity in its own display unit. ``shrinkage`` = 1 - after/before
    (noise-normalised), ``fraction_closed`` = (before^2 - after^2) /
    (before^2 - floor^2) in noise units, where floor^2 = (N - R) / N is the squared
    RMSE/noise that N points leave after R fitted zeros (1 without zeros).
    """

    effect: str
    heldout_rmse_before: float
    heldout_rmse_after: float
    unit: str
    heldout_rmse_before_noise: float
    heldout_rmse_after_noise: float
    shrinkage: float
    shrinkage_ci95: list
    fraction_closed: float
    aic: float
    bic: float
    parameters: dict
    by_quantity: dict
    folds: list
    cause: str = ""
    separate_by: str = ""
    fit_success: bool = True
    members: tuple[str, ...] = ()
    """The single effects this candidate is made of (one, or two for a pair; none for
    recalibration alone)."""
    recalibrated: dict = field(default_factory=dict)
    """The kind's calibrated parameters fitted with it on all runs: name -> {symbol, value,
    ci95, unit, stated, stated_sd, prior_sd, shift_in_stated_sds, shift_in_prior_sds,
    pinned_by} [SI]."""
    recalibration_plausible: bool | None = None
    """Whether those values are within the priors (:data:`PLAUSIBLE_LEVEL`)."""
    term_rms: float = float("nan")
    """RMS of what the effect's term adds to the predictions at its all-runs fit, at the same
    recalibrated parameters [noise-floor multiples] (NaN for recalibration alone)."""
    shift_u: np.ndarray | None = field(default=None, repr=False)
    """The calibrated parameters' shift from their stated values in fitted coordinates
    (log value, or value over prior sd), in the order of ``recalibrated``."""
    shift_cov: np.ndarray | None = field(default=None, repr=False)
    """Posterior covariance of ``shift_u`` (the effect's parameters marginalised out)."""
    joint_cov: np.ndarray | None = field(default=None, repr=False)
    """Posterior covariance of (``shift_u``, the effect's parameters [SI]), in the order of
    ``recalibrated`` then ``parameters``."""

    def to_dict(self) -> dict:
        return to_jsonable(
            {
                "effect": self.effect,
                "heldout_rmse_before": self.heldout_rmse_before,
                "heldout_rmse_after": self.heldout_rmse_after,
                "unit": self.unit,
                "heldout_rmse_before_noise": self.heldout_rmse_before_noise,
                "heldout_rmse_after_noise": self.heldout_rmse_after_noise,
                "shrinkage": self.shrinkage,
                "shrinkage_ci95": self.shrinkage_ci95,
                "fraction_closed": self.fraction_closed,
                "aic": self.aic,
                "bic": self.bic,
                "parameters": self.parameters,
                "by_quantity": self.by_quantity,
                "folds": self.folds,
                "cause": self.cause,
                "separate_by": self.separate_by,
                "fit_success": self.fit_success,
                "recalibrated": self.recalibrated,
                "recalibration_plausible": self.recalibration_plausible,
                "term_rms_noise": self.term_rms,
                "recalibrated_shift": (
                    {"u": self.shift_u, "covariance": self.shift_cov, "joint_covariance": self.joint_cov}
                    if self.shift_u is not None
                    else None
                ),
            }
        )


def _and(words) -> str:
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def stand_ins_text(stand_ins: dict) -> str:
    """Stand-ins and the moved parameters each takes over, in words.

    Parameters
    ----------
    stand_ins : dict
        ``{effect: [parameters]}``, or ``{effect: None}`` when that is not known.

    Returns
    -------
    str
        "E (with P at its stated value) and F"; an effect with no parameters takes over
        the combination the data fix (:func:`tcamlab.diagnosis.verdict.restores_combination`).
    """

    def one(effect, params):
        if params is None:
            return effect
        if not params:
            return f"{effect} (with the combination of parameters the data fix at its stated value)"
        if len(params) == 1:
            return f"{effect} (with {params[0]} at its stated value)"
        return f"{effect} (with {_and(params)} at their stated values)"

    return _and([one(e, p) for e, p in stand_ins.items()])


@dataclass
class DiagnosisResult:
    """Outcome of :func:`diagnose`; see :meth:`to_dict` for the JSON layout."""

    kind: str
    experiment: dict
    verdict: str
    effect: str | None
    ranking: list[CandidateResult]
    aliased_with: list[str]
    separate_by: dict
    noise_floor: NoiseFloor
    baseline: Baseline
    regimes: list[Regime]
    runs: list[RunStatistics]
    gap: Gap
    reason: str
    settings: Settings
    combination: dict | None = None
    recalibration: dict | None = None
    """The recalibration behind a ``miscalibrated`` (or parameter-aliased) verdict:
    {parameters {name: ...}, named [names], plausible, prior_chi2}; else None."""
    paired_tests: list[dict] | None = None
    """The paired tests of every other candidate against the named one on the withheld folds
    (:func:`tcamlab.diagnosis.paired.paired_tests`, computed from ``ranking`` and ``settings``
    when the result is made), one dict per other candidate in ranking order: ``candidate``,
    ``best`` (the candidate it is tested against), ``diff`` (pooled held-out mean squared
    normalised residual of it minus the best's [noise sd²], each fold weighted by its
    held-out rows), ``ci95`` ([lo, hi], 95 % paired bootstrap over folds), ``p_boot``
    (one-sided: share of resamples with ``diff`` <= 0), ``n_boot``, ``seed`` (the bootstrap's),
    ``worse_folds``, ``folds``, ``p_sign`` (one-sided sign test over folds),
    ``intervals_overlap`` (its shrinkage interval overlaps the best's) and ``clearly_worse``
    (``ci95`` above 0 and no overlap). Empty without a named candidate or per-fold scores."""
    stand_ins_words: str | None = None
    """For ``miscalibrated`` with effects in ``aliased_with``: those effects with the
    parameters each takes over, in words (:func:`stand_ins_text`, from
    ``recalibration["stand_ins"]``; filled when the result is made); else ""."""
    warnings: list = field(default_factory=list)
    """Lines on the logs themselves that bear on every figure (a channel beyond what a thread
    muscle plausibly logs: :func:`tcamlab.metrics.implausible_value_warnings`)."""
    next_experiment: dict | None = None
    """The protocol to run next, when the design was run on this diagnosis
    (:meth:`tcamlab.design.DesignResult.to_dict`); None otherwise (then not in :meth:`to_dict`)."""
    _series: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.paired_tests is None:
            self.paired_tests = paired_tests(self)
        if self.stand_ins_words is None:
            self.stand_ins_words = _stand_ins_words(self.verdict, self.aliased_with, self.recalibration)

    # -- export --------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-safe dict (no NaN: non-finite numbers become null)."""
        return to_jsonable(
            {
                "schema_version": SCHEMA_VERSION,
                "kind": self.kind,
                "experiment": self.experiment,
                "verdict": self.verdict,
                "effect": self.effect,
                "aliased_with": self.aliased_with,
                "separate_by": self.separate_by,
                "reason": self.reason,
                "gap": self.gap,
                "noise_floor": self.noise_floor,
                "baseline": self.baseline,
                "ranking": [c.to_dict() for c in self.ranking],
                "combination": self.combination,
                "recalibration": self.recalibration,
                "regimes": self.regimes,
                "runs": self.runs,
                "settings": self.settings,
                "paired_tests": self.paired_tests,
                "stand_ins_words": self.stand_ins_words,
                "warnings": list(self.warnings),
            }
            | ({"next_experiment": self.next_experiment} if self.next_experiment is not None else {})
        )

    def to_pandas(self) -> pd.DataFrame:
        """The ranking as a table, one row per candidate (best first)."""
        rows = []
        for c in self.ranking:
            row = {
                "effect": c.effect,
                "unit": c.unit,
                "heldout_rmse_before": c.heldout_rmse_before,
                "heldout_rmse_after": c.heldout_rmse_after,
                "shrinkage": c.shrinkage,
                "shrinkage_ci95_low": c.shrinkage_ci95[0],
                "shrinkage_ci95_high": c.shrinkage_ci95[1],
                "fraction_closed": c.fraction_closed,
                "aic": c.aic,
                "bic": c.bic,
            }
            for name, p in c.parameters.items():
                row[f"{name} [{p['unit']}]"] = p["value"]
                row[f"{name}_ci95_low"] = p["ci95"][0]
                row[f"{name}_ci95_high"] = p["ci95"][1]
            rows.append(row)
        return pd.DataFrame(rows)

    @property
    def best(self) -> CandidateResult | None:
        return self.ranking[0] if self.ranking else None

    # -- plots ---------------------------------------------------------------
    def plot_residuals(self, ax=None, *, group: str | None = None):
        """Baseline residuals (noise-floor multiples) per regime, +-noise band."""
        ax = _axes(ax)
        s = self._series
        groups = [g for g in s.get("regime_groups", [])]
        if not groups:
            return ax
        group = group or groups[0]
        labels = s["labels"][group]
        names = list(dict.fromkeys(lab for lab in labels if lab))
        data = [s["z"][labels == name] for name in names]
        if data:
            ax.boxplot(data, showfliers=False)
            ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
        ax.axhspan(-1, 1, color="0.85", zorder=0, label="noise floor")
        ax.axhline(0, color="0.3", lw=0.8)
        ax.set_ylabel("residual / noise floor")
        ax.set_title(f"baseline residuals by {group}")
        return ax

    def plot_forest(self, ax=None):
        """Held-out shrinkage with its bootstrap interval per candidate."""
        ax = _axes(ax)
        names = [c.effect for c in self.ranking]
        y = np.arange(len(names))[::-1]
        for yi, c in zip(y, self.ranking):
            lo, hi = c.shrinkage_ci95
            color = "#d62728" if c.effect == self.effect else "#1f77b4"
            ax.errorbar(
                [c.shrinkage * 100],
                [yi],
                xerr=[[max(0.0, (c.shrinkage - lo) * 100)], [max(0.0, (hi - c.shrinkage) * 100)]],
                fmt="o",
                color=color,
                capsize=3,
            )
        ax.axvline(0, color="0.3", lw=0.8)
        ax.set_yticks(y, names)
        ax.set_xlabel("held-out RMSE shrinkage [%] (95 % bootstrap interval)")
        return ax

    def plot_overlay(self, ax=None, run: int = 0, quantity: str | None = None):
        """Measured, baseline and best-candidate prediction of one run."""
        ax = _axes(ax)
        s = self._series
        if not s.get("runs"):
            return ax
        r = s["runs"][run]
        q = quantity or self.noise_floor["quantities"][0]
        unit, fac = display(q)
        x, xlabel = r["x"], r["xlabel"]
        ax.plot(x, r["measured"][q] * fac, ".", ms=2, color="0.4", label="measured")
        ax.plot(x, r["baseline"][q] * fac, "-", color="#1f77b4", label="thesis model")
        if r.get("best") is not None:
            name = self.effect or (self.ranking[0].effect if self.verdict != "miscalibrated" else None)
            label = f"+ {name}" if name else "recalibrated"
            ax.plot(x, r["best"][q] * fac, "-", color="#d62728", label=label)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{q} [{unit}]")
        ax.legend()
        return ax


def _stand_ins_words(verdict: str, aliased_with: list, recalibration: dict | None) -> str:
    """:attr:`DiagnosisResult.stand_ins_words` of a result ("" unless ``miscalibrated`` with
    effects in ``aliased_with``)."""
    if verdict != "miscalibrated" or not aliased_with:
        return ""
    takes = (recalibration or {}).get("stand_ins") or {}
    return stand_ins_text({e: takes.get(e) for e in aliased_with})


def _axes(ax):
    if ax is not None:
        return ax
    from tcamlab.report.figures import new_figure

    return new_figure()[1]
