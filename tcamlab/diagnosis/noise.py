"""Noise floor and gap test: how large the baseline misfit is compared with the noise.

The noise floor comes from the data alone (second differences of the baseline
residuals, pooled with the between-run spread where runs repeat one protocol);
the gap test compares the baseline's normalised RMSE with its no-gap
distribution (:func:`gap_limit`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from tcamlab.calibration.problem import EFFECT_STEP, profile_random_effects, random_effect_basis
from tcamlab.diagnosis.problem import MODEL_ERRORS, Problem, fit_effect
from tcamlab.diagnosis.result import Baseline, Gap, NoiseFloor, QuantityNoise
from tcamlab.effects import Mods
from tcamlab.io.quantisation import unseen_variance
from tcamlab.signals import second_difference_sigma
from tcamlab.units import display

__all__ = [
    "GAP_LEVEL",
    "SECOND_DIFF_EFFICIENCY",
    "MEDIAN_EFFICIENCY",
    "POOL_CONSISTENCY_LEVEL",
    "BaselineFit",
    "all_rows",
    "baseline_fit",
    "estimate_noise",
    "check_gap",
    "second_difference_sigma",
    "gap_limit",
    "between_run_spread",
    "pool_noise_estimates",
    "run_noise_sigma",
    "slow_input_variance",
    "run_effect_columns",
    "profile_run_effects",
]


GAP_LEVEL = 0.99
"""Quantile of the no-gap distribution above which the baseline gap counts as
real: a 1 % false-alarm rate per experiment when the model is right and the
noise white."""


SECOND_DIFF_EFFICIENCY = 36.0 / 70.0
"""Degrees of freedom of the second-difference variance estimate per point,
relative to a chi-square estimate: for white Gaussian noise the second
differences d_i have var 6 sigma^2 and lag-1/lag-2 covariances -4 and 1
sigma^2, so var(sum d_i^2) = 2 (36 + 2 16 + 2 1) sigma^4 (n - 2) and the
estimate has 2 (n - 2) 36 / 140 = (36/70) (n - 2) degrees of freedom."""


MEDIAN_EFFICIENCY = 2.0 / math.pi
"""Asymptotic efficiency of a median relative to a mean (pooling over runs)."""


POOL_CONSISTENCY_LEVEL = 0.99
"""Two-sided level of the F test that admits the between-run variance into
the noise floor (:func:`pool_noise_estimates`)."""


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

    ``reference`` lists (share of the points, k) of terms adding share * chi2_1 / k
    to the statistic (a zero re-estimated from k rows and then held fixed).
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


def between_run_spread(problem: Problem, base_res) -> dict:
    """Between-run sd of measured quantities where runs share their inputs."""
    frames = problem.frames
    if len(frames) < 2:
        return {"available": False, "reason": "a single run"}
    n = {len(d) for d in frames}
    if len(n) != 1:
        return {"available": False, "reason": "runs differ in length"}
    for c in (c for c in problem.k.shared_inputs if all(c in d for d in frames)):
        X = np.vstack([d[c].to_numpy(float) for d in frames])
        span = float(np.ptp(X)) or 1.0
        if np.max(np.abs(X - X.mean(axis=0))) > 0.02 * span:
            return {"available": False, "reason": f"runs do not share the {c} input"}
    out = {"available": True}
    for q in (q for q in problem.quantities if all(problem.logs(i, q) for i in range(len(frames)))):
        unit, fac = display(q)
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


@dataclass
class BaselineFit:
    """The thesis model (no effect terms) on every run, before any candidate."""

    spring: float | None
    """Sensing S on all runs [N/m] (None where the kind identifies none)."""
    predictions: list
    """Per run: quantity -> predicted values [SI]."""
    residuals: list
    """Per run: quantity -> measured - predicted [SI]."""
    mods: Mods = Mods()
    """The effect terms of the baseline: none."""
    floor2: float = 1.0
    """Expected mean squared normalised residual per point without a gap: (N - R) / N with R
    nuisance zeros profiled out of N residuals."""
    n_params: int = 0
    """Parameters fitted by the baseline (the sensing S nuisance, if identified)."""


def all_rows(problem: Problem) -> list[tuple[int, np.ndarray]]:
    """Every row of every run, as (run index, row mask) pairs."""
    return [(i, np.ones(len(d), bool)) for i, d in enumerate(problem.frames)]


def baseline_fit(problem: Problem) -> BaselineFit:
    """The thesis model on every run with the kind's per-run constants."""
    spring = problem.spring_for(all_rows(problem))
    preds = [problem.predict(i, Mods(), spring) for i in range(len(problem.frames))]
    return BaselineFit(spring, preds, [problem.resid(i, p) for i, p in enumerate(preds)])


