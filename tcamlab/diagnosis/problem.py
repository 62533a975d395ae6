"""The diagnosis's view of one experiment: runs, per-run constants, noise scales and fits.

:class:`Problem` evaluates the kind's model with effect terms on chosen rows
and returns residuals normalised by the noise floor; :func:`fit_effect` fits
an effect's parameters (and the sensing spring-constant nuisance) on training
rows; :func:`folds` and :func:`complement` split the rows into held-out and
training sets.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import optimize

from tcamlab.effects import Effect, Mods
from tcamlab.errors import ConfigError, TcamlabError
from tcamlab.kinds import get_kind, predict, run_scatter, scored_quantities, step_rows

__all__ = [
    "serial_kernels",
    "best_least_squares",
    "bounded_gauss_newton_step",
    "inner_box",
    "FAIL_RESIDUAL",
    "MODEL_ERRORS",
    "Problem",
    "Fit",
    "fit_effect",
    "domain_bounds",
    "folds",
    "complement",
]


FAIL_RESIDUAL = 1.0e3
"""Normalised residual returned for every point of a model evaluation outside
the model's domain, so the optimiser backs away instead of crashing."""


SPRING_STEP = 0.01
"""Scale of the sensing spring-constant nuisance: S = S0 (1 + SPRING_STEP theta)."""


MODEL_ERRORS = (TcamlabError, ArithmeticError, FloatingPointError, ZeroDivisionError, ValueError)
"""Exceptions of a model evaluated outside its domain."""


PREDICTIONS_KEPT = 2
"""Thesis-model predictions :meth:`Problem.predict` keeps per run (a sensing experiment's
folds each identify their own spring constant)."""


DOMAIN_BISECTIONS = 12
"""Bisection steps that locate the edge of a parameter's physical domain (to 1/4096 of
the library bound: the fit only needs to stay inside)."""


@contextmanager
def serial_kernels():
    """Run the compiled model kernels on one thread inside the block (restored after).

    The diagnosis evaluates the model thousands of times on a run's few dozen rows; the
    static kernel's thread pool (``parallel=True``, meant for Monte Carlo batches) then costs
    far more than it saves: 5.8 ms of CPU per static prediction of 26 rows on two threads
    against 0.13 ms on one (40 ms against 1.3 ms of wall time on a loaded 2-core machine).
    The diagnosis's own parallelism is over candidates (``workers``).
    """
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a dependency
        yield
        return
    n = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(n)


