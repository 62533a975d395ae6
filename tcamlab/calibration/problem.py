"""The calibration problem: parameter vector, priors, noise floors and stacked residuals.

The fitted vector ``u`` holds one entry per calibrated parameter: ``log(value)``
for a parameter whose physics requires it to be positive (a stiffness, a thermal
mass), ``value / prior_sd`` for one whose physics allows 0 or a sign (rho, the G_t
slope, a sensor offset, a TCR): a fitted coordinate is defined at every value the
experiment file may state. Each run's zero of a
zero-referenced quantity (:attr:`tcamlab.kinds.Kind.nuisance_zeros`) has a flat
prior and enters linearly, so it is profiled out exactly (variable projection):
for any ``u`` it is the mean of the run's ``measured - predicted``.
"""

from __future__ import annotations

import math
import warnings
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from tcamlab import reduction
from tcamlab.errors import InputError, ModelDomainError, TcamlabError
from tcamlab.kinds import CalibrationParam, get_kind, rest_reading, run_scatter, scored_quantities, step_rows
from tcamlab.params import RIG_KEYS, SAMPLE_KEYS
from tcamlab.signals import block_means, n_blocks
from tcamlab.text import did_you_mean

__all__ = [
    "Spec",
    "CalibrationProblem",
    "FAIL_RESIDUAL",
    "FD_STEP",
    "random_effect_basis",
    "profile_random_effects",
]

FAIL_RESIDUAL = 1.0e3
"""Normalised residual of every point when the model fails (outside its domain)."""

FD_STEP = 1e-5
"""Finite-difference step of the Jacobian in ``u`` (1e-5 of a positive parameter): the
models are smooth to about 1e-10 of a residual at this scale, and the curvature kind's
R0 column is curved enough that a 1e-3 step puts 7 % into a forward difference."""

CACHE_SIZE = 8
"""Residual sets kept per experiment (the centre of a Jacobian and its last steps)."""

INPUT_STEP = 1e-6
"""Relative step of a noisy input column for the slopes of :meth:`CalibrationProblem.row_noise`."""

ROW_SIGMA_FLOOR = 0.5
"""Smallest row sd of :meth:`CalibrationProblem.row_noise`, a fraction of the single-sd
noise floor: no row weighs more than four times as much as under one sd."""

EFFECT_STEP = 1e-4
"""Relative step of a sample field for the random-effect columns of a run (its departures
are about 5e-4: the model is linear over them)."""

RESIDUAL_OVERFLOW = 1e100
"""Largest residual [SI] the noise floor squares and sums without overflow (any physical
quantity of these rigs is many orders of magnitude below it)."""

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
    reading : (float, float) or None
        The parameter as the logs read it directly, mean and sd [SI]
        (:attr:`~tcamlab.kinds.CalibrationParam.read_at_rest`), or None.
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
    reading: tuple[float, float] | None = None

    @property
    def stated_u0(self) -> float:
        """Centre of the stated prior in fitted coordinates."""
        return self.to_u(self.stated)

    @property
    def stated_sd_u(self) -> float:
        """Sd of the stated prior in fitted coordinates (sd / value for a positive parameter)."""
        return self.prior_sd / abs(self.stated) if self.param.positive else 1.0

    def _reading_u(self) -> tuple[float, float] | None:
        if self.reading is None:
            return None
        mean, sd = self.reading
        if self.param.positive:
            return (math.log(mean), sd / mean) if mean > 0 else None
        return mean / self.prior_sd, sd / self.prior_sd

    @property
    def u0(self) -> float:
        """Prior centre in fitted coordinates: the stated prior times the reading, if any
        (precision-weighted, in the fitted coordinates where both are Gaussian)."""
        r = self._reading_u()
        if r is None:
            return self.stated_u0
        w0, w1 = self.stated_sd_u**-2, r[1] ** -2
        return (w0 * self.stated_u0 + w1 * r[0]) / (w0 + w1)

    @property
    def sd_u(self) -> float:
        """Prior sd in fitted coordinates, the reading multiplied in."""
        r = self._reading_u()
        if r is None:
            return self.stated_sd_u
        return (self.stated_sd_u**-2 + r[1] ** -2) ** -0.5

    def to_u(self, value: float) -> float:
        """Fitted coordinate of a value [SI]."""
        return math.log(value) if self.param.positive else value / self.prior_sd

    def from_u(self, u: float) -> float:
        """Value [SI] of a fitted coordinate."""
        return math.exp(u) if self.param.positive else u * self.prior_sd


