"""Sim-to-real gap diagnosis: where the thesis model misses, which effect explains it, how far.

:func:`diagnose` looks only at an experiment file (:class:`tcamlab.config.Experiment`)
and its run logs (:class:`tcamlab.io.RunData`). It never reads a simulator's answer key
files and never looks at file names, seeds or how the data was made.

Steps
-----
1. **Baseline.** The thesis model (:func:`tcamlab.forward.predict`, no effect
   terms) with the experiment's parameters. Sensing: ``spring_constant`` is
   ``rig.spring_constant`` or, when unset, identified on the *training*
   runs: started at the least-squares fit through the origin of force on
   displacement (:func:`tcamlab.fitting.fit_spring`), then refined as a
   nuisance parameter by least squares on the noise-normalised residuals of
   both quantities, jointly with each candidate's parameters (a fit of F on
   delta alone is biased by a load-cell zero offset or a force-side effect,
   and the inversion amplifies an S error by 1 / (1 - S f11));
   ``initial_resistance`` is ``rig.initial_resistance`` or the run's first
   row. Curvature: ``rig.spring_constant`` and ``rig.initial_resistance``
   for both segments, or when that is unset the first row of ``r1``, ``r2``
   (averaged over the leading rows at rest). Residual = measured - predicted for each
   quantity of :data:`tcamlab.forward.OUTPUTS`, divided by that quantity's
   noise floor before pooling.

2. **Where.** Noise floor per quantity from the data alone: the
   second-difference estimator ``sigma^2 = sum((r[i+1] - 2 r[i] + r[i-1])^2) /
   (6 (n - 2))`` on each run's residuals (a smooth model gap has a small
   second difference, white noise gives exactly sigma^2), pooled over runs
   by the median. Where runs share their inputs (a replicated protocol) the
   between-run spread of the residuals is a second (correlated) estimate;
   when the two agree (F test) they are pooled with the weights that
   minimise the variance, which matters for short runs (the camera rig
   logs 11 rows a run) (:func:`pool_noise_estimates`). Residual RMSE, bias,
   share of squared error and RMSE/noise per regime; lag-1 autocorrelation
   and Durbin-Watson per run; correlation of residuals with each input.

3. **Which.** Every candidate effect (:mod:`tcamlab.effects`) is fitted with
   :func:`scipy.optimize.least_squares` on training runs and scored on the
   withheld run (leave one run out; a single run is cut into contiguous
   blocks). A bootstrap over folds gives intervals; AIC/BIC and parameter
   confidence intervals come from the fit on all runs.

4. **Verdict** (constants below, reasons in their docstrings):

   * ``none`` -- the baseline's mean squared normalised residual is below
     the :data:`GAP_LEVEL` quantile of its no-gap distribution, F(N, nu) per
     quantity (N points, nu the effective degrees of freedom of the noise
     estimate), pooled over quantities by seeded Monte Carlo
     (:func:`gap_limit`);
   * ``attributed`` -- the best candidate (lowest held-out RMSE) closes at
     least :data:`MIN_FRACTION_CLOSED` of the gap above the noise floor, its
     bootstrap shrinkage interval excludes 0, and no other candidate is
     indistinguishable from it;
   * ``aliased`` -- as attributed, but another candidate also closes at least
     :data:`MIN_FRACTION_CLOSED` and the paired bootstrap interval of its
     held-out MSE minus the best's contains 0;
   * ``unexplained`` -- the gap is significant and no candidate qualifies.

5. **Two effects.** When no single candidate qualifies, candidates that alone
   close at least :data:`MIN_PARTIAL_FRACTION` of the gap (the best
   :data:`PAIR_POOL`) are fitted in pairs (:func:`tcamlab.effects.combine`)
   and scored the same way; a pair that qualifies and beats each member alone
   gives ``attributed`` (or ``aliased``, with rival pairs), naming the member
   that ranks higher alone; the pair is ``DiagnosisResult.combination``.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import optimize, stats

from tcamlab import forward as F
from tcamlab.effects import Effect, combine, effects_for, get_effect
from tcamlab.errors import ConfigError, TcamlabError
from tcamlab.forward import Mods
from tcamlab.jsonutil import to_jsonable

__all__ = [
    "SCHEMA_VERSION",
    "GAP_LEVEL",
    "MIN_FRACTION_CLOSED",
    "CI_LEVEL",
    "DISPLAY_UNITS",
    "CandidateResult",
    "DiagnosisResult",
    "diagnose",
    "gap_limit",
    "pool_noise_estimates",
    "second_difference_sigma",
]

SCHEMA_VERSION = 1
"""Version of the :meth:`DiagnosisResult.to_dict` layout."""

GAP_LEVEL = 0.99
"""Quantile of the no-gap distribution above which the baseline gap counts as
real: a 1 % false-alarm rate per experiment when the model is right and the
noise white."""

MIN_FRACTION_CLOSED = 0.5
"""Share of the excess squared error (above the noise floor) a candidate must
remove on withheld data to count as an explanation: it must explain the
majority of the gap, not just part of it."""

CI_LEVEL = 0.95
"""Level of every reported interval."""

MIN_PARTIAL_FRACTION = 0.05
"""When no single candidate explains the gap, candidates that alone close at
least this share of it (and improve the withheld runs) are paired."""

PAIR_POOL = 4
"""At most this many of the best single candidates enter the pair search
(6 pairs), which bounds its cost."""

SECOND_DIFF_EFFICIENCY = 36.0 / 70.0
"""Degrees of freedom of the second-difference variance estimate per point,
relative to a chi-square estimate: for white Gaussian noise the second
differences d_i have var 6 sigma^2 and lag-1/lag-2 covariances -4 and 1
sigma^2, so var(sum d_i^2) = 2 (36 + 2 16 + 2 1) sigma^4 (n - 2) and the
estimate has 2 (n - 2) 36 / 140 = (36/70) (n - 2) degrees of freedom."""

MEDIAN_EFFICIENCY = 2.0 / math.pi
"""Asymptotic efficiency of a median relative to a mean (pooling over runs)."""

ZERO_REFERENCED: tuple[str, ...] = ()
"""Quantities whose logged zero is re-estimated from the leading rows at rest.

Empty: the thesis rigs tare the displacement on a mean of many readings at
rest (and the pull-test encoder is exact), so the logged zero is taken as
exact. Re-estimating it from model predictions at rest was tried and biases
the sensing displacement (the inverted model is not symmetric about R0).
Add ``"displacement"`` here for logs whose first row is a single noisy reading."""

SHARED_INPUTS: dict[str, tuple[str, ...]] = {
    "static": ("temperature",),
    "dynamic": ("voltage",),
    "sensing": ("resistance",),
    "curvature": ("cable",),
}
"""Inputs that set a row's operating point: runs whose values of these agree
row by row (within 2 % of their range) are replicates, and the spread of their
residuals across runs measures the noise. The curvature rig's r1, r2 are
measured responses of the commanded cable, so only the cable counts there."""

POOL_CONSISTENCY_LEVEL = 0.99
"""Two-sided level of the F test that admits the between-run variance into
the noise floor (:func:`pool_noise_estimates`)."""

REST_TOLERANCE = 0.02
"""Inputs within this fraction of their range of the first row count as "at rest"."""

FAIL_RESIDUAL = 1.0e3
"""Normalised residual returned for every point of a model evaluation outside
the model's domain, so the optimiser backs away instead of crashing."""

DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "displacement": ("mm", 1e3),
    "force": ("N", 1.0),
    "kappa1": ("1/mm", 1e-3),
    "kappa2": ("1/mm", 1e-3),
    "temperature": ("degC", 1.0),
}
"""Quantity -> (display unit, factor from SI)."""

_INPUT_UNITS = {
    "temperature": ("degC", 1.0),
    "time": ("s", 1.0),
    "voltage": ("V", 1.0),
    "resistance": ("ohm", 1.0),
    "cable": ("mm", 1e3),
    "r1": ("ohm", 1.0),
    "r2": ("ohm", 1.0),
    "force": ("N", 1.0),
}


# ---------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------


def second_difference_sigma(r) -> float:
    """Noise sd of a series from its second differences (robust to smooth trends).

    sigma^2 = sum((r[i+1] - 2 r[i] + r[i-1])^2) / (6 (n - 2)).
    """
    r = np.asarray(r, float)
    if r.size < 3:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    return float(math.sqrt(np.sum(d2 * d2) / (6.0 * (r.size - 2))))


def gap_limit(
    n_points, noise_dof, level: float = GAP_LEVEL, *, reference: Sequence[tuple[float, int]] = ()
) -> float:
    """Largest baseline RMSE/noise consistent with "no gap".

    Without a gap each quantity's normalised residuals are its noise divided
    by its estimated noise sd, so that quantity's mean(z^2) is
    (chi2_N / N) / (sigma_hat^2 / sigma^2) ~ F(N, nu), with nu the effective
    degrees of freedom of sigma_hat^2 (:data:`SECOND_DIFF_EFFICIENCY`,
    :data:`MEDIAN_EFFICIENCY`). Treating numerator and denominator as
    independent is conservative: they share the data, which makes the ratio
    less variable. Several quantities (``n_points`` and ``noise_dof`` as
    sequences) are pooled point-weighted, each with its own sigma_hat; the
    ``level`` quantile is then taken from 40000 seeded Monte Carlo draws.

    ``reference`` lists (share of the points, rest rows k) of runs whose zero
    was re-estimated from k rest rows (see :data:`ZERO_REFERENCED`): off by
    noise/sqrt(k), adding share * chi2_1 / k to the statistic.
    Returns sqrt of the quantile.
    """
    ns = [max(int(n), 1) for n in np.atleast_1d(n_points)]
    nus = [max(float(v), 1.0) for v in np.atleast_1d(noise_dof)]
    if len(nus) == 1 and len(ns) > 1:
        nus = nus * len(ns)
    if len(ns) == 1 and not reference:
        return float(math.sqrt(stats.f.ppf(level, ns[0], nus[0])))
    rng = np.random.default_rng(20240601)
    m = 40000
    total = float(sum(ns))
    stat = np.zeros(m)
    for n, nu in zip(ns, nus):
        stat += (n / total) * (rng.chisquare(n, m) / n) / (rng.chisquare(nu, m) / nu)
    for w, k in reference:
        stat = stat + w * rng.chisquare(1, m) / max(int(k), 1)
    return float(math.sqrt(np.quantile(stat, level)))


def _ci(samples: np.ndarray) -> list[float]:
    a = (1.0 - CI_LEVEL) / 2.0
    s = np.asarray(samples, float)
    s = s[np.isfinite(s)]
    if s.size == 0:
        return [float("nan"), float("nan")]
    return [float(np.quantile(s, a)), float(np.quantile(s, 1.0 - a))]