class Problem:
    """Runs, per-run constants and noise scales of one experiment; evaluates Mods on rows.

    ``sigma`` holds each quantity's noise floor [SI] once :func:`estimate_noise` has run.
    """

    def __init__(self, experiment, runs):
        self.kind = experiment.kind
        self.k = get_kind(self.kind)
        self.sample = experiment.sample
        self.rig = experiment.rig
        self.quantities = tuple(self.k.outputs)
        self.frames: list[pd.DataFrame] = [r.data for r in runs]
        # noisy inputs a slower instrument logged, read averaged over frames (tcamlab.io)
        self.smoothed: list[dict] = [dict(getattr(r, "smoothed", None) or {}) for r in runs]
        self.names = [getattr(r, "path", None) for r in runs]
        self.sigma = {q: 1.0 for q in self.quantities}
        for i, d in enumerate(self.frames):
            missing = [c for c in self.k.inputs + self.quantities if c not in d]
            if missing:
                raise ConfigError(f"diagnosis: run {i} has no column(s) {', '.join(missing)}")
        self._fixed_opts = [self._run_options(i) for i in range(len(self.frames))]
        self.spring_nuisance = self.k.needs_training and self.rig.spring_constant is None
        # what else every run logs of what the model predicts (a voltage-step test's current or
        # temperature) is scored too, as calibration scores it
        self.quantities = self._scored_quantities()
        self.sigma = {q: 1.0 for q in self.quantities}
        # a column only some runs log (the current, on the runs a design added) is scored on
        # those runs; elsewhere its residual is a constant zero the fits cannot move
        self.logged = [frozenset(q for q in self.quantities if q in d) for d in self.frames]
        # A run's logged zero (the laser's first reading, the load cell's tare) carries the
        # instrument's noise: it is a per-run nuisance, profiled out as in calibration.
        self.zeroed = tuple(q for q in self.quantities if q in self.k.nuisance_zeros)
        # how far a run's sample may depart from the shared one (re-mounting a sensor)
        self.run_to_run = run_scatter(experiment)

    def _scored_quantities(self) -> tuple[str, ...]:
        """The kind's outputs and every other predicted column all runs log
        (:func:`tcamlab.kinds.scored_quantities`), from the first run's stated prediction; the
        outputs alone where the stated model has no prediction there, or needs a spring constant
        the runs are still to identify (the pull test's extra columns are inputs anyway)."""
        if self.spring_nuisance:
            return self.quantities
        try:
            pred = self.predict(0, Mods(), None)
        except MODEL_ERRORS:
            return self.quantities
        return scored_quantities(self.k, pred, self.frames, every=False)

    def logs(self, i: int, q: str) -> bool:
        """Whether run i logs quantity q (every run logs the kind's outputs)."""
        return q in self.logged[i]

    def step_rows(self, i: int) -> np.ndarray:
        """Rows of run i next to a commanded step, which the noise floor leaves out
        (:func:`tcamlab.kinds.step_rows`)."""
        return step_rows(self.k, self.frames[i])

    def n_entries(self, i: int, mask=None) -> int:
        """Measured entries of run i's stacked residuals on the rows in ``mask``."""
        n = len(self.frames[i]) if mask is None else int(np.count_nonzero(mask))
        return n * len(self.logged[i])

    # options -------------------------------------------------------------
    def _run_options(self, i: int) -> dict:
        """The kind's per-run constants (R0 ...), without a spring constant to identify."""
        where = "diagnosis"
        return dict(self.k.run_options(self.sample, self.rig, self.frames[i], where=where).options)

    def spring_for(self, rows: Sequence[tuple[int, np.ndarray]]) -> float | None:
        """The spring constant identified on the given (training) rows, where the kind needs one."""
        if not self.spring_nuisance:
            return None
        training = [(self.frames[i], m) for i, m in rows]
        ro = self.k.run_options(self.sample, self.rig, self.frames[rows[0][0]], training=training)
        return float(ro.options["spring_constant"])

    def options(self, i: int, spring: float | None) -> dict:
        opts = dict(self._fixed_opts[i])
        if spring is not None:
            opts["spring_constant"] = spring
        return opts

    # evaluation ----------------------------------------------------------
    def predict(self, i: int, mods: Mods, spring: float | None, sample=None) -> dict[str, np.ndarray]:
        """Predictions [SI] of run i (with ``sample`` in place of the experiment's, if given).

        The thesis model's (no effect terms, the experiment's sample) are kept: the baseline is
        asked for again on every fold and by every effect's domain check (on an hour of 1 kHz
        log, a third of a second each), and its arrays are the baseline fit's own."""
        key = (i, spring) if sample is None and mods == Mods() else None
        cache = self.__dict__.setdefault("_predicted", {})
        if key is not None and key in cache:
            return dict(cache[key])
        sample = self.sample if sample is None else sample
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = predict(self.kind, sample, self.rig, self.frames[i], mods, **self.options(i, spring))
        for q in self.quantities:
            if not np.all(np.isfinite(out[q])):
                raise ArithmeticError("non-finite prediction")
        if key is not None:
            cache[key] = dict(out)
            while len(cache) > PREDICTIONS_KEPT * len(self.frames):
                cache.pop(next(iter(cache)))
        return out

    def input_gain(self, i: int, column: str, spring: float | None) -> dict[str, np.ndarray] | None:
        """d predicted / d input [SI per the input's unit] of run i, per row, at the stated
        values, or None where the model has no prediction there: the column moved by a
        millionth of its size on every row but the first (the models read an input row by
        row, and a model referred to its first row, the static displacement, would otherwise
        see only its gain's change since then)."""
        col = self.frames[i][column].to_numpy(float)
        h = 1e-6 * max(float(np.max(np.abs(col))), 1e-300)
        moved = self.frames[i].copy()
        moved[column] = col + np.where(np.arange(col.size) > 0, h, 0.0)
        try:
            base = self.predict(i, Mods(), spring)
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                up = predict(self.kind, self.sample, self.rig, moved, Mods(), **self.options(i, spring))
        except MODEL_ERRORS:
            return None
        return {q: (up[q] - base[q]) / h for q in self.quantities}

    def measured(self, i: int, q: str) -> np.ndarray:
        return self.frames[i][q].to_numpy(float)

    def resid(self, i: int, pred: dict, mask=None) -> dict[str, np.ndarray]:
        """measured - predicted - zero [SI] per quantity (every row of the run).

        The zero of a quantity of :attr:`tcamlab.kinds.Kind.nuisance_zeros` is profiled
        out as calibration does (:class:`tcamlab.calibration.problem.CalibrationProblem`):
        the mean of ``measured - predicted`` over the rows scored (``mask``, default the
        whole run). A withheld run's zero is thus estimated from that run, like any run's.
        """
        out = {}
        for q in self.quantities:
            if not self.logs(i, q):
                out[q] = np.zeros(len(self.frames[i]))
                continue
            r = self.measured(i, q) - pred[q]
            if q in self.zeroed:
                r = r - float(np.mean(r if mask is None else r[mask]))
            out[q] = r
        return out

    def n_zeros(self, rows) -> int:
        """Nuisance zeros profiled out on the given (run, mask) pairs."""
        return sum(self.logs(i, q) for i, _ in rows for q in self.zeroed)

    def scaled(self, i: int, pred: dict, mask=None) -> np.ndarray:
        """Normalised residuals of run i's rows in ``mask`` (quantities stacked)."""
        res = self.resid(i, pred, mask)
        parts = []
        for q in self.quantities:
            r = res[q] / self.sigma[q]
            parts.append(r if mask is None else r[mask])
        return np.concatenate(parts)

    def failed(self, i: int, mask=None) -> np.ndarray:
        """The residuals of a model evaluation outside its domain (:data:`FAIL_RESIDUAL`)."""
        n = len(self.frames[i]) if mask is None else int(np.count_nonzero(mask))
        return np.full(n * len(self.quantities), FAIL_RESIDUAL)

    def norm_resid(self, i: int, mods: Mods, spring, mask=None) -> np.ndarray:
        """Normalised residuals of run i (quantities stacked), or FAIL_RESIDUAL."""
        try:
            pred = self.predict(i, mods, spring)
        except MODEL_ERRORS:
            return self.failed(i, mask)
        return self.scaled(i, pred, mask)


