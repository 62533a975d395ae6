"""Small operations on logged signals shared by the kinds, the diagnosis and fitting.

Pure numpy, no files: a run's clock, a first-order lag, moving averages,
the time spent in the current dwell of a stepped test, and the unloading
branch of a pull test.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from tcamlab.errors import InputError

__all__ = [
    "clock",
    "first_order_lag",
    "mad_scale",
    "moving_average",
    "rolling_median",
    "second_difference_sigma",
    "split_branches",
    "time_in_dwell",
    "unloading_mask",
]


def clock(data: pd.DataFrame) -> np.ndarray:
    """Time from the first row [s], or the sample index where there is no ``time`` column."""
    if "time" in data:
        t = data["time"].to_numpy(float)
        return t - t[0]
    return np.arange(len(data), dtype=float)


def first_order_lag(
    x: np.ndarray, t: np.ndarray, tau: float, conductance_tc: float = 0.0, reference: float = 0.0
) -> np.ndarray:
    """First-order lag of a stepwise signal: y' = (x - y) / tau, x held between samples.

    Parameters
    ----------
    x : ndarray
        The driving signal, e.g. the oven temperature [any unit].
    t : ndarray
        Sample times [s] (or sample indices when ``tau`` is in samples).
    tau : float
        Time constant at ``reference`` [s]; ``tau <= 0`` returns ``x`` unchanged.
    conductance_tc : float
        gamma of a heat-transfer coefficient h (1 + gamma (T_film - reference)) that
        grows with the film temperature T_film = (y + x) / 2 (convection and radiation
        both do): y' = (x - y) (1 + gamma (T_film - reference)) / tau [1/unit of x].
        0: one time constant.
    reference : float
        Temperature at which the time constant is ``tau`` [unit of x].

    Notes
    -----
    With x held, u = x - y obeys the logistic equation u' = -(a u - b u^2) / tau,
    a = 1 + gamma (x - reference), b = gamma / 2, whose exact solution over a step
    dt is u a E / (a - b u (1 - E)), E = exp(-a dt / tau): no step-size error.
    """
    if tau <= 0:
        return x
    out = np.empty_like(x, dtype=float)
    out[0] = x[0]
    dt = np.diff(t)
    b = 0.5 * conductance_tc  # gamma = 0: a = 1, b = 0, the one-tau lag u E
    for k in range(1, x.size):
        u = x[k] - out[k - 1]
        # Floor: the coefficient must stay positive far below the reference (not physical there).
        a = max(0.05, 1.0 + conductance_tc * (x[k] - reference))
        decay = math.exp(-a * dt[k - 1] / tau)
        den = a - b * u * (1.0 - decay)
        out[k] = x[k] - (u * a * decay / den if den > 0.0 else u * decay)
    return out


def moving_average(x: np.ndarray, k: int) -> np.ndarray:
    """Centred moving average over ``k`` samples, edges padded with the end values."""
    k = max(1, min(int(k), x.size))
    if k <= 1:
        return x.astype(float)
    pad = np.pad(x.astype(float), (k // 2, k - 1 - k // 2), mode="edge")
    return np.convolve(pad, np.ones(k) / k, mode="valid")


def time_in_dwell(resistance: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Time since the last step of a stepped pull test, from jumps in resistance [s].

    A step is a jump larger than 8 times the median absolute jump (the
    dwell's noise), so the dwells of any step size are found.
    """
    jumps = np.abs(np.diff(resistance))
    scale = np.median(jumps) if jumps.size else 0.0
    thresh = max(8.0 * scale, 1e-12)
    step_rows = np.concatenate(([0], np.flatnonzero(jumps > thresh) + 1))
    last = np.zeros(resistance.size, dtype=int)
    last[step_rows] = step_rows
    last = np.maximum.accumulate(last)
    return t - t[last]


MAD_TO_SD = 1.482602218505602
"""Median absolute deviation to standard deviation for normal data."""


def mad_scale(r: np.ndarray) -> float:
    """Robust standard deviation of ``r``: 1.4826 times its median absolute deviation."""
    return MAD_TO_SD * float(np.median(np.abs(r - np.median(r))))


def rolling_median(x: np.ndarray, window: int) -> np.ndarray:
    """Centred rolling median, the window shrinking at the ends."""
    return pd.Series(x).rolling(window, center=True, min_periods=1).median().to_numpy()


