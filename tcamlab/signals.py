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
    "LINEAR_BETWEEN_ROWS",
    "clock",
    "first_order_lag",
    "mad_scale",
    "moving_average",
    "rolling_median",
    "second_difference_sigma",
    "robust_second_difference_sigma",
    "step_rows",
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


LINEAR_BETWEEN_ROWS = "inputs_between_rows"
"""``DataFrame.attrs`` key of a frame whose inputs are straight lines between its rows, not
held (the value ``"linear"``): the reduction's grid of a long log (:mod:`tcamlab.reduction`),
where a time filter of an input must not see a step at every grid row."""


def first_order_lag(
    x: np.ndarray,
    t: np.ndarray,
    tau: float,
    conductance_tc: float = 0.0,
    reference: float = 0.0,
    hold: str = "end",
) -> np.ndarray:
    """First-order lag of a sampled signal: y' = (x - y) / tau.

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
    hold : {"end", "midpoint"}
        What x does between samples: ``"end"`` holds each sample's value over the interval
        before it (an oven stepped to its next set point and read after the dwell);
        ``"midpoint"`` holds the interval's mean, the second-order rule for an x that runs
        straight between samples (the reduction's grid of a long log, whose rows are up to
        64 apart: ``"end"`` there would lead the input by half a grid step, and a lag
        fitted on the grid came out 0.03 s longer than on every row).

    Notes
    -----
    With x held, u = x - y obeys the logistic equation u' = -(a u - b u^2) / tau,
    a = 1 + gamma (x - reference), b = gamma / 2, whose exact solution over a step
    dt is u a E / (a - b u (1 - E)), E = exp(-a dt / tau): no step-size error.
    """
    if tau <= 0:
        return x
    held = np.asarray(x, float)
    if hold == "midpoint":
        held = np.concatenate((held[:1], 0.5 * (held[1:] + held[:-1])))
    out = np.empty_like(held)
    out[0] = held[0]
    dt = np.diff(t)
    b = 0.5 * conductance_tc  # gamma = 0: a = 1, b = 0, the one-tau lag u E
    for k in range(1, held.size):
        u = held[k] - out[k - 1]
        # Floor: the coefficient must stay positive far below the reference (not physical there).
        a = max(0.05, 1.0 + conductance_tc * (held[k] - reference))
        decay = math.exp(-a * dt[k - 1] / tau)
        den = a - b * u * (1.0 - decay)
        out[k] = held[k] - (u * a * decay / den if den > 0.0 else u * decay)
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


def second_difference_sigma(r, skip=None) -> float:
    """Noise sd of a series from its second differences (robust to smooth trends).

    sigma^2 = sum((r[i+1] - 2 r[i] + r[i-1])^2) / (6 (n - 2)), over the centres i not in
    ``skip`` (a boolean mask over the rows, True: leave that row's second difference out).
    """
    r = np.asarray(r, float)
    if r.size < 3:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    if skip is not None and np.size(skip) == r.size and np.any(skip):
        d2 = d2[~np.asarray(skip, bool)[1:-1]]
        if d2.size == 0:
            return float("nan")
    return float(math.sqrt(np.sum(d2 * d2) / (6.0 * d2.size)))


def robust_second_difference_sigma(r) -> float:
    """Noise sd of a series from the median absolute second difference (robust to steps and
    outliers as well as smooth trends; NaN rows dropped, NaN when fewer than 3 remain).

    sigma = 1.4826 median(|r[i+1] - 2 r[i] + r[i-1]|) / sqrt(6): a second difference of white
    noise has variance 6 sigma^2, and 1.4826 MAD is a normal sd.
    """
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    if r.size < 3:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    return 1.4826 * float(np.median(np.abs(d2))) / math.sqrt(6.0)


