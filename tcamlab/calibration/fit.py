"""MAP fit, Laplace covariance and profile-likelihood intervals of a calibration problem.

The objective is the penalised chi-square ``chi2(u) = sum(residuals(u)^2)``
(data residuals over their noise floor plus the prior residuals). The 95 %
profile interval of a parameter is where ``min over the others of chi2`` rises
by :data:`CHI2_95` above its minimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from tcamlab.calibration.problem import CalibrationProblem

__all__ = [
    "CHI2_95",
    "MapFit",
    "Profile",
    "map_fit",
    "solve",
    "laplace_covariance",
    "profile_interval",
    "every_row_chi2",
]

Z95 = 1.959963984540054
"""norm.ppf(0.975): the signed-root target of the profile search and the Laplace intervals' z."""

CHI2_95 = Z95**2
"""95 % quantile of chi-square with one degree of freedom (Z95 squared, so the two cannot drift)."""

PROFILE_TOL = 0.05
"""Stop the profile search when the signed root is within this of :data:`Z95`."""

BOUND_TOL = 0.05
"""Stop the profile search when the bound is bracketed to this fraction of its Laplace sd
(the same precision as :data:`PROFILE_TOL` where the profile is quadratic)."""

PROFILE_STEPS = 8
"""Most profile evaluations per side of an interval."""

PROFILE_NFEV = 40
"""Most residual evaluations of one profile refit (a refit stuck against the model's domain
edge otherwise runs to the optimiser's limit)."""

PROFILE_CHI2_TOL = 2e-3
"""Absolute chi-square precision of one profile point (0.0005 in the signed root near 1.96)."""


@dataclass
class MapFit:
    """The MAP point: fitted coordinates ``u``, penalised chi-square and optimiser status."""

    u: np.ndarray
    chi2: float
    nfev: int
    message: str


@dataclass
class Profile:
    """One side's result: the bound in fitted coordinates, the profile points ``(c, z)``
    (signed root; points where the model has no solution are left out), and whether the
    bound is open: the box, or the edge of the model's domain, was reached before
    chi-square rose by CHI2_95."""

    bound: float
    points: list[tuple[float, float]]
    open: bool


def solve(
    problem: CalibrationProblem,
    u_start: np.ndarray,
    free: list[int],
    ftol: float = 1e-10,
    max_nfev: int = 100,
) -> tuple[np.ndarray, float, int]:
    """Minimise chi2 over the ``free`` coordinates from ``u_start``; the rest stay fixed.

    Forward-difference Jacobian (its centre is the optimiser's own cached evaluation).
    """
    u = np.array(u_start, float)
    lo, hi = problem.bounds()
    if not free:
        r = problem.residuals(u)
        return u, float(r @ r), 1

    def fun(x):
        v = u.copy()
        v[free] = x
        return problem.residuals(v)

    def jac(x):
        v = u.copy()
        v[free] = x
        return problem.jacobian(v, free, central=False)

    x0 = np.clip(u[free], lo[free] + 1e-12, hi[free] - 1e-12)
    sol = optimize.least_squares(
        fun,
        x0,
        jac=jac,
        bounds=(lo[free], hi[free]),
        x_scale=problem.sd_u[free],
        method="trf",
        xtol=1e-8,
        ftol=ftol,
        gtol=1e-10,
        max_nfev=max_nfev,
    )
    u[free] = sol.x
    return u, float(2 * sol.cost), int(sol.nfev)


RESTART_SDS = (-2.0, 2.0)
"""Extra starts of the MAP fit, in prior sds along the least determined direction and along
each parameter's axis."""

RESTART_Z = 3.0
"""The MAP fit restarts when its chi-square exceeds its expectation (the number of residuals)
by more than this many sds of chi-square (sqrt(2 n)): a fit stopped short of the minimum."""


def _restarts(problem: CalibrationProblem, lead: np.ndarray):
    """Starts along ``lead`` and along each parameter's axis, :data:`RESTART_SDS` prior sds out."""
    for t in RESTART_SDS:
        yield problem.u0 + t * lead
    for k, sd in enumerate(problem.sd_u):
        for t in RESTART_SDS:
            start = problem.u0.copy()
            start[k] += t * sd
            yield start


def every_row_chi2(problem: CalibrationProblem, u: np.ndarray, chi2: float) -> tuple[float, int]:
    """The penalised chi-square at ``u`` over every row and its expectation (the residuals'
    number), given the fitted ``chi2``: the same unless a long run was fitted on its blocks'
    moments (:mod:`tcamlab.reduction`), where a misfit shared by a block's rows is summed
    into a few moments and the moments' chi-square is no test of the fit."""
    n = len(problem.u0) + problem.size
    if problem.n_resid == problem.size:
        return chi2, n
    with problem.full_rows():
        r = problem.residuals(u)
    return float(r @ r), n


