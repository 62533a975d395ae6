"""Spring constant of a coil from pull tests (thesis section 3.3: F = S delta).

The rig stretches the unheated coil and logs its extension delta [m] and the
force F [N]. :func:`fit_spring` fits F = S delta + F0 or F = S delta (through
the origin, the thesis form), by ordinary least squares or robustly;
:func:`fit_spring_runs` fits several logs, per run, per loading/unloading
branch (:func:`split_branches`) and pooled; :func:`leave_one_out_spring`
refits the pool without one run, for cross-validation.

F0 is the load cell's zero (tare) offset, a nuisance parameter: a tare left
at -0.4 mN biases an origin-forced S by about F0 mean(delta) / mean(delta^2)
(-0.012 N/m on a 0-50 mm pull, 20 standard errors). :func:`fit_spring_runs`
(and ``tcamlab fit-spring``) therefore fit F0 by default, one per run in the
pooled fit (each run is tared on its own), and warn when it is significant
(:attr:`SpringFitReport.warnings`). Uncertainties are one standard error
(``stderr``) and Student-t 95 % intervals (``ci95``).

Everything here is SI: displacement in m, force in N, S in N/m. Plots show
displacement in mm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from tcamlab.errors import ConvergenceError, InputError
from tcamlab.jsonutil import json_float
from tcamlab.signals import mad_scale, split_branches

__all__ = [
    "SpringFit",
    "SpringFitReport",
    "fit_spring",
    "fit_spring_runs",
    "leave_one_out_spring",
    "split_branches",
    "starts_under_load",
]

"""1 / Phi^-1(3/4): scales a median absolute deviation to a normal sd."""

_HINT_SET_S = "set spring_constant_N_per_m in [rig]"

_METHODS = ("ols-origin", "ols-intercept", "robust-origin", "robust-intercept")


@dataclass
class SpringFit:
    """Result of fitting F = S delta (+ c).

    Attributes
    ----------
    spring_constant : float
        S [N/m].
    stderr : float
        Standard error of S [N/m].
    ci95 : tuple of float
        95 % confidence interval of S, Student-t with n - p degrees of
        freedom [N/m].
    intercept : float
        F0 [N], the load cell's zero offset; 0.0 for a fit through the origin.
        For a pooled fit with one F0 per run, the mean of the runs' F0.
    intercept_stderr : float
        Standard error of F0 [N]; 0.0 for a fit through the origin.
    r2 : float
        Coefficient of determination: uncentred (1 - SS_res / sum F^2) for
        a fit through the origin, centred for a fit with intercept.
    n : int
        Number of points.
    method : str
        ``"ols-origin"``, ``"ols-intercept"``, ``"robust-origin"`` or
        ``"robust-intercept"``.
    branch_label : str
        ``"all"``, ``"loading"`` or ``"unloading"``.
    residuals : ndarray
        F - (S delta + c) [N].
    displacement, force : ndarray
        The data fitted [m], [N].
    run : str
        Run name; ``"pooled"`` for a fit over several runs.
    intercept_ci95 : tuple of float
        95 % confidence interval of F0 [N] (0, 0 through the origin).
    run_intercepts : list of dict
        Pooled fit with an intercept: each run's own F0, ``{run, intercept_N,
        intercept_stderr_N, intercept_ci95_N}`` (empty otherwise).
    """

    spring_constant: float
    stderr: float
    ci95: tuple[float, float]
    intercept: float
    intercept_stderr: float
    r2: float
    n: int
    method: str
    branch_label: str
    residuals: np.ndarray = field(repr=False)
    displacement: np.ndarray = field(repr=False)
    force: np.ndarray = field(repr=False)
    run: str = "pooled"
    intercept_ci95: tuple[float, float] = (0.0, 0.0)
    run_intercepts: list = field(default_factory=list)

    @property
    def through_origin(self) -> bool:
        """Whether F0 was forced to 0."""
        return self.method.endswith("origin")

    @property
    def r2_kind(self) -> str:
        """``"uncentred"`` (through the origin: 1 - SS_res / sum F^2) or ``"centred"``."""
        return "uncentred" if self.through_origin else "centred"

    @property
    def dof(self) -> int:
        """Residual degrees of freedom: n - 1 (origin), n - 2 (intercept), n - 1 - runs (one F0 per run)."""
        if self.through_origin:
            return self.n - 1
        return self.n - 1 - max(1, len(self.run_intercepts))

    @property
    def intercept_significant(self) -> bool:
        """Whether the 95 % interval of F0 excludes 0 (never through the origin)."""
        lo, hi = self.intercept_ci95
        return (not self.through_origin) and bool(lo > 0.0 or hi < 0.0)

    @property
    def model(self) -> str:
        """The fitted model in words."""
        if self.through_origin:
            return "F = S delta (forced through the origin: the load cell's tare taken as exact)"
        if self.run_intercepts:
            return "F = S delta + F0, one F0 (load-cell tare) per run"
        return "F = S delta + F0 (F0: load-cell tare)"

    def predict(self, displacement) -> np.ndarray:
        """Force [N] of the fitted line at ``displacement`` [m]."""
        return self.spring_constant * np.asarray(displacement, float) + self.intercept

    def to_dict(self, include_residuals: bool = False) -> dict:
        """JSON-safe dict; units in the key names; non-finite floats become None.

        With ``include_residuals=True`` the residuals [N] are added as a list
        under ``residuals_N``.
        """
        d = {
            "run": self.run,
            "branch": self.branch_label,
            "method": self.method,
            "model": self.model,
            "through_origin": self.through_origin,
            "n": int(self.n),
            "spring_constant_N_per_m": json_float(self.spring_constant),
            "stderr_N_per_m": json_float(self.stderr),
            "ci95_N_per_m": [json_float(self.ci95[0]), json_float(self.ci95[1])],
            "intercept_N": json_float(self.intercept),
            "intercept_stderr_N": json_float(self.intercept_stderr),
            "intercept_ci95_N": [json_float(self.intercept_ci95[0]), json_float(self.intercept_ci95[1])],
            "intercept_significant": self.intercept_significant,
            "r2": json_float(self.r2),
            "r2_kind": self.r2_kind,
        }
        if self.run_intercepts:
            d["run_intercepts"] = [
                {
                    "run": r["run"],
                    "intercept_N": json_float(r["intercept_N"]),
                    "intercept_stderr_N": json_float(r["intercept_stderr_N"]),
                    "intercept_ci95_N": [json_float(v) for v in r["intercept_ci95_N"]],
                }
                for r in self.run_intercepts
            ]
        if include_residuals:
            d["residuals_N"] = [json_float(r) for r in np.asarray(self.residuals, float)]
        return d

    def to_pandas(self):
        """One-row DataFrame of :meth:`to_dict` with the CI split in two columns."""
        import pandas as pd

        d = self.to_dict()
        d.pop("run_intercepts", None)
        flo, fhi = d.pop("intercept_ci95_N")
        d["intercept_ci95_low_N"] = np.nan if flo is None else flo
        d["intercept_ci95_high_N"] = np.nan if fhi is None else fhi
        lo, hi = d.pop("ci95_N_per_m")
        row = {}
        for k, v in d.items():
            row[k] = np.nan if v is None else v
            if k == "stderr_N_per_m":
                row["ci95_low_N_per_m"] = np.nan if lo is None else lo
                row["ci95_high_N_per_m"] = np.nan if hi is None else hi
        return pd.DataFrame([row])

    def label(self) -> str:
        """``S = 4.698 ± 0.00052 N/m (± SE), F0 = -0.34 mN`` (F0 only with an intercept)."""
        text = f"S = {self.spring_constant:.5g} ± {self.stderr:.2g} N/m (± SE)"
        if not self.through_origin:
            mean = "mean " if self.run_intercepts else ""
            text += f", {mean}F0 = {self.intercept * 1e3:.3g} ± {self.intercept_stderr * 1e3:.2g} mN"
        else:
            text += ", through the origin"
        return text

    def plot(self, ax=None, *, color=None, label: str | None = None):
        """Data and fitted line, displacement in mm, force in N; returns ``ax``.

        Without ``ax`` a new :class:`matplotlib.figure.Figure` is made (no
        pyplot state is touched); get it back with ``ax.figure``.
        """
        ax = _new_axes(ax)
        x = np.asarray(self.displacement, float)
        f = np.asarray(self.force, float)
        name = label if label is not None else f"{self.run} ({self.branch_label})"
        pts = ax.plot(x * 1e3, f, ".", ms=3, alpha=0.5, color=color, label=f"{name} data")
        line_color = pts[0].get_color()
        lo = min(0.0, float(x.min())) if x.size else 0.0
        hi = float(x.max()) if x.size else 0.0
        xs = np.linspace(lo, hi, 50)
        ax.plot(xs * 1e3, self.predict(xs), "-", color=line_color, label=f"{name}: {self.label()}")
        ax.set_xlabel("displacement [mm]")
        ax.set_ylabel("force [N]")
        ax.legend(fontsize="small")
        return ax

    def plot_residuals(self, ax=None):
        """Residuals [mN] against displacement [mm]; returns ``ax``."""
        ax = _new_axes(ax)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.plot(
            np.asarray(self.displacement, float) * 1e3,
            np.asarray(self.residuals, float) * 1e3,
            ".",
            ms=3,
        )
        ax.set_xlabel("displacement [mm]")
        ax.set_ylabel("residual force [mN]")
        ax.set_title(f"{self.run} ({self.branch_label}), {self.method}")
        return ax


def _new_axes(ax):
    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.0, 4.0)).add_subplot()
    return ax


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------


def _validate(displacement, force, *, intercept: bool, where: str) -> tuple[np.ndarray, np.ndarray]:
    try:
        x = np.asarray(displacement, dtype=float).ravel()
        f = np.asarray(force, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(
            f"{where}: displacement/force are not numeric",
            "pass numeric arrays in SI (m, N)",
        ) from None
    if x.size != f.size:
        raise InputError(
            f"{where}: {x.size} displacement values but {f.size} force values",
            "pass one force per displacement sample",
        )
    bad = ~(np.isfinite(x) & np.isfinite(f))
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{where}: {int(bad.sum())} non-finite displacement/force value(s), first at sample {first}",
            "drop or interpolate missing samples before fitting",
        )
    if x.size < 3:
        raise InputError(
            f"{where}: {x.size} point(s), a spring fit needs at least 3",
            "log more samples across the pull test or " + _HINT_SET_S,
        )
    if not np.any(x != 0.0):
        raise InputError(
            f"{where}: displacement is zero everywhere, S is undetermined",
            "check the displacement column and its unit, or " + _HINT_SET_S,
        )
    if intercept and np.ptp(x) == 0.0:
        raise InputError(
            f"{where}: displacement is constant, slope and intercept are undetermined",
            "fit through the origin (intercept=False) or pull over a range of lengths",
        )
    return x, f


# --------------------------------------------------------------------------
# single fit
# --------------------------------------------------------------------------


def _r2(f: np.ndarray, resid: np.ndarray, intercept: bool) -> float:
    ss_res = float(np.dot(resid, resid))
    if intercept:
        df = f - f.mean()
        ss_tot = float(np.dot(df, df))
    else:
        ss_tot = float(np.dot(f, f))
    return 1.0 - ss_res / ss_tot if ss_tot > 0.0 else float("nan")


def _ols(x: np.ndarray, f: np.ndarray, intercept: bool):
    """(S, c, se_S, se_c, residuals) of ordinary least squares."""
    n = x.size
    if intercept:
        xm, fm = x.mean(), f.mean()
        dx = x - xm
        sxx = float(np.dot(dx, dx))
        s = float(np.dot(dx, f - fm)) / sxx
        c = float(fm - s * xm)
        resid = f - (s * x + c)
        var = float(np.dot(resid, resid)) / (n - 2)
        se_s = math.sqrt(var / sxx)
        se_c = math.sqrt(var * (1.0 / n + xm * xm / sxx))
    else:
        sxx = float(np.dot(x, x))
        s = float(np.dot(x, f)) / sxx
        c = 0.0
        resid = f - s * x
        var = float(np.dot(resid, resid)) / (n - 1)
        se_s = math.sqrt(var / sxx)
        se_c = 0.0
    return s, c, se_s, se_c, resid


def _robust(x: np.ndarray, f: np.ndarray, intercept: bool, s0: float, c0: float, resid0: np.ndarray):
    """(S, c, se_S, se_c, residuals) of a soft_l1 M-estimate started at OLS."""
    if intercept:
        design = np.column_stack([x, np.ones_like(x)])
        start = np.array([s0, c0])
    else:
        design = x[:, None]
        start = np.array([s0])
    theta, cov, resid = _robust_design(design, f, start, resid0)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    s = float(theta[0])
    c = float(theta[1]) if intercept else 0.0
    se_c = float(se[1]) if intercept else 0.0
    return s, c, float(se[0]), se_c, resid


def _robust_design(design: np.ndarray, f: np.ndarray, start: np.ndarray, resid0: np.ndarray):
    """(theta, covariance, residuals) of a soft_l1 M-estimate of f = design theta, started at OLS."""
    n, p = design.shape
    # f_scale: the noise level of the inliers, from the OLS residuals; a floor
    # keeps it positive when most points lie exactly on a line.
    floor = 1e-12 * max(float(np.max(np.abs(f))), 1e-300)
    f_scale = max(mad_scale(resid0), floor)

    def fun(theta):
        return design @ theta - f

    def jac(theta):
        return design

    res = optimize.least_squares(
        fun, start, jac=jac, loss="soft_l1", f_scale=f_scale, method="trf", x_scale="jac"
    )
    if not res.success or not np.all(np.isfinite(res.x)):
        raise ConvergenceError(
            f"fit_spring: robust fit did not converge ({res.message})",
            "use robust=False or remove gross outliers by hand",
        )
    theta = res.x
    resid = f - design @ theta
    # Jacobian at the solution weighted as in the Gauss-Newton Hessian of the
    # soft_l1 cost (what least_squares itself uses): J_w = J sqrt(psi'), with
    # psi(r) = r / sqrt(1 + z), psi'(r) = (1 + z)^(-3/2), z = (r / C)^2, so
    # outliers carry (almost) no information. It is scaled by the robust
    # residual scale of an M-estimate (Huber 1981, sec. 7.6),
    # s^2 = sum(psi^2) / ((n - p) mean(psi')), which reduces to the OLS
    # residual variance when C -> infinity.
    z = (resid / f_scale) ** 2
    dpsi = (1.0 + z) ** -1.5
    psi = resid / np.sqrt(1.0 + z)
    wj = design * np.sqrt(dpsi)[:, None]
    scale2 = float(np.dot(psi, psi)) / ((n - p) * float(dpsi.mean()))
    try:
        cov = scale2 * np.linalg.inv(wj.T @ wj)
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.nan)
    return theta, cov, resid


def fit_spring(
    displacement,
    force,
    *,
    intercept: bool = False,
    robust: bool = False,
    branch_label: str = "all",
    run: str = "pooled",
) -> SpringFit:
    """Fit the spring constant S of F = S delta (+ c), section 3.3.

    Ordinary least squares through the origin (the thesis form) gives
    S = sum(delta F) / sum(delta^2); with ``intercept=True`` the usual
    straight line F = S delta + c. The standard error of S comes from the
    residual variance with n - 1 (origin) or n - 2 (intercept) degrees of
    freedom, and the 95 % CI from Student's t with the same dof.

    R^2: through the origin the *uncentred* R^2 = 1 - SS_res / sum(F^2) is
    reported (the centred one is not meaningful without an intercept and
    can be negative); with an intercept the usual centred
    R^2 = 1 - SS_res / sum((F - mean F)^2).

    ``robust=True`` minimises the soft_l1 loss with
    :func:`scipy.optimize.least_squares`, starting at the OLS solution with
    ``f_scale`` = 1.4826 MAD of the OLS residuals. Its standard error is
    from the Jacobian at the solution, weighted by the loss as in the
    Gauss-Newton Hessian (so outliers carry no information), times the
    robust residual scale of an M-estimate, sum(psi^2) / ((n - p) mean psi')
    with psi the soft_l1 influence function. soft_l1 bounds the influence
    of an outlier but does not remove it, so many one-sided gross outliers
    still leave a small bias (a few standard errors on long logs). R^2 is
    computed as for OLS, from all residuals including outliers.

    Parameters
    ----------
    displacement : array_like
        Extension delta [m].
    force : array_like
        Force F [N], same length.
    intercept : bool
        Fit F = S delta + c instead of F = S delta.
    robust : bool
        soft_l1 M-estimate instead of OLS.
    branch_label : str
        Stored on the result (``"all"``, ``"loading"``, ``"unloading"``).
    run : str
        Run name stored on the result.

    Returns
    -------
    SpringFit

    Raises
    ------
    InputError
        Fewer than 3 points, displacement zero everywhere (or constant with
        an intercept), lengths differ, or a value is not finite.
    ConvergenceError
        The robust solver failed.
    """
    where = f"fit_spring[{run}/{branch_label}]"
    x, f = _validate(displacement, force, intercept=intercept, where=where)
    s, c, se_s, se_c, resid = _ols(x, f, intercept)
    if robust:
        s, c, se_s, se_c, resid = _robust(x, f, intercept, s, c, resid)
    method = ("robust" if robust else "ols") + ("-intercept" if intercept else "-origin")
    n = int(x.size)
    dof = n - (2 if intercept else 1)
    t = float(stats.t.ppf(0.975, dof))
    return SpringFit(
        spring_constant=float(s),
        stderr=float(se_s),
        ci95=(float(s - t * se_s), float(s + t * se_s)),
        intercept=float(c),
        intercept_stderr=float(se_c),
        r2=_r2(f, resid, intercept),
        n=n,
        method=method,
        branch_label=branch_label,
        residuals=np.asarray(resid, float),
        displacement=x,
        force=f,
        run=run,
        intercept_ci95=(float(c - t * se_c), float(c + t * se_c)),
    )


def _pooled_per_run_intercepts(xs, fs, names, *, robust: bool) -> SpringFit:
    """One S and one F0 per run over all runs: f = S x + F0[run] (least squares, or soft_l1).

    The mean F0 and its standard error come from the covariance of the run F0s.
    """
    x, f = np.concatenate(xs), np.concatenate(fs)
    sizes = [v.size for v in xs]
    m = len(sizes)
    design = np.zeros((x.size, m + 1))
    design[:, 0] = x
    design[np.arange(x.size), 1 + np.repeat(np.arange(m), sizes)] = 1.0
    theta, *_ = np.linalg.lstsq(design, f, rcond=None)
    resid = f - design @ theta
    dof = x.size - m - 1
    if dof < 1:
        raise InputError(
            f"fit_spring[pooled]: {x.size} points for {m + 1} parameters (S and one F0 per run)",
            "log more samples, or fit through the origin",
        )
    cov = float(np.dot(resid, resid)) / dof * np.linalg.pinv(design.T @ design)
    if robust:
        theta, cov, resid = _robust_design(design, f, theta, resid)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    t = float(stats.t.ppf(0.975, dof))
    runs = [
        {
            "run": name,
            "intercept_N": float(theta[1 + i]),
            "intercept_stderr_N": float(se[1 + i]),
            "intercept_ci95_N": [float(theta[1 + i] - t * se[1 + i]), float(theta[1 + i] + t * se[1 + i])],
        }
        for i, name in enumerate(names)
    ]
    c = float(np.mean(theta[1:]))
    se_c = float(np.sqrt(max(float(cov[1:, 1:].sum()), 0.0)) / m)
    s, se_s = float(theta[0]), float(se[0])
    return SpringFit(
        spring_constant=s,
        stderr=se_s,
        ci95=(s - t * se_s, s + t * se_s),
        intercept=c,
        intercept_stderr=se_c,
        r2=_r2(f, resid, True),
        n=int(x.size),
        method=("robust" if robust else "ols") + "-intercept",
        branch_label="all",
        residuals=np.asarray(resid, float),
        displacement=x,
        force=f,
        run="pooled",
        intercept_ci95=(c - t * se_c, c + t * se_c),
        run_intercepts=runs,
    )


# --------------------------------------------------------------------------
# branches
# --------------------------------------------------------------------------


# --------------------------------------------------------------------------
# several runs
# --------------------------------------------------------------------------


@dataclass
class SpringFitReport:
    """Spring fits of several runs, per run and branch, and pooled.

    Attributes
    ----------
    fits : list of SpringFit
        Per run: the fit over the whole run (``branch_label="all"``), then,
        when the run has both, its ``"loading"`` and ``"unloading"`` fits.
    pooled : SpringFit
        Fit over all runs (``run="pooled"``): one S, and one F0 per run
        unless forced through the origin.
    warnings : list of str
        What the reader must see: a significant F0, or an origin-forced fit
        whose data show one.
    """

    fits: list[SpringFit]
    pooled: SpringFit
    warnings: list[str] = field(default_factory=list)

    @property
    def spring_constant(self) -> float:
        """Pooled S [N/m]."""
        return self.pooled.spring_constant

    def to_pandas(self):
        """One row per fit, the pooled fit last."""
        import pandas as pd

        return pd.concat([f.to_pandas() for f in [*self.fits, self.pooled]], ignore_index=True)

    def to_dict(self, include_residuals: bool = False) -> dict:
        """JSON-safe dict: ``spring_constant_N_per_m`` (pooled S), its ``stderr`` and ``ci95``,
        ``model``, ``r2_kind``, ``warnings``, ``uncertainty`` (what ± means), ``pooled``, ``runs``."""
        p = self.pooled
        return {
            "spring_constant_N_per_m": json_float(p.spring_constant),
            "stderr_N_per_m": json_float(p.stderr),
            "ci95_N_per_m": [json_float(p.ci95[0]), json_float(p.ci95[1])],
            "method": p.method,
            "model": p.model,
            "through_origin": p.through_origin,
            "r2_kind": p.r2_kind,
            "uncertainty": UNCERTAINTY_NOTE,
            "warnings": list(self.warnings),
            "pooled": p.to_dict(include_residuals),
            "runs": [f.to_dict(include_residuals) for f in self.fits],
        }

    def _whole_runs(self) -> list[SpringFit]:
        return [f for f in self.fits if f.branch_label == "all"]

    def plot(self, ax=None):
        """Each run's loading (filled) and unloading (open) points, the pooled fit; returns ``ax``.

        Displacement in mm, force in N. Runs are told apart by colour (named
        in the legend up to :data:`MAX_NAMED_RUNS`), branches by the marker.
        """
        from matplotlib.lines import Line2D

        ax = _new_axes(ax)
        runs = self._whole_runs()
        for i, fit in enumerate(runs):
            name = fit.run if len(runs) <= MAX_NAMED_RUNS else None
            _branch_points(ax, fit.displacement, fit.force, f"C{i % 10}", name)
        x_all = np.asarray(self.pooled.displacement, float)
        xs = np.linspace(min(0.0, float(x_all.min())), float(x_all.max()), 50)
        ax.plot(xs * 1e3, self.pooled.predict(xs), "k-", lw=1.4, label="pooled fit")
        ax.set_title(f"pooled fit: {self.pooled.label()}", fontsize="small")
        handles, _ = ax.get_legend_handles_labels()
        handles += [
            Line2D([], [], ls="", marker="o", ms=4, color="0.3", label="loading"),
            Line2D([], [], ls="", marker="o", ms=4, mfc="none", color="0.3", label="unloading"),
        ]
        ax.set_xlabel("displacement [mm]")
        ax.set_ylabel("force [N]")
        ax.legend(handles=handles, fontsize="small", loc="upper left")
        return ax

    def plot_residuals(self, ax=None):
        """Residuals of the pooled fit [mN] against displacement [mm], by branch; returns ``ax``."""
        ax = _new_axes(ax)
        ax.axhline(0.0, color="0.5", lw=0.8)
        start = 0
        for i, fit in enumerate(self._whole_runs()):
            n = fit.displacement.size
            r = np.asarray(self.pooled.residuals[start : start + n], float)
            start += n
            _branch_points(ax, fit.displacement, r * 1e3, f"C{i % 10}", None)
        ax.set_xlabel("displacement [mm]")
        ax.set_ylabel("residual force, measured − fit [mN]")
        ax.set_title(f"pooled fit ({self.pooled.method}): {self.pooled.model}", fontsize="small")
        return ax


MAX_NAMED_RUNS = 6
"""Runs named in the plot's legend; more are drawn but not named (a legend stays readable)."""

UNCERTAINTY_NOTE = (
    "stderr_*: one standard error (the ± of the text output); ci95_*: Student-t 95% confidence "
    "interval with the fit's residual degrees of freedom"
)
"""What the uncertainties of a spring fit are (text and JSON)."""


def _branch_points(ax, x, y, color, name) -> None:
    """Loading points filled, unloading points open, in one colour (mm on the x axis)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    branches = split_branches(x) if x.size else {"loading": np.ones(0, bool)}
    style = {"loading": {}, "unloading": {"mfc": "none"}}
    for label, mask in branches.items():
        ax.plot(
            x[mask] * 1e3, y[mask], "o", ms=2.5, alpha=0.6, color=color, mew=0.6,
            label=name if label == "loading" else None, **style[label],
        )  # fmt: skip


def _intercept_warnings(pooled: SpringFit, runs, *, robust: bool) -> list[str]:
    """Warnings on the load cell's zero: a significant F0, or one an origin-forced fit ignores."""
    if pooled.through_origin:
        free = _pooled_per_run_intercepts(
            [np.asarray(x, float) for _, x, _ in runs],
            [np.asarray(f, float) for _, _, f in runs],
            [name for name, _, _ in runs],
            robust=robust,
        )
        if not free.intercept_significant:
            return []
        return [
            f"forced through the origin, but a fit with one F0 per run finds a mean F0 of "
            f"{_mn(free.intercept)} ({_in_se(free)}): the load cell's zero is off and the "
            f"origin-forced S = {pooled.spring_constant:.5g} N/m is biased (the fit with F0 gives "
            f"{free.spring_constant:.5g} N/m); fit with the intercept (the default)"
        ]
    preloaded = {name: float(f[0]) for name, x, f in runs if starts_under_load(f)}
    out = [
        f"{name} starts under load (first reading {start:+.4g} N): a preloaded segment, whose F0 is "
        f"the preload, not a load-cell tare error; S, the slope, is not biased by it"
        for name, start in preloaded.items()
    ]
    if pooled.intercept_significant and len(preloaded) < len(runs):
        out.append(
            f"the load cell's zero is off: mean F0 = {_mn(pooled.intercept)} ({_in_se(pooled)}); "
            f"it is fitted as a nuisance, so S is not biased by it, but check the tare"
        )
    bad = [
        r
        for r in pooled.run_intercepts
        if (r["intercept_ci95_N"][0] > 0 or r["intercept_ci95_N"][1] < 0) and r["run"] not in preloaded
    ]
    if bad and len(pooled.run_intercepts) > 1:
        out.append(
            "runs whose own F0 is significant: "
            + ", ".join(
                f"{r['run']} {_mn(r['intercept_N'])} ({abs(r['intercept_N']) / r['intercept_stderr_N']:.1f} SE)"
                for r in bad
            )
        )
    return out


def starts_under_load(force) -> bool:
    """A segment whose first force reading is a fifth or more of its largest and of its span: it
    starts preloaded (a release, or a segment cut from a longer test), not at the unloaded length
    (a load cell's tare error is a small fraction of the force)."""
    f = np.asarray(force, float)
    f = f[np.isfinite(f)]
    if f.size < 2 or np.ptp(f) == 0.0:
        return False
    return bool(abs(f[0]) >= 0.2 * np.ptp(f) and abs(f[0]) >= 0.2 * np.max(np.abs(f)))


def _mn(force: float) -> str:
    return f"{force * 1e3:+.3g} mN"


def _in_se(fit: SpringFit) -> str:
    lo, hi = fit.intercept_ci95
    z = abs(fit.intercept) / fit.intercept_stderr if fit.intercept_stderr > 0 else float("inf")
    return f"{z:.1f} standard errors from 0, 95% CI {_mn(lo)} to {_mn(hi)}"


def _check_runs(runs) -> list[tuple[str, np.ndarray, np.ndarray]]:
    out = []
    seen = set()
    for item in runs:
        try:
            name, x, f = item
        except (TypeError, ValueError):
            raise InputError(
                "fit_spring_runs: each run must be a (name, displacement, force) triple",
                "build runs as [(name, displacement_m, force_N), ...]",
            ) from None
        name = str(name)
        if name in seen:
            raise InputError(
                f"fit_spring_runs: run name {name!r} appears twice", "give every run a unique name"
            )
        seen.add(name)
        out.append((name, x, f))
    if not out:
        raise InputError("fit_spring_runs: no runs given", "pass at least one pull test or " + _HINT_SET_S)
    return out


def fit_spring_runs(
    runs: Sequence[tuple[str, object, object]],
    *,
    intercept: bool = True,
    robust: bool = False,
    by_branch: bool = True,
) -> SpringFitReport:
    """Fit S per run, per branch and pooled, with the load cell's zero F0 as a nuisance.

    Parameters
    ----------
    runs : sequence of (name, displacement [m], force [N])
        Run names must be unique.
    intercept : bool
        Fit F = S delta + F0 (default); the pooled fit has one S and one F0
        per run, since each run is tared on its own. False forces every fit
        through the origin (the thesis form), and a warning says if the data
        show a significant F0.
    robust : bool
        As in :func:`fit_spring`.
    by_branch : bool
        Also fit the loading and unloading branches (:func:`split_branches`)
        of each run that has both (a branch with fewer than 3 points or
        zero displacement is skipped).

    Returns
    -------
    SpringFitReport
        With ``warnings`` on F0.

    Raises
    ------
    InputError
        No runs, duplicate names, or a run fails :func:`fit_spring` validation.
    """
    checked = _check_runs(runs)
    fits: list[SpringFit] = []
    for name, disp, frc in checked:
        whole = fit_spring(disp, frc, intercept=intercept, robust=robust, branch_label="all", run=name)
        fits.append(whole)
        if by_branch:
            fits.extend(_branch_fits(whole, intercept=intercept, robust=robust))
    wholes = [f for f in fits if f.branch_label == "all"]
    xs, fs = [f.displacement for f in wholes], [f.force for f in wholes]
    if intercept:
        pooled = _pooled_per_run_intercepts(xs, fs, [f.run for f in wholes], robust=robust)
    else:
        pooled = fit_spring(
            np.concatenate(xs), np.concatenate(fs), intercept=False, robust=robust, run="pooled"
        )
    checked = [(f.run, f.displacement, f.force) for f in wholes]
    return SpringFitReport(fits, pooled, _intercept_warnings(pooled, checked, robust=robust))


def _branch_fits(whole: SpringFit, *, intercept: bool, robust: bool) -> list[SpringFit]:
    """The loading and unloading fits of a run that has both branches."""
    branches = split_branches(whole.displacement)
    if len(branches) < 2:
        return []
    out = []
    for label in ("loading", "unloading"):
        mask = branches[label]
        bx, bf = whole.displacement[mask], whole.force[mask]
        if bx.size < 3 or not np.any(bx != 0.0) or (intercept and np.ptp(bx) == 0.0):
            continue
        out.append(fit_spring(bx, bf, intercept=intercept, robust=robust, branch_label=label, run=whole.run))
    return out


def leave_one_out_spring(
    runs, exclude: str, *, intercept: bool = False, robust: bool = False, **kw
) -> SpringFit:
    """Pooled fit over every run except ``exclude`` (cross-validation).

    Other keyword arguments of :func:`fit_spring_runs` (``by_branch``) are
    accepted and ignored. The result has ``run="pooled-without-<exclude>"``.

    Raises
    ------
    InputError
        ``exclude`` is not a run name, or no run is left.
    """
    unknown = set(kw) - {"by_branch"}
    if unknown:
        raise TypeError(f"leave_one_out_spring() got unexpected keyword argument(s) {sorted(unknown)}")
    checked = _check_runs(runs)
    names = [name for name, _, _ in checked]
    if str(exclude) not in names:
        raise InputError(
            f"leave_one_out_spring: no run named {exclude!r}",
            "runs are: " + ", ".join(names),
        )
    kept = [(name, x, f) for name, x, f in checked if name != str(exclude)]
    if not kept:
        raise InputError(
            f"leave_one_out_spring: excluding {exclude!r} leaves no run; leave-one-out needs at least two runs",
            _HINT_SET_S,
        )
    xs, fs = [], []
    for name, x, f in kept:
        vx, vf = _validate(x, f, intercept=intercept, where=f"leave_one_out_spring[{name}]")
        xs.append(vx)
        fs.append(vf)
    return fit_spring(
        np.concatenate(xs),
        np.concatenate(fs),
        intercept=intercept,
        robust=robust,
        branch_label="all",
        run=f"pooled-without-{exclude}",
    )