def step_rows(columns) -> np.ndarray:
    """Rows next to a step of a piecewise-constant column (a commanded voltage), True.

    A column is piecewise constant where most of its rows repeat the row before
    (:data:`STEP_FLAT_SHARE`); the two rows either side of each change are marked. A residual
    jumps there by whatever the model misses of the step response, which is not noise: a
    voltage-step test's current, 30 mA off at the end of a pulse, read 14 times its sense's
    noise from second differences taken across the pulse's edges."""
    cols = [np.asarray(c, float) for c in columns]
    n = cols[0].size if cols else 0
    out = np.zeros(n, bool)
    for c in cols:
        if c.size < 3:
            continue
        moved = np.diff(c) != 0
        if np.mean(~moved) < STEP_FLAT_SHARE:
            continue
        at = np.flatnonzero(moved)
        out[at] = True
        out[at + 1] = True
    return out


STEP_FLAT_SHARE = 0.9
"""Share of a column's rows equal to the row before for it to count as piecewise constant."""


FRAME_MIN_EDGES = 20
"""Fewest frame edges for a column to count as a slower instrument's reading."""
FRAME_REGULARITY = 0.8
"""Share of the spacings between frame edges that must be a whole number of frames (within
:data:`FRAME_JITTER`): a camera's or a meter's frames come on its own clock; a slowly moving
reading of a coarse converter changes where the signal crosses a step, irregularly."""
FRAME_JITTER = 0.25
"""How far a spacing between frame edges may be from a whole number of frames [frames]: a
25 Hz camera's time stamps jittering by +-5 ms on a 1 kHz log move its edges by up to a
quarter of a frame."""
WITHIN_FRAME = 0.95
"""Share of the rows inside frames whose first (held) or second (interpolated) difference is
within two steps of the column's resolution: a slower instrument adds nothing in between."""
SMOOTHING_FRAMES = (32, 16, 8, 4)
"""Frames a slower instrument's reading is averaged over, the longest first
(:func:`smooth_slow_input`)."""


def instrument_frames(x) -> tuple[int, np.ndarray]:
    """Rows per frame of a slower instrument's reading joined onto a faster log, and the
    first row of each frame.

    A thermal camera at 25 Hz joined onto a 1 kHz laser log holds each frame for 40 rows (a
    staircase: the first difference is zero inside a frame) or is interpolated between its
    frames (straight lines: the second difference is zero inside a frame). A frame edge is
    a row whose first (then second) difference is more than 8 times the median's size;
    the edges of a slower instrument are many and evenly spaced (:data:`FRAME_REGULARITY`),
    and the rows between them carry none of its noise (:data:`WITHIN_FRAME`).

    Parameters
    ----------
    x : array_like
        The logged column [any unit].

    Returns
    -------
    (int, ndarray)
        Rows per frame (1: every row is its own reading) and the frames' first rows
        (empty when 1).
    """
    x = np.asarray(x, float)
    if x.size < 10 * FRAME_MIN_EDGES:
        return 1, np.zeros(0, int)
    # within a frame the differences are zero to the last digit written
    digit = max(2.0 * resolution(x), 1e-12 * max(float(np.max(np.abs(x))), 1e-300))
    for order in (1, 2):
        d = np.abs(np.diff(x, order))
        edges = np.flatnonzero(d > max(8.0 * float(np.median(d)), digit))
        # an interpolated frame whose time falls between two rows bends the line at both
        edges = edges[np.diff(edges, prepend=-2) > 1]
        if edges.size < FRAME_MIN_EDGES:
            continue
        gaps = np.diff(edges)
        first = float(np.median(gaps))
        if first < 2:
            continue
        # a frame clock beating against the log's (39 and 41 rows for 40) averages out
        frames = gaps / (np.sum(gaps) / max(float(np.sum(np.round(gaps / first))), 1.0))
        period = int(round(float(np.sum(gaps) / np.sum(np.round(frames)))))
        if np.mean(np.abs(frames - np.round(frames)) <= FRAME_JITTER) < FRAME_REGULARITY:
            continue
        # a slower instrument adds nothing between its frames (held: equal rows; interpolated:
        # a straight line, to the logged digits); a stepped test (a pull held at each step)
        # has the same regular edges but its meter's noise on every row
        inside = np.delete(d, edges)
        if np.mean(inside <= digit) >= WITHIN_FRAME:
            return period, _every_frame(np.concatenate(([0], edges + 1)), period)
    return 1, np.zeros(0, int)