def map_fit(problem: CalibrationProblem) -> MapFit:
    """The maximum a posteriori point: the best of fits from the stated values and from
    :data:`RESTART_SDS` prior sds along the leading eigenvector of the prior-whitened
    posterior covariance there (the direction the data pin least) and along each axis,
    when the first fit's chi-square is implausibly high (:data:`RESTART_Z`). A fit from the stated
    values alone can stop at the edge of the model's domain (the static G_t' = 0 limit),
    where the optimiser's steps leave the domain, although the chi-square falls along it."""
    free = list(range(len(problem.specs)))
    u, chi2, nfev = solve(problem, problem.u0, free)
    rows_chi2, n = every_row_chi2(problem, u, chi2)
    # an acceptable fit (chi-square within RESTART_Z of its expectation) needs no restarts
    if not free or rows_chi2 <= n + RESTART_Z * np.sqrt(2.0 * n):
        return MapFit(u, chi2, nfev, "ok")
    cov, _ = laplace_covariance(problem, u)
    white = cov / np.outer(problem.sd_u, problem.sd_u)
    lead = np.linalg.eigh(white)[1][:, -1] * problem.sd_u
    lo, hi = problem.bounds()
    for start in _restarts(problem, lead):
        u_t, chi2_t, nfev_t = solve(problem, np.clip(start, lo, hi), free)
        nfev += nfev_t
        if chi2_t < chi2 - PROFILE_CHI2_TOL and not problem.failed(chi2_t):
            u, chi2 = u_t, chi2_t
    return MapFit(u, chi2, nfev, "ok")