def _quantity_noise(
    problem: Problem, q: str, per_run: list, spread: dict, residuals
) -> tuple[float, float, str]:
    """(sigma [SI], dof, method) of one quantity; records in ``spread`` whether the runs agree."""
    runs = [i for i in range(len(problem.frames)) if problem.logs(i, q)]
    n_runs = len(runs)
    vals = np.array([per_run[i] for i in runs if np.isfinite(per_run[i]) and per_run[i] > 0])
    if vals.size == 0:
        resid = np.concatenate([residuals[i][q] for i in runs])
        vals = np.array([max(float(np.std(resid)), 1e-300)])
    sigma = float(np.median(vals))
    dof = (
        SECOND_DIFF_EFFICIENCY
        * sum(max(len(problem.frames[i]) - 2, 0) for i in runs)
        * (MEDIAN_EFFICIENCY if n_runs >= 3 else 1.0)
    )
    method = "second difference"
    if spread.get("available") and q in spread and vals.size == n_runs:
        between_var = (spread[q]["sd"] / display(q)[1]) ** 2
        pooled = pool_noise_estimates(np.asarray(per_run) ** 2, between_var, len(problem.frames[0]), dof)
        spread[q]["consistent"] = pooled is not None
        if pooled is not None:
            sigma, dof = math.sqrt(pooled[0]), pooled[1]
            method = "second difference + between runs"
    return sigma, dof, method


def slow_input_variance(problem: Problem, i: int, q: str, spring=None) -> float:
    """Variance [SI^2] that the noise left in run i's frame-averaged inputs adds to ``q``.

    A slower instrument's reading (a thermal camera's frames on a 1 kHz log) is read
    averaged over K frames (:func:`tcamlab.signals.smooth_slow_input`); its noise left,
    ``frame_sd**2 / K``, reaches the output through the model's gain and is correlated over
    the K frames' rows, so second differences cannot see it. Without it, a 142,100-row static
    log of a 0.5 degC camera came out at 1.006 noise floors against a limit of 1.0075:
    on a longer log, a gap with nothing in it."""
    var = 0.0
    for column, info in problem.smoothed[i].items():
        gain = problem.input_gain(i, column, spring)
        if gain is not None:
            var += float(np.mean(gain[q] ** 2)) * info["frame_sd"] ** 2 / info["frames"]
    return var


def run_noise_sigma(
    problem: Problem, i: int, q: str, residual, spring=None
) -> tuple[float, float | None, float, float]:
    """(noise sd [SI], quantisation step [SI] or None, and the shares of the variance second
    differences miss: the quantisation error of a slowly moving reading on a coarse converter
    (:mod:`tcamlab.io.quantisation`), then the noise left in a slower instrument's averaged
    input (:func:`slow_input_variance`)) of quantity ``q`` in run ``i``."""
    seen = second_difference_sigma(residual, problem.step_rows(i))
    if not np.isfinite(seen):
        return seen, None, 0.0, 0.0
    measured = problem.measured(i, q)
    hidden, step = unseen_variance(measured, measured - np.asarray(residual, float), seen * seen)
    slow = slow_input_variance(problem, i, q, spring)
    total = seen * seen + hidden + slow
    if total <= 0:
        return 0.0, step, 0.0, 0.0
    return math.sqrt(total), step, hidden / total, slow / total