def _every_frame(starts: np.ndarray, period: int) -> np.ndarray:
    """Frame starts with the frames no edge shows put back, evenly within their gap: two
    frames read alike (held) or a frame on the line of its neighbours (interpolated) make no
    edge, and leaving them out would keep only the frames that moved (a frame noise 3.5 %
    high on a 0.5 degC camera written to 0.1 degC)."""
    gaps = np.diff(starts)
    n = np.maximum(np.round(gaps / period), 1).astype(np.int64)
    first = np.repeat(starts[:-1], n)
    step = np.repeat(gaps / n, n)
    j = np.arange(first.size) - np.repeat(np.cumsum(n) - n, n)
    return np.append(first + np.round(j * step).astype(np.int64), starts[-1])


def frame_noise(frames) -> float:
    """Noise sd of a slower instrument's frame values [their unit]: their second differences'
    root mean square over 6, leaving out those beyond 5 sds of a first, median-based guess (a
    real step of the input; the median alone moves in whole digits of a coarsely written
    reading: 0.545 for every 0.5 degC camera written to 0.1 degC)."""
    d2 = np.diff(np.asarray(frames, float), 2)
    if d2.size == 0:
        return float("nan")
    guess = mad_scale(d2)
    kept = d2[np.abs(d2) <= 5.0 * guess] if guess > 0 else d2
    return math.sqrt(float(np.mean(kept**2)) / 6.0)


NOISE_FRAMES = 100
"""Fewest frames from which a slower instrument's frame-to-frame changes can be told from a
pattern of its own (:func:`frames_look_like_noise`)."""
NOISE_FLATNESS = 1.5
"""Largest ratio between the frames' second-difference variances at lags of 1 to 4 frames."""


def frames_look_like_noise(frames) -> bool:
    """Whether a slower instrument's frame-to-frame changes are noise about a smooth course.

    Second differences at a lag of ``L`` frames, ``f[i+L] - 2 f[i] + f[i-L]``, have variance
    ``6 sd**2`` at every lag for noise on a straight (or gently curved) course. A pattern of
    the input itself (a drive stepped at every frame, or every other) makes them differ by
    lag: an alternation has none at lag 2; two frames high, two low, four times as much at
    lag 2 as at lag 1. Such an input is a signal and is never averaged. The variances at
    lags 1 to 4 must agree within :data:`NOISE_FLATNESS`, over at least
    :data:`NOISE_FRAMES` frames.
    """
    f = np.asarray(frames, float)
    if f.size < NOISE_FRAMES:
        return False
    v = [float(np.mean((f[2 * k :] - 2.0 * f[k:-k] + f[: -2 * k]) ** 2)) for k in (1, 2, 3, 4)]
    return min(v) > 0 and max(v) <= NOISE_FLATNESS * min(v)


def resolution(x) -> float:
    """The smallest step between the distinct values of a logged column [its unit]: the last
    digit it was written with (above the float rounding of parsing it)."""
    x = np.asarray(x, float)
    u = np.unique(x)
    gaps = np.diff(u)
    gaps = gaps[gaps > 1e-9 * max(float(np.max(np.abs(u))), 1e-300)]
    return float(gaps.min()) if gaps.size else 0.0