def random_effect_basis(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(U, 1 - 1/sqrt(1 + s^2))`` of random-effect columns ``G = U S V^T`` (normalised
    residual per prior sd of each effect): what :func:`profile_random_effects` needs."""
    u_mat, sv, _ = np.linalg.svd(g, full_matrices=False)
    return u_mat, 1.0 - 1.0 / np.sqrt(1.0 + sv**2)


def profile_random_effects(r: np.ndarray, u_mat: np.ndarray, shrink: np.ndarray) -> np.ndarray:
    """Normalised residuals ``r`` with random effects ``delta ~ N(0, I)`` of columns
    ``G = U S V^T`` profiled out exactly: minimising ``|r - G delta|^2 + |delta|^2`` over
    ``delta`` leaves ``r^T (I + G G^T)^-1 r``, the squared norm of
    ``(I + G G^T)^-1/2 r = r - U diag(1 - 1/sqrt(1 + s^2)) U^T r`` (same length as ``r``)."""
    return r - u_mat @ (shrink * (u_mat.T @ r))


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


def _slope_sum(g: dict[str, np.ndarray], n: int) -> np.ndarray:
    """sum over the noisy inputs of (d predicted / d input)^2, per row (zeros without inputs)."""
    out = np.zeros(n)
    for v in g.values():
        out = out + np.asarray(v, float) ** 2
    return out


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
    effect_params : bool
        Include parameters that are an effect of the library (``CalibrationParam.effect``,
        dynamic beta); the diagnosis's recalibration leaves them out.
    reduce : bool
        Fit a long run on its blocks' moments (:mod:`tcamlab.reduction`); the diagnosis
        reduces its own (with its noise floor and folds) and passes False.
    """

    def __init__(
        self,
        experiments: Sequence,
        runs: Sequence[list],
        names: Sequence[str] | None = None,
        effect_params: bool = True,
        reduce: bool = True,
    ):
        self.effect_params = effect_params
        self._reduce = reduce
        self.experiments = list(experiments)
        self.runs = [list(r) for r in runs]
        self.kinds = [get_kind(e.kind) for e in self.experiments]
        self.samples = [e.sample for e in self.experiments]
        self.rigs = [self._filled_rig(i) for i in range(len(self.experiments))]
        self.held: dict[str, str] = {}  # parameter -> why it is not fitted
        specs = self._all_specs()
        self.specs = self._select(specs, names)
        self.u0 = np.array([s.u0 for s in self.specs])
        self.sd_u = np.array([s.sd_u for s in self.specs])
        # the stated values and sds alone, without the readings at rest: what reports compare to
        self.stated_u0 = np.array([s.stated_u0 for s in self.specs])
        self.stated_sd_u = np.array([s.stated_sd_u for s in self.specs])
        self._measured: dict[tuple[int, int, str], np.ndarray] = {}
        self._reach = [
            np.array([k for k, s in enumerate(self.specs) if i in s.experiments], int)
            for i in range(len(self.experiments))
        ]
        self._cache = [OrderedDict() for _ in self.experiments]
        self.quantities = [self._quantities(i) for i in range(len(self.experiments))]
        self.sigma = self._noise()
        self.size = sum(
            len(r.data) * len(self.run_quantities(i, j))
            for i, rs in enumerate(self.runs)
            for j, r in enumerate(rs)
        )
        self.reductions, self._active = {}, False
        self.run_effects = self._run_effects()
        # a long run is fitted on its blocks' moments (tcamlab.reduction); see full_rows()
        self.reductions = self._reductions()
        self._active = any(r is not None for r in self.reductions.values())
        self.n_reduced = sum(
            (len(self.runs[i][j].data) if red is None else red.size) * len(self.run_quantities(i, j))
            for (i, j), red in self.reductions.items()
        )
        # a kind read from noisy inputs is fitted on block means (Kind.fit_block); see full_rows()
        self._blocking = not self._active and any(k.fit_block > 1 for k in self.kinds)
        self.n_blocked = sum(
            n_blocks(len(r.data), self.kinds[i].fit_block) * len(self.run_quantities(i, j))
            for i, rs in enumerate(self.runs)
            for j, r in enumerate(rs)
        )

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
        if sd_stated:
            prior_sd = float(sd)
        else:  # relative to the stated value; absolute (zero_sd) where that is 0
            prior_sd = p.default_sd * abs(value) if value != 0 else float(p.zero_sd or p.default_sd)
        reading = None
        if p.read_at_rest:
            logs = [r.data for i in idx for r in self.runs[i]]
            reading = rest_reading(self.kinds[idx[0]], logs, p.read_at_rest)
        return Spec(name, p, idx, value, in_file, prior_sd, sd_stated, key, factor, reading)

    def _all_specs(self) -> list[Spec]:
        specs: dict[str, Spec] = {}
        several = len(self.experiments) > 1
        for i, kind in enumerate(self.kinds):
            for p in kind.calibration:
                if p.needs and not any(c in r.data for c in p.needs for r in self.runs[i]):
                    continue  # e.g. dynamic R without a logged current or resistance
                if p.effect is not None and not self.effect_params:
                    continue  # the diagnosis's recalibration: the effect is a candidate
                if self._stated_exactly(i, p):
                    continue  # a stated sd of 0: the value is known, not fitted
                if p.where == "sample":
                    if p.field not in specs:
                        specs[p.field] = self._spec(p, tuple(range(len(self.experiments))), p.field)
                else:
                    name = f"{self.experiments[i].name}.{p.field}" if several else p.field
                    specs[name] = self._spec(p, (i,), name)
        return list(specs.values())

    def _stated_exactly(self, i: int, p: CalibrationParam) -> bool:
        """Whether experiment ``i`` states parameter ``p``'s sd as 0 (held, listed in :attr:`held`)."""
        exp = self.experiments[i]
        unc = exp.sample_uncertainty if p.where == "sample" else exp.rig.uncertainty
        if unc.get(p.field) != 0:
            return False
        key = _LAB_KEYS[p.where][p.field][0]
        self.held[p.field] = (
            f"{p.where}.{key}: held at its stated value (its sd in [{p.where}.uncertainty] is 0: known exactly)"
        )
        return True

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
        """The kind's outputs plus every other predicted column a run logs (temperature,
        current), each scored on the runs that log it (:meth:`run_quantities`)."""
        return scored_quantities(
            self.kinds[i], self.predict_run(i, 0, self.u0), [r.data for r in self.runs[i]], every=False
        )

    def run_quantities(self, i: int, j: int) -> tuple[str, ...]:
        """The quantities scored on run ``j`` of experiment ``i``: those of :attr:`quantities`
        it logs (a run a design added may log the current the others lack)."""
        data = self.runs[i][j].data
        return tuple(q for q in self.quantities[i] if q in data)

    def _noise(self) -> dict[tuple[int, str], float]:
        """Noise sd per (experiment, quantity) [SI], the RMS of :attr:`row_sigma` over the rows;
        sets ``row_sigma``, the sd of each row (:meth:`row_noise`)."""
        out = {}
        self.row_sigma: dict[tuple[int, int, str], np.ndarray] = {}
        for i, qs in enumerate(self.quantities):
            preds = [self.predict_run(i, j, self.u0) for j in range(len(self.runs[i]))]
            slopes = [self._input_slopes(i, j, p) for j, p in enumerate(preds)]
            for q in qs:
                js = [j for j in range(len(preds)) if q in self.run_quantities(i, j)]
                resid = [self.measured(i, j, q) - preds[j][q] for j in js]
                self._check_finite(i, q, resid)
                rows = self.row_noise(
                    resid,
                    [{x: slopes[j][x][q] for x in slopes[j]} for j in js],
                    [step_rows(self.kinds[i], self.runs[i][j].data) for j in js],
                )
                if rows is None:
                    from tcamlab.io import INTERNAL_TO_CANONICAL

                    col = INTERNAL_TO_CANONICAL.get(q, q)
                    raise InputError(
                        f"{self.experiments[i].path}: the noise of {col} cannot be estimated from its "
                        f"runs ({', '.join(self.runs[i][j].path.name for j in js)}): is the column constant?",
                        hint=f"check the {col} column of those runs and its unit (diagnose and validate "
                        f"also take --ignore {col})",
                    )
                for j, sd in zip(js, rows):
                    self.row_sigma[(i, j, q)] = sd
                out[(i, q)] = float(np.sqrt(np.mean(np.concatenate(rows) ** 2)))
        return out

    def _check_finite(self, i: int, q: str, resid: list[np.ndarray]) -> None:
        """Refuse stated values at which the model's residuals of ``q`` are not finite, or so
        large that their squares overflow (e.g. a sensor offset so small that (4.1) divides
        by almost 0): no noise floor or fit is defined there."""
        for j, r in enumerate(resid):
            r = np.asarray(r, float)
            bad = ~np.isfinite(r) | (np.abs(r) > RESIDUAL_OVERFLOW)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise ModelDomainError(
                    f"{self.experiments[i].path}: at the stated values the {self.kinds[i].name} model "
                    f"predicts no usable {q} on {int(bad.sum())} of {bad.size} rows of run {j + 1} "
                    f"(first at row {k}: {r[k]:.3g} from the measurement)",
                    "check the stated [sample] and [rig] values (a value far outside the sample's "
                    "physical range, e.g. in the wrong unit)",
                )

    def _input_slopes(self, i: int, j: int, pred: dict) -> dict[str, dict[str, np.ndarray]]:
        """{noisy input: {quantity: d predicted / d input, per row}} of run ``j`` at the stated
        values (the whole column moved by one step; the models read an input row by row)."""
        kind, out = self.kinds[i], {}
        data = self.runs[i][j].data
        sample, rig = self.models(i, self.u0)
        opts = dict(kind.run_options(sample, rig, data, where=str(self.experiments[i].path)).options)
        opts.update(kind.variants[kind.primary])
        for x in kind.noisy_inputs:
            col = data[x].to_numpy(float)
            h = INPUT_STEP * max(float(np.max(np.abs(col))), 1e-300)
            moved = data.copy()
            moved[x] = col + h
            try:
                with np.errstate(all="ignore"), warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    up = kind.predict(sample, rig, moved, **opts)
            except (TcamlabError, ArithmeticError, ValueError):
                continue
            out[x] = {q: (up[q] - pred[q]) / h for q in pred}
        return out

    @staticmethod
    def row_noise(
        resid: list[np.ndarray], slopes: list[dict[str, np.ndarray]], skips: list | None = None
    ) -> list[np.ndarray] | None:
        """Each row's noise sd [SI] under errors in the inputs (effective variance).

        The model reads noisy inputs x, so a residual carries the output's own noise plus
        (d predicted / d x) times x's noise: sd^2 = a + b G with G = sum_x g_x^2 (the inputs
        of one kind share one instrument, e.g. the ohmmeter for R1 and R2). a, b >= 0 are the
        least-squares fit of the squared second differences of the residuals / 6 (the
        estimator of :func:`~tcamlab.signals.second_difference_sigma`, row by row) on the
        local G; without noisy inputs it is that estimator. Where the slope varies along a
        run (the sensing pull: d delta / d R is largest near rest, where R0 and E are
        pinned), one sd would be too small exactly where the information is. No row's sd
        falls below :data:`ROW_SIGMA_FLOOR` of the single-sd estimate (a row where G = 0,
        e.g. one the model pins to zero, would otherwise get unbounded weight). ``skips`` holds,
        per run, the rows whose second difference is left out (True), or None: those either
        side of a commanded input's step (:func:`~tcamlab.signals.step_rows`), where the
        residual jumps by what the model misses of the step response.
        """
        d2, big = [], []
        for r, g, skip in zip(resid, slopes, skips or [None] * len(resid)):
            if r.size < 3:
                continue
            keep = slice(None) if skip is None or np.size(skip) != r.size else ~np.asarray(skip, bool)[1:-1]
            d2.append(((r[2:] - 2.0 * r[1:-1] + r[:-2]) ** 2 / 6.0)[keep])
            big.append(_slope_sum(g, r.size)[1:-1][keep])
        if not d2:
            return None
        y, gx = np.concatenate(d2), np.concatenate(big)
        total = float(np.mean(y))
        a, b = total, 0.0
        if np.any(gx > 0):
            scale = float(np.sqrt(np.mean(gx**2)))
            a, b = optimize.nnls(np.column_stack([np.ones_like(gx), gx / scale]), y)[0]
            b /= scale
        floor = (ROW_SIGMA_FLOOR**2) * total
        rows = [np.sqrt(np.maximum(a + b * _slope_sum(g, r.size), floor)) for r, g in zip(resid, slopes)]
        if not (total > 0 and all(np.all(np.isfinite(v)) for v in rows)):
            return None
        return rows

    def _run_effects(self) -> list[tuple[slice, np.ndarray, np.ndarray]]:
        """Per run with a random effect: its rows in :meth:`data_residuals`, the orthonormal
        basis U of its whitened effect columns and the shrink factors 1 - 1/sqrt(1 + s^2).

        Each run's sample may depart from the shared one by the experiment's
        ``[sample.run_to_run]`` (relative sds), else the kind's ``run_reproducibility`` (the
        virtual rig's per-run scatter of twists and coil length is such a departure).
        Linearised at the stated values (the departures are 1e-3 or less), a run's
        normalised residuals carry ``G delta`` with ``delta ~ N(0, I)``, profiled out exactly
        like the zeros (:func:`profile_random_effects`). G's columns are taken after the
        zeros are projected out (a flat-prior zero absorbs any constant part first).
        """
        out, start = [], 0
        for i in range(len(self.experiments)):
            scatter = run_scatter(self.experiments[i])
            for j, run in enumerate(self.runs[i]):
                n = len(run.data) * len(self.run_quantities(i, j))
                g = self._effect_columns(i, j, scatter) if scatter else np.zeros((n, 0))
                if g.shape[1]:
                    out.append((slice(start, start + n), *random_effect_basis(g)))
                start += n
        return out

    def _effect_columns(self, i: int, j: int, scatter: dict[str, float]) -> np.ndarray:
        """Whitened columns G of run ``j``'s random effects: d (residual / row sd) per prior sd
        of each sample field, zeros projected out, quantities stacked as in the residuals."""
        sample, rig = self.models(i, self.u0)
        base = self.predict_with(i, j, sample, rig)
        cols = []
        for fld, rel in sorted(scatter.items()):
            pred, step = None, EFFECT_STEP
            for step in (EFFECT_STEP, -EFFECT_STEP):  # the inner side at the model's domain edge
                try:
                    pred = self.predict_with(
                        i, j, sample.replace(**{fld: getattr(sample, fld) * (1.0 + step)}), rig
                    )
                    break
                except (TcamlabError, ArithmeticError, ValueError):
                    continue
            if pred is None:
                continue  # no effect column where the model has no solution either side
            parts = []
            for q in self.run_quantities(i, j):
                g = (pred[q] - base[q]) * (rel / step)
                sd = self.row_sigma[(i, j, q)]
                if self.is_zeroed(i, q):
                    g = g - self.zero_of(i, j, q, g)
                parts.append(g / sd)
            cols.append(np.concatenate(parts))
        n = len(self.runs[i][j].data) * len(self.run_quantities(i, j))
        return np.column_stack(cols) if cols else np.zeros((n, 0))

    def _reductions(self) -> dict:
        """Each run's :class:`~tcamlab.reduction.Reduction`, or None (scored row by row): runs
        of at least :data:`~tcamlab.reduction.MIN_ROWS` rows, none where a run has a random
        effect (its columns are laid out row by row)."""
        out = {}
        for i in range(len(self.experiments)):
            held = [c for c in self.kinds[i].inputs if c != "time"]
            for j, run in enumerate(self.runs[i]):
                red, qs = None, self.run_quantities(i, j)
                if self._reduce and reduction.enabled(len(run.data)) and not self.run_effects:
                    stated = self.predict_run(i, j, self.u0)
                    red = reduction.checked_reduction(
                        run.data,
                        [c for c in held if c in run.data],
                        {q: stated[q] for q in qs},
                        {q: self.measured(i, j, q) for q in qs},
                        {q: self.sigma[(i, q)] for q in qs},
                        lambda f, i=i, j=j: self.predict_run(i, j, self.u0, frame=f),
                        noisy=[c for c in self.kinds[i].noisy_inputs if c in run.data],
                    )
                out[(i, j)] = red
        return out

    @property
    def n_resid(self) -> int:
        """Data residuals of :meth:`data_residuals`: rows times quantities, or the moments of
        the reduced runs while the reduction is on, or a blocked kind's block means
        (:attr:`~tcamlab.kinds.Kind.fit_block`) outside :meth:`full_rows`."""
        if getattr(self, "_active", False):
            return self.n_reduced
        return self.n_blocked if getattr(self, "_blocking", False) else self.size

    def _block(self, i: int) -> int:
        """Rows per residual of experiment i's runs while blocking is on (1: row by row)."""
        return self.kinds[i].fit_block if getattr(self, "_blocking", False) else 1

    @contextmanager
    def full_rows(self) -> Iterator[None]:
        """Residuals of every row inside the block, whatever the runs' length or the kind's
        :attr:`~tcamlab.kinds.Kind.fit_block` (the final residuals and the fit quality)."""
        before = self._active, self._blocking
        self._active = self._blocking = False
        try:
            yield
        finally:
            self._active, self._blocking = before

    def _reduced(self, i: int, j: int):
        """Run j of experiment i's reduction while the reduction is on, else None."""
        return self.reductions.get((i, j)) if getattr(self, "_active", False) else None

    def _block_sd(self, i: int, j: int, q: str) -> np.ndarray:
        """Sd [SI] of each moment of a reduced run: its block's RMS row sd."""
        key = (i, j, q, "blocks")
        if key not in self._measured:
            red = self.reductions[(i, j)]
            var = np.add.reduceat(self.row_sigma[(i, j, q)] ** 2, red.starts) / red.counts
            sd = np.sqrt(var)
            self._measured[key] = red.per_moment(sd)
        return self._measured[key]

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

    def predict_run(self, i: int, j: int, u: np.ndarray, mods=None, frame=None) -> dict[str, np.ndarray]:
        """Predictions [SI] of run ``j`` of experiment ``i`` at ``u`` (raises outside the domain).

        ``mods`` (a :class:`tcamlab.effects.Mods`) adds effect terms; the diagnosis fits an
        effect together with the calibrated parameters through it. ``frame`` (some of the
        run's rows, :mod:`tcamlab.reduction`) is predicted instead of every row, with the
        run's own per-run constants."""
        sample, rig = self.models(i, u)
        return self.predict_with(i, j, sample, rig, mods, frame)

    def predict_with(self, i: int, j: int, sample, rig, mods=None, frame=None) -> dict[str, np.ndarray]:
        """Predictions [SI] of run ``j`` of experiment ``i`` with the given sample and rig
        (on the rows of ``frame`` where given)."""
        kind = self.kinds[i]
        data = self.runs[i][j].data
        opts = dict(kind.run_options(sample, rig, data, where=str(self.experiments[i].path)).options)
        opts.update(kind.variants[kind.primary])
        rows = data if frame is None else frame
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = (
                kind.predict(sample, rig, rows, **opts)
                if mods is None
                else kind.predict(sample, rig, rows, mods, **opts)
            )
        for q, v in out.items():
            if not np.all(np.isfinite(v)):
                raise ArithmeticError(f"non-finite prediction of {q}")
        return out

    def measured(self, i: int, j: int, q: str) -> np.ndarray:
        """Logged column ``q`` of run ``j`` of experiment ``i`` [SI] (read once)."""
        key = (i, j, q)
        if key not in self._measured:
            self._measured[key] = self.runs[i][j].data[q].to_numpy(float)
        return self._measured[key]

    def experiment_residuals(self, i: int, u: np.ndarray) -> list[tuple[int, str, np.ndarray]] | None:
        """``(run, quantity, measured - predicted [SI])`` of experiment ``i``, or None outside the
        domain. The last few are cached by the coordinates that reach experiment ``i``, so a
        Jacobian column of another experiment's rig parameter costs no prediction here."""
        key = (np.asarray(u, float)[self._reach[i]].tobytes(), self._active)
        cache = self._cache[i]
        if key in cache:
            cache.move_to_end(key)
            return cache[key]
        out = []
        try:
            for j in range(len(self.runs[i])):
                red = self._reduced(i, j)
                if red is None:
                    pred = self.predict_run(i, j, u)
                    out.extend((j, q, self.measured(i, j, q) - pred[q]) for q in self.run_quantities(i, j))
                    continue
                pred = self.predict_run(i, j, u, frame=red.frame)
                slopes = red.slopes(lambda f, j=j: self.predict_run(i, j, u, frame=f), pred)
                for q in self.run_quantities(i, j):
                    level, rest = red.residual(q, pred[q], slopes.get(q))
                    out.append((j, q, np.concatenate([level, rest])))
        except (TcamlabError, ArithmeticError, FloatingPointError, ZeroDivisionError, ValueError):
            out = None
        cache[key] = out
        if len(cache) > CACHE_SIZE:
            cache.popitem(last=False)
        return out

    def raw_residuals(self, u: np.ndarray) -> list[tuple[int, int, str, np.ndarray]] | None:
        """``(experiment, run, quantity, measured - predicted [SI])``, or None outside the domain."""
        out = []
        for i in range(len(self.experiments)):
            part = self.experiment_residuals(i, u)
            if part is None:
                return None
            out.extend((i, j, q, r) for j, q, r in part)
        return out

    def is_zeroed(self, i: int, q: str) -> bool:
        """Whether quantity ``q`` of experiment ``i`` carries a per-run nuisance zero."""
        return q in self.kinds[i].nuisance_zeros

    def zeros(self, u: np.ndarray) -> np.ndarray:
        """The profiled nuisance zeros at ``u`` [SI], in :meth:`zero_labels` order."""
        raw = self.raw_residuals(u)
        if raw is None:
            return np.full(len(self.zero_labels()), np.nan)
        return np.array([self.zero_of(i, j, q, r) for i, j, q, r in raw if self.is_zeroed(i, q)])

    def zero_of(self, i: int, j: int, q: str, r: np.ndarray) -> float:
        """The profiled zero of one run's residuals ``r`` [SI]: their mean weighted by
        1 / row_sigma^2 (the exact minimiser of the chi-square over the zero)."""
        red = self._reduced(i, j)
        if red is not None:  # a block's level moment carries sqrt(rows) of the zero, its slope none
            load = np.sqrt(red.counts)
            w = self._block_sd(i, j, q)[: red.counts.size] ** -2.0
            return float(np.sum(w * load * r[: red.counts.size]) / np.sum(w * red.counts))
        w = self.row_sigma[(i, j, q)] ** -2.0
        return float(np.sum(w * r) / np.sum(w))

    def zero_labels(self) -> list[tuple[int, int, str]]:
        return [
            (i, j, q)
            for i in range(len(self.experiments))
            for j in range(len(self.runs[i]))
            for q in self.run_quantities(i, j)
            if self.is_zeroed(i, q)
        ]

    def data_residuals(self, u: np.ndarray) -> np.ndarray:
        """Normalised data residuals (measured - predicted - zero) / sigma, stacked."""
        raw = self.raw_residuals(u)
        if raw is None:
            return np.full(self.n_resid, FAIL_RESIDUAL)
        parts, blocks = [], []
        for i, j, q, r in raw:
            zero = self.zero_of(i, j, q, r) if self.is_zeroed(i, q) else 0.0
            red = self._reduced(i, j)
            blocks.append(self._block(i) if red is None else 1)
            if red is None:
                parts.append((r - zero) / self.row_sigma[(i, j, q)])
                continue
            load = np.concatenate([np.sqrt(red.counts), np.zeros(red.size - red.counts.size)])
            parts.append((r - load * zero) / self._block_sd(i, j, q))
        out = np.concatenate(parts)
        # per-run random effects profiled out (see _run_effects)
        for rows, u_mat, shrink in self.run_effects:
            out[rows] = profile_random_effects(out[rows], u_mat, shrink)
        if max(blocks) > 1:  # row by row for the random effects' layout, then block means
            pieces = np.split(out, np.cumsum([p.size for p in parts])[:-1])
            out = np.concatenate([block_means(x, 1, b) if b > 1 else x for x, b in zip(pieces, blocks)])
        return out

    def failed(self, chi2: float) -> bool:
        """Whether a chi-square comes from :data:`FAIL_RESIDUAL` (the model has no solution)."""
        return chi2 >= 0.5 * self.n_resid * FAIL_RESIDUAL**2

    def residuals(self, u: np.ndarray) -> np.ndarray:
        """Data residuals followed by the prior residuals (u - u0) / sd_u."""
        return np.concatenate([self.data_residuals(u), (np.asarray(u) - self.u0) / self.sd_u])

    def prior_residuals(self, u: np.ndarray) -> np.ndarray:
        """The prior residuals ``(u - u0) / sd_u`` (the tail of :meth:`residuals`)."""
        return (np.asarray(u) - self.u0) / self.sd_u

    def jacobian(
        self, u: np.ndarray, cols: Sequence[int] | None = None, fn=None, *, central: bool = True
    ) -> np.ndarray:
        """Finite-difference Jacobian of ``fn`` (default :meth:`residuals`) in the given columns.

        Central differences (two evaluations a column) for the covariance; forward
        differences (one, the centre is cached) inside the optimiser, whose steps need
        no more than their direction.
        """
        fn = fn or self.residuals
        cols = range(len(u)) if cols is None else cols
        f0 = fn(u)
        out = [self._difference(fn, u, f0, k, central) for k in cols]
        return np.column_stack(out) if out else np.zeros((len(f0), 0))

    def _outside(self, f: np.ndarray) -> bool:
        """Whether ``f`` comes from outside the model's domain (no solution, or non-finite)."""
        return not np.all(np.isfinite(f)) or bool(np.all(f[: self.n_resid] == FAIL_RESIDUAL))

    def _difference(self, fn, u: np.ndarray, f0: np.ndarray, k: int, central: bool) -> np.ndarray:
        """One Jacobian column. Next to the edge of the model's domain (e.g. G_t' = 0) a step
        that leaves it would put FAIL_RESIDUAL / FD_STEP into the column, and the optimiser
        stalls there, so a failed side falls back to the one-sided difference of the other."""
        up, dn = np.array(u, float), np.array(u, float)
        up[k] += FD_STEP
        dn[k] -= FD_STEP
        f_up = fn(up)
        up_ok = not self._outside(f_up)
        if up_ok and not central:
            return (f_up - f0) / FD_STEP
        f_dn = fn(dn)
        dn_ok = not self._outside(f_dn)
        if up_ok and dn_ok:
            return (f_up - f_dn) / (2 * FD_STEP)
        if up_ok:
            return (f_up - f0) / FD_STEP
        if dn_ok:
            return (f0 - f_dn) / FD_STEP
        return np.zeros_like(f0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box of the fitted coordinates: six prior sds, at most a factor 1000 for positives."""
        span = np.array(
            [
                min(6 * sd, MAX_LOG_SPAN) if s.param.positive else 6 * sd
                for s, sd in zip(self.specs, self.sd_u)
            ]
        )
        return self.u0 - span, self.u0 + span
