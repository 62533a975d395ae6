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

* the same held inputs (the kind's inputs but time: a model reading its inputs
  row by row and holding them in between then sees the same input on the coarse
  grid as on every row);
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

__all__ = [
    "MIN_ROWS",
    "MIN_ROWS_ENV",
    "ENV",
    "SPREAD",
    "MAX_BLOCK",
    "GRID_TOLERANCE",
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
    """The run's grid rows (a DataFrame), set by :func:`checked_reduction`."""

    @property
    def two(self) -> np.ndarray:
        """Blocks with a slope moment (two rows or more)."""
        return self.counts >= 2

    @property
    def size(self) -> int:
        """Moments per quantity."""
        return int(self.counts.size + np.count_nonzero(self.two))

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


def _changes(data, held: list[str]) -> np.ndarray:
    """True where a held input differs from the previous row's."""
    n = len(data)
    out = np.zeros(n, bool)
    for c in held:
        x = data[c].to_numpy(float)
        out[1:] |= x[1:] != x[:-1]
    return out


def reduce_run(
    data, held: list[str], stated: dict, measured: dict, sigma: dict, breaks=(), knot_every: int = 1
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
    """
    n = len(data)
    t = data["time"].to_numpy(float)
    cut = np.zeros(n, bool)
    cut[np.asarray(list(breaks), int)] = True
    changes = _changes(data, held)
    starts = block_edges(_curvature(stated, sigma), changes, cut, SPREAD, MAX_BLOCK)
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
    for q, x in measured.items():
        red.measured[q] = red.moments(x, t)
        full, coarse = red.moments(stated[q], t), red.coarse_moments(np.asarray(stated[q])[grid])
        red.offset[q] = (full[0] - coarse[0], full[1] - coarse[1])
        r = np.asarray(x, float) - np.asarray(stated[q], float)
        r0, r1 = red.moments(r, t)
        red.within[q] = np.maximum(np.add.reduceat(r * r, starts) - r0 * r0 - r1 * r1, 0.0)
    return red


KNOT_EVERY = (64, 16, 4)
"""Rows between the grid's extra rows, tried in turn (:func:`checked_reduction`): 64 ms at
1 kHz, about the mechanical time constant m / b of the thesis rig."""


def checked_reduction(data, held, stated, measured, sigma, predict, breaks=()) -> Reduction | None:
    """:func:`reduce_run` with the coarsest grid whose prediction at the stated values
    matches the full one at the grid rows to :data:`GRID_TOLERANCE` noise floors, or None.

    ``predict(frame)`` is the model at the stated values on a frame of some of the rows
    (a dict of quantity to ndarray; it may raise where the coarse grid fails)."""
    for every in KNOT_EVERY:
        red = reduce_run(data, held, stated, measured, sigma, breaks, every)
        if red.grid.size * 2 > len(data):
            return None  # nothing to gain
        red.frame = data.iloc[red.grid]
        try:
            coarse = predict(red.frame)
        except (TcamlabError, ArithmeticError, ValueError):  # a failed coarse step: finer grid
            continue
        worst = max(
            float(np.max(np.abs(np.asarray(coarse[q]) - np.asarray(stated[q])[red.grid]))) / sigma[q]
            for q in measured
        )
        if worst <= GRID_TOLERANCE:
            return red
    return None