@dataclass
class Fit:
    """Outcome of :func:`fit_effect`."""

    theta: np.ndarray  # scaled parameters (effect, then the S nuisance if any)
    values: np.ndarray  # effect parameters, SI
    sse: float  # normalised
    n: int
    jac: np.ndarray | None
    success: bool
    spring: float | None = None


def domain_bounds(problem: Problem, effect: Effect, rows, spring, scales, lo, hi) -> None:
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
            except MODEL_ERRORS:
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


def fit_effect(problem: Problem, effect: Effect | None, rows, spring, *, max_nfev: int = 60) -> Fit:
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
        domain_bounds(problem, effect, rows, spring, scales, lo, hi)
    if k == 0:
        r0 = fun(np.zeros(0))
        return Fit(np.zeros(0), np.zeros(0), float(np.sum(r0**2)), r0.size, None, True, spring)
    starts = [np.zeros(k)]
    if k_eff:
        for sgn in (1.0, -1.0):
            x0 = np.zeros(k)
            x0[:k_eff] = sgn
            starts.append(x0)
    res = best_least_squares(fun, starts, lo, hi, 1.0, max_nfev)
    if res is None:
        r0 = fun(np.zeros(k))
        return Fit(np.zeros(k), np.zeros(k_eff), float(np.sum(r0**2)), r0.size, None, False, spring)
    sse = float(np.sum(res.fun**2))
    values, sp = unpack(res.x)
    return Fit(res.x, values, sse, res.fun.size, res.jac, bool(res.success), sp)


