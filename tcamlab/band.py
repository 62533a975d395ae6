"""Prediction bands for measured points: parameter draws, the model, the noise and the zero.

A measured point of a zero-referenced quantity is modelled as

    y(t) = f(t; theta) + z + e(t),

the model at the true parameters ``theta``, the run's zero ``z`` (estimated
from the rest rows, known to ``zero_sd``) and noise ``e`` of sd ``sigma`` (the
noise floor). The band draws ``theta`` from a :class:`ParameterDistribution`,
runs the model once per draw (``f_k``), and takes at every time the central
interval of the mixture ``(1/K) sum_k N(f_k(t) + z, sigma^2 + zero_sd^2)``,
solved exactly for the K draws (no noise is sampled, so the band is smooth).

Where the parameters come from decides what the band is called:

* a calibrated file (``[calibration]``, :class:`tcamlab.config.CalibratedJoint`):
  the joint posterior, Gaussian with its correlations in the coordinates the
  calibration fits (``log`` for positive parameters) -- a **prediction band**;
* otherwise the stated sds (``[rig.uncertainty]``, ``[sample.uncertainty]``),
  drawn independently (log-normal with the stated mean and sd for a positive
  value) -- a **stated-uncertainty band (parameters not calibrated)**. Its
  parameter part is not a posterior, so its coverage is no test of the model.

Coverage is reported over all rows and over the *informative* rows, where the
parameter part of the band is at least :data:`INFORMATIVE_RATIO` of the noise
part (elsewhere the band is the noise band and covers ~95 % whatever the
parameters). On a long log the model runs on a decimated grid and the band is
interpolated onto the rows (:func:`band_grid`).

Everything here is pure numpy/scipy; the model runs are the caller's
(:mod:`tcamlab.kinds.dynamic`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import special

__all__ = [
    "NOMINAL",
    "MAX_GRID_POINTS",
    "MAX_GRID_STEP_S",
    "INFORMATIVE_RATIO",
    "PREDICTION_LABEL",
    "STATED_LABEL",
    "ParameterDistribution",
    "from_calibration",
    "from_stated",
    "band_grid",
    "draws_for",
    "rest_zero",
    "mixture_interval",
    "mixture_quantile",
    "parameter_interval",
    "informative_rows",
    "coverage",
    "band_label",
]

NOMINAL = 0.95
"""Nominal coverage of the band [-]."""

MAX_GRID_POINTS = 5000
"""Most rows the model runs on per draw; a longer log is decimated (plus every input change)."""

MAX_GRID_STEP_S = 0.2
"""Widest spacing of the decimated grid [s]. The dynamic kernel's Monte Carlo on a coarser
grid (2 s on a 10-million-row 1 kHz log with 5000 points) left the model's domain for
every draw, the nominal one included, while every row of the same log stays inside; at
0.2 s it matches. A longer log therefore keeps more than :data:`MAX_GRID_POINTS` rows."""

INFORMATIVE_RATIO = 0.5
"""A row is informative when the parameter part's half-width is at least this times the
noise part's (z * sqrt(sigma^2 + zero_sd^2)) [-]."""

DRAW_SECONDS = 200_000.0
"""Budget of draws x simulated seconds per run [s] (about 5 s of integration on a 2-core
machine); a longer log gets fewer draws, never fewer than :data:`MIN_DRAWS`."""

MIN_DRAWS = 100
"""Fewest draws on a long log [-]."""

PREDICTION_LABEL = "prediction band"
"""Label of a band drawn from a calibrated joint distribution."""

STATED_LABEL = "stated-uncertainty band (parameters not calibrated)"
"""Label of a band drawn independently from the stated sds."""

BISECTION_TOL = 1e-4
"""Stop the mixture-quantile search when its step is this fraction of the spread sd [-]."""