def frame_average(x, window: int) -> np.ndarray:
    """Centred moving average over ``window`` rows (made odd); within half a window of either
    end, the least-squares line over the first (last) ``window`` rows, so that a trend is
    not bent at the ends (a static log is referred to its first row).

    Parameters
    ----------
    x : array_like
        The signal [any unit].
    window : int
        Rows averaged [-].
    """
    x = np.asarray(x, float)
    n = x.size
    h = min(int(window) // 2, (n - 1) // 2)
    if h < 1:
        return x.copy()
    w = 2 * h + 1
    c = np.concatenate(([0.0], np.cumsum(x - x[0])))
    out = np.empty(n)
    out[h : n - h] = x[0] + (c[w:] - c[:-w]) / w
    t = np.arange(w, dtype=float)
    head = np.polyfit(t, x[:w], 1)
    tail = np.polyfit(t, x[n - w :], 1)
    out[:h] = np.polyval(head, t[:h])
    out[n - h :] = np.polyval(tail, t[w - h :])
    return out


def smooth_slow_input(x) -> tuple[np.ndarray, dict | None]:
    """A slower instrument's reading, averaged over whole frames for a model to read.

    A model reading a noisy input ``x`` turns its noise into a residual ``f'(x) e``. Where
    every row is its own reading, that residual is white and the noise floor (second
    differences) sees it. A slower instrument's noise is held (or interpolated) over a
    frame of many rows: second differences miss it, the residual looks like a misfit, and
    an effect that smooths the input over time (a thermal lag) explains it. Averaged over
    ``K`` frames, the noise left is ``sd / sqrt(K)``; ``K`` is the longest of
    :data:`SMOOTHING_FRAMES` over which the input's change stays below that noise (the
    average over ``K`` frames departs from the one over ``K/2`` by no more than 1.5 times
    the ``sd / sqrt(K)`` that noise alone gives).

    Parameters
    ----------
    x : array_like
        The logged column [any unit].

    Returns
    -------
    (ndarray, dict or None)
        The column the models read, and ``{"rows_per_frame", "frames", "window_rows",
        "frame_sd"}`` (``frame_sd`` in the column's unit: the frame values' second-difference
        noise), or ``(x, None)`` where the column is not a slower instrument's or changes too
        fast to average.
    """
    x = np.asarray(x, float)
    period, starts = instrument_frames(x)
    if period < 2:
        return x, None
    sd = frame_noise(x[starts])
    if not (np.isfinite(sd) and sd > 0 and frames_look_like_noise(x[starts])):
        return x, None
    for k in SMOOTHING_FRAMES:
        if k * period > x.size // 4:
            continue
        full, half = frame_average(x, k * period), frame_average(x, k * period // 2)
        if float(np.sqrt(np.mean((full - half) ** 2))) <= 1.5 * sd / math.sqrt(k):
            info = {"rows_per_frame": period, "frames": k, "window_rows": k * period, "frame_sd": sd}
            return full, info
    return x, None


def block_means(z, n_parts: int, block: int) -> np.ndarray:
    """A stacked residual vector (``n_parts`` equal parts) averaged over blocks of ``block``
    rows of each part, times sqrt(rows in the block): white noise keeps its variance per
    element, a misfit constant over a block keeps its sum of squares, and the noise's share of
    the sum falls ``block``-fold (a last, shorter block is averaged over its own rows).

    Fitting these instead of the rows keeps a fit from buying a smaller residual by shrinking
    the gain through which an input's white noise reaches an output (errors in variables)."""
    out = []
    for part in np.split(np.asarray(z, float), n_parts):
        edges = np.arange(0, part.size, block)
        if part.size == 0:
            out.append(part)
            continue
        counts = np.diff(np.append(edges, part.size))
        out.append(np.add.reduceat(part, edges) / np.sqrt(counts))
    return np.concatenate(out) if out else np.asarray(z, float)


def n_blocks(rows: int, block: int) -> int:
    """Blocks of :func:`block_means` in a part of ``rows`` rows."""
    return -(-rows // block) if block > 1 else rows
