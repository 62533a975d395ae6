"""A long log's reduced representation for fits: two moments per block of rows.

A 1 kHz log of hours holds millions of rows but far fewer independent pieces of
information about a handful of parameters: between two input changes the model's
prediction is a smooth curve whose shape is set by its time constants, and a block
of rows over which that curve is a straight line to within a fraction of the noise
floor says, about the parameters, only its level and its slope. Fits
(:mod:`tcamlab.calibration`, the diagnosis's recalibration and candidates) work on
those two numbers per block and evaluate the model only at two rows of each block
(plus the rows where an input changes); the noise floor, the residual tests and the
final residuals stay on every row.

The blocks (:func:`reduce_run`)
-------------------------------
A block is a run of consecutive rows with

* the same held inputs (the kind's inputs but time and but its noisy inputs, below: a
  model reading its inputs row by row and holding them in between then sees the same
  input on the coarse grid as on every row);
* no fold edge inside it (a fold's rows are a union of blocks);
* at most ``L`` rows, where ``max |second difference| * L**2 / 8 <= SPREAD``: the
  stated prediction's largest departure from a straight line over the block,
  in multiples of the noise floor. The second difference per row of a response
  of amplitude ``A`` and time constant ``tau`` sampled every ``dt`` is about
  ``A dt**2 / tau**2``, so ``L dt`` is about ``tau sqrt(8 SPREAD sigma / A)``:
  shorter than the time constants, longer where the response is flat or the
  noise floor ``sigma`` is high;
* at most :data:`MAX_BLOCK` rows (a slow drift of the log stays resolved).

Per block and quantity the fit sees ``r0 = sum(r) / sqrt(L)`` and ``r1 =
sum(r (t - tbar)) / sqrt(sum((t - tbar)**2))`` of the residuals ``r`` (orthonormal
moments: each is N(0, sigma**2) where the rows' noise is white with sd sigma, so
each block is weighted by its rows' noise variance). The model's moments come from
its values at two rows of the block (the Gauss-Legendre points of a line), plus
the difference between the full and the two-row moments of the stated prediction
(its curvature, at most :data:`SPREAD` noise floors, which hardly moves with the
parameters). What the reduction leaves out is the rows' departure from a line in
each block: noise, and the curvature's change with the parameters.

Noisy inputs
------------
An input logged by an instrument with its own noise (:attr:`tcamlab.kinds.Kind.noisy_inputs`:
the static oven test's temperature read by a thermometer or a thermal camera, held between
the camera's frames or noisy on every row) changes on every row, so no two rows hold the
same input. Such an input does not cut blocks; instead

* the curvature above is that of the stated prediction's means over windows of
  :data:`NOISY_WINDOW` rows (second differences of the window means over
  ``NOISY_WINDOW**2``, taken as every row's of the window and its neighbours): the smoothed
  level of the prediction, hence of the input, is a straight line over a block to within
  :data:`SPREAD` noise floors, while the rows' noise (sd ``s`` per row, at most the noise
  floor) adds only about ``2.5 s / NOISY_WINDOW**2.5`` per row to the curvature (blocks of
  several hundred rows where the input's propagated noise is the whole noise floor);
* the model is evaluated on the grid at the input's block line ``x_line(t) = xbar +
  b (t - tbar)`` (its level and slope moments, :attr:`Reduction.lines`), not at the noisy
  value of the grid row. The first row keeps its logged value (a model referred to its
  first row, the static displacement, keeps the reference of the fit on every row);
* each block gets a third moment per quantity and noisy input, the residuals projected on
  the input's unit departure from its line ``e / |e|`` (:meth:`Reduction.residual`). The
  fit on every row sees the input's noise through ``f' e`` in its residuals: their sum of
  squares ``f'(theta)**2 |e|**2`` pulls the parameters that set ``f'`` (errors in
  variables), and its curvature adds to their information. On the block lines that term is
  gone; the noise moment restores it, predicted as ``f'(theta) |e|`` (``f'`` from the model
  on the grid with the input raised by :data:`INPUT_SHIFT`, all rows but the first) plus
  its value at the stated values beyond that first-order part. The chi-square and its
  Jacobian in the parameters are then those of every row to first order in ``e``; without
  it the calibrated G(T) slope of the static test moved 0.13 interval widths from the
  every-row fit's, with it 0.001.

The approximation: over a block, write the input ``x_i = x_line(t_i) + e_i``; ``e`` has
zero level and slope moments (the line is its least-squares line). The full prediction
``f(x_i) = f(x_line) + f' e_i + f'' e_i**2 / 2 + ...``: the ``f' e`` term has zero moments
where ``f'`` is constant over the block, and the coarse prediction leaves out
``f'' L var(e) / 2`` of the level moment (``L var(e) = sum(e**2)``, the within-block input
variance, noise and the smoothed level's departure from the line) and the ``f'`` change's
share. Both are in the offset (full minus coarse moments at the stated values), which is
taken here from the coarse prediction on the block lines; what is left is their change
with the parameters, ``d f''/d theta L var(e) / 2``, relative to the noise floor ``sigma
sqrt(L)`` of the moment: ``sqrt(L) var(e) |d f''/d theta| / (2 sigma)``. For the static
oven test (``f'`` about -5.7 um/K, ``f''`` about 0.016 um/K**2 on the thesis sample) with a
0.5 K camera noise, a 5 um laser and blocks of 500 rows the left-out term is
``sqrt(500) 0.25 0.016 / 2 / 5``, about 0.01 noise floors, and it moves with the
parameters by its relative change, a few per cent across an interval: about 1e-4 noise
floors per block, negligible against the intervals (the tests compare both fits to a
tenth of an interval's width). A model with state (a thermal lag of the
input) filters ``e`` across the blocks; that response at the stated values is in the
offsets too, and the grid check below compares the coarse prediction with the full
prediction on the block lines. What is not reduced exactly is an effect that filters the
noisy input over time away from the stated values (the diagnosis's oven-thermal-lag
candidate): the fit on every row gains from the lag's smoothing of the input's noise
(``|lag(e)| < |e|``, a pull towards a longer lag) and steps the lag over every row, the
reduced fit steps it over the grid rows on the lines. Its lag differed by 0.5 to 0.9
interval widths on the 20,000-row camera logs of the tests (the verdict the same).

Below :data:`MIN_ROWS` rows in a run nothing is reduced (the bundled experiments'
results are those of a fit on every row), and a run whose coarse prediction at the
stated values departs from its full prediction at the grid rows by more than
:data:`GRID_TOLERANCE` noise floors (a model that reads more than its held inputs)
is not reduced either.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from tcamlab.errors import TcamlabError
from tcamlab.signals import LINEAR_BETWEEN_ROWS

__all__ = [
    "MIN_ROWS",
    "MIN_ROWS_ENV",
    "ENV",
    "SPREAD",
    "MAX_BLOCK",
    "GRID_TOLERANCE",
    "NOISY_WINDOW",
    "enabled",
    "block_edges",
    "Reduction",
    "reduce_run",
    "checked_reduction",
]

MIN_ROWS = 50_000
"""Rows of a run below which fits use every row (the bundled runs have a few thousand)."""

SPREAD = 0.1
"""Largest departure of the stated prediction from a straight line within a block, in
noise floors (see the module docstring)."""

MAX_BLOCK = 4096
"""Most rows of a block."""

GRID_TOLERANCE = 0.05
"""Largest difference, in noise floors, between the coarse and the full prediction at the
grid rows at the stated values for a run to be reduced."""

NOISY_WINDOW = 256
"""Rows of the windows whose means give the curvature of a run with noisy inputs (module
docstring): long enough that the rows' noise hardly adds to it, short against a thermal
response of seconds at 1 kHz."""

ENV = "TCAMLAB_NO_REDUCTION"
"""Set (to anything but empty or ``0``) to fit on every row whatever the log's length: the
straightforward reference of ``bench/bench_large_log.py`` and the agreement tests."""


MIN_ROWS_ENV = "TCAMLAB_REDUCTION_MIN_ROWS"
"""Set to a number of rows to reduce runs from that length on instead of :data:`MIN_ROWS`
(the benchmark compares both fits on a log short enough for the every-row fit)."""


def enabled(rows: int) -> bool:
    """Whether a run of ``rows`` rows is fitted on its reduced representation."""
    least = int(os.environ.get(MIN_ROWS_ENV, "") or MIN_ROWS)
    return rows >= least and os.environ.get(ENV, "") in ("", "0")


def block_edges(curv: np.ndarray, held: np.ndarray, breaks: np.ndarray, spread: float, max_block: int):
    """First row of every block (see the module docstring).

    Parameters
    ----------
    curv : ndarray, shape (n,)
        Largest |second difference| of the stated prediction at each row over the
        quantities, in noise floors (0 at the first and last rows).
    held : ndarray, shape (n,) of bool
        True where a held input differs from the previous row's.
    breaks : ndarray, shape (n,) of bool
        True where a block must start (a fold edge).
    spread : float
        :data:`SPREAD` [noise floors].
    max_block : int
        :data:`MAX_BLOCK` [rows].
    """
    return _edges_kernel()(curv, held | breaks, float(spread), int(max_block))


_KERNEL = []


def _edges_kernel():
    """The numba loop that grows the blocks (compiled once, on first use)."""
    if _KERNEL:
        return _KERNEL[0]
    from numba import njit

    @njit(cache=False)
    def edges(curv, cut, spread, max_block):
        n = curv.size
        out = np.empty(n, np.int64)
        k, a, worst = 0, 0, 0.0
        out[0] = 0
        k = 1
        for i in range(1, n):
            worst_i = max(worst, curv[i - 1]) if i - 1 > a else 0.0
            length = i - a + 1
            if cut[i] or length > max_block or worst_i * length * length > 8.0 * spread:
                out[k] = i
                k += 1
                a, worst = i, 0.0
            else:
                worst = worst_i
        return out[:k]

    _KERNEL.append(edges)
    return edges


@dataclass
class Reduction:
    """The blocks of one run and the moments of its logged quantities.

    Attributes
    ----------
    starts, counts : ndarray of int
        First row and rows of each block.
    grid : ndarray of int
        Rows the model is evaluated at (sorted).
    g1, g2 : ndarray of int
        Positions in ``grid`` of each block's two rows (equal for a one-row block).
    tbar, tsd : ndarray
        Block mean time [s] and ``sqrt(sum((t - tbar)**2))`` [s].
    t_grid : ndarray
        Time of the grid rows [s].
    measured : dict of str to (ndarray, ndarray)
        Moments ``(r0, r1)`` of each logged quantity [SI].
    offset : dict of str to (ndarray, ndarray)
        Full minus two-row moments of the stated prediction [SI].
    within : dict of str to ndarray
        Per block, the sum of squares of the residuals at the stated values that the two
        moments leave out [SI^2]: the rows' noise about the block's line, which hardly moves
        with the parameters. A fit adds it as one constant residual so that its chi-square,
        and a relative stopping tolerance, are those of every row.
    """

    starts: np.ndarray
    counts: np.ndarray
    grid: np.ndarray
    g1: np.ndarray
    g2: np.ndarray
    tbar: np.ndarray
    tsd: np.ndarray
    t_grid: np.ndarray
    measured: dict = field(default_factory=dict)
    offset: dict = field(default_factory=dict)
    within: dict = field(default_factory=dict)
    frame: object = None
    """The run's grid rows (a DataFrame), set by :func:`checked_reduction`; a noisy input's
    column holds its block line there (module docstring)."""
    lines: dict = field(default_factory=dict)
    """Per noisy input, ``(level, slope)`` of its block line: mean [unit of the input] and
    slope [unit / s] over each block (module docstring)."""
    norms: dict = field(default_factory=dict)
    """Per noisy input, ``|e|`` per block: the root sum of squares of its departure from the
    block line [unit of the input]."""
    gram: dict = field(default_factory=dict)
    """``gram[x][z]``: per block, input z's departure projected on input x's unit departure."""
    noise_measured: dict = field(default_factory=dict)
    """``[q][x]``: per block, logged quantity q projected on input x's unit departure [SI]."""
    noise_stated: dict = field(default_factory=dict)
    """``[q][x]``: the same of the full prediction at the stated values [SI]."""
    noise_offset: dict = field(default_factory=dict)
    """``[q][x]``: that minus its first-order part ``sum_z f'_z gram[x][z]`` at the stated
    values, set by :func:`checked_reduction` [SI]."""
    shifted: dict = field(default_factory=dict)
    """Per noisy input, ``(frame, h)``: the grid frame with the input raised by ``h``, for
    the model's slope in it."""

    @property
    def two(self) -> np.ndarray:
        """Blocks with a slope moment (two rows or more)."""
        return self.counts >= 2

    def rough(self, x: str) -> np.ndarray:
        """Blocks with an input-noise moment of noisy input ``x`` (a departure from the line)."""
        return self.norms[x] > 0

    @property
    def size(self) -> int:
        """Moments per quantity."""
        extra = sum(int(np.count_nonzero(self.rough(x))) for x in self.norms)
        return int(self.counts.size + np.count_nonzero(self.two)) + extra

    def per_moment(self, v: np.ndarray, sel=None) -> np.ndarray:
        """A per-block value laid out as the moments of :meth:`residual` (blocks in ``sel``)."""
        sel = np.ones(self.counts.size, bool) if sel is None else sel
        parts = [v[sel], v[sel & self.two]] + [v[sel & self.rough(x)] for x in self.norms]
        return np.concatenate(parts)

    def residual(self, q: str, x_grid: np.ndarray, slopes=None, sel=None):
        """``(level, rest)``: measured minus predicted moments of ``q`` over the blocks in
        ``sel`` for a prediction given on the grid (curvature offsets added): the level
        moments, then the slope moments and each noisy input's noise moment (module
        docstring), the latter from ``slopes`` (input: d prediction / d input on the grid)."""
        sel = np.ones(self.counts.size, bool) if sel is None else sel
        (m0, m1), (p0, p1) = self.measured[q], self.predicted(q, x_grid)
        parts = [(m1 - p1)[sel & self.two]]
        for x in self.norms:
            pred = self.noise_offset[q][x].copy()
            for z in self.norms:
                g = np.asarray(slopes[z], float)
                pred += 0.5 * (g[self.g1] + g[self.g2]) * self.gram[x][z]
            parts.append((self.noise_measured[q][x] - pred)[sel & self.rough(x)])
        return (m0 - p0)[sel], np.concatenate(parts)

    def moments(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Orthonormal level and slope moments of a full-length column ``x`` per block."""
        x = np.asarray(x, float)
        s0 = np.add.reduceat(x, self.starts)
        rel = t - np.repeat(t[self.starts], self.counts)  # small numbers: no cancellation
        s1 = np.add.reduceat(x * rel, self.starts)
        rbar = self.tbar - t[self.starts]
        r1 = (s1 - rbar * s0) / np.where(self.tsd > 0, self.tsd, 1.0)
        return s0 / np.sqrt(self.counts), np.where(self.two, r1, 0.0)

    def coarse_moments(self, x_grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The moments of the line through a prediction's values at each block's two rows."""
        x_grid = np.asarray(x_grid, float)
        a, b = x_grid[self.g1], x_grid[self.g2]
        dt = self.t_grid[self.g2] - self.t_grid[self.g1]
        slope = np.where(dt > 0, (b - a) / np.where(dt > 0, dt, 1.0), 0.0)
        level = a + slope * (self.tbar - self.t_grid[self.g1])
        return level * np.sqrt(self.counts), slope * self.tsd

    def predicted(self, q: str, x_grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Moments of a prediction of ``q`` given on the grid, curvature offset added."""
        p0, p1 = self.coarse_moments(x_grid)
        c0, c1 = self.offset[q]
        return p0 + c0, p1 + c1

    def on_lines(self, data, rows: np.ndarray):
        """Rows ``rows`` of ``data`` with each noisy input replaced by its block line (the
        first row keeps its logged value)."""
        frame = data.iloc[rows].copy() if len(rows) < len(data) else data.copy()
        if not self.lines:
            return frame
        frame.attrs[LINEAR_BETWEEN_ROWS] = "linear"  # a time filter must not see steps
        block = np.searchsorted(self.starts, rows, side="right") - 1
        t = frame["time"].to_numpy(float)
        for x, (level, slope) in self.lines.items():
            value = level[block] + slope[block] * (t - self.tbar[block])
            value[rows == 0] = float(data[x].iloc[0])
            frame[x] = value
        return frame

    def slopes(self, predict, base: dict) -> dict:
        """``{q: {x: d prediction / d input x}}`` on the grid, from ``base = predict(frame)``
        and ``predict`` on each shifted frame (empty without noisy inputs)."""
        out = {q: {} for q in base}
        for x, (frame, h) in self.shifted.items():
            up = predict(frame)
            for q in base:
                out[q][x] = (np.asarray(up[q], float) - np.asarray(base[q], float)) / h
        return out

    def blocks_in(self, mask) -> np.ndarray | None:
        """Blocks whose rows are in ``mask`` (all rows: None), or None when a block
        straddles its edge (then the rows are scored one by one)."""
        if mask is None:
            return np.ones(self.counts.size, bool)
        m = np.asarray(mask, bool)
        inside = np.add.reduceat(m.astype(np.int64), self.starts)
        if np.any((inside != 0) & (inside != self.counts)):
            return None
        return inside > 0


def _curvature(preds: dict, sigma: dict) -> np.ndarray:
    """Largest |second difference| over the quantities per row, in noise floors."""
    n = len(next(iter(preds.values())))
    out = np.zeros(n)
    for q, p in preds.items():
        p = np.asarray(p, float)
        d2 = np.abs(p[2:] - 2.0 * p[1:-1] + p[:-2]) / sigma[q]
        np.maximum(out[1:-1], d2, out=out[1:-1])
    return out


def _smooth_curvature(preds: dict, sigma: dict, window: int) -> np.ndarray:
    """Largest |second difference| per row over the quantities, in noise floors, of the
    predictions' means over windows of ``window`` rows (module docstring: noisy inputs)."""
    n = len(next(iter(preds.values())))
    m = n // window
    if m < 3:
        return _curvature(preds, sigma)
    worst = np.zeros(m)
    for q, p in preds.items():
        means = np.asarray(p, float)[: m * window].reshape(m, window).mean(axis=1)
        d2 = np.abs(means[2:] - 2.0 * means[1:-1] + means[:-2]) / (sigma[q] * window * window)
        np.maximum(worst[1:-1], d2, out=worst[1:-1])
    worst[0], worst[-1] = worst[1], worst[-2]
    # a window and its neighbours: a block across a window edge sees both sides' curvature
    near = np.maximum(worst, np.maximum(np.append(worst[1:], 0.0), np.insert(worst[:-1], 0, 0.0)))
    out = np.repeat(near, window)
    return np.concatenate([out, np.full(n - out.size, near[-1])])


def _lines(red: Reduction, data, noisy: list[str], t: np.ndarray) -> dict:
    """``(level, slope)`` of each noisy input over each block (least-squares line in time)."""
    out = {}
    for x in noisy:
        m0, m1 = red.moments(data[x].to_numpy(float), t)
        level = m0 / np.sqrt(red.counts)
        slope = np.where(red.tsd > 0, m1 / np.where(red.tsd > 0, red.tsd, 1.0), 0.0)
        out[x] = (level, slope)
    return out


def _changes(data, held: list[str]) -> np.ndarray:
    """True where a held input differs from the previous row's."""
    n = len(data)
    out = np.zeros(n, bool)
    for c in held:
        x = data[c].to_numpy(float)
        out[1:] |= x[1:] != x[:-1]
    return out


def reduce_run(
    data,
    held: list[str],
    stated: dict,
    measured: dict,
    sigma: dict,
    breaks=(),
    knot_every: int = 1,
    noisy=(),
) -> Reduction:
    """The blocks and moments of one run (module docstring).

    Parameters
    ----------
    data : DataFrame
        The run's columns (``time`` [s] and the held inputs).
    held : list of str
        Input columns held between rows (every input but time).
    stated : dict of str to ndarray
        Full prediction at the stated values per quantity [SI].
    measured : dict of str to ndarray
        Logged quantities [SI].
    sigma : dict of str to float
        Noise floor per quantity [SI].
    breaks : sequence of int
        Rows where a block must start (fold edges).
    knot_every : int
        Rows between extra grid rows inside long blocks (none when 1): an explicit
        integrator stepping over a whole quiet block at once can overshoot into the
        model's domain edge on its trial step.
    noisy : sequence of str
        Held inputs logged with their own noise: they cut no block and are replaced by
        their block lines on the grid (module docstring).
    """
    n = len(data)
    t = data["time"].to_numpy(float)
    cut = np.zeros(n, bool)
    cut[np.asarray(list(breaks), int)] = True
    noisy = [x for x in noisy if x in held]
    changes = _changes(data, [c for c in held if c not in noisy])
    curv = _smooth_curvature(stated, sigma, NOISY_WINDOW) if noisy else _curvature(stated, sigma)
    starts = block_edges(curv, changes, cut, SPREAD, MAX_BLOCK)
    counts = np.diff(np.append(starts, n))
    r1 = starts + np.round((counts - 1) * (0.5 - 0.5 / math.sqrt(3.0))).astype(np.int64)
    r2 = starts + np.round((counts - 1) * (0.5 + 0.5 / math.sqrt(3.0))).astype(np.int64)
    r2 = np.where(counts >= 2, np.maximum(r2, r1 + 1), r1)
    knots = starts[changes[starts] | (starts == 0)]  # where the held input changes
    extra = np.arange(0, n, knot_every) if knot_every > 1 else np.zeros(0, np.int64)
    grid = np.unique(np.concatenate([knots, r1, r2, extra]))
    tbar = np.add.reduceat(t, starts) / counts
    rel2 = (t - np.repeat(tbar, counts)) ** 2
    red = Reduction(
        starts=starts,
        counts=counts,
        grid=grid,
        g1=np.searchsorted(grid, r1),
        g2=np.searchsorted(grid, r2),
        tbar=tbar,
        tsd=np.sqrt(np.add.reduceat(rel2, starts)),
        t_grid=t[grid],
    )
    red.lines = _lines(red, data, noisy, t)
    dirs = _noise_directions(red, data, t)
    for q, x in measured.items():
        red.measured[q] = red.moments(x, t)
        full, coarse = red.moments(stated[q], t), red.coarse_moments(np.asarray(stated[q])[grid])
        red.offset[q] = (full[0] - coarse[0], full[1] - coarse[1])
        r = np.asarray(x, float) - np.asarray(stated[q], float)
        r0, r1 = red.moments(r, t)
        left = np.add.reduceat(r * r, starts) - r0 * r0 - r1 * r1
        red.noise_measured[q], red.noise_stated[q] = {}, {}
        for v, unit in dirs.items():
            red.noise_measured[q][v] = np.add.reduceat(np.asarray(x, float) * unit, starts)
            red.noise_stated[q][v] = np.add.reduceat(np.asarray(stated[q], float) * unit, starts)
            left = left - (red.noise_measured[q][v] - red.noise_stated[q][v]) ** 2
        red.within[q] = np.maximum(left, 0.0)
    return red


def _noise_directions(red: Reduction, data, t: np.ndarray) -> dict:
    """Per noisy input, its departure from its block lines normalised to a unit vector per
    block (full length, zero in a block without departure); sets ``red.norms`` and
    ``red.gram``."""
    dev = {}
    for x, (level, slope) in red.lines.items():
        line = np.repeat(level, red.counts) + np.repeat(slope, red.counts) * (
            t - np.repeat(red.tbar, red.counts)
        )
        dev[x] = data[x].to_numpy(float) - line
    units = {}
    for x, e in dev.items():
        norm = np.sqrt(np.add.reduceat(e * e, red.starts))
        red.norms[x] = norm
        units[x] = e / np.repeat(np.where(norm > 0, norm, 1.0), red.counts)
    for x, unit in units.items():
        red.gram[x] = {z: np.add.reduceat(e * unit, red.starts) for z, e in dev.items()}
    return units


KNOT_EVERY = (64, 16, 4)
"""Rows between the grid's extra rows, tried in turn (:func:`checked_reduction`): 64 ms at
1 kHz, about the mechanical time constant m / b of the thesis rig."""


def checked_reduction(data, held, stated, measured, sigma, predict, breaks=(), noisy=()) -> Reduction | None:
    """:func:`reduce_run` with the coarsest grid whose prediction at the stated values
    matches the full one at the grid rows to :data:`GRID_TOLERANCE` noise floors, or None.

    ``predict(frame)`` is the model at the stated values on a frame of some of the rows
    (a dict of quantity to ndarray; it may raise where the coarse grid fails). With noisy
    inputs (module docstring) the full prediction compared is the one on the block lines,
    and the curvature offsets are taken from the coarse prediction itself."""
    errors = (TcamlabError, ArithmeticError, ValueError)
    for every in KNOT_EVERY:
        red = reduce_run(data, held, stated, measured, sigma, breaks, every, noisy)
        if red.grid.size * 2 > len(data):
            return None  # nothing to gain
        red.frame = red.on_lines(data, red.grid)
        try:
            coarse = predict(red.frame)
            reference = stated
            if red.lines:  # the model on every row of the block lines
                reference = predict(red.on_lines(data, np.arange(len(data))))
        except errors:  # a failed coarse step: finer grid
            continue
        worst = max(
            float(np.max(np.abs(np.asarray(coarse[q]) - np.asarray(reference[q])[red.grid]))) / sigma[q]
            for q in measured
        )
        if worst > GRID_TOLERANCE:
            continue
        if red.lines:
            try:
                _noise_offsets(red, data, stated, coarse, predict)
            except errors:
                continue
        return red
    return None


INPUT_SHIFT = 1e-4
"""Shift of a noisy input for the model's slope in it, relative to its largest magnitude."""


def _noise_offsets(red: Reduction, data, stated: dict, coarse: dict, predict) -> None:
    """The offsets of a reduction with noisy inputs, from the coarse prediction at the stated
    values: the within-block input variance's share of the level and slope moments, and
    what the noise moments hold beyond the model's slope times the input's departure."""
    t = data["time"].to_numpy(float)
    for x in red.lines:
        h = INPUT_SHIFT * max(float(np.max(np.abs(data[x].to_numpy(float)))), 1e-300)
        frame = red.frame.copy()
        # the first row keeps its value: a model referred to it (the static displacement)
        # would otherwise cancel a uniform shift
        frame[x] = frame[x].to_numpy(float) + np.where(red.grid > 0, h, 0.0)
        red.shifted[x] = (frame, h)
    slopes = red.slopes(predict, {q: coarse[q] for q in red.measured})
    for q in red.measured:
        full, low = red.moments(stated[q], t), red.coarse_moments(coarse[q])
        red.offset[q] = (full[0] - low[0], full[1] - low[1])
        red.noise_offset[q] = {}
        for x in red.norms:
            first = sum(
                0.5 * (slopes[q][z][red.g1] + slopes[q][z][red.g2]) * red.gram[x][z] for z in red.norms
            )
            red.noise_offset[q][x] = red.noise_stated[q][x] - first