@dataclass(frozen=True)
class ParameterDistribution:
    """A Gaussian distribution of parameters in fitted coordinates.

    Attributes
    ----------
    fields : tuple of (str, str)
        ``("rig" or "sample", SI field)`` of each parameter.
    log : tuple of bool
        Coordinate of each: ``log(value)`` (True) or the value [SI].
    mean : ndarray
        Mean in the fitted coordinates.
    covariance : ndarray
        Covariance in the fitted coordinates.
    calibrated : bool
        From a calibration's joint posterior (True) or independent stated sds.
    description : str
        How it was made, for reports.
    below, above : ndarray or None
        Sds below and above the mean (split-normal marginals, e.g. from profile
        intervals); the covariance then only gives the correlations. None: normal.
    """

    fields: tuple[tuple[str, str], ...]
    log: tuple[bool, ...]
    mean: np.ndarray
    covariance: np.ndarray
    calibrated: bool
    description: str
    below: np.ndarray | None = None
    above: np.ndarray | None = None

    def draw(self, n: int, rng: np.random.Generator) -> dict[tuple[str, str], np.ndarray]:
        """``n`` parameter vectors, {(where, field): ndarray of n} [SI].

        Correlated normal draws in the fitted coordinates (eigen-decomposition,
        so a singular covariance is fine), mapped back with ``exp`` for log ones.
        With ``below``/``above`` the correlated standard normals are scaled by
        the sd of their side (a Gaussian copula with split-normal marginals).
        """
        k = len(self.fields)
        if self.below is None:
            u = rng.multivariate_normal(self.mean, self.covariance, size=n, method="eigh")
        else:
            sd = np.sqrt(np.clip(np.diag(self.covariance), 1e-300, None))
            corr = self.covariance / np.outer(sd, sd)
            z = rng.multivariate_normal(np.zeros(k), corr, size=n, method="eigh").reshape(n, k)
            u = self.mean + np.where(z < 0, z * self.below, z * self.above)
        u = np.asarray(u).reshape(n, k)
        return {
            f: (np.exp(u[:, i]) if lg else u[:, i]) for i, (f, lg) in enumerate(zip(self.fields, self.log))
        }


def from_calibration(joint, values: Mapping[tuple[str, str], float]) -> ParameterDistribution:
    """The joint posterior of a calibrated experiment file.

    Parameters
    ----------
    joint : tcamlab.config.CalibratedJoint
        The file's ``[calibration]`` table.
    values : mapping
        {(where, field): calibrated value [SI]}, the centre (MAP).

    Returns
    -------
    ParameterDistribution
        ``calibrated=True``; mean ``log(value)`` (log) or ``value``.
    """
    mean = np.array(
        [math.log(values[f]) if lg else float(values[f]) for f, lg in zip(joint.fields, joint.log)]
    )
    if joint.sd_below is None:
        how = "Gaussian with the Laplace sds and correlations"
        below = above = None
    else:
        how = (
            "Laplace correlations, each marginal split-normal with the sds of its "
            "profile-likelihood 95% interval below and above the value"
        )
        below, above = np.asarray(joint.sd_below, float), np.asarray(joint.sd_above, float)
    return ParameterDistribution(
        tuple(joint.fields),
        tuple(joint.log),
        mean,
        joint.covariance(),
        True,
        f"calibrated joint posterior ([calibration]): {how}, in log for positive parameters",
        below,
        above,
    )


