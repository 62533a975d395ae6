"""The calibration problem: parameter vector, priors, noise floors and stacked residuals.

The fitted vector ``u`` holds one entry per calibrated parameter: ``log(value)``
for positive parameters, ``value / prior_sd`` otherwise. Each run's zero of a
zero-referenced quantity (:attr:`tcamlab.kinds.Kind.nuisance_zeros`) has a flat
prior and enters linearly, so it is profiled out exactly (variable projection):
for any ``u`` it is the mean of the run's ``measured - predicted``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tcamlab.errors import InputError, TcamlabError
from tcamlab.kinds import CalibrationParam, get_kind
from tcamlab.params import RIG_KEYS, SAMPLE_KEYS
from tcamlab.signals import second_difference_sigma
from tcamlab.text import did_you_mean

__all__ = ["Spec", "CalibrationProblem", "FAIL_RESIDUAL", "FD_STEP"]

FAIL_RESIDUAL = 1.0e3
"""Normalised residual of every point when the model fails (outside its domain)."""

FD_STEP = 1e-3
"""Central-difference step of the Jacobian in ``u`` (0.1 % of a positive parameter)."""

MAX_LOG_SPAN = math.log(1e3)
"""Largest excursion of a positive parameter from its stated value, in log space."""

_LAB_KEYS = {
    "sample": {si: (key, f) for key, (si, f) in SAMPLE_KEYS.items()},
    "rig": {si: (key, f) for key, (si, f) in RIG_KEYS.items()},
}


@dataclass(frozen=True)
class Spec:
    """One calibrated parameter of the problem.

    Attributes
    ----------
    name : str
        ``field``, or ``EXPERIMENT.field`` for a rig parameter of several experiments.
    param : CalibrationParam
        The kind's description (symbol, unit, default sd, positivity).
    experiments : tuple of int
        Indices of the experiments it applies to.
    stated : float
        Value the prior is centred on [SI]: the file's, or identified when it states none.
    stated_in_file : bool
        Whether the experiment file (or its preset) states the value.
    prior_sd : float
        Prior sd [SI]: the stated sd, else ``default_sd * |stated|``.
    sd_stated : bool
        Whether ``prior_sd`` is the file's ``[rig.uncertainty]``/``[sample.uncertainty]``.
    key : str
        Key of the experiment file (lab units), e.g. ``thermal_mass_J_per_K``.
    factor : float
        SI per lab unit of ``key``.
    """

    name: str
    param: CalibrationParam
    experiments: tuple[int, ...]
    stated: float
    stated_in_file: bool
    prior_sd: float
    sd_stated: bool
    key: str
    factor: float

    @property
    def u0(self) -> float:
        """Prior centre in fitted coordinates."""
        return self.to_u(self.stated)

    @property
    def sd_u(self) -> float:
        """Prior sd in fitted coordinates (sd / value for a positive parameter)."""
        return self.prior_sd / abs(self.stated) if self.param.positive else 1.0

    def to_u(self, value: float) -> float:
        """Fitted coordinate of a value [SI]."""
        return math.log(value) if self.param.positive else value / self.prior_sd

    def from_u(self, u: float) -> float:
        """Value [SI] of a fitted coordinate."""
        return math.exp(u) if self.param.positive else u * self.prior_sd


def _unstated_start(kind, exp, runs, fld: str) -> float:
    """Start value of a rig field the file leaves unstated, by the kind's own rule on all runs."""
    training = [(r.data, np.ones(len(r.data), bool)) for r in runs]
    values = []
    for r in runs:
        ro = kind.run_options(exp.sample, exp.rig, r.data, training=training, where=str(exp.path))
        if fld not in ro.options:
            raise InputError(f"{exp.path}: calibration needs a start value of {fld}", "state it in [rig]")
        values.append(float(ro.options[fld]))
    return float(np.mean(values))


