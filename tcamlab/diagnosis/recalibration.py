"""Recalibration as a candidate explanation, and every effect fitted together with it.

The kind's calibratable parameters (:attr:`tcamlab.kinds.Kind.calibration`) are
refitted under their priors by the calibration package's
:class:`~tcamlab.calibration.problem.CalibrationProblem`: its fitted coordinates
``u`` (log value for a positive parameter, value / prior sd otherwise), its
model at ``u`` (``predict_run``, with an effect's :class:`~tcamlab.effects.Mods`)
and its prior residuals ``(u - u0) / sd_u``. The data residuals are the
diagnosis's own (:meth:`Problem.scaled`): the kind's outputs over the
diagnosis's noise floor, each run's nuisance zero profiled out over the rows
scored, so the recalibration, every effect and the baseline are scored alike.

An effect candidate is fitted jointly with the recalibrated parameters (and the
zeros): it must explain what recalibration cannot. Fits on the folds' training
rows start from the fit on all rows (warm start), which is why the all-rows fit
comes first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from tcamlab import reduction
from tcamlab.calibration.problem import CalibrationProblem
from tcamlab.diagnosis.problem import (
    FAIL_RESIDUAL,
    MODEL_ERRORS,
    Problem,
    best_least_squares,
    bounded_gauss_newton_step,
    domain_bounds,
    folds,
    inner_box,
)
from tcamlab.effects import Effect, Mods
from tcamlab.signals import block_means, n_blocks

__all__ = [
    "RECALIBRATION",
    "PLAUSIBLE_LEVEL",
    "ALIAS_CORRELATION",
    "EDGE_STEP",
    "correlations",
    "JointFit",
    "Recalibration",
    "effect_box",
]


RECALIBRATION = "recalibration"
"""Name of the recalibration candidate in the ranking."""


PLAUSIBLE_LEVEL = 0.999
"""A recalibration is plausible when the prior chi-square of its shift,
sum(((u - u0) / sd_u)^2), is below this quantile of chi-square with one degree
of freedom per parameter: beyond it the stated values and their stated
uncertainties are themselves in doubt, and an effect that explains the data
with plausible parameters is an equal explanation (``aliased``)."""


PIN_WEIGHT = 1.0e3
"""A calibrated parameter an effect generalises (:attr:`tcamlab.effects.Effect.generalises`)
is held at its stated value in that effect's fit by a prior row this many times its prior's
weight: the effect's term is that parameter's error, and fitting both would leave one
direction to two parameters (a singular Jacobian, and a fit that stalls)."""


EDGE_STEP = 0.01
"""A fitted parameter a step of this many prior sds from the model's domain edge is at it
(:meth:`Recalibration.at_domain_edge`): far inside the prior's width, far outside any
interval the data would give a parameter the model is smooth in."""


ALIAS_CORRELATION = 0.9
"""Two recalibrated parameters whose posterior correlation is at least this in magnitude are
named together: the data fix mainly a combination of them (the curvature rig's E and S both set
the sensor's stiffness), so a shift of one may be an error of the other."""


def correlations(cov: np.ndarray) -> np.ndarray:
    """The correlation matrix of a covariance (0 where a variance is not positive or finite)."""
    cov = np.asarray(cov, float)
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = cov / np.outer(d, d)
    return np.where(np.isfinite(r), r, 0.0)


MAX_NFEV_FULL = 80
"""Most residual evaluations of a fit on all rows (per start)."""


MAX_NFEV_FOLD = 30
"""Most residual evaluations of a fold's fit, started from the fit on all rows."""


SCREEN_NFEV = 12
"""Most residual evaluations of each start of a reduced fit before the best start is run to
convergence (:func:`~tcamlab.diagnosis.problem.best_least_squares`): two Jacobians of a
recalibration with an effect, enough to tell the basins apart."""

FLOOR_BLOCK = 16
"""Rows averaged into one residual by the recalibration that sets the noise floor where an input
is noisy (:meth:`Recalibration.fitted_residuals`). An input's white noise reaches the residuals
through the model's gain, so a row-by-row fit gains by any parameter shift that lowers that gain
(errors in variables: regression dilution). On three self-sensing runs of tcamlab's own law with
every parameter at its true value, such a fit moved R0 from 24.0 to 23.43 ohm: a 26 um misfit
bought a 1.6 % smaller noise, and the floor at that gain (0.1128 mm against 0.1165 mm) put the
true model 1.04 floors above it, a gap with nothing in it. Averaged over 16 rows, the noise's
share of the sum falls 16-fold; a smooth misfit's does not."""
FLOOR_MIN_BLOCKS = 64
"""Fewest blocks a run keeps in that fit: a shorter run is averaged over fewer rows."""


@dataclass
class JointFit:
    """Recalibrated parameters (and an effect's) fitted on some rows."""

    u: np.ndarray
    """Fitted coordinates of the calibrated parameters."""
    theta: np.ndarray
    """The effect's parameters over their scales [-] (empty for recalibration alone)."""
    values: np.ndarray
    """The effect's parameters [SI]."""
    sse: float
    """Sum of squared normalised data residuals (without the prior)."""
    n: int
    """Data residuals."""
    jac: np.ndarray | None
    """Jacobian of the data and prior residuals in (u, theta)."""
    success: bool
    spring: float | None = None
    """Unused (the sensing S is a calibrated parameter here); for the plots' interface."""
    fun: np.ndarray | None = None
    """Data and prior residuals at the fit (data: run by run, quantities stacked)."""
    box: tuple | None = None
    """Bounds of (u, theta) the fit respected."""
    sizes: list | None = None
    """Data residuals of each run in ``fun`` and ``jac`` where the fit ran on the runs'
    reduced representation (:mod:`tcamlab.reduction`; ``sse`` and ``n`` are then of every
    row at the fit); None: one per row and quantity."""

    @property
    def x(self) -> np.ndarray:
        return np.concatenate([self.u, self.theta])


def effect_box(problem: Problem, effect: Effect | None, spring) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of an effect's scaled parameters, shrunk to the model's domain once (stated values)."""
    if effect is None:
        return np.zeros(0), np.zeros(0)
    scales = np.array([p.scale for p in effect.params], float)
    lo = np.array([p.lower / p.scale for p in effect.params], float)
    hi = np.array([p.upper / p.scale for p in effect.params], float)
    rows = [(i, np.ones(len(d), bool)) for i, d in enumerate(problem.frames)]
    domain_bounds(problem, effect, rows, spring, scales, lo, hi)
    return lo, hi


class Recalibration:
    """The calibration problem of one experiment, evaluated with the diagnosis's residuals.

    Parameters
    ----------
    problem : Problem
        The diagnosis's view of the runs (noise floor set).
    experiment : Experiment
        The experiment file (stated values and uncertainties).
    runs : list of RunData
        Its runs, in ``problem``'s order.
    """

    def __init__(self, problem: Problem, experiment, runs):
        self.problem = problem
        # parameters that are an effect (dynamic beta) stay out: the effect is its own candidate
        # reduced with the diagnosis's noise floor and folds, not the calibration's (reductions())
        self.cal = CalibrationProblem([experiment], [runs], effect_params=False, reduce=False)
        self.specs = self.cal.specs
        self.p = len(self.specs)
        self.lo, self.hi = self.cal.bounds()
        self._reductions = None
        self._coarse_last = None

    def reductions(self) -> list:
        """Each run's :class:`~tcamlab.reduction.Reduction` (None: scored row by row), made on
        first use from the stated prediction and the noise floor, with the folds' edges."""
        if self._reductions is not None:
            return self._reductions
        frames, problem = self.problem.frames, self.problem
        out = [None] * len(frames)
        if any(reduction.enabled(len(d)) for d in frames):
            edges = [set() for _ in frames]
            for held in folds(problem):
                for i, m in held:
                    edges[i].update((np.flatnonzero(np.diff(m.astype(np.int8))) + 1).tolist())
            held_inputs = [c for c in problem.k.inputs if c != "time"]
            for i, d in enumerate(frames):
                # a run without one of the scored columns is scored row by row (its moments
                # would need the missing column's zeros in their layout)
                if not reduction.enabled(len(d)) or len(problem.logged[i]) < len(problem.quantities):
                    continue
                stated = self.cal.predict_run(0, i, self.cal.u0, Mods())
                out[i] = reduction.checked_reduction(
                    d,
                    held_inputs,
                    {q: stated[q] for q in problem.quantities},
                    {q: problem.measured(i, q) for q in problem.quantities},
                    dict(problem.sigma),
                    lambda f, i=i: self.cal.predict_run(0, i, self.cal.u0, Mods(), f),
                    sorted(edges[i]),
                    noisy=[c for c in problem.k.noisy_inputs if c in d],
                )
        self._reductions = out
        return out

    def _coarse(self, i: int, u: np.ndarray, mods: Mods) -> dict:
        """Predictions [SI] at run i's grid rows (the last one kept: a fold's fit asks for the
        held-out run's, to check the model's domain, right after the training residuals)."""
        key = (i, np.asarray(u, float).tobytes(), mods)
        if self._coarse_last is not None and self._coarse_last[0] == key:
            return self._coarse_last[1]
        red = self.reductions()[i]
        pred = self.cal.predict_run(0, i, u, mods, red.frame)
        # with noisy inputs, the model's slope in them (the noise moments)
        pred = dict(pred, slopes=red.slopes(lambda f: self.cal.predict_run(0, i, u, mods, f), pred))
        self._coarse_last = (key, pred)
        return pred

    def reducible(self, rows) -> bool:
        """Whether every (run, mask) of ``rows`` is scored on its reduced representation."""
        reds = self.reductions()
        return all(reds[i] is not None and self._blocks(reds[i], m) is not None for i, m in rows)

    def reduced_resid(self, i: int, u: np.ndarray, mods: Mods, mask=None) -> np.ndarray:
        """Normalised moments of run i's residuals over the blocks in ``mask``
        (:mod:`tcamlab.reduction`), quantities stacked, each run's zero profiled out over
        those blocks as :meth:`Problem.resid` does over the rows, then the constant residual
        of what the moments leave out (``Reduction.within``); or FAIL_RESIDUAL."""
        red = self.reductions()[i]
        sel = self._blocks(red, mask)
        counts = red.counts[sel]
        try:
            pred = self._coarse(i, u, mods)
        except MODEL_ERRORS:
            size = red.per_moment(red.counts, sel).size
            return np.full(len(self.problem.quantities) * size + 1, FAIL_RESIDUAL)
        parts, rest = [], 0.0
        for q in self.problem.quantities:
            d0, d1 = red.residual(q, pred[q], pred["slopes"].get(q), sel)
            if q in self.problem.zeroed:  # the mean of the rows' residuals, as Problem.resid
                root = np.sqrt(counts)
                d0 = d0 - root * (float(root @ d0) / float(counts.sum()))
            parts += [d0 / self.problem.sigma[q], d1 / self.problem.sigma[q]]
            rest += float(np.sum(red.within[q][sel])) / self.problem.sigma[q] ** 2
        return np.concatenate(parts + [np.array([np.sqrt(rest)])])

    def resid(self, i: int, u: np.ndarray, mods: Mods, mask=None) -> np.ndarray:
        """Normalised residuals of run i's rows in ``mask`` at ``u`` with ``mods``. Those of
        all of a long run's rows are kept for the last (run, u, mods): a reduced fit scores
        every row at its optimum and the term's RMS asks for the same rows again."""
        whole = mask is None or (len(mask) >= reduction.MIN_ROWS and bool(np.all(mask)))
        key = (i, np.asarray(u, float).tobytes(), mods) if whole else None
        last = self.__dict__.get("_whole_last")
        if key is not None and last is not None and last[0] == key:
            return last[1]
        try:
            pred = self._rows_predicted(i, u, mods, mask)
        except MODEL_ERRORS:
            return self.problem.failed(i, mask)
        out = self.problem.scaled(i, pred, None if whole else mask)
        if key is not None and len(self.problem.frames[i]) >= reduction.MIN_ROWS:
            self._whole_last = (key, out)
        return out

    def _rows_predicted(self, i: int, u: np.ndarray, mods: Mods, mask) -> dict:
        """Predictions [SI] of run i for :meth:`resid`. On a reduced run (whose model reads its
        rows in time order and steps over the grid rows as over every row: the reduction's
        check) a fold's rows are predicted from the grid rows before them and every row of
        the fold, filled in at the fold's rows only: the rest of the run is not scored."""
        red = self.reductions()[i] if mask is not None else None
        if red is None or self._blocks(red, mask) is None or mask.all():
            return self.cal.predict_run(0, i, u, mods)
        rows = np.flatnonzero(mask)
        first, last = int(rows[0]), int(rows[-1])
        take = np.concatenate([red.grid[red.grid < first], np.arange(first, last + 1)])
        frame = self.problem.frames[i].iloc[take]
        if red.lines:  # the grid rows before the fold as the fit saw them, on the block lines
            before = red.frame.iloc[: int(np.count_nonzero(red.grid < first))]
            frame = pd.concat([before, frame.iloc[before.shape[0] :]])
        part = self.cal.predict_run(0, i, u, mods, frame)
        out = {}
        for q, v in part.items():
            full = np.zeros(len(mask))
            full[first : last + 1] = np.asarray(v)[take.size - (last + 1 - first) :]
            out[q] = full
        return out

    def _blocks(self, red, mask):
        """``red.blocks_in(mask)``, kept per mask (the folds' masks recur in every fit)."""
        if mask is None:
            return red.blocks_in(None)
        cache = self.__dict__.setdefault("_blocks_of", {})
        key = (id(red), id(mask))
        if key not in cache or cache[key][0] is not mask:
            cache[key] = (mask, red.blocks_in(mask))
        return cache[key][1]

    def outside(self, i: int, u: np.ndarray, mods: Mods, coarse: bool = False) -> float:
        """:data:`~tcamlab.diagnosis.problem.FAIL_RESIDUAL` when the model has no solution on
        run i's inputs at ``u`` with ``mods``, else 0 (a wall, not a residual); ``coarse``:
        on run i's grid rows (:mod:`tcamlab.reduction`), where it has them."""
        try:
            if coarse and self.reductions()[i] is not None:
                self._coarse(i, u, mods)
            else:
                self.cal.predict_run(0, i, u, mods)
        except MODEL_ERRORS:
            return FAIL_RESIDUAL
        return 0.0

    def at_domain_edge(self, u: np.ndarray, m: int) -> bool:
        """Whether parameter m sits at the edge of the model's domain on these runs' inputs:
        a step of :data:`EDGE_STEP` prior sds either way leaves it for some run.

        There the chi-square is no parabola (a G_t slope where G_t' of (2.13) reaches zero at the
        hottest reading made a static recalibration's 95 % interval 1e-6 of the value wide), so
        the Laplace interval is not a posterior interval and the report says so.
        """
        for sgn in (1.0, -1.0):
            x = np.array(u, float)
            x[m] += sgn * EDGE_STEP * self.cal.sd_u[m]
            if any(self.outside(i, x, Mods()) for i in range(len(self.problem.frames))):
                return True
        return False

    def predict(self, i: int, u: np.ndarray, mods: Mods) -> dict:
        """Predictions [SI] of run i at ``u`` with ``mods`` (raises outside the domain)."""
        return self.cal.predict_run(0, i, u, mods)

    def fitted_residuals(self) -> tuple[list, list] | None:
        """(predictions, residuals) [SI] of every run at recalibration alone fitted on every
        row from the stated values, or None when it fails (one start: the noise floor needs
        the model's gain near the data's, not the best of the starts the verdict uses). The
        fit reads the residuals averaged over :data:`FLOOR_BLOCK` rows, so that it follows the
        data's smooth misfit and not a gain that merely shrinks an input's noise."""
        rows = [(i, np.ones(len(d), bool)) for i, d in enumerate(self.problem.frames)]
        shortest = min(len(d) for d in self.problem.frames)
        block = max(1, min(max(FLOOR_BLOCK, self.problem.k.fit_block), shortest // FLOOR_MIN_BLOCKS))
        box = effect_box(self.problem, None, None)
        fit = self.fit(None, rows, [self.cal.u0], box, MAX_NFEV_FULL, block=block)
        if fit.jac is None:
            return None
        try:
            preds = [self.predict(i, fit.u, Mods()) for i, _ in rows]
        except MODEL_ERRORS:
            return None
        return preds, [self.problem.resid(i, p) for i, p in enumerate(preds)]

    def term_rms(self, fit: JointFit, effect: Effect | None) -> float:
        """RMS over every row of what ``effect``'s term adds to the predictions at ``fit``:
        the model with the fitted effect minus the model without it, both at the fit's
        recalibrated parameters [noise-floor multiples]. NaN for recalibration alone, or
        where either model has no solution on some run's inputs (the term then matters).
        """
        if effect is None:
            return float("nan")
        mods, d2, n = effect.mods(fit.values), 0.0, 0
        sizes = [len(d) * len(self.problem.quantities) for d in self.problem.frames]
        # an all-rows fit's residuals start with every run's, in run order: no re-evaluation
        fitted = fit.fun is not None and fit.fun.size >= sum(sizes)
        starts = np.concatenate([[0], np.cumsum(sizes)])
        for i in range(len(self.problem.frames)):
            with_term = fit.fun[starts[i] : starts[i + 1]] if fitted else self.resid(i, fit.u, mods)
            without = self.resid(i, fit.u, Mods())
            if np.any(with_term == FAIL_RESIDUAL) or np.any(without == FAIL_RESIDUAL):
                return float("nan")
            d2 += float(np.sum((with_term - without) ** 2))
            n += self.problem.n_entries(i)
        return math.sqrt(d2 / max(n, 1))

    def prior_chi2(self, u: np.ndarray) -> float:
        """Prior chi-square of a recalibration's shift from the stated values."""
        r = self.cal.prior_residuals(u)
        return float(r @ r)

    def plausible(self, u: np.ndarray) -> bool:
        """Whether the shift is within :data:`PLAUSIBLE_LEVEL` of the priors."""
        return self.prior_chi2(u) <= float(stats.chi2.ppf(PLAUSIBLE_LEVEL, max(self.p, 1)))

    def pinned(self, effect: Effect | None) -> np.ndarray:
        """Indices of the calibrated parameters ``effect`` generalises (held at stated values)."""
        names = set(effect.generalises) if effect is not None else set()
        return np.array([m for m, s in enumerate(self.specs) if s.param.field in names], int)

    def fit(
        self, effect: Effect | None, rows, starts, box, max_nfev: int, defined_on=(), block: int | None = None
    ) -> JointFit:
        """Least-squares fit of (u, theta) on ``rows`` from each start; the best.

        ``box`` is the effect's (lower, upper) scaled bounds (:func:`effect_box`). The
        parameters the effect generalises are held at their stated values
        (:data:`PIN_WEIGHT`). ``defined_on`` holds (run, mask) pairs whose *inputs* the
        model must stay defined on, without their residuals entering the fit: a fold's
        held-out run. Fitted on the other runs alone, a G_t slope moved far enough to soften
        the coil turns G_t' non-positive a few kelvin above their hottest reading, where the
        held-out run's oven reading can lie (static, 10x G(T): 14 of 20 cases came out
        ``unexplained`` that way, every candidate failing one fold). ``block`` > 1 fits the
        residuals averaged over that many rows (:func:`tcamlab.signals.block_means`); None:
        the kind's :attr:`~tcamlab.kinds.Kind.fit_block`.
        """
        params = effect.params if effect is not None else ()
        scales = np.array([p.scale for p in params], float)
        p, k = self.p, len(params)
        pin = self.pinned(effect)
        lo = np.concatenate([self.lo, box[0]])
        hi = np.concatenate([self.hi, box[1]])
        u0, sd_u = self.cal.u0, self.cal.sd_u
        # a long log is fitted on its blocks' moments (tcamlab.reduction), scored on every row
        reduced = self.reducible(rows)
        resid = self.reduced_resid if reduced else self.resid
        block = self.problem.k.fit_block if block is None else block
        blocked = block > 1 and not reduced
        if blocked:
            nq = len(self.problem.quantities)

            def resid(i, u, mods, m):
                return block_means(self.resid(i, u, mods, m), nq, block)

        def fun(x):
            u = x[:p]
            mods = effect.mods(x[p:] * scales) if k else Mods()
            data = [resid(i, u, mods, m) for i, m in rows]
            pins = [PIN_WEIGHT * (u[pin] - u0[pin]) / sd_u[pin]]
            walls = [self.outside(i, u, mods, reduced) for i, _ in defined_on]
            return np.concatenate(data + [self.cal.prior_residuals(u)] + pins + [np.array(walls, float)])

        x_scale = np.concatenate([sd_u, np.ones(k)])
        x_scale[pin] /= PIN_WEIGHT
        starts = [np.concatenate([np.where(np.isin(np.arange(p), pin), u0, x0[:p]), x0[p:]]) for x0 in starts]
        extra = p + pin.size + len(defined_on)
        best = best_least_squares(fun, starts, lo, hi, x_scale, max_nfev, SCREEN_NFEV if reduced else None)
        x = np.clip(np.asarray(starts[0], float), *inner_box(lo, hi)) if best is None else best.x
        r = fun(x)[: -extra or None] if best is None else best.fun[: best.fun.size - extra]
        sizes = [nq * n_blocks(self._n_rows(i, m), block) for i, m in rows] if blocked else None
        if reduced:  # the chi-square of every row at the fit, and the moments' layout
            mods = effect.mods(x[p:] * scales) if k else Mods()
            sizes = [resid(i, x[:p], mods, m).size for i, m in rows]
            r = self._every_row(rows, x[:p], mods, r, defined_on)
        n = self._measured(rows, r.size)
        if best is None:
            return JointFit(x[:p], x[p:], x[p:] * scales, float(r @ r), n, None, False)
        return JointFit(
            best.x[:p],
            best.x[p:],
            best.x[p:] * scales,
            float(r @ r),
            n,
            best.jac,
            bool(best.success),
            fun=best.fun,
            box=(lo, hi),
            sizes=sizes,
        )

    def _measured(self, rows, size: int) -> int:
        """Of ``size`` data residuals laid out over ``rows``, those of a column the run logs
        (the others are constant zeros: :meth:`Problem.resid`)."""
        total = sum(self._n_rows(i, m) * len(self.problem.quantities) for i, m in rows)
        logged = sum(self.problem.n_entries(i, m) for i, m in rows)
        return int(size) if logged == total else int(round(size * logged / max(total, 1)))

    def _n_rows(self, i: int, mask) -> int:
        return len(self.problem.frames[i]) if mask is None else int(np.count_nonzero(mask))

    def _every_row(self, rows, u: np.ndarray, mods: Mods, moments: np.ndarray, defined_on) -> np.ndarray:
        """The normalised residuals of every row of ``rows`` at a reduced fit's optimum; for a
        fold's fit (``defined_on`` its held-out rows, which the caller scores row by row) the
        moments stand in, padded with zeros to the rows' number (nothing reads a fold fit's
        chi-square, and a model evaluation on every training row would double its cost)."""
        if not defined_on:
            return np.concatenate([self.resid(i, u, mods, m) for i, m in rows])
        n = sum(int(np.count_nonzero(m)) if m is not None else len(self.problem.frames[i]) for i, m in rows)
        pad = n * len(self.problem.quantities) - moments.size
        return np.concatenate([moments, np.zeros(max(pad, 0))])

    def refit_without(self, fit: JointFit, effect: Effect | None, held: set[int]) -> JointFit:
        """The fit on every run but ``held``: one Gauss-Newton step from the all-runs ``fit``.

        The step uses the all-runs fit's residuals and Jacobian restricted to the training
        runs' rows (and the prior rows): no model evaluation. For a model linear in
        (u, theta) it is the exact leave-runs-out fit; for these smooth models, near the
        optimum, it is the one-step approximation of leave-one-out refitting, and it is
        what makes the fold fits cost nothing beside the all-runs fit. ``fit`` must be a
        fit on all rows (:meth:`fit` with every row of every run) with its Jacobian.
        """
        rows = [len(d) * len(self.problem.quantities) for d in self.problem.frames]
        sizes = rows if fit.sizes is None else fit.sizes
        priors = self.p + self.pinned(effect).size
        keep = np.concatenate(
            [np.full(n, i not in held, bool) for i, n in enumerate(sizes)] + [np.ones(priors, bool)]
        )
        n_rows = sum(n for i, n in enumerate(rows) if i not in held)
        J = np.asarray(fit.jac, float)[keep]
        x = fit.x + bounded_gauss_newton_step(J, fit.fun[keep], fit.x, fit.box[0], fit.box[1])
        p = self.p
        scales = np.array([q.scale for q in effect.params], float) if effect is not None else np.zeros(0)
        return JointFit(x[:p], x[p:], x[p:] * scales, float("nan"), n_rows, None, fit.success)

    def starts(self, effect: Effect | None, u: np.ndarray, box) -> list[np.ndarray]:
        """Starts of a fit on all rows: the recalibration's ``u`` with theta 0, +1 and -1;
        recalibration alone also starts one prior sd off ``u`` along each parameter.

        Parameters that act alike (E and S of the curvature rig's sensor) leave the stated
        values on a ridge: a curvature experiment with E 2.8 stated sds low stalled there at
        3.5 times the chi-square of the minimum every one-sd start found (342 against 97).
        """
        k = len(effect.params) if effect is not None else 0
        out = [np.concatenate([u, np.zeros(k)])]
        if effect is None:  # (the fit clips every start into the parameters' bounds)
            for m, s in enumerate(self.specs):
                for sgn in (1.0, -1.0):
                    x = np.array(u, float)
                    x[m] += sgn * s.sd_u
                    out.append(x)
        for sgn in (1.0, -1.0) if k else ():
            t = np.clip(np.full(k, sgn), box[0], box[1])
            if not np.allclose(t, 0.0):
                out.append(np.concatenate([u, t]))
        return out

    def covariance(self, fit: JointFit) -> np.ndarray:
        """Laplace covariance of (u, theta): inverse Gauss-Newton Hessian, priors included,
        scaled up by the data's chi-square per degree of freedom when it exceeds 1."""
        k = fit.x.size
        if fit.jac is None:
            return np.full((k, k), np.nan)
        J = np.asarray(fit.jac, float)
        s2 = max(1.0, fit.sse / max(fit.n - len(fit.theta), 1))
        try:
            return np.linalg.pinv(J.T @ J) * s2
        except np.linalg.LinAlgError:
            return np.full((k, k), np.nan)

    def parameters(self, fit: JointFit, cov: np.ndarray, z: float) -> dict:
        """Each recalibrated parameter: value, interval, stated value and shift in stated sds [SI],
        and the parameters the data cannot tell it from (posterior correlation at least
        :data:`ALIAS_CORRELATION` in magnitude, with the correlation)."""
        out = {}
        corr = correlations(cov[: self.p, : self.p])
        for m, s in enumerate(self.specs):
            sd_u = math.sqrt(max(cov[m, m], 0.0)) if np.isfinite(cov[m, m]) else float("nan")
            value = s.from_u(float(fit.u[m]))
            sd = s.prior_sd if s.sd_stated else None
            out[s.name] = {
                "symbol": s.param.symbol,
                "value": value,
                "ci95": [s.from_u(fit.u[m] - z * sd_u), s.from_u(fit.u[m] + z * sd_u)],
                "unit": s.param.unit,
                "stated": s.stated,
                # an unstated value (sensing S, R0) is the kind's rule on the logs
                "stated_in_file": bool(s.stated_in_file),
                "stated_sd": sd,
                "prior_sd": s.prior_sd,
                "shift_in_stated_sds": (value - s.stated) / sd if sd else None,
                # against the stated value and prior sd: a reading at rest sharpens the prior
                # the fit uses, not the yardstick of a shift
                "shift_in_prior_sds": float((fit.u[m] - s.stated_u0) / s.stated_sd_u),
                "reading": list(s.reading) if s.reading is not None else None,
                "pinned_by": s.param.pinned_by,
                "aliased_with": {
                    o.name: float(corr[m, j])
                    for j, o in enumerate(self.specs)
                    if j != m and abs(corr[m, j]) >= ALIAS_CORRELATION
                },
            }
        return out