def estimate_noise(problem: Problem, baseline: BaselineFit) -> NoiseFloor:
    """Each quantity's noise floor from the baseline residuals; sets ``problem.sigma``."""
    res = baseline.residuals
    unlogged = (float("nan"), None, 0.0, 0.0)
    per = {
        q: [
            run_noise_sigma(problem, i, q, r[q], baseline.spring) if problem.logs(i, q) else unlogged
            for i, r in enumerate(res)
        ]
        for q in problem.quantities
    }
    spread = between_run_spread(problem, res)
    by_q = {}
    for q in problem.quantities:
        per_run = [s for s, *_ in per[q]]
        problem.sigma[q], dof, method = _quantity_noise(problem, q, per_run, spread, res)
        steps = [st for _, st, _, _ in per[q] if st is not None]
        unit, fac = display(q)
        step = float(np.median(steps)) * fac if steps else None
        logged = [per[q][i] for i in range(len(res)) if problem.logs(i, q)]
        hidden = float(np.median([h for _, _, h, _ in logged]))
        if hidden >= 0.01:
            method += f" + {hidden:.0%} of the variance: the error of its {step:.3g} {unit} quantisation step"
        slow = float(np.median([v for *_, v in logged]))
        if slow >= 0.001:
            method += f" + {slow:.1%} of the variance: the noise left in a slower instrument's averaged input"
        by_q[q] = QuantityNoise(problem.sigma[q] * fac, unit, [v * fac for v in per_run], dof, method, step)
    method = (
        "second difference of baseline residuals (median over runs), plus what second "
        "differences cannot see: the error of a quantised reading that moves slowly and the "
        "noise left in a slower instrument's input averaged over its frames; pooled "
        "with the between-run spread where runs share their inputs and the two agree"
    )
    return NoiseFloor(list(problem.quantities), method, by_q, spread)


def _refit_nuisance(problem: Problem, baseline: BaselineFit) -> BaselineFit:
    """The baseline with the sensing S refitted on the normalised residuals (once sigma is known)."""
    if not problem.spring_nuisance:
        return baseline
    spring = fit_effect(problem, None, all_rows(problem), baseline.spring).spring
    preds = [problem.predict(i, Mods(), spring) for i in range(len(problem.frames))]
    return BaselineFit(spring, preds, [problem.resid(i, p) for i, p in enumerate(preds)], n_params=1)


def run_effect_columns(problem: Problem, baseline: BaselineFit, i: int) -> np.ndarray:
    """Columns G of run i's departures from the shared sample: d(normalised residual) per
    relative sd of each field of ``problem.run_to_run``, quantities stacked as in
    :meth:`Problem.scaled`, each run's zero projected out (it is profiled first)."""
    base = baseline.predictions[i]
    cols = []
    for fld, rel in sorted(problem.run_to_run.items()):
        pred = None
        for step in (EFFECT_STEP, -EFFECT_STEP):  # the inner side at the domain's edge
            moved = problem.sample.replace(**{fld: getattr(problem.sample, fld) * (1.0 + step)})
            try:
                pred = problem.predict(i, baseline.mods, baseline.spring, sample=moved)
                break
            except MODEL_ERRORS:
                continue
        if pred is None:
            continue
        parts = []
        for q in problem.quantities:
            if not problem.logs(i, q):  # its residual is a constant zero
                parts.append(np.zeros(len(problem.frames[i])))
                continue
            g = (pred[q] - base[q]) * (rel / step)
            parts.append((g - np.mean(g) if q in problem.zeroed else g) / problem.sigma[q])
        cols.append(np.concatenate(parts))
    return np.column_stack(cols) if cols else np.zeros((0, 0))