class CalibrationProblem:
    """Experiments of one sample, their runs, the calibrated parameters and the residuals.

    Parameters
    ----------
    experiments : sequence of Experiment
        Loaded experiment files with equal ``[sample]``.
    runs : sequence of list of RunData
        The runs of each experiment.
    names : sequence of str, optional
        Parameters to calibrate (``Spec.name``); default all of the kinds'.
    """

    def __init__(self, experiments: Sequence, runs: Sequence[list], names: Sequence[str] | None = None):
        self.experiments = list(experiments)
        self.runs = [list(r) for r in runs]
        self.kinds = [get_kind(e.kind) for e in self.experiments]
        self.samples = [e.sample for e in self.experiments]
        self.rigs = [self._filled_rig(i) for i in range(len(self.experiments))]
        specs = self._all_specs()
        self.specs = self._select(specs, names)
        self.u0 = np.array([s.u0 for s in self.specs])
        self.sd_u = np.array([s.sd_u for s in self.specs])
        self.quantities = [self._quantities(i) for i in range(len(self.experiments))]
        self.sigma = self._noise()
        self.size = sum(len(r.data) * len(q) for rs, q in zip(self.runs, self.quantities) for r in rs)

    # construction ----------------------------------------------------------------------
    def _filled_rig(self, i: int):
        """The rig with every unstated calibratable field set to its start value."""
        exp, kind = self.experiments[i], self.kinds[i]
        fill = {}
        for p in kind.calibration:
            if p.where == "rig" and getattr(exp.rig, p.field) is None:
                fill[p.field] = _unstated_start(kind, exp, self.runs[i], p.field)
        return exp.rig.replace(**fill)

    def _spec(self, p: CalibrationParam, idx: tuple[int, ...], name: str) -> Spec:
        exp = self.experiments[idx[0]]
        holder = self.samples[idx[0]] if p.where == "sample" else self.rigs[idx[0]]
        value = float(getattr(holder, p.field))
        unc = exp.sample_uncertainty if p.where == "sample" else exp.rig.uncertainty
        sd = unc.get(p.field)
        sd_stated = sd is not None and sd > 0
        in_file = p.where == "sample" or getattr(exp.rig, p.field) is not None
        key, factor = _LAB_KEYS[p.where][p.field]
        prior_sd = float(sd) if sd_stated else p.default_sd * abs(value)
        return Spec(name, p, idx, value, in_file, prior_sd, sd_stated, key, factor)

    def _all_specs(self) -> list[Spec]:
        specs: dict[str, Spec] = {}
        several = len(self.experiments) > 1
        for i, kind in enumerate(self.kinds):
            for p in kind.calibration:
                if p.where == "sample":
                    if p.field not in specs:
                        specs[p.field] = self._spec(p, tuple(range(len(self.experiments))), p.field)
                else:
                    name = f"{self.experiments[i].name}.{p.field}" if several else p.field
                    specs[name] = self._spec(p, (i,), name)
        return list(specs.values())

    @staticmethod
    def _select(specs: list[Spec], names: Sequence[str] | None) -> list[Spec]:
        if not names:
            return specs
        known = [s.name for s in specs]
        for n in names:
            if n not in known:
                raise InputError(
                    f"--params: {n!r} is not a calibratable parameter of these experiments"
                    + did_you_mean(n, known),
                    "one of " + ", ".join(known),
                )
        return [s for s in specs if s.name in names]

    def _quantities(self, i: int) -> tuple[str, ...]:
        """The kind's outputs plus every other predicted column logged in all runs (temperature)."""
        kind = self.kinds[i]
        pred = self.predict_run(i, 0, self.u0)
        extra = [q for q in pred if q not in kind.outputs and all(q in r.data for r in self.runs[i])]
        return tuple(kind.outputs) + tuple(extra)

    def _noise(self) -> dict[tuple[int, str], float]:
        """Noise sd per (experiment, quantity) [SI]: second differences of the residuals at
        the stated values, median over runs."""
        out = {}
        for i, qs in enumerate(self.quantities):
            preds = [self.predict_run(i, j, self.u0) for j in range(len(self.runs[i]))]
            for q in qs:
                s = [second_difference_sigma(self.measured(i, j, q) - p[q]) for j, p in enumerate(preds)]
                sd = float(np.nanmedian(s))
                if not (sd > 0 and math.isfinite(sd)):
                    raise InputError(
                        f"{self.experiments[i].path}: the noise of {q} cannot be estimated (a constant log?)"
                    )
                out[(i, q)] = sd
        return out

    # evaluation ------------------------------------------------------------------------
    def values(self, u: np.ndarray) -> dict[str, float]:
        """Calibrated values [SI] by spec name."""
        return {s.name: s.from_u(float(x)) for s, x in zip(self.specs, u)}

    def models(self, i: int, u: np.ndarray):
        """Sample and rig of experiment ``i`` at ``u``."""
        sample_kw, rig_kw = {}, {}
        for s, x in zip(self.specs, u):
            if i in s.experiments:
                (sample_kw if s.param.where == "sample" else rig_kw)[s.param.field] = s.from_u(float(x))
        return self.samples[i].replace(**sample_kw), self.rigs[i].replace(**rig_kw)

    def predict_run(self, i: int, j: int, u: np.ndarray, mods=None) -> dict[str, np.ndarray]:
        """Predictions [SI] of run ``j`` of experiment ``i`` at ``u`` (raises outside the domain).

        ``mods`` (a :class:`tcamlab.effects.Mods`) adds effect terms; the diagnosis fits an
        effect together with the calibrated parameters through it."""
        kind = self.kinds[i]
        sample, rig = self.models(i, u)
        data = self.runs[i][j].data
        opts = dict(kind.run_options(sample, rig, data, where=str(self.experiments[i].path)).options)
        opts.update(kind.variants[kind.primary])
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = (
                kind.predict(sample, rig, data, **opts)
                if mods is None
                else kind.predict(sample, rig, data, mods, **opts)
            )
        for q, v in out.items():
            if not np.all(np.isfinite(v)):
                raise ArithmeticError(f"non-finite prediction of {q}")
        return out

    def measured(self, i: int, j: int, q: str) -> np.ndarray:
        return self.runs[i][j].data[q].to_numpy(float)

    def raw_residuals(self, u: np.ndarray) -> list[tuple[int, int, str, np.ndarray]] | None:
        """``(experiment, run, quantity, measured - predicted [SI])``, or None outside the domain."""
        out = []
        try:
            for i, qs in enumerate(self.quantities):
                for j in range(len(self.runs[i])):
                    pred = self.predict_run(i, j, u)
                    out.extend((i, j, q, self.measured(i, j, q) - pred[q]) for q in qs)
        except (TcamlabError, ArithmeticError, FloatingPointError, ZeroDivisionError, ValueError):
            return None
        return out

    def is_zeroed(self, i: int, q: str) -> bool:
        """Whether quantity ``q`` of experiment ``i`` carries a per-run nuisance zero."""
        return q in self.kinds[i].nuisance_zeros

    def zeros(self, u: np.ndarray) -> np.ndarray:
        """The profiled nuisance zeros at ``u`` [SI], in :meth:`zero_labels` order."""
        raw = self.raw_residuals(u)
        if raw is None:
            return np.full(len(self.zero_labels()), np.nan)
        return np.array([float(np.mean(r)) for i, _, q, r in raw if self.is_zeroed(i, q)])

    def zero_labels(self) -> list[tuple[int, int, str]]:
        return [
            (i, j, q)
            for i, qs in enumerate(self.quantities)
            for j in range(len(self.runs[i]))
            for q in qs
            if self.is_zeroed(i, q)
        ]

    def data_residuals(self, u: np.ndarray) -> np.ndarray:
        """Normalised data residuals (measured - predicted - zero) / sigma, stacked."""
        raw = self.raw_residuals(u)
        if raw is None:
            return np.full(self.size, FAIL_RESIDUAL)
        parts = []
        for i, _, q, r in raw:
            parts.append(((r - r.mean()) if self.is_zeroed(i, q) else r) / self.sigma[(i, q)])
        return np.concatenate(parts)

    def residuals(self, u: np.ndarray) -> np.ndarray:
        """Data residuals followed by the prior residuals (u - u0) / sd_u."""
        return np.concatenate([self.data_residuals(u), (np.asarray(u) - self.u0) / self.sd_u])

    def prior_residuals(self, u: np.ndarray) -> np.ndarray:
        """The prior residuals ``(u - u0) / sd_u`` (the tail of :meth:`residuals`)."""
        return (np.asarray(u) - self.u0) / self.sd_u

    def jacobian(self, u: np.ndarray, cols: Sequence[int] | None = None, fn=None) -> np.ndarray:
        """Central-difference Jacobian of ``fn`` (default :meth:`residuals`) in the given columns."""
        fn = fn or self.residuals
        cols = range(len(u)) if cols is None else cols
        out = []
        for k in cols:
            up, dn = np.array(u, float), np.array(u, float)
            up[k] += FD_STEP
            dn[k] -= FD_STEP
            out.append((fn(up) - fn(dn)) / (2 * FD_STEP))
        return np.column_stack(out) if out else np.zeros((len(fn(u)), 0))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box of the fitted coordinates: six prior sds, at most a factor 1000 for positives."""
        span = np.array(
            [
                min(6 * sd, MAX_LOG_SPAN) if s.param.positive else 6 * sd
                for s, sd in zip(self.specs, self.sd_u)
            ]
        )
        return self.u0 - span, self.u0 + span
