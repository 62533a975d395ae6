"""Fast CSV text for long numeric tables (predictions.csv of a long log).

pandas formats every float through Python (about 1 us a value), so a 10-million-row
predictions table took minutes. Here numbers are written by a numba kernel in fixed
point: each column with :data:`SIGNIFICANT` significant digits of its largest magnitude
(so a column up to 9999.5 s keeps 1e-5 s), trailing zeros trimmed, NaN as an empty
cell (as pandas writes it). Text columns are allowed only as a label constant over
blocks of rows (the run name), written as pandas' csv module would quote it.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pandas as pd
from numba import njit

__all__ = ["SIGNIFICANT", "fixed_csv_bytes", "column_decimals"]

SIGNIFICANT = 9
"""Significant digits kept, relative to each column's largest magnitude [-]."""

CHUNK_ROWS = 500_000
"""Rows formatted per kernel call (bounds the scratch buffer) [-]."""

MAX_DECIMALS = 15
"""Most decimals written (a column of tiny values) [-]."""


def column_decimals(values: np.ndarray) -> int:
    """Decimals that keep :data:`SIGNIFICANT` digits of the largest finite magnitude."""
    finite = np.abs(values[np.isfinite(values)])
    top = float(finite.max()) if finite.size else 0.0
    if top == 0.0:
        return 0
    return int(min(MAX_DECIMALS, max(0, SIGNIFICANT - 1 - math.floor(math.log10(top)))))


@njit(cache=True)
def _write_digits(out, pos, value):
    """Decimal digits of a non-negative int64 at out[pos:]; returns the new position."""
    if value == 0:
        out[pos] = 48
        return pos + 1
    start = pos
    while value > 0:
        out[pos] = 48 + value % 10
        value //= 10
        pos += 1
    out[start:pos] = out[start:pos][::-1].copy()
    return pos


@njit(cache=True)
def _format_rows(values, decimals, prefix, out):
    """Rows of ``values`` (n, k) as CSV lines after ``prefix`` bytes; returns bytes used."""
    pos = 0
    n, k = values.shape
    for i in range(n):
        for b in range(prefix.size):
            out[pos] = prefix[b]
            pos += 1
        for j in range(k):
            if j:
                out[pos] = 44  # ","
                pos += 1
            v = values[i, j]
            if not np.isfinite(v):
                continue
            d = decimals[j]
            unit = np.int64(10) ** d
            m = np.int64(round(abs(v) * 10.0**d))
            if v < 0 and m > 0:
                out[pos] = 45  # "-"
                pos += 1
            pos = _write_digits(out, pos, m // unit)
            frac = m % unit
            if frac:
                out[pos] = 46  # "."
                pos += 1
                width = d
                while frac % 10 == 0:
                    frac //= 10
                    width -= 1
                end = pos + width
                for w in range(width):
                    out[end - 1 - w] = 48 + frac % 10
                    frac //= 10
                pos = end
        out[pos] = 10
        pos += 1
    return pos


def _cell(text: str) -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="").writerow([text])
    return buf.getvalue().encode()


def fixed_csv_bytes(
    df: pd.DataFrame, label: str | None = None, text=str, header: bytes | None = None
) -> bytearray:
    """``df`` as CSV bytes (header, then one line a row, "\\n" line ends).

    Parameters
    ----------
    df : DataFrame
        Numeric columns, plus optionally the text column ``label`` (e.g. ``"run"``),
        which must be the first column; it is written per block of equal values.
    label : str, optional
        Name of that text column.
    text : callable
        Turns a label value into the cell's text (default ``str``).
    header : bytes, optional
        The header line (default: the column names as pandas writes them).

    Returns
    -------
    bytearray
        The CSV text (a bytearray, so that it is built in place).
    """
    if header is None:
        header = df.iloc[:0].to_csv(index=False, lineterminator="\n").encode()
    numeric = [c for c in df.columns if c != label]
    decimals = np.array([column_decimals(df[c].to_numpy(float)) for c in numeric], np.int64)
    width = int(sum(22 + d for d in decimals)) + len(numeric) + 1
    # the text grows in one bytearray (large reallocations are remapped, not copied), so
    # the peak is about the text's size, not twice it as a list of parts and a join would be
    text_out = bytearray(header)
    if label is None:
        blocks = [(0, len(df), b"")]
    else:
        codes = df[label].to_numpy()
        starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]]) if len(df) else []
        ends = list(starts[1:]) + [len(df)]
        blocks = [(a, e, _cell(text(codes[a])) + b",") for a, e in zip(starts, ends)]
    cols = [df.columns.get_loc(c) for c in numeric]
    for a, e, prefix in blocks:
        pre = np.frombuffer(prefix, np.uint8)
        scratch = np.empty(min(CHUNK_ROWS, e - a) * (width + pre.size), np.uint8)
        for s in range(a, e, CHUNK_ROWS):
            chunk = df.iloc[s : min(e, s + CHUNK_ROWS), cols].to_numpy(float)
            used = _format_rows(np.ascontiguousarray(chunk), decimals, pre, scratch)
            text_out += memoryview(scratch)[:used]
    return text_out
