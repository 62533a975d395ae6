"""Sim-to-real gap diagnosis: where the thesis model misses, which effect explains it, how far.

The package's modules are the steps below: :mod:`~tcamlab.diagnosis.problem`
(the model on chosen rows, fits, folds), :mod:`~tcamlab.diagnosis.noise`
(noise floor, gap test), :mod:`~tcamlab.diagnosis.regimes` (where),
:mod:`~tcamlab.diagnosis.candidates` (which), :mod:`~tcamlab.diagnosis.verdict`
and :mod:`~tcamlab.diagnosis.result` (typed results). :func:`diagnose` calls
them in order.

:func:`diagnose` looks only at an experiment file (:class:`tcamlab.config.Experiment`)
and its run logs (:class:`tcamlab.io.RunData`). It never reads a simulator's answer key
files and never looks at file names, seeds or how the data was made.

Steps
-----
1. **Baseline.** The thesis model (:func:`tcamlab.kinds.predict`, no effect
   terms) with the experiment's parameters. Sensing: ``spring_constant`` is
   ``rig.spring_constant`` or, when unset, identified on the *training*
   runs: started at the least-squares fit through the origin of force on
   displacement (:func:`tcamlab.fitting.fit_spring`), then refined as a
   nuisance parameter by least squares on the noise-normalised residuals of
   both quantities, jointly with each candidate's parameters (a fit of F on
   delta alone is biased by a load-cell zero offset or a force-side effect,
   and the inversion amplifies an S error by 1 / (1 - S f11));
   R0 follows the kind's one rule (:attr:`tcamlab.kinds.Kind.run_options`):
   ``rig.initial_resistance``, else the mean of the run's leading rows at
   rest. Curvature: ``rig.spring_constant`` and R0 by the same rule per segment. Residual = measured - predicted for each
   quantity of kind's outputs (:attr:`tcamlab.kinds.Kind.outputs`), divided by that quantity's
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

3. **Which.** Recalibration (:mod:`~tcamlab.diagnosis.recalibration`: the
   kind's calibratable parameters refitted under their priors through
   :class:`tcamlab.calibration.problem.CalibrationProblem`) and every
   candidate effect (:mod:`tcamlab.effects`) fitted *together with* the
   recalibrated parameters are fitted with :func:`scipy.optimize.least_squares`
   on all runs, then on each fold's training runs by one Gauss-Newton step
   from that fit, and scored on the withheld run (leave one run out; a single
   run is cut into contiguous blocks, refitted from the all-runs fit). Each
   run's zero of a :attr:`~tcamlab.kinds.Kind.nuisance_zeros` quantity is
   profiled out over the rows scored (a withheld run's from that run). A
   bootstrap over folds gives intervals; AIC/BIC and parameter intervals come
   from the fit on all runs.

4. **Verdict** (constants below, reasons in their docstrings):

   * ``none`` -- the baseline's mean squared normalised residual (over N - R
     points, R profiled zeros) is below the :data:`GAP_LEVEL` quantile of its
     no-gap distribution, F(N - R, nu) per quantity (nu the effective degrees
     of freedom of the noise estimate), pooled over quantities by seeded
     Monte Carlo (:func:`gap_limit`);
   * ``attributed`` -- an effect (with recalibration) closes at least
     :data:`MIN_FRACTION_CLOSED` of the gap above the noise floor on withheld
     runs, its bootstrap shrinkage interval excludes 0, it beats
     recalibration alone (paired bootstrap of the held-out MSE difference)
     while closing at least :data:`MIN_FRACTION_CLOSED` of the gap it leaves
     (:func:`~tcamlab.diagnosis.verdict.closes_the_rest`), does not leave a
     gap of its own (:func:`~tcamlab.diagnosis.verdict.leaves_a_gap`), and no
     other such effect is indistinguishable from it;
   * ``miscalibrated`` -- recalibration alone closes at least
     :data:`MIN_FRACTION_CLOSED` (interval above 0) and no effect beats it;
     the parameters that moved are named with values, intervals and shifts
     in stated sds;
   * ``aliased`` -- as attributed, but another effect is indistinguishable;
     or recalibration needs a shift beyond its priors
     (:data:`~tcamlab.diagnosis.recalibration.PLAUSIBLE_LEVEL`) while an
     effect with plausible parameters fits as well;
   * ``unexplained`` -- the gap is significant and no candidate qualifies, or
     the best effect closes part of it but leaves a significant gap of its own.

5. **Two effects.** When no single candidate qualifies, candidates that alone
   close at least :data:`MIN_PARTIAL_FRACTION` of the gap (the best
   :data:`PAIR_POOL`) are fitted in pairs (:func:`tcamlab.effects.combine`)
   and scored the same way; a pair that qualifies and beats each member alone
   and recalibration alone gives ``attributed`` (or ``aliased``, with rival pairs), naming the member
   that ranks higher alone; the pair is ``DiagnosisResult.combination``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tcamlab import progress
from tcamlab.diagnosis.candidates import CI_LEVEL, fit_candidates, score_folds
from tcamlab.diagnosis.noise import (
    GAP_LEVEL,
    MEDIAN_EFFICIENCY,
    SECOND_DIFF_EFFICIENCY,
    BaselineFit,
    baseline_fit,
    check_gap,
    estimate_noise,
    gap_limit,
    pool_noise_estimates,
    second_difference_sigma,
)
from tcamlab.diagnosis.problem import Problem, complement, folds, serial_kernels
from tcamlab.diagnosis.recalibration import RECALIBRATION, Recalibration
from tcamlab.diagnosis.regimes import label_rows, plot_series, regime_table, run_statistics
from tcamlab.diagnosis.result import SCHEMA_VERSION, CandidateResult, DiagnosisResult, Settings
from tcamlab.diagnosis.verdict import MIN_FRACTION_CLOSED, decide
from tcamlab.effects import effects_for, get_effect
from tcamlab.errors import ConfigError
from tcamlab.metrics import implausible_value_warnings, opposite_direction_warning
from tcamlab.text import shown_path

__all__ = [
    "SCHEMA_VERSION",
    "GAP_LEVEL",
    "MEDIAN_EFFICIENCY",
    "SECOND_DIFF_EFFICIENCY",
    "MIN_FRACTION_CLOSED",
    "CI_LEVEL",
    "RECALIBRATION",
    "CandidateResult",
    "DiagnosisResult",
    "complement",
    "diagnose",
    "folds",
    "gap_limit",
    "pool_noise_estimates",
    "second_difference_sigma",
]


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
    runs = list(experiment.read_runs() if runs is None else runs)
    if not runs:
        raise ConfigError("diagnosis: no runs")
    with serial_kernels():
        return _diagnose(experiment, runs, effects, n_boot, seed, workers)


def _diagnose(experiment, runs, effects, n_boot: int, seed: int, workers) -> DiagnosisResult:
    cands = (
        [get_effect(e, experiment.kind) for e in effects]
        if effects is not None
        else effects_for(experiment.kind)
    )
    with progress.task(f"{experiment.path.name}: baseline fit", total=4) as step:
        problem = Problem(experiment, runs)
        # first: it refuses stated values at which the model's residuals are unusable
        rec = Recalibration(problem, experiment, runs)
        base = baseline_fit(problem)
        step(description=f"{experiment.path.name}: noise floor")
        noise = estimate_noise(problem, base)
        if problem.k.noisy_inputs:
            noise = _noise_at_recalibration(problem, rec, base, noise)
        base, baseline, gap = check_gap(problem, base, noise)
        labels = label_rows(problem, base)
        step(description=f"{experiment.path.name}: held-out folds")
        scores = score_folds(problem, base, n_boot, seed)
        step(description=f"{experiment.path.name}: candidate effects")
        ranking, fits = fit_candidates(problem, rec, cands, scores, base, workers=workers)
        step(description=f"{experiment.path.name}: verdict")
        decision = decide(problem, rec, cands, ranking, fits, scores, base, gap, workers)
    names = [str(getattr(r, "path", i)).rsplit("/", 1)[-1] for i, r in enumerate(runs)]
    return DiagnosisResult(
        kind=experiment.kind,
        experiment=_experiment_info(experiment, runs),
        verdict=decision.verdict,
        effect=decision.effect,
        ranking=ranking,
        aliased_with=decision.aliased_with,
        separate_by=decision.separate_by,
        noise_floor=noise,
        baseline=baseline,
        regimes=regime_table(problem, labels),
        runs=run_statistics(problem, base, noise, names),
        gap=gap,
        reason=decision.reason,
        settings=_settings(scores, cands, n_boot, seed, len(runs)),
        combination=decision.combination,
        recalibration=decision.recalibration,
        warnings=_log_warnings(problem, base, names, runs),
        _series=plot_series(problem, base, labels, _best_curve(rec, decision.best_fit)),
    )


def _log_warnings(problem: Problem, base, names, runs) -> list[str]:
    """What bears on every figure of the diagnosis: a channel beyond what a muscle plausibly
    logs, and a measurement that moves against the thesis model (a sign flipped), which a
    recalibration would absorb by flipping a parameter."""
    out = [w.message for n, r in zip(names, runs) for w in implausible_value_warnings(n, r.data)]
    for q in problem.quantities:
        pairs = [
            (problem.measured(i, q), base.predictions[i][q]) for i in range(len(runs)) if problem.logs(i, q)
        ]
        if pairs:
            m, p = (np.concatenate([np.asarray(x, float) for x in col]) for col in zip(*pairs))
            w = opposite_direction_warning(q, m, p)
            out += [w.message] if w is not None else []
    return out


def _noise_at_recalibration(problem: Problem, rec: Recalibration, base, noise):
    """The noise floor from the residuals of the recalibrated model, where an input is noisy.

    An input's noise reaches an output through the model's gain, which moves with the
    parameters: on a pull test with E 1.2 x stated, the ohmmeter's noise in the inferred
    elongation was 5.9e-5 m at the stated E and 5.1e-5 m at the true one (the data's), and
    the floor at the stated values, 22 % high, hid an effect the recalibration could not
    explain. Second differences still see only the noise, not the smooth misfit."""
    fitted = rec.fitted_residuals()
    if fitted is None:
        return noise
    return estimate_noise(problem, BaselineFit(base.spring, *fitted))


def _best_curve(rec: Recalibration, fit):
    """Predictions [SI] of run i with the best candidate's all-runs fit, or None."""
    if fit is None or fit.joint is None:
        return None
    mods = fit.effect.mods(fit.values) if fit.effect is not None else None

    def curve(i):
        return rec.predict(i, fit.joint.u, mods)

    return curve


def _experiment_info(experiment, runs) -> dict:
    """Name, title, shown path, kind and provenance: the tool's version and every input
    file (experiment file, run CSVs, joined files) with its SHA-256, paths relative to
    the experiment file's folder as the file names them (never absolute)."""
    from tcamlab import __version__
    from tcamlab.io import input_files, sha256_file
    from tcamlab.validation import relative_to

    path = getattr(experiment, "path", None)
    inputs = []
    if path:
        inputs.append({"role": "experiment", "path": Path(path).name, "sha256": sha256_file(path)})
        for r in (r for r in runs if getattr(r, "path", None) is not None):
            for role, p, sha in input_files(r):
                inputs.append({"role": role, "path": relative_to(p, Path(path).parent), "sha256": sha})
    return {
        "name": getattr(experiment, "name", None),
        "title": getattr(experiment, "title", None),
        # as reports show paths: relative to the working folder, else .../NAME (no absolute path)
        "path": shown_path(path) if path else "",
        "kind": experiment.kind,
        "n_runs": len(runs),
        "tool": f"tcamlab {__version__}",
        "inputs": inputs,
    }


def _settings(scores, cands, n_boot: int, seed: int, n_runs: int) -> Settings:
    K = len(scores.held)
    return Settings(
        n_boot=int(n_boot),
        seed=int(seed),
        folds=K,
        fold_scheme="leave one run out" if n_runs >= 2 else f"{K} contiguous blocks of one run",
        candidates=[e.name for e in cands],
        gap_level=GAP_LEVEL,
        min_fraction_closed=MIN_FRACTION_CLOSED,
        ci_level=CI_LEVEL,
        fold_details=scores.details,
    )