def profile_run_effects(problem: Problem, baseline: BaselineFit, i: int, z: np.ndarray) -> np.ndarray:
    """Run i's normalised residuals with its departures from the shared sample profiled out.

    As in calibration (:func:`tcamlab.calibration.problem.profile_random_effects`), a run's
    residuals carry ``G delta`` with ``delta ~ N(0, I)``, profiled out; without a gap the
    result is chi-square with as many degrees of freedom as before. A sensor re-mounted between
    pulls (0.05 % of twists and coil length) misses one shared geometry by more than a quiet
    load cell's noise: a fifth of the rig's noise made every sensing null `unexplained`.
    """
    if not problem.run_to_run:
        return z
    g = run_effect_columns(problem, baseline, i)
    if g.shape[0] != z.size or not g.size:
        return z
    return profile_random_effects(z, *random_effect_basis(g))


def check_gap(
    problem: Problem, baseline: BaselineFit, noise: NoiseFloor
) -> tuple[BaselineFit, Baseline, Gap]:
    """Refit the nuisance, then test whether the baseline misses the data by more than noise
    and each run's stated departure from the shared sample (:func:`profile_run_effects`)."""
    baseline = _refit_nuisance(problem, baseline)
    Q = problem.quantities
    z_all = np.concatenate(
        [
            profile_run_effects(problem, baseline, i, problem.norm_resid(i, baseline.mods, baseline.spring))
            for i in range(len(problem.frames))
        ]
    )
    runs = range(len(problem.frames))
    N = sum(problem.n_entries(i) for i in runs)
    # each profiled zero takes one degree of freedom: the RMSE is over N - R, so its
    # no-gap value is about 1 and F(N_q - R_q, nu) per quantity is its distribution
    per_q = [
        sum(len(problem.frames[i]) - (q in problem.zeroed) for i in runs if problem.logs(i, q)) for q in Q
    ]
    dof_points = sum(per_q)
    rms = float(np.sqrt(np.sum(z_all**2) / dof_points))
    dofs = [noise.by_quantity[q].dof for q in Q]
    limit = gap_limit(per_q, dofs)
    baseline.floor2 = dof_points / N
    summary = _baseline_summary(problem, baseline, z_all)
    gap = Gap(
        rmse_over_noise=rms,
        limit=limit,
        level=GAP_LEVEL,
        expected_rmse_over_noise_without_gap=1.0,
        nuisance_zeros=list(problem.zeroed),
        n_points=int(N),
        noise_dof=min(dofs),
        significant=bool(rms > limit),
        rule=f"baseline RMSE/noise above sqrt of the {GAP_LEVEL:.0%} quantile of F(N, nu)"
        + (", each run's departure from the shared sample profiled out" if problem.run_to_run else ""),
        run_to_run=dict(problem.run_to_run),
    )
    return baseline, summary, gap


def _baseline_summary(problem: Problem, baseline: BaselineFit, z_all: np.ndarray) -> Baseline:
    by_q = {}
    for q in problem.quantities:
        unit, fac = display(q)
        r = np.concatenate([res[q] for i, res in enumerate(baseline.residuals) if problem.logs(i, q)])
        by_q[q] = {
            "rmse": float(np.sqrt(np.mean(r**2))) * fac,
            "bias": float(np.mean(r)) * fac,
            "rmse_over_noise": float(np.sqrt(np.mean(r**2)) / problem.sigma[q]),
            "unit": unit,
        }
    sse, k = float(np.sum(z_all**2)), baseline.n_params
    n = sum(problem.n_entries(i) for i in range(len(problem.frames)))
    if problem.rig.spring_constant is not None:
        source = "rig"
    else:
        source = "identified on training runs" if problem.k.needs_training else None
    return Baseline(
        rmse_over_noise=float(np.sqrt(sse / n)),
        n=int(n),
        by_quantity=by_q,
        aic=sse + 2 * k,
        bic=sse + k * math.log(n),
        spring_constant_N_per_m=baseline.spring,
        options={"spring_constant": source},
    )