def laplace_covariance(problem: CalibrationProblem, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Posterior covariance of ``u`` (Gauss-Newton, priors included) and the Jacobian of the
    residuals (data rows, then the prior rows)."""
    jac = problem.jacobian(u)
    cov = np.linalg.pinv(jac.T @ jac)
    return cov, jac


class _Stop(Exception):
    """Raised inside the bracketed search when a point meets :data:`PROFILE_TOL`."""


class _ProfileSearch:
    """Profile points of parameter ``k``: each a refit of the others, warm-started from the
    nearest point already fitted, moved along the Laplace conditional mean (or, if that
    start leaves the model's domain, not moved)."""

    def __init__(self, problem: CalibrationProblem, fit: MapFit, cov: np.ndarray, k: int, jac: np.ndarray):
        self.problem, self.fit, self.k = problem, fit, k
        self.slope = cov[:, k] / cov[k, k]
        self.sd = float(np.sqrt(max(cov[k, k], 1e-16)))
        self.free = [m for m in range(len(fit.u)) if m != k]
        self.known: list[tuple[float, float, np.ndarray]] = [(float(fit.u[k]), 0.0, fit.u)]
        self.points: list[tuple[float, float]] = []
        self.tries = 0
        self.ftol = min(max(PROFILE_CHI2_TOL / max(fit.chi2, 1e-300), 1e-12), 1e-6)
        self.jac_free = jac[:, self.free]

    def _refit(self, start: np.ndarray) -> tuple[np.ndarray, float]:
        """Refit the free parameters from ``start``: one Gauss-Newton step with the MAP's
        Jacobian, kept when the chi-square it predicts is met to PROFILE_CHI2_TOL (the model
        is linear over the step, so the step lands on the minimum: two evaluations);
        otherwise the optimiser from the better of the two points."""
        r0 = self.problem.residuals(start)
        chi0 = float(r0 @ r0)
        if not self.problem.failed(chi0):
            step = np.linalg.lstsq(self.jac_free, -r0, rcond=None)[0]
            predicted = r0 + self.jac_free @ step
            u1 = start.copy()
            u1[self.free] += step
            lo, hi = self.problem.bounds()
            if np.all((u1 >= lo) & (u1 <= hi)):
                r1 = self.problem.residuals(u1)
                chi1 = float(r1 @ r1)
                if abs(chi1 - float(predicted @ predicted)) <= PROFILE_CHI2_TOL:
                    return u1, chi1
                if chi1 < chi0:
                    start = u1
        u, chi2, _ = solve(self.problem, start, self.free, self.ftol, PROFILE_NFEV)
        return u, chi2

    def z(self, c: float) -> float:
        """``sqrt(chi2_profile(c) - chi2_min)``; ``inf`` where the model has no solution."""
        for ck, zk, _ in self.known:
            if ck == c:
                return zk
        self.tries += 1
        near = min((p for p in self.known if np.isfinite(p[1])), key=lambda p: abs(p[0] - c))
        best_u, best = None, np.inf
        # a second start only where the first is steeper than the Laplace approximation
        # (where a stuck refit would show); the third only if neither solved
        z_laplace = abs(c - self.known[0][0]) / self.sd
        for base, slope in self._starts(near):
            if best_u is not None and (slope is not self.slope or best - self.fit.chi2 <= z_laplace**2):
                break
            start = base[2] + slope * (c - base[0])
            start[self.k] = c
            u, chi2 = self._refit(start)
            if not self.problem.failed(chi2) and chi2 < best:
                best_u, best = u, chi2
        if best_u is None:
            self.known.append((c, np.inf, u))
            return np.inf
        z = float(np.sqrt(max(best - self.fit.chi2, 0.0)))
        self.points.append((c, z))
        self.known.append((c, z, best_u))
        return z

    def _starts(self, near):
        """Starts of a refit, the best kept: the nearest point and the MAP, each moved along
        the conditional mean (next to the model's domain edge a refit can stick on the way,
        overstating z); the nearest point unmoved if both leave the domain."""
        yield near, self.slope
        if near is not self.known[0]:
            yield self.known[0], self.slope
        yield near, np.zeros_like(self.slope)

    def result(self, c: float) -> Profile:
        """The bound at ``c``, unless the model's domain ends first on the way out: then the
        last point inside it, open."""
        centre = float(self.fit.u[self.k])
        inside = float(centre)
        for ck, zk, _ in sorted(self.known, key=lambda p: abs(p[0] - centre)):
            if zk >= Z95 - PROFILE_TOL and np.isfinite(zk):
                break
            if not np.isfinite(zk):
                return Profile(inside, self.points, True)
            inside = ck
        return Profile(float(c), self.points, False)


def profile_interval(
    problem: CalibrationProblem,
    fit: MapFit,
    cov: np.ndarray,
    k: int,
    side: int,
    jac: np.ndarray | None = None,
) -> Profile:
    """One side (``side`` = -1 or +1) of the 95 % profile interval of parameter ``k``.

    ``jac`` is the Jacobian of the residuals at the MAP (priors included; computed when
    not given), for the Gauss-Newton refits.

    Root of ``z(c) - Z95`` with ``z(c) = sqrt(chi2_profile(c) - chi2_min)``, nearly
    linear in ``c``: steps out from the Laplace bound until the root is bracketed (or
    the box is reached), then Brent's method to :data:`BOUND_TOL` Laplace sds, stopping
    early when a point is within :data:`PROFILE_TOL` of the target. Every point refits
    the other parameters (:class:`_ProfileSearch`).
    """
    lo, hi = problem.bounds()
    edge = float(hi[k] if side > 0 else lo[k])
    sd = float(np.sqrt(max(cov[k, k], 1e-16)))
    centre = float(fit.u[k])
    jac = problem.jacobian(fit.u) if jac is None else jac
    search = _ProfileSearch(problem, fit, cov, k, jac)
    step, inside = Z95 * sd, centre
    while search.tries < PROFILE_STEPS:
        c = centre + side * step
        at_edge = side * (c - edge) >= 0
        c = edge if at_edge else c
        z = search.z(c)
        if abs(z - Z95) < PROFILE_TOL:
            return Profile(c, search.points, False)
        if z > Z95:
            return _bracketed(search, inside, c, sd)
        if at_edge:
            return Profile(c, search.points, z < Z95 - PROFILE_TOL)
        inside = c
        step = abs(c - centre) * (min(Z95 / z, 4.0) if z > 0 else 4.0)
    return search.result(search.known[-1][0])


def _bracketed(search: _ProfileSearch, inside: float, outside: float, sd: float) -> Profile:
    """Brent's method on ``z - Z95`` between a point inside and one outside the interval
    (a point without a model solution counts as outside: the search then finds the edge
    of the model's domain)."""

    def g(c: float) -> float:
        tries = search.tries
        z = search.z(c)
        value = z - Z95 if np.isfinite(z) else Z95
        if search.tries > tries and abs(value) < PROFILE_TOL or search.tries >= PROFILE_STEPS:
            raise _Stop
        return value

    try:
        c = optimize.brentq(g, inside, outside, xtol=BOUND_TOL * sd, maxiter=PROFILE_STEPS)
    except _Stop:
        c = min(search.known, key=lambda p: abs(p[1] - Z95))[0]
    return search.result(c)
