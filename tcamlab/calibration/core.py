"""``calibrate``: load the experiments, fit, and assemble the :class:`CalibrationResult`."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

from tcamlab import progress
from tcamlab.calibration.fit import Z95, every_row_chi2, laplace_covariance, map_fit, profile_interval
from tcamlab.calibration.identify import directions, identifiability_text, tier
from tcamlab.calibration.problem import CalibrationProblem
from tcamlab.calibration.result import (
    CalibrationResult,
    FitQuality,
    ParameterEstimate,
    RunCurves,
    ZeroEstimate,
)
from tcamlab.config import Experiment, load_experiment
from tcamlab.errors import InputError
from tcamlab.io import input_files, sha256_file
from tcamlab.metrics import implausible_value_warnings, opposite_sign_warning
from tcamlab.units import PARAMETER_UNITS

__all__ = ["calibrate", "load_experiments", "one_numba_thread"]


def load_experiments(experiments: Sequence) -> list[Experiment]:
    """Experiment files (paths or loaded) of one sample; several must have equal ``[sample]``."""
    if isinstance(experiments, (str, Path, Experiment)):
        experiments = [experiments]
    loaded = [e if isinstance(e, Experiment) else load_experiment(e) for e in experiments]
    if not loaded:
        raise InputError(
            "calibrate: no experiment file given", "e.g. tcamlab calibrate experiments/dynamic.toml"
        )
    for e in loaded[1:]:
        if e.sample != loaded[0].sample:
            raise InputError(
                f"{e.path}: its [sample] differs from {loaded[0].path}'s; only experiments of one "
                "sample are calibrated together",
                "calibrate them separately, or make their [sample] tables equal",
            )
    names = [e.name for e in loaded]
    if len(set(names)) < len(names):
        raise InputError("calibrate: two experiment files share the name " + repr(names[0]))
    return loaded


def _profile_points(spec, u_hat: float, sides) -> tuple[tuple[float, float], ...]:
    """The profile points of both sides in SI with the signed root, MAP included, by value."""
    pts = [(spec.from_u(u_hat), 0.0)]
    for side, prof in zip((-1, 1), sides):
        pts += [(spec.from_u(float(c)), side * float(z)) for c, z in prof.points]
    return tuple(sorted(pts))


@contextmanager
def one_numba_thread() -> Iterator[None]:
    """Run the models' numba kernels on one thread (restored after).

    A calibration makes thousands of small predictions (26 points a static run); waking
    numba's thread pool for each costs far more than the work: on this 2-core machine,
    under load, 5 ms against 0.1 ms a static prediction. The setting is numba's own,
    per calling thread.
    """
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a dependency of the models
        yield
        return
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _estimate(problem, k: int, u: np.ndarray, cov: np.ndarray, sides) -> ParameterEstimate:
    s = problem.specs[k]
    sd_u = float(math.sqrt(max(cov[k, k], 0.0)))
    value = s.from_u(float(u[k]))
    lap = (s.from_u(u[k] - Z95 * sd_u), s.from_u(u[k] + Z95 * sd_u))
    post_sd = value * sd_u if s.param.positive else sd_u * s.prior_sd
    stated_sd = s.prior_sd if s.sd_stated else None
    if s.param.positive:
        post_rel, prior_rel = sd_u, float(s.stated_sd_u)
    elif s.stated != 0:  # relative to the value; to the stated value where the fit reaches 0
        post_rel, prior_rel = post_sd / (abs(value) or abs(s.stated)), s.prior_sd / abs(s.stated)
    else:  # stated 0 (dynamic beta): relative to the default prior sd, the parameter's scale
        scale = float(s.param.zero_sd or s.prior_sd)
        post_rel, prior_rel = post_sd / scale, s.prior_sd / scale
    return ParameterEstimate(
        name=s.name,
        field=s.param.field,
        where=s.param.where,
        symbol=s.param.symbol,
        unit=s.param.unit,
        key=s.key,
        stated=s.stated,
        stated_in_file=s.stated_in_file,
        stated_sd=stated_sd,
        prior_sd=s.prior_sd,
        value=value,
        posterior_sd=post_sd,
        posterior_sd_rel=post_rel,
        prior_sd_rel=prior_rel,
        laplace_95=lap,
        profile_95=(s.from_u(sides[0].bound), s.from_u(sides[1].bound)),
        profile_open=(sides[0].open, sides[1].open),
        shift_in_stated_sds=(value - s.stated) / stated_sd if stated_sd else None,
        pinned=tier(post_rel, prior_rel) == "pinned",
        identification=tier(post_rel, prior_rel),
        pinned_by=s.param.pinned_by,
        profile_points=_profile_points(s, float(u[k]), sides),
        positive=s.param.positive,
    )


def _zeros(problem, u: np.ndarray, cov: np.ndarray) -> list[ZeroEstimate]:
    labels = problem.zero_labels()
    if not labels:
        return []
    z = problem.zeros(u)
    g = problem.jacobian(u, fn=problem.zeros)
    extra = np.einsum("ij,jk,ik->i", g, cov, g)
    out = []
    for (i, j, q), value, ex in zip(labels, z, extra):
        n = len(problem.runs[i][j].data)
        sd = float(math.sqrt(problem.sigma[(i, q)] ** 2 / n + max(ex, 0.0)))
        run = Path(getattr(problem.runs[i][j], "path", f"run{j + 1}")).name
        out.append(
            ZeroEstimate(
                problem.experiments[i].name, run, q, float(value), sd, (value - Z95 * sd, value + Z95 * sd)
            )
        )
    return out


def _full_zeros(problem, u: np.ndarray, zeros: list[ZeroEstimate]) -> list[ZeroEstimate]:
    """``zeros`` with each value the profiled zero of every row at ``u`` (the sds stay)."""
    if not zeros or not any(r is not None for r in problem.reductions.values()):
        return zeros
    out = []
    for z, value in zip(zeros, problem.zeros(u)):
        ci = (value - Z95 * z.sd, value + Z95 * z.sd)
        out.append(ZeroEstimate(z.experiment, z.run, z.quantity, float(value), z.sd, ci))
    return out


def _rms(x: np.ndarray, sigma: float) -> float:
    return float(np.sqrt(np.mean(x * x)) / sigma)


def _quality(problem, u: np.ndarray) -> list[FitQuality]:
    before = problem.raw_residuals(problem.stated_u0) or []
    after = problem.raw_residuals(u) or []
    out = []
    for i, qs in enumerate(problem.quantities):
        for q in qs:
            sig = problem.sigma[(i, q)]
            b = np.concatenate([r for e, _, qq, r in before if e == i and qq == q] or [np.array([np.nan])])
            a = [
                (r - r.mean()) if problem.is_zeroed(i, q) else r
                for e, _, qq, r in after
                if e == i and qq == q
            ]
            a = np.concatenate(a or [np.array([np.nan])])
            out.append(
                FitQuality(problem.experiments[i].name, q, sig, _rms(b, sig), _rms(a, sig), int(a.size))
            )
    return out


def _curves(problem, u: np.ndarray) -> list[RunCurves]:
    """Measured and predicted curves of every run at the stated values and at ``u``."""
    out = []
    for i, exp in enumerate(problem.experiments):
        kind = problem.kinds[i]
        for j, run in enumerate(problem.runs[i]):
            before, after = problem.predict_run(i, j, problem.stated_u0), problem.predict_run(i, j, u)
            qs = problem.run_quantities(i, j)
            measured = {q: problem.measured(i, j, q) for q in qs}
            zero = {q: float(np.mean(measured[q] - after[q])) for q in qs if problem.is_zeroed(i, q)}
            cols = [c for c in dict.fromkeys((kind.x_column, "time")) if c in run.data]
            out.append(
                RunCurves(
                    experiment=exp.name,
                    run=Path(getattr(run, "path", f"run{j + 1}")).name,
                    kind=exp.kind,
                    x=kind.x_column,
                    inputs={c: run.data[c].to_numpy(float) for c in cols},
                    measured=measured,
                    stated={q: np.asarray(before[q], float) for q in qs},
                    calibrated={q: np.asarray(after[q], float) + zero.get(q, 0.0) for q in qs},
                    zero=zero,
                )
            )
    return out


def _inputs(exps, runs) -> list[dict]:
    """Every file read, with its SHA-256: the experiment files, then their runs."""
    out = []
    for e, rs in zip(exps, runs):
        out.append(
            {"experiment": e.name, "role": "experiment", "path": str(e.path), "sha256": sha256_file(e.path)}
        )
        out += [
            {"experiment": e.name, "role": role, "path": str(path), "sha256": sha}
            for r in rs
            for role, path, sha in input_files(r)
        ]
    return out


def _describe_logs(problem) -> str:
    parts = []
    for e, qs, runs in zip(problem.experiments, problem.quantities, problem.runs):
        parts.append(f"{e.name} ({e.kind}, {len(runs)} runs, logging {', '.join(qs)})")
    return "the logs of " + " and ".join(parts)


def calibrate(
    experiments, params: Sequence[str] | str | None = None, *, drop_na: bool = False
) -> CalibrationResult:
    """Calibrate the kinds' parameters from the logs of one or more experiments of one sample.

    Parameters
    ----------
    experiments : path-like, Experiment, or a sequence of them
        Experiment files with equal ``[sample]`` (their sample parameters are shared).
    params : sequence of str or comma-separated str, optional
        Parameters to calibrate (``field``, or ``EXPERIMENT.field`` for a rig parameter of
        several experiments); default every calibratable parameter of their kinds.
    drop_na : bool
        Drop rows with blank cells instead of raising.

    Returns
    -------
    CalibrationResult
        MAP values with Laplace and profile 95 % intervals, nuisance zeros, correlation,
        identifiability in words, residuals before and after; for a selfsensing experiment
        also ``estimator``, the second stage that refits R0, TCR, R_lead and k_s through the
        EKF at these values (:mod:`tcamlab.calibration.estimator`).
    """
    exps = load_experiments(experiments)
    if isinstance(params, str):
        params = [p.strip() for p in params.split(",") if p.strip()]
    runs = [e.read_runs(drop_na=drop_na) for e in exps]
    with one_numba_thread():
        problem = CalibrationProblem(exps, runs, params)
        with progress.task("calibrating: best fit", total=1 + len(problem.specs)) as step:
            fit = map_fit(problem)
            cov, jac = laplace_covariance(problem, fit.u)
            estimates = []
            for k, spec in enumerate(problem.specs):
                step(description=f"calibrating: profile interval of {spec.name}")
                sides = [profile_interval(problem, fit, cov, k, side, jac) for side in (-1, 1)]
                estimates.append(_estimate(problem, k, fit.u, cov, sides))
            step()
        zeros = _zeros(problem, fit.u, cov)
        # a long log was fitted on its blocks' moments (tcamlab.reduction): the chi-square,
        # the zeros and the fit quality are of every row
        chi2 = every_row_chi2(problem, fit.u, fit.chi2)[0]
        with problem.full_rows():
            zeros = _full_zeros(problem, fit.u, zeros)
            quality = _quality(problem, fit.u)
        curves = _curves(problem, fit.u)
    names = [s.name for s in problem.specs]
    dirs = directions(names, problem.stated_sd_u, cov)
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    return CalibrationResult(
        experiments=[str(e.path) for e in exps],
        kinds=[e.kind for e in exps],
        parameters=estimates,
        zeros=zeros,
        fit=quality,
        correlation={"names": names, "matrix": (cov / np.outer(sd, sd)).tolist()},
        directions=[
            {"exponents": d.exponents, "ratio": d.ratio, "relative_sd": d.relative_sd, "pinned": d.pinned}
            for d in dirs
        ],
        identifiability=identifiability_text(estimates, dirs, _describe_logs(problem)),
        chi2=chi2,
        n_points=problem.size,
        inputs=_inputs(exps, runs),
        curves=curves,
        estimator=_estimator_stage(exps, runs, estimates),
        notes=list(problem.held.values())
        + _input_notes(runs)
        + _sign_notes(estimates)
        + _bound_notes(problem, fit.u, estimates),
    )


def _bound_notes(problem: CalibrationProblem, u, estimates) -> list[str]:
    """A parameter whose best value is the edge of its search box (six prior sds, or a factor
    1000): the logs pull it further, and neither its value nor its interval is a fit."""
    lo, hi = problem.bounds()
    out = []
    for k, p in enumerate(estimates):
        tol = 1e-6 * float(hi[k] - lo[k])
        if min(abs(float(u[k]) - lo[k]), abs(hi[k] - float(u[k]))) <= tol:
            out.append(
                f"{p.where}.{p.key} ({p.symbol}) stopped at the edge of its search range, six prior "
                "sds (or a factor 1000) from its stated value: the logs pull it further, so its value "
                "and interval are that edge, not a fit; check the stated value and the log's units "
                "and sign"
            )
    return out


def _input_notes(runs) -> list[str]:
    """A channel of a run beyond what a muscle plausibly logs (its unit is likely wrong)."""
    return [w.message for rs in runs for r in rs for w in implausible_value_warnings(r.path.name, r.data)]


def _sign_notes(estimates) -> list[str]:
    """A parameter calibrated to the opposite sign of its stated value (a flipped log fits it)."""
    out = []
    for p in estimates:
        unit, fac = PARAMETER_UNITS.get(p.field, (p.unit, 1.0))
        name = f"{p.where}.{p.key} ({p.symbol})"
        w = opposite_sign_warning(name, p.value * fac, p.stated * fac, unit, "calibrated")
        if w is not None:
            out.append(w.message)
    return out


def _estimator_stage(exps, runs, estimates) -> list:
    """The EKF refit of every selfsensing experiment at its open-loop values
    (:mod:`tcamlab.calibration.estimator`); empty when there is none."""
    from tcamlab.calibration.estimator import disagreement, refit_for_estimator

    out = []
    for e, rs in zip(exps, runs):
        if e.kind != "selfsensing":
            continue
        mine = [p for p in estimates if p.name in (p.field, f"{e.name}.{p.field}")]
        changes = {p.field: p.value for p in mine if p.where == "rig"}
        sds = {p.field: p.posterior_sd for p in mine}
        # a sample field the first stage fitted (rho from an oven test of the same sample)
        # enters the refit at its posterior; one it did not, at the file's prior
        moved = {p.field: p.value for p in mine if p.where == "sample"}
        sample_sd = {**e.sample_uncertainty, **{p.field: p.posterior_sd for p in mine if p.where == "sample"}}
        with progress.task(f"calibrating: {e.name}'s EKF refit", total=1) as step:
            fit = refit_for_estimator(
                e, e.rig.replace(**changes), [r.data for r in rs],
                sample=replace(e.sample, **moved), sample_sd=sample_sd,
            )  # fmt: skip
            fit = replace(fit, open_loop_sd=sds)
            words = {n: disagreement(fit, n) for n in fit.fitted}
            out.append(replace(fit, disagreements={n: w for n, w in words.items() if w}))
            step()
    return out