def _turning_point(x: np.ndarray, window: int) -> int | None:
    """Last row of the top plateau of a rise-and-fall signal, or None when it does not fall back."""
    n = x.size
    w = max(1, int(window))
    w = w + 1 if w % 2 == 0 else w
    w = min(w, n if n % 2 == 1 else n - 1)
    smooth = rolling_median(x, w)
    noise = mad_scale(x - smooth)
    span = float(np.ptp(smooth))
    tol = max(5.0 * noise, 1e-3 * span, np.finfo(float).tiny)

    i_max = int(np.argmax(smooth))
    top = smooth[i_max]
    below = np.flatnonzero(smooth[i_max:] < top - tol)
    # end of the top plateau: last sample before the first clear drop
    i_end = i_max + int(below[0]) - 1 if below.size else n - 1
    before = np.flatnonzero(smooth[:i_max] < top - tol)
    i_start = int(before[-1]) + 1 if before.size else 0
    if below.size and i_end - i_start < w:
        # a sharp peak, not a dwell: the median flattens it over ~w samples,
        # so put the turning point at the raw maximum near the flat top
        lo = max(0, i_start - w // 2)
        i_end = lo + int(np.argmax(x[lo : i_end + 1]))
    after = n - 1 - i_end
    drop = top - float(smooth[i_end + 1 :].min()) if after > 0 else 0.0
    return None if after < 3 or drop < tol else i_end


def split_branches(displacement, time=None, *, window: int = 5) -> dict[str, np.ndarray]:
    """Boolean masks of the loading and unloading branches of a pull test.

    A pull test raises the displacement (possibly in steps with dwells) and
    may lower it again. The displacement is smoothed by a centred rolling
    median of ``window`` samples (kills spikes); the loading branch runs to
    the *end* of the top plateau (all samples within a noise tolerance of
    the maximum that are contiguous with it), the unloading branch is
    everything after it. A top "plateau" shorter than the window is a sharp
    peak flattened by the median; the turning point is then the raw maximum
    near it. The tolerance is 5 robust noise sds (MAD of the
    raw minus smoothed signal), at least 1e-3 of the displacement range.

    There is no unloading branch when fewer than 3 samples follow the top
    plateau or the smoothed displacement drops by less than the tolerance
    after it; then only ``{"loading": all True}`` is returned.

    Parameters
    ----------
    displacement : array_like
        Displacement log [any length unit], in time order unless ``time``
        is given.
    time : array_like, optional
        Sample times; when given the samples are put in time order first
        (the masks refer to the original sample order).
    window : int
        Rolling-median window [samples], made odd.

    Returns
    -------
    dict of str to ndarray of bool
        ``{"loading": mask}`` or ``{"loading": mask, "unloading": mask}``;
        the masks are disjoint and cover every sample.

    Raises
    ------
    InputError
        Empty or non-finite displacement, or ``time`` of another length or
        non-finite.
    """
    x = np.asarray(displacement, dtype=float).ravel()
    n = x.size
    if n == 0:
        raise InputError("split_branches: displacement is empty", "pass the displacement log")
    if not np.all(np.isfinite(x)):
        raise InputError(
            "split_branches: displacement contains non-finite values",
            "drop or interpolate missing samples first",
        )
    order = np.arange(n)
    if time is not None:
        t = np.asarray(time, dtype=float).ravel()
        if t.size != n or not np.all(np.isfinite(t)):
            raise InputError(
                f"split_branches: time has {t.size} values (or non-finite ones) for {n} displacements",
                "pass one finite time per displacement sample",
            )
        order = np.argsort(t, kind="stable")
        x = x[order]

    loading = np.ones(n, dtype=bool)
    if n < 4:
        return {"loading": loading}

    i_end = _turning_point(x, window)
    if i_end is None:
        return {"loading": loading}
    in_order = np.arange(n) <= i_end
    loading = np.empty(n, dtype=bool)
    loading[order] = in_order
    return {"loading": loading, "unloading": ~loading}


def unloading_mask(x: np.ndarray) -> np.ndarray:
    """Rows of the unloading branch of a pull test (:func:`split_branches`); none if there is none.

    Works on any signal that rises with the elongation and falls back with it
    (displacement, or a sensor's resistance).
    """
    return split_branches(x).get("unloading", np.zeros(np.asarray(x).size, dtype=bool))


def second_difference_sigma(r) -> float:
    """Noise sd of a series from its second differences (robust to smooth trends).

    sigma^2 = sum((r[i+1] - 2 r[i] + r[i-1])^2) / (6 (n - 2)).
    """
    r = np.asarray(r, float)
    if r.size < 3:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    return float(math.sqrt(np.sum(d2 * d2) / (6.0 * (r.size - 2))))