def _smooth(x: np.ndarray, k: int) -> np.ndarray:
    k = max(1, min(int(k), x.size))
    if k <= 1:
        return x.astype(float)
    pad = np.pad(x.astype(float), (k // 2, k - 1 - k // 2), mode="edge")
    return np.convolve(pad, np.ones(k) / k, mode="valid")


# ---------------------------------------------------------------------------
# the model wrapper: predictions and normalised residuals
# ---------------------------------------------------------------------------


class _Problem:
    """Runs, options and noise scales of one experiment; evaluates Mods on rows."""

    def __init__(self, experiment, runs):
        self.kind = experiment.kind
        self.sample = experiment.sample
        self.rig = experiment.rig
        self.quantities = tuple(F.OUTPUTS[self.kind])
        self.frames: list[pd.DataFrame] = [r.data for r in runs]
        self.names = [getattr(r, "path", None) for r in runs]
        self.sigma = {q: 1.0 for q in self.quantities}
        for i, d in enumerate(self.frames):
            missing = [c for c in F.INPUTS[self.kind] + self.quantities if c not in d]
            if missing:
                raise ConfigError(f"diagnosis: run {i} has no column(s) {', '.join(missing)}")
        self._fixed_opts = [self._run_options(i) for i in range(len(self.frames))]
        # Logged displacement is relative to the (noisy) first row: its zero is
        # re-estimated from the leading rows at rest under every model evaluated.
        self.rereferenced = tuple(q for q in self.quantities if q in ZERO_REFERENCED)
        self.rest = [_rest_rows(self.kind, d) for d in self.frames]
        self.spring_nuisance = self.kind == "sensing" and self.rig.spring_constant is None

    # options -------------------------------------------------------------
    def _run_options(self, i: int) -> dict:
        d = self.frames[i]
        if self.kind == "sensing":
            r0 = self.rig.initial_resistance
            return {"initial_resistance": float(r0 if r0 is not None else d["resistance"].iloc[0])}
        if self.kind == "curvature":
            r0 = self.rig.initial_resistance
            if self.rig.spring_constant is None:
                raise ConfigError(
                    "diagnosis: a curvature experiment needs rig.spring_constant_N_per_m",
                    "set spring_constant_N_per_m in [rig] (or use preset thesis-robot)",
                )
            cable = d["cable"].to_numpy(float)
            rest = np.flatnonzero(np.abs(cable - cable[0]) > 1e-12)
            k = int(rest[0]) if rest.size else cable.size
            k = max(1, k)
            if r0 is not None:
                r0s = (float(r0), float(r0))
            else:
                r0s = (float(d["r1"].iloc[:k].mean()), float(d["r2"].iloc[:k].mean()))
            return {"spring_constant": float(self.rig.spring_constant), "initial_resistances": r0s}
        return {}

    def spring_for(self, rows: Sequence[tuple[int, np.ndarray]]) -> float | None:
        """Sensing S: the rig's, or fitted on the given (training) rows."""
        if self.kind != "sensing":
            return None
        if self.rig.spring_constant is not None:
            return float(self.rig.spring_constant)
        from tcamlab.fitting import fit_spring

        x = np.concatenate([self.frames[i]["displacement"].to_numpy(float)[m] for i, m in rows])
        f = np.concatenate([self.frames[i]["force"].to_numpy(float)[m] for i, m in rows])
        return float(fit_spring(x, f).spring_constant)

    def options(self, i: int, spring: float | None) -> dict:
        opts = dict(self._fixed_opts[i])
        if self.kind == "sensing":
            opts["spring_constant"] = spring
        return opts

    # evaluation ----------------------------------------------------------
    def predict(self, i: int, mods: Mods, spring: float | None) -> dict[str, np.ndarray]:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = F.predict(self.kind, self.sample, self.rig, self.frames[i], mods, **self.options(i, spring))
        for q in self.quantities:
            if not np.all(np.isfinite(out[q])):
                raise ArithmeticError("non-finite prediction")
        return out

    def measured(self, i: int, q: str) -> np.ndarray:
        return self.frames[i][q].to_numpy(float)

    def resid(self, i: int, pred: dict) -> dict[str, np.ndarray]:
        """measured - predicted [SI] per quantity, displacement re-referenced at rest."""
        out = {}
        for q in self.quantities:
            r = self.measured(i, q) - pred[q]
            if q in self.rereferenced:
                r = r - float(np.mean(r[self.rest[i]]))
            out[q] = r
        return out

    def norm_resid(self, i: int, mods: Mods, spring, mask=None) -> np.ndarray:
        """Normalised residuals of run i (quantities stacked), or FAIL_RESIDUAL."""
        n = len(self.frames[i]) if mask is None else int(np.count_nonzero(mask))
        try:
            pred = self.predict(i, mods, spring)
        except (TcamlabError, ArithmeticError, FloatingPointError, ZeroDivisionError):
            return np.full(n * len(self.quantities), FAIL_RESIDUAL)
        res = self.resid(i, pred)
        parts = []
        for q in self.quantities:
            r = res[q] / self.sigma[q]
            parts.append(r if mask is None else r[mask])
        return np.concatenate(parts)


def _rest_rows(kind: str, d: pd.DataFrame) -> np.ndarray:
    """Leading rows whose inputs stay at their first value (within 2 % of their range)."""
    n = len(d)
    first_move = n
    for c in F.INPUTS[kind]:
        if c == "time" or c not in d:
            continue
        x = d[c].to_numpy(float)
        span = float(np.nanmax(x) - np.nanmin(x))
        moved = np.flatnonzero(np.abs(x - x[0]) > REST_TOLERANCE * span) if span > 0 else np.array([], int)
        if moved.size:
            first_move = min(first_move, int(moved[0]))
    return np.arange(max(first_move, 1))


# ---------------------------------------------------------------------------
# fitting one effect
# ---------------------------------------------------------------------------


@dataclass
class _Fit:
    theta: np.ndarray  # scaled parameters (effect, then the S nuisance if any)
    values: np.ndarray  # effect parameters, SI
    sse: float  # normalised
    n: int
    jac: np.ndarray | None
    success: bool
    spring: float | None = None


SPRING_STEP = 0.01
"""Scale of the sensing spring-constant nuisance: S = S0 (1 + SPRING_STEP theta)."""


DOMAIN_BISECTIONS = 24
"""Bisection steps that locate the edge of a parameter's physical domain."""


def _domain_bounds(problem: _Problem, effect: Effect, rows, spring, scales, lo, hi) -> None:
    """Shrink each effect parameter's bounds (in place) to where the model is defined.

    A library bound can lie outside the model's physical domain on these runs
    (e.g. a G_t slope that makes G_t' <= 0 at the hottest reading). The fit
    must stay inside the domain: a penalty wall there makes the objective
    discontinuous and the optimiser stalls short of an optimum near the edge.
    The edge is found by bisection between 0 (the thesis model) and the bound.
    It is checked on the *inputs* of every run, withheld ones included: the
    domain depends on inputs only (e.g. the hottest reading), and a parameter
    fitted on the training runs must still give a prediction for the withheld
    run. No measured output is used here.
    """
    k_eff = len(effect.params)

    def valid(j, t):
        theta = np.zeros(k_eff)
        theta[j] = t
        mods = effect.mods(theta * scales)
        for i in range(len(problem.frames)):
            try:
                problem.predict(i, mods, spring)
            except (TcamlabError, ArithmeticError, FloatingPointError, ZeroDivisionError):
                return False
        return True

    if not valid(0, 0.0):
        return
    for j in range(k_eff):
        for bounds in (hi, lo):
            b = bounds[j]
            if not np.isfinite(b) or b == 0 or valid(j, b):
                continue
            good, bad = 0.0, b
            for _ in range(DOMAIN_BISECTIONS):
                mid = 0.5 * (good + bad)
                if valid(j, mid):
                    good = mid
                else:
                    bad = mid
            bounds[j] = good


def _fit_effect(problem: _Problem, effect: Effect | None, rows, spring, *, max_nfev: int = 60) -> _Fit:
    """Least-squares fit of an effect (None: only the nuisance) on the given rows.

    When the sensing S is identified from data it is a nuisance fitted jointly
    (start: the through-origin value ``spring``), so a force-side effect is not
    absorbed into a biased S.
    """
    params = effect.params if effect is not None else ()
    nuis = problem.spring_nuisance
    scales = np.array([p.scale for p in params], float)
    lo = [p.lower / p.scale for p in params] + ([-50.0] if nuis else [])
    hi = [p.upper / p.scale for p in params] + ([50.0] if nuis else [])
    lo, hi = np.array(lo, float), np.array(hi, float)
    k_eff = len(params)

    def unpack(theta):
        values = theta[:k_eff] * scales
        sp = spring * (1.0 + SPRING_STEP * theta[k_eff]) if nuis else spring
        return values, sp

    def fun(theta):
        values, sp = unpack(theta)
        mods = effect.mods(values) if effect is not None else Mods()
        return np.concatenate([problem.norm_resid(i, mods, sp, m) for i, m in rows])

    k = lo.size
    if k_eff:
        _domain_bounds(problem, effect, rows, spring, scales, lo, hi)
    if k == 0:
        r0 = fun(np.zeros(0))
        return _Fit(np.zeros(0), np.zeros(0), float(np.sum(r0**2)), r0.size, None, True, spring)
    width = np.where(np.isfinite(hi - lo), hi - lo, 2.0)
    lo_i, hi_i = lo + 1e-9 * width, hi - 1e-9 * width
    starts = [np.zeros(k)]
    if k_eff:
        for sgn in (1.0, -1.0):
            x0 = np.zeros(k)
            x0[:k_eff] = sgn
            starts.append(x0)
    best = None
    seen = []
    for x0 in starts:
        x0 = np.clip(x0, lo_i, hi_i)
        if any(np.allclose(x0, s_) for s_ in seen):
            continue
        seen.append(x0)
        try:
            res = optimize.least_squares(
                fun,
                x0,
                bounds=(lo, hi),
                method="trf",
                x_scale=1.0,
                diff_step=1e-4,
                max_nfev=max_nfev,
                ftol=1e-6,
                xtol=1e-6,
                gtol=1e-8,
            )
        except (ValueError, np.linalg.LinAlgError):
            continue
        sse = float(np.sum(res.fun**2))
        if best is None or sse < best[0]:
            best = (sse, res)
    if best is None:
        r0 = fun(np.zeros(k))
        return _Fit(np.zeros(k), np.zeros(k_eff), float(np.sum(r0**2)), r0.size, None, False, spring)
    sse, res = best
    values, sp = unpack(res.x)
    return _Fit(res.x, values, sse, res.fun.size, res.jac, bool(res.success), sp)


def _param_ci(fit: _Fit, effect: Effect) -> dict:
    """95 % CI of each parameter from (J^T J)^-1 s^2 of the all-runs fit (SI)."""
    scales = np.array([p.scale for p in effect.params], float)
    k = scales.size
    sd = np.full(k, np.nan)
    if fit.jac is not None and fit.n > fit.jac.shape[1]:
        J = np.asarray(fit.jac, float)
        s2 = fit.sse / (fit.n - J.shape[1])
        try:
            cov = np.linalg.inv(J.T @ J) * s2
            sd = np.sqrt(np.clip(np.diag(cov)[:k], 0.0, None)) * scales
        except np.linalg.LinAlgError:
            pass
    z = stats.norm.ppf(0.5 + CI_LEVEL / 2.0)
    out = {}
    for p, v, s in zip(effect.params, fit.values, sd):
        out[p.field] = {
            "value": float(v),
            "ci95": [float(v - z * s), float(v + z * s)],
            "stderr": float(s),
            "unit": p.unit,
            "at_bound": bool(np.isclose(v, p.lower) or np.isclose(v, p.upper)),
        }
    return out


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------


@dataclass
class CandidateResult:
    """One candidate effect's scores.

    RMSEs ``heldout_rmse_before`` / ``heldout_rmse_after`` are pooled over the
    withheld folds, in ``unit`` (the display unit when every quantity of the
    kind shares one, else ``"noise"`` = multiples of the noise floor);
    ``*_noise`` are the same in noise-floor multiples; ``by_quantity`` gives
    each quantity in its own display unit. ``shrinkage`` = 1 - after/before
    (noise-normalised), ``fraction_closed`` = (before^2 - after^2) /
    (before^2 - 1) in noise units.
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
            }
        )


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
    noise_floor: dict
    baseline: dict
    regimes: list[dict]
    runs: list[dict]
    gap: dict
    reason: str
    settings: dict
    combination: dict | None = None
    _series: dict = field(default_factory=dict, repr=False)

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
                "regimes": self.regimes,
                "runs": self.runs,
                "settings": self.settings,
            }
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
        unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
        x, xlabel = r["x"], r["xlabel"]
        ax.plot(x, r["measured"][q] * fac, ".", ms=2, color="0.4", label="measured")
        ax.plot(x, r["baseline"][q] * fac, "-", color="#1f77b4", label="thesis model")
        if r.get("best") is not None:
            ax.plot(x, r["best"][q] * fac, "-", color="#d62728", label=f"+ {self.ranking[0].effect}")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"{q} [{unit}]")
        ax.legend()
        return ax


def _axes(ax):
    if ax is not None:
        return ax
    from tcamlab.report.figures import new_figure

    return new_figure()[1]


# ---------------------------------------------------------------------------
# regimes and residual statistics
# ---------------------------------------------------------------------------


def _regime_labels(kind: str, d: pd.DataFrame, q: str, force_edges=None) -> dict[str, np.ndarray]:
    """Regime labels of every row of one run for one quantity: {group: labels}."""
    n = len(d)
    out: dict[str, np.ndarray] = {}
    if kind == "static":
        T = d["temperature"].to_numpy(float)
        edges = [25, 50, 75, 100, 125, 150]
        band = np.full(n, "", dtype=object)
        lo_edge = np.concatenate(([-np.inf], edges))
        for a, b in zip(lo_edge[:-1], lo_edge[1:]):
            lbl = f"<{b} degC" if not np.isfinite(a) else f"{a}-{b} degC"
            band[(T >= a) & (T < b)] = lbl
        band[T >= edges[-1]] = f">={edges[-1]} degC"
        out["temperature band"] = band
        clock = d["time"].to_numpy(float) if "time" in d else np.arange(n, dtype=float)
        k = max(3, n // 20)
        slope = np.gradient(_smooth(T, k), clock) if n > 2 else np.zeros(n)
        tol = 0.05 * np.quantile(np.abs(slope), 0.95) if n > 2 else 0.0
        out["phase"] = np.where(
            np.abs(slope) <= tol, "steady", np.where(slope > 0, "heating", "cooling")
        ).astype(object)
    elif kind == "dynamic":
        t = d["time"].to_numpy(float)
        v = d["voltage"].to_numpy(float)
        on = np.abs(v) > 0.01 * max(np.abs(v).max(), 1e-12)
        lab = np.full(n, "steady", dtype=object)
        lab[on] = "heating"
        if on.any():
            # after each pulse ends, the next 3 s are cooling
            ends = np.flatnonzero(on[:-1] & ~on[1:]) + 1
            for e in ends:
                m = (~on) & (t >= t[e - 1]) & (t <= t[e - 1] + 3.0)
                m[:e] = False
                lab[m] = "cooling"
        out["phase"] = lab
    elif kind == "sensing":
        f = d["force"].to_numpy(float)
        e = force_edges
        band = np.full(n, "", dtype=object)
        idx = np.clip(np.searchsorted(e, f, side="right") - 1, 0, 3)
        names = [f"F quartile {j + 1}" for j in range(4)]
        band[:] = [names[j] for j in idx]
        out["force band"] = band
        r = d["resistance"].to_numpy(float)
        k = max(1, min(9, n // 10))
        sm = _smooth(r, k)
        peak = int(np.argmax(sm))
        br = np.full(n, "loading", dtype=object)
        if n - peak > 2 and sm[peak] - sm[-1] > 0.25 * (sm[peak] - sm.min()):
            br[peak + 1 :] = "unloading"
        out["branch"] = br
    elif kind == "curvature":
        c = d["cable"].to_numpy(float)
        mid = 0.5 * (np.nanmin(c) + np.nanmax(c))
        seg = "segment 1" if q == "kappa1" else "segment 2"
        out["segment x bending"] = np.where(c <= mid, f"{seg}, low bend", f"{seg}, high bend").astype(object)
    return out


def _autocorr1(r: np.ndarray) -> float:
    r = r - r.mean()
    den = float(np.sum(r * r))
    return float(np.sum(r[1:] * r[:-1]) / den) if den > 0 and r.size > 2 else float("nan")


def _durbin_watson(r: np.ndarray) -> float:
    den = float(np.sum(r * r))
    return float(np.sum(np.diff(r) ** 2) / den) if den > 0 else float("nan")


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if a.size < 3 or np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def _between_run_spread(problem: _Problem, base_res) -> dict:
    """Between-run sd of measured quantities where runs share their inputs."""
    frames = problem.frames
    if len(frames) < 2:
        return {"available": False, "reason": "a single run"}
    n = {len(d) for d in frames}
    if len(n) != 1:
        return {"available": False, "reason": "runs differ in length"}
    for c in SHARED_INPUTS[problem.kind]:
        X = np.vstack([d[c].to_numpy(float) for d in frames])
        span = float(np.ptp(X)) or 1.0
        if np.max(np.abs(X - X.mean(axis=0))) > 0.02 * span:
            return {"available": False, "reason": f"runs do not share the {c} input"}
    out = {"available": True}
    for q in problem.quantities:
        unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
        # spread of the residuals (the model removes the input dependence)
        R = np.vstack([base_res[i][q] for i in range(len(frames))])
        var = float(np.mean(np.var(R, axis=0, ddof=1)))
        out[q] = {"sd": math.sqrt(var) * fac, "unit": unit, "dof": (len(frames) - 1) * len(frames[0])}
    return out


def pool_noise_estimates(
    run_vars, between_var: float, n_rows: int, median_dof: float, level: float = POOL_CONSISTENCY_LEVEL
):
    """Pool the second-difference and between-run noise variances, if they agree.

    With ``n`` runs of ``m`` rows at the same inputs, the second-difference
    variance (mean over runs) ``a`` and the between-run variance ``b`` (the
    residuals' variance across runs at each row, averaged over rows) are both
    unbiased for white noise, with degrees of freedom nu_a = (36/70) (m - 2) n
    (:data:`SECOND_DIFF_EFFICIENCY`) and nu_b = (n - 1) m. They share the data:
    as quadratic forms e' A e and e' B e with tr(A) = tr(B) = 1,
    tr(A^2) = 1/nu_a, tr(B^2) = 1/nu_b and tr(A B) = 1/(n m) (the Kronecker
    structure gives tr(D'D) tr(C) = 6 (m - 2)(n - 1)). The weight
    w = (tb - tab) / (ta + tb - 2 tab) on ``a`` minimises the variance of
    w a + (1 - w) b, whose degrees of freedom are 1 / tr(M^2).

    ``b`` also holds run-to-run differences that are not noise (sample scatter,
    an effect that changes between runs), so it is used only when its ratio to
    the robust estimate (median over runs, ``median_dof``) lies inside the
    two-sided ``level`` interval of F(nu_b, median_dof).

    Parameters
    ----------
    run_vars : array_like
        Second-difference variance of each run [quantity unit^2].
    between_var : float
        Between-run variance [quantity unit^2].
    n_rows : int
        Rows per run.
    median_dof : float
        Degrees of freedom of the median-pooled estimate.

    Returns
    -------
    (variance, dof) or None
        None when the two disagree (the second-difference estimate stands).
    """
    run_vars = np.asarray(run_vars, float)
    n, m = run_vars.size, int(n_rows)
    if n < 2 or m < 3 or not (between_var > 0) or not np.all(run_vars > 0):
        return None
    nu_a = SECOND_DIFF_EFFICIENCY * (m - 2) * n
    nu_b = (n - 1) * m
    lo, hi = stats.f.ppf([(1.0 - level) / 2.0, (1.0 + level) / 2.0], nu_b, median_dof)
    if not lo <= between_var / float(np.median(run_vars)) <= hi:
        return None
    a = float(np.mean(run_vars))
    ta, tb, tab = 1.0 / nu_a, 1.0 / nu_b, 1.0 / (n * m)
    w = min(max((tb - tab) / (ta + tb - 2.0 * tab), 0.0), 1.0)
    tr = w * w * ta + (1.0 - w) ** 2 * tb + 2.0 * w * (1.0 - w) * tab
    return w * a + (1.0 - w) * between_var, 1.0 / tr


# ---------------------------------------------------------------------------
# folds and bootstrap
# ---------------------------------------------------------------------------


def _folds(problem: _Problem) -> list[list[tuple[int, np.ndarray]]]:
    """Held-out sets: one run each, or contiguous blocks of a single run."""
    frames = problem.frames
    if len(frames) >= 2:
        return [[(i, np.ones(len(d), bool))] for i, d in enumerate(frames)]
    n = len(frames[0])
    k = 5 if n >= 100 else 3
    k = min(k, max(n // 3, 1))
    k = max(k, 3) if n >= 9 else k
    edges = np.linspace(0, n, k + 1).round().astype(int)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        m = np.zeros(n, bool)
        m[a:b] = True
        out.append([(0, m)])
    return out


def _complement(problem: _Problem, held) -> list[tuple[int, np.ndarray]]:
    held_map = {i: m for i, m in held}
    rows = []
    for i, d in enumerate(problem.frames):
        m = np.ones(len(d), bool)
        if i in held_map:
            m &= ~held_map[i]
        if m.any():
            rows.append((i, m))
    return rows


# ---------------------------------------------------------------------------
# the diagnosis
# ---------------------------------------------------------------------------


def diagnose(
    experiment, runs=None, *, effects=None, n_boot: int = 1000, seed: int = 0, workers: int | None = None
) -> DiagnosisResult:
    """Diagnose the gap between the thesis model and an experiment's runs.

    Parameters
    ----------
    experiment : tcamlab.config.Experiment
        The experiment (sample, rig, kind).
    runs : list of tcamlab.io.RunData, optional
        Default: ``experiment.read_runs()``.
    effects : list of str, optional
        Candidate effect names; default every effect of the kind.
    n_boot : int
        Bootstrap resamples over folds.
    seed : int
        Seed of the bootstrap only (the diagnosis is otherwise deterministic).
    workers : int, optional
        Processes (spawned) for the candidate fits; default 1 (serial). Results
        do not depend on it.

    Returns
    -------
    DiagnosisResult
    """
    kind = experiment.kind
    if runs is None:
        runs = experiment.read_runs()
    runs = list(runs)
    if not runs:
        raise ConfigError("diagnosis: no runs")
    cands = [get_effect(e, kind) for e in effects] if effects is not None else effects_for(kind)
    problem = _Problem(experiment, runs)
    Q = problem.quantities
    n_runs = len(runs)
    all_rows = [(i, np.ones(len(d), bool)) for i, d in enumerate(problem.frames)]

    # --- baseline and noise floor ---------------------------------------------------
    spring_all = problem.spring_for(all_rows)
    base = Mods()
    base_pred = [problem.predict(i, base, spring_all) for i in range(n_runs)]
    base_res = [problem.resid(i, p) for i, p in enumerate(base_pred)]
    per_run_sigma = {q: [second_difference_sigma(base_res[i][q]) for i in range(n_runs)] for q in Q}
    spread = _between_run_spread(problem, base_res)
    noise_dof_q, noise_method = {}, {}
    for q in Q:
        vals = np.array([v for v in per_run_sigma[q] if np.isfinite(v) and v > 0])
        if vals.size == 0:
            resid = np.concatenate([base_res[i][q] for i in range(n_runs)])
            vals = np.array([max(float(np.std(resid)), 1e-300)])
        problem.sigma[q] = float(np.median(vals))
        noise_dof_q[q] = (
            SECOND_DIFF_EFFICIENCY
            * sum(max(len(d) - 2, 0) for d in problem.frames)
            * (MEDIAN_EFFICIENCY if n_runs >= 3 else 1.0)
        )
        noise_method[q] = "second difference"
        if spread.get("available") and vals.size == n_runs:
            between_var = (spread[q]["sd"] / DISPLAY_UNITS.get(q, ("", 1.0))[1]) ** 2
            pooled = pool_noise_estimates(
                np.asarray(per_run_sigma[q]) ** 2, between_var, len(problem.frames[0]), noise_dof_q[q]
            )
            spread[q]["consistent"] = pooled is not None
            if pooled is not None:
                problem.sigma[q], noise_dof_q[q] = math.sqrt(pooled[0]), pooled[1]
                noise_method[q] = "second difference + between runs"

    noise_floor = {
        "quantities": list(Q),
        "method": "second difference of baseline residuals "
        "(median over runs); pooled with the between-run spread where runs share their "
        "inputs and the two agree",
        "by_quantity": {},
        "between_runs": spread,
    }
    for q in Q:
        unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
        noise_floor["by_quantity"][q] = {
            "sigma": problem.sigma[q] * fac,
            "unit": unit,
            "per_run": [v * fac for v in per_run_sigma[q]],
            "dof": noise_dof_q[q],
            "method": noise_method[q],
        }

    # --- baseline gap ------------------------------------------------------------------
    if problem.spring_nuisance:
        spring_all = _fit_effect(problem, None, all_rows, spring_all).spring
        base_pred = [problem.predict(i, base, spring_all) for i in range(n_runs)]
        base_res = [problem.resid(i, p) for i, p in enumerate(base_pred)]
    z_runs = [problem.norm_resid(i, base, spring_all) for i in range(n_runs)]
    z_all = np.concatenate(z_runs)
    N = z_all.size
    base_rms_noise = float(np.sqrt(np.mean(z_all**2)))
    nu = min(noise_dof_q.values())
    # Zero re-estimated from k >= 2 rest rows: off by about noise/sqrt(k). With
    # k = 1 nothing is re-estimated and the logged zero (a tare) is taken as exact.
    ref_weights = (
        [
            (len(problem.frames[i]) * len(problem.rereferenced) / N, len(problem.rest[i]))
            for i in range(n_runs)
            if len(problem.rest[i]) >= 2
        ]
        if problem.rereferenced
        else []
    )
    limit = gap_limit(
        [sum(len(d) for d in problem.frames)] * len(Q), [noise_dof_q[q] for q in Q], reference=ref_weights
    )
    floor2 = 1.0 + sum(w / k for w, k in ref_weights)
    gap_significant = base_rms_noise > limit
    common_unit = _common_unit(Q)

    base_by_q = {}
    for q in Q:
        unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
        r = np.concatenate([base_res[i][q] for i in range(n_runs)])
        base_by_q[q] = {
            "rmse": float(np.sqrt(np.mean(r**2))) * fac,
            "bias": float(np.mean(r)) * fac,
            "rmse_over_noise": float(np.sqrt(np.mean(r**2)) / problem.sigma[q]),
            "unit": unit,
        }
    k_base = 1 if (kind == "sensing" and experiment.rig.spring_constant is None) else 0
    base_sse = float(np.sum(z_all**2))
    baseline = {
        "rmse_over_noise": base_rms_noise,
        "n": int(N),
        "by_quantity": base_by_q,
        "aic": base_sse + 2 * k_base,
        "bic": base_sse + k_base * math.log(N),
        "spring_constant_N_per_m": spring_all,
        "options": {
            "spring_constant": "rig"
            if experiment.rig.spring_constant is not None
            else ("identified on training runs" if kind == "sensing" else None)
        },
    }
    gap = {
        "rmse_over_noise": base_rms_noise,
        "limit": limit,
        "level": GAP_LEVEL,
        "expected_rmse_over_noise_without_gap": math.sqrt(floor2),
        "rest_rows": [int(len(r)) for r in problem.rest] if problem.rereferenced else None,
        "n_points": int(N),
        "noise_dof": nu,
        "significant": bool(gap_significant),
        "rule": f"baseline RMSE/noise above sqrt of the {GAP_LEVEL:.0%} quantile of F(N, nu)",
    }

    # --- where: regimes and per-run statistics ---------------------------------
    force_edges = None
    if kind == "sensing":
        fall = np.concatenate([problem.measured(i, "force") for i in range(n_runs)])
        force_edges = np.quantile(fall, [0, 0.25, 0.5, 0.75, 1.0])
    labels: dict[str, list] = {}
    zs: list[np.ndarray] = []
    qlab: list[np.ndarray] = []
    for i in range(n_runs):
        d = problem.frames[i]
        for q in Q:
            lab = _regime_labels(kind, d, q, force_edges)
            r = base_res[i][q]
            zs.append(r / problem.sigma[q])
            qlab.append(np.full(len(d), q, dtype=object))
            for g, v in lab.items():
                labels.setdefault(g, []).append(v)
    z_cat = np.concatenate(zs)
    q_cat = np.concatenate(qlab)
    lab_cat = {g: np.concatenate(v) if len(v) == len(zs) else None for g, v in labels.items()}
    regimes = []
    for g, lab in lab_cat.items():
        if lab is None:
            continue
        tot = float(np.sum(z_cat**2)) or 1.0
        for name in dict.fromkeys(lab):
            if not name:
                continue
            m = lab == name
            zz = z_cat[m]
            entry = {
                "group": g,
                "regime": str(name),
                "n": int(m.sum()),
                "rmse_over_noise": float(np.sqrt(np.mean(zz**2))),
                "bias_over_noise": float(np.mean(zz)),
                "share": float(np.sum(zz**2) / tot),
                "by_quantity": {},
            }
            for q in Q:
                mq = m & (q_cat == q)
                if mq.any():
                    unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
                    zq = z_cat[mq] * problem.sigma[q] * fac
                    entry["by_quantity"][q] = {
                        "n": int(mq.sum()),
                        "rmse": float(np.sqrt(np.mean(zq**2))),
                        "bias": float(np.mean(zq)),
                        "unit": unit,
                    }
            regimes.append(entry)

    run_stats = []
    inputs = list(F.INPUTS[kind]) + (
        ["time"] if kind != "dynamic" and any("time" in d for d in problem.frames) else []
    )
    for i in range(n_runs):
        d = problem.frames[i]
        entry = {
            "index": i,
            "name": str(getattr(runs[i], "path", i)).rsplit("/", 1)[-1],
            "n": int(len(d)),
            "by_quantity": {},
        }
        for q in Q:
            unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
            r = base_res[i][q]
            entry["by_quantity"][q] = {
                "rmse": float(np.sqrt(np.mean(r**2))) * fac,
                "bias": float(np.mean(r)) * fac,
                "unit": unit,
                "noise_sigma": per_run_sigma[q][i] * fac,
                "lag1_autocorrelation": _autocorr1(r),
                "durbin_watson": _durbin_watson(r),
                "correlation_with_inputs": {c: _corr(r, d[c].to_numpy(float)) for c in inputs if c in d},
            }
        run_stats.append(entry)

    # --- which: candidates, leave one out -------------------------------------------
    folds = _folds(problem)
    K = len(folds)
    fold_info = []
    before_fold = np.zeros(K)
    n_fold = np.zeros(K)
    before_q = np.zeros((K, len(Q)))
    n_q = np.zeros((K, len(Q)))
    train_rows_f, spring_f = [], []
    for k, held in enumerate(folds):
        train = _complement(problem, held)
        spring = problem.spring_for(train)
        if problem.spring_nuisance:
            spring = _fit_effect(problem, None, train, spring).spring
        train_rows_f.append(train)
        spring_f.append(spring)
        for i, m in held:
            zb = problem.norm_resid(i, base, spring, m)
            before_fold[k] += np.sum(zb**2)
            n_fold[k] += zb.size
            nm = int(m.sum())
            for j, q in enumerate(Q):
                before_q[k, j] += np.sum((zb[j * nm : (j + 1) * nm] * problem.sigma[q]) ** 2)
                n_q[k, j] += nm
        fold_info.append(
            {
                "held_out": [
                    {"run": i, "rows": [int(np.flatnonzero(m)[0]), int(np.flatnonzero(m)[-1])]}
                    for i, m in held
                ]
            }
        )

    rng = np.random.default_rng(seed)
    boot_idx = rng.integers(0, K, size=(max(int(n_boot), 1), K))
    b_before = before_fold[boot_idx].sum(axis=1)
    b_n = n_fold[boot_idx].sum(axis=1)

    cand_results: list[CandidateResult] = []
    after_folds: dict[str, np.ndarray] = {}
    best_values: dict[str, np.ndarray] = {}
    best_springs: dict[str, float | None] = {}
    b4 = math.sqrt(before_fold.sum() / n_fold.sum())

    def run_jobs(effs):
        jobs = [(problem, eff, folds, train_rows_f, spring_f, all_rows, spring_all) for eff in effs]
        n_work = _n_workers(workers, len(jobs))
        if n_work > 1:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            with ProcessPoolExecutor(max_workers=n_work, mp_context=mp.get_context("spawn")) as pool:
                return list(pool.map(_candidate_job, jobs))
        return [_candidate_job(j) for j in jobs]

    def scored(eff, outcome) -> CandidateResult:
        after_fold, after_q, fold_vals, full = outcome
        fold_rows = [
            {
                "fold": k,
                "rmse_before_noise": math.sqrt(before_fold[k] / n_fold[k]),
                "rmse_after_noise": math.sqrt(after_fold[k] / n_fold[k]),
                "parameters": {p.field: float(v) for p, v in zip(eff.params, fold_vals[k])},
            }
            for k in range(K)
        ]
        after_folds[eff.name] = after_fold
        best_values[eff.name] = full.values
        best_springs[eff.name] = full.spring
        af = math.sqrt(after_fold.sum() / n_fold.sum())
        shrink = 1.0 - af / b4 if b4 > 0 else 0.0
        b_after = after_fold[boot_idx].sum(axis=1)
        with np.errstate(all="ignore"):
            boot_shrink = 1.0 - np.sqrt(b_after / b_n) / np.sqrt(b_before / b_n)
        frac = (b4**2 - af**2) / (b4**2 - floor2) if b4**2 > floor2 else float("nan")
        kp = len(eff.params) + k_base
        by_q = {}
        for j, q in enumerate(Q):
            unit, fac = DISPLAY_UNITS.get(q, ("", 1.0))
            by_q[q] = {
                "heldout_rmse_before": math.sqrt(before_q[:, j].sum() / n_q[:, j].sum()) * fac,
                "heldout_rmse_after": math.sqrt(after_q[:, j].sum() / n_q[:, j].sum()) * fac,
                "unit": unit,
            }
        if common_unit == "noise":
            rb, ra = b4, af
        else:
            fac = DISPLAY_UNITS[Q[0]][1]
            rb = math.sqrt(before_q.sum() / n_q.sum()) * fac
            ra = math.sqrt(after_q.sum() / n_q.sum()) * fac
        return CandidateResult(
            effect=eff.name,
            heldout_rmse_before=rb,
            heldout_rmse_after=ra,
            unit=common_unit,
            heldout_rmse_before_noise=b4,
            heldout_rmse_after_noise=af,
            shrinkage=shrink,
            shrinkage_ci95=_ci(boot_shrink),
            fraction_closed=frac,
            aic=full.sse + 2 * kp,
            bic=full.sse + kp * math.log(max(full.n, 1)),
            parameters=_param_ci(full, eff),
            by_quantity=by_q,
            folds=fold_rows,
            cause=eff.cause,
            separate_by=eff.separate_by,
            fit_success=full.success,
        )

    for eff, outcome in zip(cands, run_jobs(cands)):
        cand_results.append(scored(eff, outcome))
    cand_results.sort(key=lambda c: (c.heldout_rmse_after_noise, c.effect))

    # --- verdict -----------------------------------------------------------------------
    verdict, effect, aliased, reason = _verdict(
        cand_results, gap_significant, after_folds, boot_idx, b_n, base_rms_noise, limit
    )
    # Two effects at once: when no single candidate explains the gap, try pairs of
    # the candidates that each explain part of it (forward selection, one step).
    combination = None
    by_name = {e.name: e for e in cands}
    if verdict == "unexplained" and gap_significant:
        pool = [
            c.effect
            for c in cand_results
            if np.isfinite(c.fraction_closed)
            and c.fraction_closed >= MIN_PARTIAL_FRACTION
            and c.shrinkage_ci95[0] > 0
        ][:PAIR_POOL]
        pairs = [combine(by_name[a], by_name[b]) for a, b in itertools.combinations(pool, 2)]
        pairs = [e for e in pairs if e is not None]
        if pairs:
            combos = [scored(e, o) for e, o in zip(pairs, run_jobs(pairs))]
            combos.sort(key=lambda c: (c.heldout_rmse_after_noise, c.effect))
            order = {c.effect: i for i, c in enumerate(cand_results)}
            picked = _pair_verdict(combos, after_folds, boot_idx, b_n, order)
            if picked is not None:
                verdict, effect, aliased, reason, combination = picked
    separate = (
        {c.effect: c.separate_by for c in cand_results if c.effect in ([effect] + aliased)}
        if verdict == "aliased"
        else {}
    )

    # --- series for plots -----------------------------------------------------------
    best = cand_results[0] if cand_results else None
    best_eff = by_name.get(best.effect) if best is not None else None
    if combination is not None:
        best = next(c for c in combos if c.effect == combination["effect"])
        best_eff = combine(*(by_name[m] for m in combination["effects"]))
    series_runs = []
    for i in range(n_runs):
        d = problem.frames[i]
        xcol = {"static": "temperature", "dynamic": "time", "sensing": "time", "curvature": "cable"}[kind]
        if xcol not in d:
            x, xlabel = np.arange(len(d)), "row"
        else:
            unit, fac = _INPUT_UNITS.get(xcol, ("", 1.0))
            x, xlabel = d[xcol].to_numpy(float) * fac, f"{xcol} [{unit}]"
        best_pred = None
        if best is not None:
            try:
                best_pred = problem.predict(
                    i, best_eff.mods(best_values[best.effect]), best_springs[best.effect]
                )
            except (TcamlabError, ArithmeticError):
                best_pred = None
        series_runs.append(
            {
                "x": x,
                "xlabel": xlabel,
                "measured": {q: problem.measured(i, q) for q in Q},
                "baseline": base_pred[i],
                "best": best_pred,
            }
        )
    series = {
        "runs": series_runs,
        "z": z_cat,
        "labels": {g: v for g, v in lab_cat.items() if v is not None},
        "regime_groups": [g for g, v in lab_cat.items() if v is not None],
    }

    exp_info = {
        "name": getattr(experiment, "name", None),
        "title": getattr(experiment, "title", None),
        "path": str(getattr(experiment, "path", "")),
        "kind": kind,
        "n_runs": n_runs,
    }
    settings = {
        "n_boot": int(n_boot),
        "seed": int(seed),
        "folds": K,
        "fold_scheme": "leave one run out" if n_runs >= 2 else f"{K} contiguous blocks of one run",
        "candidates": [e.name for e in cands],
        "gap_level": GAP_LEVEL,
        "min_fraction_closed": MIN_FRACTION_CLOSED,
        "ci_level": CI_LEVEL,
        "fold_details": fold_info,
    }
    return DiagnosisResult(
        kind=kind,
        experiment=exp_info,
        verdict=verdict,
        effect=effect,
        ranking=cand_results,
        aliased_with=aliased,
        separate_by=separate,
        noise_floor=noise_floor,
        baseline=baseline,
        regimes=regimes,
        runs=run_stats,
        gap=gap,
        reason=reason,
        settings=settings,
        combination=combination,
        _series=series,
    )


def _candidate_job(job):
    """Fit one candidate on every fold's training rows and on all rows."""
    problem, eff, folds, train_rows_f, spring_f, all_rows, spring_all = job
    Q = problem.quantities
    K = len(folds)
    after_fold = np.zeros(K)
    after_q = np.zeros((K, len(Q)))
    fold_vals = []
    for k, held in enumerate(folds):
        fit = _fit_effect(problem, eff, train_rows_f[k], spring_f[k])
        fold_vals.append(fit.values)
        mods = eff.mods(fit.values)
        for i, m in held:
            za = problem.norm_resid(i, mods, fit.spring, m)
            after_fold[k] += np.sum(za**2)
            nm = int(m.sum())
            for j, q in enumerate(Q):
                after_q[k, j] += np.sum((za[j * nm : (j + 1) * nm] * problem.sigma[q]) ** 2)
    full = _fit_effect(problem, eff, all_rows, spring_all)
    return after_fold, after_q, fold_vals, full


def _n_workers(workers, n_jobs: int) -> int:
    """Processes for the candidate fits (default 1; never inside a daemon process)."""
    import multiprocessing as mp

    if workers is None or mp.current_process().daemon:
        return 1
    return max(1, min(int(workers), n_jobs))


def _common_unit(Q) -> str:
    units = {DISPLAY_UNITS.get(q, ("", 1.0))[0] for q in Q}
    return units.pop() if len(units) == 1 else "noise"


def _verdict(ranking, gap_significant, after_folds, boot_idx, b_n, base_rms, limit):
    if not gap_significant:
        return (
            "none",
            None,
            [],
            f"the baseline RMSE is {base_rms:.2f} x the noise floor, within the "
            f"no-gap limit {limit:.2f}: the thesis model explains the data to within noise",
        )
    if not ranking:
        return "unexplained", None, [], "the gap is significant and there are no candidates"
    best = ranking[0]
    ok = (
        np.isfinite(best.fraction_closed)
        and best.fraction_closed >= MIN_FRACTION_CLOSED
        and best.shrinkage_ci95[0] > 0
    )
    if not ok:
        return (
            "unexplained",
            None,
            [],
            f"the baseline RMSE is {base_rms:.2f} x the noise floor (limit {limit:.2f}); the best "
            f"candidate, {best.effect}, closes {_pct(best.fraction_closed)} of the gap on withheld "
            f"data (needs {MIN_FRACTION_CLOSED:.0%} and a shrinkage interval above 0)",
        )
    aliased = []
    a_best = after_folds[best.effect][boot_idx].sum(axis=1)
    for c in ranking[1:]:
        if not (np.isfinite(c.fraction_closed) and c.fraction_closed >= MIN_FRACTION_CLOSED):
            continue
        diff = (after_folds[c.effect][boot_idx].sum(axis=1) - a_best) / b_n
        lo, hi = _ci(diff)
        if lo <= 0.0:
            aliased.append(c.effect)
    if aliased:
        return (
            "aliased",
            best.effect,
            aliased,
            f"{best.effect} closes {_pct(best.fraction_closed)} of the gap on withheld data, but "
            f"{', '.join(aliased)} fit{'s' if len(aliased) == 1 else ''} the withheld runs "
            "indistinguishably well",
        )
    return (
        "attributed",
        best.effect,
        [],
        f"{best.effect} closes {_pct(best.fraction_closed)} of the gap above the noise floor on "
        f"withheld data (held-out RMSE shrinks by {best.shrinkage:.0%}) and every other candidate "
        "is clearly worse",
    )


def _pair_verdict(combos, after_folds, boot_idx, b_n, order):
    """Verdict from pairs of effects, or None when no pair qualifies.

    A pair qualifies when it closes at least :data:`MIN_FRACTION_CLOSED` of the
    gap on withheld data with a shrinkage interval above 0 and is clearly
    better than each of its members alone (paired bootstrap of the held-out
    MSE difference above 0): both effects are needed. The best qualifying pair
    names the effect (the member that ranks higher alone); other qualifying
    pairs that fit the withheld runs indistinguishably well make it ``aliased``.
    """

    def boot(name):
        return after_folds[name][boot_idx].sum(axis=1)

    qualified = []
    for c in combos:
        if not (
            np.isfinite(c.fraction_closed)
            and c.fraction_closed >= MIN_FRACTION_CLOSED
            and c.shrinkage_ci95[0] > 0
        ):
            continue
        a_pair = boot(c.effect)
        if all(_ci((boot(m) - a_pair) / b_n)[0] > 0 for m in c.effect.split("+")):
            qualified.append(c)
    if not qualified:
        return None
    best = qualified[0]
    members = sorted(best.effect.split("+"), key=lambda m: order.get(m, len(order)))
    primary, second = members[0], members[1:]
    a_best = boot(best.effect)
    rivals = [c for c in qualified[1:] if _ci((boot(c.effect) - a_best) / b_n)[0] <= 0]
    combination = {"effects": members, **best.to_dict()}
    both = " and ".join(members)
    closes = (
        f"no single candidate closes {MIN_FRACTION_CLOSED:.0%} of the gap; {both} together "
        f"close {_pct(best.fraction_closed)} of it on withheld data (held-out RMSE shrinks "
        f"by {best.shrinkage:.0%}), and the pair beats either alone"
    )
    if rivals:
        others = sorted(
            ({m for c in rivals for m in c.effect.split("+")} | set(second)) - {primary},
            key=lambda m: order.get(m, len(order)),
        )
        return (
            "aliased",
            primary,
            others,
            closes
            + "; but "
            + ", ".join(c.effect for c in rivals)
            + " fit the withheld runs indistinguishably well",
            combination,
        )
    return "attributed", primary, [], closes, combination


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.0%}"