def from_stated(stated: Mapping[tuple[str, str], tuple[float, float]]) -> ParameterDistribution | None:
    """Independent draws from stated sds.

    Parameters
    ----------
    stated : mapping
        {(where, field): (value, sd)} [SI]; entries with sd 0 are left out.

    Returns
    -------
    ParameterDistribution or None
        ``calibrated=False``. A positive value is log-normal with the stated mean
        and sd (moment-matched: s^2 = ln(1 + (sd/value)^2), mean ln(value) - s^2/2),
        so it stays positive although lambda's stated sd exceeds its value;
        otherwise normal. None when no sd is positive.
    """
    fields, log, mean, var = [], [], [], []
    for f, (value, sd) in stated.items():
        if not sd > 0:
            continue
        lg = value > 0
        s2 = math.log1p((sd / value) ** 2) if lg else sd * sd
        fields.append(f)
        log.append(lg)
        mean.append(math.log(value) - s2 / 2 if lg else value)
        var.append(s2)
    if not fields:
        return None
    return ParameterDistribution(
        tuple(fields),
        tuple(log),
        np.array(mean),
        np.diag(var),
        False,
        "stated sds drawn independently (log-normal with the stated mean and sd for positive values)",
    )


def band_grid(
    time: np.ndarray,
    inputs: np.ndarray,
    max_points: int = MAX_GRID_POINTS,
    max_step: float = MAX_GRID_STEP_S,
) -> tuple[np.ndarray, bool]:
    """Rows the model runs on: all of them, or a decimated subset on a long log.

    Parameters
    ----------
    time : ndarray
        Row times [s], increasing.
    inputs : ndarray
        A held input (voltage [V]); every row where it changes is kept, so the
        input held on the grid is the log's exactly.
    max_points : int
        Rows kept besides the input changes (evenly spaced, first and last included),
        more where the log is longer than ``max_points * max_step``.
    max_step : float
        Widest spacing of the evenly spaced rows [s] (:data:`MAX_GRID_STEP_S`).

    Returns
    -------
    (ndarray of int, bool)
        Sorted row indices, and whether the grid is decimated (band interpolated).
    """
    n = len(time)
    if n > 1 and max_step > 0:
        duration = float(time[-1] - time[0])
        max_points = max(max_points, int(math.ceil(duration / max_step)) + 1)
    if n <= max_points:
        return np.arange(n), False
    even = np.unique(np.linspace(0, n - 1, max_points).round().astype(int))
    changes = np.flatnonzero(np.diff(inputs) != 0) + 1
    return np.union1d(even, changes), True


def draws_for(duration: float, requested: int) -> int:
    """Draws for a run of ``duration`` [s]: ``requested``, cut to the :data:`DRAW_SECONDS`
    budget on a long log (the integration grows with the simulated time), at least
    :data:`MIN_DRAWS` (or ``requested`` if fewer)."""
    if duration <= 0:
        return requested
    return min(requested, max(MIN_DRAWS, int(DRAW_SECONDS / duration)))


def rest_zero(
    residual: np.ndarray, rest: np.ndarray, sigma: float, zero_sd: float | None = None
) -> tuple[float, float, int]:
    """A run's zero from its rest rows and its sd.

    Parameters
    ----------
    residual : ndarray
        Measured - predicted of every row [SI].
    rest : ndarray of bool
        Rest rows (before the input first acts; the zeroing row left out).
    sigma : float
        Noise sd [SI].
    zero_sd : float, optional
        Sd of the zero when known otherwise (a nuisance estimated elsewhere).

    Returns
    -------
    (float, float, int)
        The zero (mean residual of the rest rows, 0 without any) [SI]; its sd:
        ``zero_sd``, else sigma / sqrt(n), else sigma (a log zeroed on one reading) [SI];
        the number of rest rows.
    """
    n = int(np.count_nonzero(rest))
    zero = float(np.mean(residual[rest])) if n else 0.0
    if zero_sd is None:
        zero_sd = sigma / math.sqrt(n) if n else sigma
    return zero, float(zero_sd), n


