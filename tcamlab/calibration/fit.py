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

__all__ = ["CHI2_95", "MapFit", "Profile", "map_fit", "laplace_covariance", "profile_interval"]

CHI2_95 = 3.841458820694124
"""95 % quantile of chi-square with one degree of freedom."""

Z95 = 1.959963984540054
"""sqrt(CHI2_95): the signed-root target of the profile search."""

PROFILE_TOL = 0.02
"""Stop the profile search when the signed root is within this of :data:`Z95`."""

PROFILE_STEPS = 8
"""Most profile evaluations per side of an interval."""


@dataclass
class MapFit:
    """The MAP point: fitted coordinates ``u``, penalised chi-square and optimiser status."""

    u: np.ndarray
    chi2: float
    nfev: int
    message: str


@dataclass
class Profile:
    """One side's result: the bound in fitted coordinates, the points tried, and whether the
    bound is open (the box was reached before chi-square rose by CHI2_95)."""

    bound: float
    points: list[tuple[float, float]]
    open: bool


def _solve(
    problem: CalibrationProblem, u_start: np.ndarray, free: list[int]
) -> tuple[np.ndarray, float, int]:
    """Minimise chi2 over the ``free`` coordinates from ``u_start``; the rest stay fixed."""
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
        return problem.jacobian(v, free)

    x0 = np.clip(u[free], lo[free] + 1e-12, hi[free] - 1e-12)
    sol = optimize.least_squares(
        fun,
        x0,
        jac=jac,
        bounds=(lo[free], hi[free]),
        x_scale=problem.sd_u[free],
        method="trf",
        xtol=1e-8,
        ftol=1e-10,
        gtol=1e-10,
        max_nfev=100,
    )
    u[free] = sol.x
    return u, float(2 * sol.cost), int(sol.nfev)


def map_fit(problem: CalibrationProblem) -> MapFit:
    """The maximum a posteriori point from the stated values."""
    free = list(range(len(problem.specs)))
    u, chi2, nfev = _solve(problem, problem.u0, free)
    return MapFit(u, chi2, nfev, "ok")


def laplace_covariance(problem: CalibrationProblem, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Posterior covariance of ``u`` (Gauss-Newton, priors included) and the data-only Jacobian."""
    jac = problem.jacobian(u)
    cov = np.linalg.pinv(jac.T @ jac)
    return cov, jac[: problem.size]


def profile_interval(problem: CalibrationProblem, fit: MapFit, cov: np.ndarray, k: int, side: int) -> Profile:
    """One side (``side`` = -1 or +1) of the 95 % profile interval of parameter ``k``.

    Secant search on the signed root ``z(c) = sqrt(chi2_profile(c) - chi2_min)``,
    nearly linear in ``c``; every profile point re-optimises the other parameters
    from the Laplace conditional mean.
    """
    lo, hi = problem.bounds()
    edge = hi[k] if side > 0 else lo[k]
    sd = float(np.sqrt(max(cov[k, k], 1e-16)))
    free = [m for m in range(len(fit.u)) if m != k]
    step = Z95 * sd
    points: list[tuple[float, float]] = []
    for _ in range(PROFILE_STEPS):
        c = fit.u[k] + side * step
        at_edge = side * (c - edge) >= 0
        c = edge if at_edge else c
        start = fit.u + cov[:, k] / cov[k, k] * (c - fit.u[k])
        start[k] = c
        _, chi2, _ = _solve(problem, start, free)
        z = float(np.sqrt(max(chi2 - fit.chi2, 0.0)))
        points.append((c, z))
        if abs(z - Z95) < PROFILE_TOL or (at_edge and z < Z95):
            return Profile(c, points, bool(at_edge and z < Z95 - PROFILE_TOL))
        ratio = Z95 / z if z > 0 else 4.0
        step = abs(c - fit.u[k]) * min(max(ratio, 0.25), 4.0)
    return Profile(points[-1][0], points, False)
