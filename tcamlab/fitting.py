"""Spring constant of a coil from pull tests (thesis section 3.3: F = S delta).

The rig stretches the unheated coil and logs its extension delta [m] and the
force F [N]. :func:`fit_spring` fits F = S delta (through the origin, the
thesis form) or F = S delta + c, by ordinary least squares or robustly;
:func:`fit_spring_runs` fits several logs, per run, per loading/unloading
branch (:func:`split_branches`) and pooled; :func:`leave_one_out_spring`
refits the pool without one run, for cross-validation.

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
        c [N]; 0.0 for a fit through the origin.
    intercept_stderr : float
        Standard error of c [N]; 0.0 for a fit through the origin.
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

    @property
    def dof(self) -> int:
        """Residual degrees of freedom, n - 1 (origin) or n - 2 (intercept)."""
        return self.n - (2 if self.method.endswith("intercept") else 1)

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
            "n": int(self.n),
            "spring_constant_N_per_m": json_float(self.spring_constant),
            "stderr_N_per_m": json_float(self.stderr),
            "ci95_N_per_m": [json_float(self.ci95[0]), json_float(self.ci95[1])],
            "intercept_N": json_float(self.intercept),
            "intercept_stderr_N": json_float(self.intercept_stderr),
            "r2": json_float(self.r2),
        }
        if include_residuals:
            d["residuals_N"] = [json_float(r) for r in np.asarray(self.residuals, float)]
        return d

    def to_pandas(self):
        """One-row DataFrame of :meth:`to_dict` with the CI split in two columns."""
        import pandas as pd

        d = self.to_dict()
        lo, hi = d.pop("ci95_N_per_m")
        row = {}
        for k, v in d.items():
            row[k] = np.nan if v is None else v
            if k == "stderr_N_per_m":
                row["ci95_low_N_per_m"] = np.nan if lo is None else lo
                row["ci95_high_N_per_m"] = np.nan if hi is None else hi
        return pd.DataFrame([row])

    def _label(self) -> str:
        text = f"S = {self.spring_constant:.4g} ± {self.stderr:.2g} N/m"
        if self.method.endswith("intercept"):
            text += f", c = {self.intercept * 1e3:.3g} mN"
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
        ax.plot(xs * 1e3, self.predict(xs), "-", color=line_color, label=f"{name}: {self._label()}")
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
    n = x.size
    p = 2 if intercept else 1
    # f_scale: the noise level of the inliers, from the OLS residuals; a floor
    # keeps it positive when most points lie exactly on a line.
    floor = 1e-12 * max(float(np.max(np.abs(f))), 1e-300)
    f_scale = max(mad_scale(resid0), floor)

    if intercept:
        design = np.column_stack([x, np.ones_like(x)])
        start = np.array([s0, c0])
    else:
        design = x[:, None]
        start = np.array([s0])

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
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    s = float(theta[0])
    c = float(theta[1]) if intercept else 0.0
    se_c = float(se[1]) if intercept else 0.0
    return s, c, float(se[0]), se_c, resid


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
        Fit over all runs concatenated (``run="pooled"``).
    """

    fits: list[SpringFit]
    pooled: SpringFit

    @property
    def spring_constant(self) -> float:
        """Pooled S [N/m]."""
        return self.pooled.spring_constant

    def to_pandas(self):
        """One row per fit, the pooled fit last."""
        import pandas as pd

        return pd.concat([f.to_pandas() for f in [*self.fits, self.pooled]], ignore_index=True)

    def to_dict(self, include_residuals: bool = False) -> dict:
        """JSON-safe dict: ``spring_constant_N_per_m`` (pooled S), ``pooled``, ``runs``."""
        return {
            "spring_constant_N_per_m": json_float(self.pooled.spring_constant),
            "method": self.pooled.method,
            "pooled": self.pooled.to_dict(include_residuals),
            "runs": [f.to_dict(include_residuals) for f in self.fits],
        }

    def plot(self, ax=None):
        """Each run's data with its own fit, and the pooled line; returns ``ax``."""
        ax = _new_axes(ax)
        x_all = np.asarray(self.pooled.displacement, float)
        for fit in self.fits:
            if fit.branch_label != "all":
                continue
            pts = ax.plot(np.asarray(fit.displacement) * 1e3, fit.force, ".", ms=3, alpha=0.4, label=fit.run)
            xs = np.linspace(min(0.0, float(fit.displacement.min())), float(fit.displacement.max()), 50)
            ax.plot(xs * 1e3, fit.predict(xs), "-", lw=0.8, color=pts[0].get_color())
        xs = np.linspace(min(0.0, float(x_all.min())), float(x_all.max()), 50)
        ax.plot(xs * 1e3, self.pooled.predict(xs), "k-", lw=1.6, label=f"pooled: {self.pooled._label()}")
        ax.set_xlabel("displacement [mm]")
        ax.set_ylabel("force [N]")
        ax.legend(fontsize="small")
        return ax


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
    intercept: bool = False,
    robust: bool = False,
    by_branch: bool = True,
) -> SpringFitReport:
    """Fit S per run, per branch and pooled.

    Parameters
    ----------
    runs : sequence of (name, displacement [m], force [N])
        Run names must be unique.
    intercept, robust : bool
        As in :func:`fit_spring`.
    by_branch : bool
        Also fit the loading and unloading branches (:func:`split_branches`)
        of each run that has both (a branch with fewer than 3 points or
        zero displacement is skipped).

    Returns
    -------
    SpringFitReport
        ``pooled`` is one fit on all runs concatenated.

    Raises
    ------
    InputError
        No runs, duplicate names, or a run fails :func:`fit_spring` validation.
    """
    checked = _check_runs(runs)
    fits: list[SpringFit] = []
    xs, fs = [], []
    for name, disp, frc in checked:
        whole = fit_spring(disp, frc, intercept=intercept, robust=robust, branch_label="all", run=name)
        fits.append(whole)
        xs.append(whole.displacement)
        fs.append(whole.force)
        if not by_branch:
            continue
        branches = split_branches(whole.displacement)
        if len(branches) < 2:
            continue
        for label in ("loading", "unloading"):
            mask = branches[label]
            bx, bf = whole.displacement[mask], whole.force[mask]
            if bx.size < 3 or not np.any(bx != 0.0) or (intercept and np.ptp(bx) == 0.0):
                continue
            fits.append(fit_spring(bx, bf, intercept=intercept, robust=robust, branch_label=label, run=name))
    pooled = fit_spring(
        np.concatenate(xs),
        np.concatenate(fs),
        intercept=intercept,
        robust=robust,
        branch_label="all",
        run="pooled",
    )
    return SpringFitReport(fits=fits, pooled=pooled)


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