def mixture_interval(
    centres: np.ndarray, spread: float | np.ndarray, level: float = NOMINAL
) -> tuple[np.ndarray, np.ndarray]:
    """Central interval of an equal-weight mixture of normals, at every column.

    Parameters
    ----------
    centres : ndarray, shape (K, n)
        Centre of each of the K components at n points [SI].
    spread : float or ndarray of n
        Common sd of the components [SI] (noise and zero), > 0.
    level : float
        Central probability [-].

    Returns
    -------
    (ndarray, ndarray)
        Lower and upper bounds, shape (n,): where the mixture CDF is (1 -+ level) / 2,
        to :data:`BISECTION_TOL` of the spread.
    """
    centres = np.atleast_2d(np.asarray(centres, float))
    s = np.broadcast_to(np.asarray(spread, float), centres.shape[1:])
    if not np.all(s > 0):
        return parameter_interval(centres, level)
    z = float(special.ndtri(0.5 + level / 2))
    mean, sd = centres.mean(axis=0), np.sqrt(centres.var(axis=0) + s * s)
    bracket = (centres.min(axis=0) - (z + 1) * s, centres.max(axis=0) + (z + 1) * s)
    lower = mixture_quantile(centres, s, (1 - level) / 2, mean - z * sd, bracket)
    upper = mixture_quantile(centres, s, (1 + level) / 2, mean + z * sd, bracket)
    return lower, upper


def mixture_quantile(centres, s, p: float, start, bracket, max_iter: int = 60) -> np.ndarray:
    """The ``p`` quantile of the mixture ``(1/K) sum_k N(centres[k], s^2)`` at every column.

    Newton steps from ``start`` (the normal approximation), kept inside a bracket
    that shrinks with every step (bisection where Newton would leave it), until
    the step is below :data:`BISECTION_TOL` * s everywhere [SI].
    """
    lo, hi = (np.array(b, float) for b in bracket)
    x = np.clip(start, lo, hi)
    for _ in range(max_iter):
        u = (x - centres) / s
        cdf = special.ndtr(u).mean(axis=0)
        pdf = np.exp(-0.5 * u * u).mean(axis=0) / (math.sqrt(2 * math.pi) * s)
        below = cdf < p
        lo, hi = np.where(below, x, lo), np.where(below, hi, x)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - (cdf - p) / pdf
        new = np.where((step > lo) & (step < hi), step, (lo + hi) / 2)
        done = np.max(np.abs(new - x) / s) < BISECTION_TOL
        x = new
        if done:
            break
    return x


def parameter_interval(centres: np.ndarray, level: float = NOMINAL) -> tuple[np.ndarray, np.ndarray]:
    """Central ``level`` interval of the model draws alone (the parameter part) [SI], shape (n,)."""
    q = np.quantile(np.atleast_2d(centres), [(1 - level) / 2, (1 + level) / 2], axis=0)
    return q[0], q[1]


def informative_rows(
    parameter_halfwidth: np.ndarray, spread: float | np.ndarray, level: float = NOMINAL
) -> np.ndarray:
    """Rows where the band says something about the parameters.

    Parameters
    ----------
    parameter_halfwidth : ndarray
        Half-width of the parameter part [SI].
    spread : float or ndarray
        Sd of the noise part (noise and zero) [SI].
    level : float
        Nominal level [-].

    Returns
    -------
    ndarray of bool
        parameter half-width >= :data:`INFORMATIVE_RATIO` * z * spread.
    """
    z = float(special.ndtri(0.5 + level / 2))
    return np.asarray(parameter_halfwidth) >= INFORMATIVE_RATIO * z * np.asarray(spread)


def coverage(
    measured: np.ndarray, lower: np.ndarray, upper: np.ndarray, rows: np.ndarray | None = None
) -> float | None:
    """Fraction of measured points inside [lower, upper] over ``rows`` (default all); None if none."""
    inside = (measured >= lower) & (measured <= upper)
    if rows is not None:
        inside = inside[rows]
    return float(np.mean(inside)) if inside.size else None


def band_label(calibrated: bool, level: float = NOMINAL) -> str:
    """``"95% prediction band"`` or ``"95% stated-uncertainty band (parameters not calibrated)"``."""
    return f"{level:.0%} " + (PREDICTION_LABEL if calibrated else STATED_LABEL)