def inner_box(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box ``[lo, hi]`` shrunk by 1e-9 of its width (2 where unbounded): starts strictly
    inside, as ``least_squares`` requires."""
    width = np.where(np.isfinite(hi - lo), hi - lo, 2.0)
    return lo + 1e-9 * width, hi - 1e-9 * width


def bounded_gauss_newton_step(J: np.ndarray, f: np.ndarray, x: np.ndarray, lo, hi) -> np.ndarray:
    """The Gauss-Newton step from ``x`` (residuals ``f``, Jacobian ``J``) inside the box
    ``[lo, hi]``: a parameter at a bound that the step would push out of the box is held
    there (an active set), and the step is solved for the others.

    Clipping the unconstrained step instead keeps the other parameters' share of a move the
    bound forbids: from a fit with the curvature rig's d1 error at its 4 mm bound, the
    clipped step of two of three folds moved S from 17.0 to 21.6 N/m and predicted the
    withheld run at 7 x recalibration's held-out RMSE (off-library tilted sensor at 10x).
    """
    free = np.ones(x.size, bool)
    width = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    at_lo, at_hi = x <= lo + 1e-6 * width, x >= hi - 1e-6 * width
    for _ in range(x.size + 1):
        step = np.zeros(x.size)
        if free.any():
            step[free] = np.linalg.lstsq(J[:, free], -f, rcond=None)[0]
        out = free & ((at_lo & (step < 0)) | (at_hi & (step > 0)))
        if not out.any():
            break
        free &= ~out
    return np.clip(x + step, lo, hi) - x


def best_least_squares(fun, starts, lo, hi, x_scale, max_nfev: int, screen: int | None = None):
    """The best of bounded ``least_squares`` fits of ``fun`` from each distinct start (clipped
    into the box), or None when every start fails; one set of solver settings for the
    diagnosis's effect fits and its joint recalibration fits.

    With ``screen``, several starts are each run for at most that many evaluations and the
    best is then run to convergence (a long log's reduced fits, where the starts are
    many and each evaluation is the model over hours of log)."""
    if screen is not None and len(starts) > 1:
        first = best_least_squares(fun, starts, lo, hi, x_scale, screen)
        if first is not None:
            starts = [first.x]
    lo_i, hi_i = inner_box(lo, hi)
    best, seen = None, []
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, float), lo_i, hi_i)
        if any(np.allclose(x0, s_) for s_ in seen):
            continue
        seen.append(x0)
        try:
            res = optimize.least_squares(
                fun,
                x0,
                bounds=(lo, hi),
                method="trf",
                x_scale=x_scale,
                diff_step=1e-4,
                max_nfev=max_nfev,
                ftol=1e-6,
                xtol=1e-6,
                gtol=1e-8,
            )
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or res.cost < best.cost:
            best = res
    return best


def folds(problem: Problem) -> list[list[tuple[int, np.ndarray]]]:
    """Held-out sets: one run each, or contiguous blocks of a single run.

    Only ``problem.frames`` is read. The held-out rows of all folds cover every
    row exactly once; :func:`complement` gives the training rows (no guard band).
    """
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


def complement(problem: Problem, held) -> list[tuple[int, np.ndarray]]:
    """Training rows of a fold: every row not held out (runs left empty are dropped)."""
    held_map = {i: m for i, m in held}
    rows = []
    for i, d in enumerate(problem.frames):
        m = np.ones(len(d), bool)
        if i in held_map:
            m &= ~held_map[i]
        if m.any():
            rows.append((i, m))
    return rows
