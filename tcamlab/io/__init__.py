"""Ingestion of rig CSV logs into validated SI data.

One CSV file holds one run. Its columns carry lab units in their canonical
names (``temperature_C``, ``displacement_mm``, ``time_s`` ...); inside
tcamlab every column has a short internal name and SI units (``temperature``
[degC], ``displacement`` [m], ``time`` [s] ...). :data:`VARIABLE_MAP` is the
one place that links the two, in the spirit of pvlib's ``VARIABLE_MAP``;
:func:`canonical_to_internal` and :func:`internal_to_canonical` apply it so
that writers (the simulator, ``predictions.csv``) use the same mapping.

Files whose headers are not canonical are described by the experiment
file's ``[columns]`` table, for example::

    [columns]
    time_s = { from = "reltime", unit = "ms" }
    temperature_C = { from = "Temp (F)", unit = "degF" }
    displacement_mm = { from = "laser", scale = 0.01, offset = -2.5 }
    force_N = "Fz"

For each column the value stored inside tcamlab is::

    value_SI = to_SI(raw * scale + offset, unit)

that is, ``scale`` and ``offset`` act on the raw number in the file and give
a value in ``unit`` (default: the canonical column's own unit, e.g. ``mm``
for ``displacement_mm``), which is then converted with :data:`UNITS`.

:func:`read_run` never modifies the raw file. It reads only the needed
columns with the pandas C engine as float64, detects a UTF-8 byte-order mark,
falls back to Latin-1 for non-UTF-8 headers, recognises ``;``-separated
files with decimal commas, and skips full-line ``#`` comments and blank
lines before the header (rigs write metadata there). Every problem it
detects raises :class:`tcamlab.errors.InputError` with a one-line message
naming the file and, where it applies, the line number (as an editor shows
it, 1-based) and the column.
"""

from __future__ import annotations

import csv
import hashlib
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tcamlab import kinds as _kinds
from tcamlab.errors import InputError
from tcamlab.signals import smooth_slow_input
from tcamlab.text import close_matches, did_you_mean
from tcamlab.units import QUANTITIES

__all__ = [
    "sign_flip_entry",
    "ABSOLUTE_ZERO_C",
    "DEFAULT_MAX_BYTES",
    "KINDS",
    "MIN_ROWS",
    "OPTIONAL",
    "REQUIRED",
    "SI_UNITS",
    "UNITS",
    "UNIT_ALIASES",
    "CLOCK_UNITS",
    "FORMAT_KEYS",
    "FileFormat",
    "file_format",
    "VARIABLE_MAP",
    "ColumnSpec",
    "RunData",
    "canonical_to_internal",
    "column_spec",
    "column_option",
    "convert",
    "internal_to_canonical",
    "read_run",
    "input_files",
    "sha256_file",
    "unit_key",
    "unit_suggestion",
]

# --- units ------------------------------------------------------------------

UNITS: dict[str, tuple[str, float, float]] = {
    # unit: (dimension, factor, offset) with value_SI = value * factor + offset
    # time -> s
    "s": ("time", 1.0, 0.0),
    "ms": ("time", 1e-3, 0.0),
    "us": ("time", 1e-6, 0.0),
    "min": ("time", 60.0, 0.0),
    "h": ("time", 3600.0, 0.0),
    # temperature -> degC (absolute temperatures stay in degC inside tcamlab)
    "degC": ("temperature", 1.0, 0.0),
    "degF": ("temperature", 5.0 / 9.0, -32.0 * 5.0 / 9.0),
    "K": ("temperature", 1.0, -273.15),
    # length -> m
    "m": ("length", 1.0, 0.0),
    "cm": ("length", 1e-2, 0.0),
    "mm": ("length", 1e-3, 0.0),
    "um": ("length", 1e-6, 0.0),
    "nm": ("length", 1e-9, 0.0),
    "in": ("length", 0.0254, 0.0),
    # force -> N
    "N": ("force", 1.0, 0.0),
    "mN": ("force", 1e-3, 0.0),
    "kN": ("force", 1e3, 0.0),
    "gf": ("force", 9.80665e-3, 0.0),
    "kgf": ("force", 9.80665, 0.0),
    "lbf": ("force", 4.4482216152605, 0.0),
    # resistance -> ohm ("mohm" is milli-ohm, "Mohm" mega-ohm)
    "ohm": ("resistance", 1.0, 0.0),
    "mohm": ("resistance", 1e-3, 0.0),
    "kohm": ("resistance", 1e3, 0.0),
    "Mohm": ("resistance", 1e6, 0.0),
    # voltage -> V
    "V": ("voltage", 1.0, 0.0),
    "mV": ("voltage", 1e-3, 0.0),
    # current -> A
    "A": ("current", 1.0, 0.0),
    "mA": ("current", 1e-3, 0.0),
    "uA": ("current", 1e-6, 0.0),
    # curvature -> 1/m
    "per_m": ("curvature", 1.0, 0.0),
    "per_cm": ("curvature", 1e2, 0.0),
    "per_mm": ("curvature", 1e3, 0.0),
}
"""Unit name -> (dimension, factor, offset); ``SI = value * factor + offset``."""


def _aliases() -> dict[str, str]:
    table = {
        "s": "s sec secs second seconds",
        "ms": "ms msec millisecond milliseconds",
        "us": "us µs μs usec microsecond microseconds",
        "min": "min mins minute minutes",
        "h": "h hr hrs hour hours",
        "degC": "degC °C ºC ℃ C deg_C deg.C celsius Celsius",
        "degF": "degF °F ºF ℉ F deg_F deg.F fahrenheit Fahrenheit",
        "K": "K kelvin Kelvin",
        "m": "m metre meter metres meters",
        "cm": "cm",
        "mm": "mm millimetre millimeter millimetres millimeters",
        "um": "um µm μm micron microns micrometre micrometer micrometres micrometers",
        "nm": "nm nanometre nanometer nanometres nanometers",
        "in": "in inch inches",
        "N": "N newton newtons Newton",
        "mN": "mN",
        "kN": "kN",
        # a load cell read out in grams or kilograms reads the weight of that mass
        "gf": "gf g gram grams",
        "kgf": "kgf kg kilogram kilograms",
        "lbf": "lbf",
        "ohm": "ohm ohms Ohm Ohms OHM Ω Ω",
        "mohm": "mohm mOhm mΩ mΩ",
        "kohm": "kohm kOhm kΩ kΩ KOhm",
        "Mohm": "Mohm MOhm MΩ MΩ",
        "V": "V volt volts Volt",
        "mV": "mV",
        "A": "A amp amps ampere amperes",
        "mA": "mA",
        "uA": "uA µA μA",
        "per_m": "per_m 1/m m^-1 m-1",
        "per_cm": "per_cm 1/cm cm^-1 cm-1",
        "per_mm": "per_mm 1/mm mm^-1 mm-1",
    }
    out = {}
    for unit, words in table.items():
        for word in words.split():
            out[word] = unit
    return out


UNIT_ALIASES: dict[str, str] = _aliases()
"""Spelling of a unit in a header or ``[columns]`` -> its key in :data:`UNITS`
(``"µm"`` and ``"um"`` -> ``"um"``, ``"Ω"`` and ``"Ohm"`` -> ``"ohm"``, ``"°C"`` -> ``"degC"``,
``"F"`` -> ``"degF"``). Case matters where a prefix does (``"mohm"`` milli, ``"Mohm"`` mega)."""


def unit_key(text: str) -> str | None:
    """The :data:`UNITS` key of a unit as written (an alias of :data:`UNIT_ALIASES`), or None.

    Spaces and a leading ``"deg "`` / ``"°"`` spelled apart are tolerated
    (``"deg C"``, ``"° C"``); a different letter case is accepted only where
    it cannot change the prefix (``"OHMS"`` but never ``"MM"`` for ``"mm"``).
    """
    if not isinstance(text, str):
        return None
    word = text.strip()
    if word in UNIT_ALIASES:
        return UNIT_ALIASES[word]
    squeezed = "".join(word.split())
    if squeezed.lower().startswith("deg") and len(squeezed) == 4:
        squeezed = "deg" + squeezed[3:].upper()
    if squeezed in UNIT_ALIASES:
        return UNIT_ALIASES[squeezed]
    lowered = {}
    for alias, key in UNIT_ALIASES.items():
        if len(alias) > 2:
            lowered.setdefault(alias.lower(), set()).add(key)
    keys = lowered.get(squeezed.lower(), set())
    return next(iter(keys)) if len(keys) == 1 else None


def unit_suggestion(text: str, dimension: str | None = None) -> str:
    """``"; did you mean 'x'?"`` among real units (of ``dimension`` when given), or ``""``.

    A unit that differs from ``text`` only by a prefix or by letter case is never proposed:
    ``"xm"`` and ``"MM"`` are not answered ``"m"`` or ``"mm"`` (a factor of 10^3..10^6); a
    unit spelt as one in another case is told that a prefix's case is its size.
    """
    choices = [a for a, k in UNIT_ALIASES.items() if dimension is None or UNITS[k][0] == dimension]
    word = str(text).strip()
    low = word.lower()
    if any(c.lower() == low for c in choices):  # 'MM', 'Mm': a prefix's case is its size
        return " (a unit's prefix is case-sensitive: M mega, m milli)"
    ok = [
        c
        for c in close_matches(word, choices, n=3)
        if not (c.lower().endswith(low) or low.endswith(c.lower()))
    ]
    return "; did you mean " + repr(ok[0]) + "?" if ok else ""


CLOCK_UNITS: tuple[str, ...] = ("datetime", "clock")
"""``unit`` values of a ``time_s`` column holding wall-clock time stamps
(``2019-06-11 14:03:52.123456`` or ``14:03:52.1``), read as seconds from the first row."""

FORMAT_KEYS: dict[str, str] = {
    "header_row": "line of the header, 1 = first line; lines above it are skipped (a title); "
    "0 = the file has no header, columns are named by number (from = 1)",
    "units_row": "line holding the units under the header (skipped; gives the unit of a column "
    "whose [columns] entry states none)",
    "skip_rows": "lines at the top to skip before the header or, with header_row = 0, before the data "
    "(a title above a file without a header)",
}
"""Keys of ``[columns]`` that describe the file's layout, not a column -> what they mean."""

SI_UNITS: dict[str, str] = {
    "time": "s",
    "temperature": "degC",
    "length": "m",
    "force": "N",
    "resistance": "ohm",
    "voltage": "V",
    "current": "A",
    "curvature": "per_m",
}
"""Dimension -> the unit used inside tcamlab."""

VARIABLE_MAP: dict[str, tuple[str, str]] = {q.column: (q.name, q.column_unit) for q in QUANTITIES.values()}
"""Canonical CSV column -> (internal column name, unit of the canonical column).

Internal columns are in SI: time [s], temperature [degC], displacement [m],
voltage [V], current [A], resistance [ohm], force [N], cable [m],
r1/r2 [ohm], kappa1/kappa2 [1/m].
"""

INTERNAL_TO_CANONICAL: dict[str, str] = {v[0]: k for k, v in VARIABLE_MAP.items()}
"""Internal column name -> canonical CSV column name."""

KINDS: tuple[str, ...] = _kinds.KINDS
"""The kinds of run tcamlab knows (:mod:`tcamlab.kinds`)."""

REQUIRED: dict[str, tuple[str, ...]] = {k.name: k.required_columns for k in _kinds.REGISTRY.values()}
"""Kind -> canonical columns a run of that kind must have (from the kind registry)."""

OPTIONAL: dict[str, tuple[str, ...]] = {k.name: k.optional_columns for k in _kinds.REGISTRY.values()}
"""Kind -> canonical columns a run of that kind may have (from the kind registry)."""

MIN_ROWS: dict[str, int] = {k.name: k.min_rows for k in _kinds.REGISTRY.values()}
"""Kind -> fewest data rows a run needs to be fitted (from the kind registry)."""

DEFAULT_MAX_BYTES: int = 2 * 1024**3
"""Largest CSV file :func:`read_run` reads unless told otherwise [bytes] (2 GiB)."""

ABSOLUTE_ZERO_C: float = -273.15
"""Absolute zero [degC]."""

_NONNEGATIVE = ("resistance", "r1", "r2")
_HANGING_LOAD_KINDS = {"static": False, "dynamic": True}
"""Kinds whose logged ``load`` is a hanging weight, whose mean must not push -> whether it must
be strictly positive (the voltage-step model moves a mass; the oven test's coil may hang free).
A pull test's load cell is not among them: it reads zero at rest."""
_MAX_PREAMBLE_LINES = 10_000
_COLUMNS_HINT = (
    "map the file's header to the canonical name in the experiment file's "
    '[columns] table, e.g. time_s = { from = "reltime", unit = "ms" } (tcamlab init KIND --csv FILE '
    "writes one; fit-spring also takes --column CANON=HEADER[:UNIT])"
)


def _dimension(unit: str) -> str:
    return UNITS[unit][0]


def convert(values: Any, from_unit: str, to_unit: str) -> Any:
    """Convert numbers between two units of the same dimension.

    Parameters
    ----------
    values : float, numpy.ndarray or pandas.Series
        Values in ``from_unit``.
    from_unit, to_unit : str
        Keys of :data:`UNITS`.

    Returns
    -------
    Same type as ``values``, in ``to_unit``.

    Raises
    ------
    ValueError
        If a unit is unknown or the dimensions differ.
    """
    from_unit, to_unit = unit_key(from_unit) or from_unit, unit_key(to_unit) or to_unit
    for u in (from_unit, to_unit):
        if u not in UNITS:
            raise ValueError(f"unknown unit {u!r}")
    dim_a, fa, oa = UNITS[from_unit]
    dim_b, fb, ob = UNITS[to_unit]
    if dim_a != dim_b:
        raise ValueError(f"cannot convert {from_unit} ({dim_a}) to {to_unit} ({dim_b})")
    if from_unit == to_unit:
        return values
    return ((values * fa + oa) - ob) / fb


def canonical_to_internal(df: pd.DataFrame) -> pd.DataFrame:
    """Rename canonical columns to internal names and convert them to SI.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns named as in :data:`VARIABLE_MAP` (``displacement_mm`` ...),
        in their lab units. Other columns are passed through unchanged.

    Returns
    -------
    pandas.DataFrame
        A new frame with internal column names (``displacement`` ...) in SI.
    """
    out = {}
    for col in df.columns:
        if col in VARIABLE_MAP:
            name, unit = VARIABLE_MAP[col]
            out[name] = convert(df[col].to_numpy(dtype=np.float64), unit, SI_UNITS[_dimension(unit)])
        else:
            out[col] = df[col].to_numpy()
    return pd.DataFrame(out, index=df.index)


def internal_to_canonical(df: pd.DataFrame) -> pd.DataFrame:
    """Rename internal SI columns to canonical names in lab units.

    The inverse of :func:`canonical_to_internal`; columns that are not
    internal names are passed through unchanged.

    Parameters
    ----------
    df : pandas.DataFrame
        Internal columns (``time`` [s], ``displacement`` [m] ...).

    Returns
    -------
    pandas.DataFrame
        A new frame with canonical column names (``time_s``,
        ``displacement_mm`` ...) in lab units.
    """
    out = {}
    for col in df.columns:
        if col in INTERNAL_TO_CANONICAL:
            canon = INTERNAL_TO_CANONICAL[col]
            unit = VARIABLE_MAP[canon][1]
            out[canon] = convert(df[col].to_numpy(dtype=np.float64), SI_UNITS[_dimension(unit)], unit)
        else:
            out[col] = df[col].to_numpy()
    return pd.DataFrame(out, index=df.index)


# --- column specifications ----------------------------------------------------


@dataclass(frozen=True)
class ColumnSpec:
    """Where one canonical column comes from in a CSV file.

    Attributes
    ----------
    canonical : str
        Canonical column name (a key of :data:`VARIABLE_MAP`).
    header : str or int
        Header of the column in the file, or its number (1 = first column).
    unit : str
        Unit of ``raw * scale + offset`` (a key of :data:`UNITS`).
    scale : float
        Factor applied to the raw number [-].
    offset : float
        Added after scaling, in ``unit``.
    explicit : bool
        True when the experiment file named this column in ``[columns]``.
    clock : bool
        True for wall-clock time stamps (``unit = "datetime"``), read as
        seconds from the first row.
    unit_given : bool
        True when ``[columns]`` states the unit (else a units row may give it).
    """

    canonical: str
    header: str | int
    unit: str
    scale: float = 1.0
    offset: float = 0.0
    explicit: bool = False
    clock: bool = False
    unit_given: bool = False

    @property
    def label(self) -> str:
        """The column as error messages name it: its header, or ``column N``."""
        return f"column {self.header}" if isinstance(self.header, int) else repr(self.header)

    def to_si(self, raw: np.ndarray) -> np.ndarray:
        """``to_SI(raw * scale + offset, unit)`` as float64 [SI]."""
        values = raw
        if self.scale != 1.0:
            values = values * self.scale
        if self.offset != 0.0:
            values = values + self.offset
        dim, factor, off = UNITS[self.unit]
        if factor != 1.0:
            values = values * factor
        if off != 0.0:
            values = values + off
        return np.asarray(values, dtype=np.float64)


def column_spec(
    kind: str,
    canonical: str,
    spec: Any = None,
    *,
    where: str = "[columns]",
    error: type[Exception] = InputError,
) -> ColumnSpec:
    """Validate one ``[columns]`` entry and return it as a :class:`ColumnSpec`.

    Parameters
    ----------
    kind : str
        Run kind (one of :data:`KINDS`).
    canonical : str
        The key of the entry: a canonical column name for this kind.
    spec : str, mapping or None
        A header name, or a mapping with ``from`` (header), optional
        ``unit``, ``scale`` [-] and ``offset`` [unit]; None means the header
        is the canonical name itself.
    where : str
        Prefix for error messages (file name and table).
    error : exception class
        :class:`InputError` (default) or :class:`tcamlab.errors.ConfigError`.

    Raises
    ------
    InputError or ConfigError
        Unknown canonical name for the kind, unknown key, unknown unit, a
        unit of the wrong dimension, or a non-finite scale/offset.
    """
    if kind not in REQUIRED:
        raise error(f"{where}: unknown kind {kind!r}", "one of " + ", ".join(KINDS))
    allowed = REQUIRED[kind] + OPTIONAL[kind]
    if canonical not in allowed:
        raise error(
            f"{where}: {canonical!r} is not a column of a {kind} run{did_you_mean(canonical, allowed)}",
            "columns of a " + kind + " run: " + ", ".join(allowed),
        )
    canon_unit = VARIABLE_MAP[canonical][1]
    if spec is None:
        return ColumnSpec(canonical, canonical, canon_unit)
    if isinstance(spec, str):
        return ColumnSpec(canonical, spec, canon_unit, explicit=True)
    if not isinstance(spec, Mapping):
        raise error(
            f"{where}.{canonical}: expected a header name or an inline table, got {spec!r}",
            f'e.g. {canonical} = "Header in file" or {canonical} = {{ from = "Header", unit = "{canon_unit}" }}',
        )
    keys = ("from", "unit", "scale", "offset")
    for key in spec:
        if key not in keys:
            raise error(
                f"{where}.{canonical}: unknown key {key!r}{did_you_mean(str(key), keys)}",
                "allowed keys: from, unit, scale, offset",
            )
    header = spec.get("from", canonical)
    if isinstance(header, int) and not isinstance(header, bool):
        if header < 1:
            raise error(f"{where}.{canonical}.from: column numbers start at 1, got {header!r}")
    elif not isinstance(header, str) or not header.strip():
        raise error(
            f"{where}.{canonical}.from: expected a header name or a column number, got {header!r}",
            'e.g. from = "Load [mN]" or from = 3 (the third column)',
        )
    else:
        header = header.strip()
    written = spec.get("unit", canon_unit)
    if written in CLOCK_UNITS:
        if canonical != "time_s":
            raise error(f"{where}.{canonical}.unit: {written!r} (wall-clock time stamps) is for time_s only")
        numbers = _numbers(spec, where, canonical, error)
        return ColumnSpec(canonical, header, "s", *numbers, explicit=True, clock=True, unit_given=True)
    unit = unit_key(written) if isinstance(written, str) else None
    if unit is None:
        raise error(
            f"{where}.{canonical}.unit: unknown unit {written!r}"
            + unit_suggestion(str(written), _dimension(canon_unit)),
            f"{_dimension(canon_unit)} units: "
            + ", ".join(u for u, v in UNITS.items() if v[0] == _dimension(canon_unit)),
        )
    if _dimension(unit) != _dimension(canon_unit):
        raise error(
            f"{where}.{canonical}.unit: {unit!r} is a {_dimension(unit)} unit but {canonical} "
            f"holds a {_dimension(canon_unit)}",
            f"{_dimension(canon_unit)} units: "
            + ", ".join(u for u, v in UNITS.items() if v[0] == _dimension(canon_unit)),
        )
    scale, offset = _numbers(spec, where, canonical, error)
    return ColumnSpec(canonical, header, unit, scale, offset, explicit=True, unit_given="unit" in spec)


def _numbers(spec: Mapping, where: str, canonical: str, error: type[Exception]) -> tuple[float, float]:
    """``(scale, offset)`` of a ``[columns]`` entry, checked finite, scale not zero."""
    numbers = {}
    for key, default in (("scale", 1.0), ("offset", 0.0)):
        value = spec.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise error(f"{where}.{canonical}.{key}: expected a finite number, got {value!r}")
        numbers[key] = float(value)
    if numbers["scale"] == 0.0:
        raise error(f"{where}.{canonical}.scale: must not be zero")
    return numbers["scale"], numbers["offset"]


# --- reading ----------------------------------------------------------------


@dataclass
class RunData:
    """One ingested run.

    Attributes
    ----------
    path : pathlib.Path
        The CSV file.
    kind : str
        Run kind (one of :data:`KINDS`).
    data : pandas.DataFrame
        Internal SI columns (see :data:`VARIABLE_MAP`), float64, RangeIndex.
        ``displacement`` [m] is relative to the first kept row.
    sha256 : str
        SHA-256 of the raw file bytes (hex).
    n_rows_raw : int
        Data rows in the file (trailing blank lines not counted).
    n_dropped : int
        Rows dropped because of blank/NaN cells (``drop_na=True``).
    source_columns : dict of str to str
        Internal column name -> header in the file it came from.
    header_line : int
        1-based line number of the header in the file.
    displacement_zero : float
        Displacement of the first kept row that was subtracted so that
        ``displacement`` is the change from the first row [m]; 0 when the file
        already starts at zero or has no displacement column.
    units : dict of str to str
        Internal column name -> its SI unit (``"s"``, ``"m"``, ``"degC"`` ...).
    source_units : dict of str to str
        Internal column name -> how the file's numbers were read (``"um"``,
        ``"mN, scale -1"``, ``"datetime"``).
    join : dict or None
        For a run joined with a second instrument's file: the file, ``offset_s`` [s],
        the overlap [s], rows of the run outside it (dropped), the joined rows and
        columns, and the resampling.
    join_path : pathlib.Path or None
        The second instrument's file of a joined run.
    dropped : dict of str to int
        Every row not kept, by why: ``"blank cells"`` (``drop_na``), ``"outside the joined
        file's time span"``, ``"blank cells in <joined file>"``; empty when none was.
    columns : dict of str to dict
        The ``[columns]`` mapping as applied: canonical column -> ``from`` (header or column
        number), ``unit``, ``scale``, ``offset`` (and ``file`` for a joined column).
    smoothed : dict of str to dict
        Noisy inputs read by a slower instrument (a thermal camera's frames held or
        interpolated onto a 1 kHz log), which the models read averaged over whole frames:
        internal column -> ``rows_per_frame``, ``frames``, ``window_rows`` and ``frame_sd``
        [the column's SI unit] (:func:`tcamlab.signals.smooth_slow_input`). ``data`` holds the
        averaged column; the file keeps the logged one.
    """

    path: Path
    kind: str
    data: pd.DataFrame
    sha256: str
    n_rows_raw: int
    n_dropped: int
    source_columns: dict[str, str]
    header_line: int = 1
    displacement_zero: float = 0.0
    units: dict[str, str] = field(default_factory=dict)
    source_units: dict[str, str] = field(default_factory=dict)
    join: dict | None = None
    join_path: Path | None = None
    dropped: dict[str, int] = field(default_factory=dict)
    columns: dict[str, dict] = field(default_factory=dict)
    smoothed: dict[str, dict] = field(default_factory=dict)

    @property
    def n_dropped_total(self) -> int:
        """Rows dropped for any reason (:attr:`dropped`)."""
        return int(sum(self.dropped.values()))


def _mapping(selected: dict, file: str | None = None) -> dict[str, dict]:
    """The ``[columns]`` entries as applied to the selected columns (see :attr:`RunData.columns`)."""
    out = {}
    for name, (spec, _) in selected.items():
        entry = {"from": spec.header, "unit": "datetime" if spec.clock else spec.unit}
        entry |= {"scale": float(spec.scale), "offset": float(spec.offset)}
        out[INTERNAL_TO_CANONICAL[name]] = entry | ({"file": file} if file else {})
    return out


def input_files(run: RunData) -> list[tuple[str, Path, str]]:
    """Every file a run was read from, as ``(role, path, SHA-256)``: the run's CSV
    (``"run"``) and, for a run joined on time, the second instrument's file (``"joined"``),
    so that each output's provenance lists both."""
    files = [("run", run.path, run.sha256)]
    if run.join is not None and run.join_path is not None:
        files.append(("joined", run.join_path, run.join["sha256"]))
    return files


def sha256_file(path: str | os.PathLike, chunk_size: int = 1 << 20) -> str:
    """SHA-256 of a file's bytes, read in chunks.

    Parameters
    ----------
    path : path-like
        The file.
    chunk_size : int
        Bytes read at a time [bytes].

    Returns
    -------
    str
        Hex digest.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(chunk_size):
            h.update(chunk)
    return h.hexdigest()


@dataclass(frozen=True)
class FileFormat:
    """The layout of a log as ``[columns]`` declares it (:data:`FORMAT_KEYS`).

    Attributes
    ----------
    header_row : int or None
        1-based line of the header; 0 for a file without one; None to find it
        (the first line that is not blank or a ``#`` comment).
    units_row : int
        1-based line of a units row under the header, 0 when there is none.
    skip_rows : int
        Lines at the top never read as the header or data (a title).
    """

    header_row: int | None = None
    units_row: int = 0
    skip_rows: int = 0


def file_format(
    columns: Mapping[str, Any] | None, *, where: str = "[columns]", error: type[Exception] = InputError
) -> tuple[FileFormat, dict[str, Any]]:
    """Split ``[columns]`` into the file's layout and the column entries.

    Parameters
    ----------
    columns : mapping or None
        The ``[columns]`` table: :data:`FORMAT_KEYS` and canonical column entries.
    where : str
        Prefix for error messages.
    error : exception class
        :class:`InputError` or :class:`tcamlab.errors.ConfigError`.

    Returns
    -------
    (FileFormat, dict)
        The layout and the column entries (every other key).
    """
    columns = dict(columns or {})
    rows = {}
    for key in FORMAT_KEYS:
        if key not in columns:
            continue
        value = columns.pop(key)
        low = 1 if key == "units_row" else 0
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise error(
                f"{where}.{key}: expected a line number >= {low}, got {value!r}", f"{key}: {FORMAT_KEYS[key]}"
            )
        rows[key] = value
    fmt = FileFormat(rows.get("header_row"), rows.get("units_row", 0), rows.get("skip_rows", 0))
    if fmt.skip_rows and fmt.header_row and fmt.skip_rows >= fmt.header_row:
        raise error(
            f"{where}.skip_rows = {fmt.skip_rows} skips the header (header_row = {fmt.header_row})",
            "with header_row, the lines above it are skipped anyway: leave skip_rows out",
        )
    if fmt.units_row and fmt.header_row == 0:
        raise error(f"{where}.units_row: a file without a header (header_row = 0) has no units row")
    if fmt.units_row and fmt.header_row is not None and fmt.units_row <= fmt.header_row:
        raise error(
            f"{where}.units_row = {fmt.units_row} must come after header_row = {fmt.header_row}",
            "the units row is the line under the header",
        )
    return fmt, columns


@dataclass
class _Layout:
    """What the file's preamble and header look like."""

    header_line: int  # 1-based; 0 when the file has no header
    headers: list[str]
    sep: str
    decimal: str
    encoding: str
    data_start: int = 0  # lines before the first data line
    units: list[str] = field(default_factory=list)


def _check_text(first: bytes, shown: str) -> None:
    if first.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(
            f"{shown}: file is UTF-16 encoded",
            "save it as CSV in UTF-8 (or Latin-1); in Excel: 'CSV UTF-8 (comma delimited)'",
        )
    nul = first.find(b"\x00")
    if nul >= 0:
        raise InputError(
            f"{shown}: not a text CSV file (NUL byte at byte {nul + 1})",
            "a run is a text CSV file; check that the right file is named",
        )


def _scan(path: Path, shown: str, fmt: FileFormat) -> tuple[list[bytes], int | None, list[bytes]]:
    """The lines up to the header (or first data line), its index, and up to 50 data lines after it."""
    with open(path, "rb") as fh:
        _check_text(fh.read(8192), shown)
        fh.seek(0)
        raw_lines: list[bytes] = []
        found = None
        for i, line in enumerate(fh):
            if i == 0 and line.startswith(b"\xef\xbb\xbf"):
                line = line[3:]
            raw_lines.append(line)
            stripped = line.strip()
            if i < fmt.skip_rows:
                continue
            if fmt.header_row:
                if i + 1 == fmt.header_row:
                    found = i
                    break
            elif stripped and not stripped.startswith(b"#"):
                found = i
                break
            if i >= max(_MAX_PREAMBLE_LINES, fmt.header_row or 0, fmt.skip_rows):
                break
        data_sample: list[bytes] = []
        if found is not None:
            skip = max(fmt.units_row - found - 1, 0) if fmt.units_row else 0
            for line in fh:
                if skip:
                    skip -= 1
                    continue
                if line.strip():
                    data_sample.append(line)
                if len(data_sample) >= 50:
                    break
    return raw_lines, found, data_sample


def _no_header_found(shown: str, raw_lines: list[bytes], fmt: FileFormat) -> InputError:
    if fmt.header_row:
        return InputError(
            f"{shown}: header_row = {fmt.header_row} but the file has only {len(raw_lines)} lines",
            "header_row in [columns] is the 1-based line of the header",
        )
    if all(not line.strip() for line in raw_lines):
        return InputError(f"{shown}: file is empty", "a run needs a header line and data rows")
    return InputError(
        f"{shown}: no header line found (only '#' comments and blank lines"
        + (f" in the first {_MAX_PREAMBLE_LINES} lines)" if len(raw_lines) > _MAX_PREAMBLE_LINES else ")"),
        "a run needs a header line and data rows after any '#' comment lines",
    )


def _split_line(text: str, sep: str, shown: str, line: int) -> list[str]:
    try:
        cells = next(csv.reader([text], delimiter=sep, quotechar='"', skipinitialspace=True))
    except (csv.Error, StopIteration) as exc:
        raise InputError(f"{shown}: line {line}: cannot parse the line ({exc})") from None
    return [h.strip() for h in cells]


def _is_number(cell: str, decimal: str) -> bool:
    try:
        float(cell.replace(",", ".") if decimal == "," else cell)
        return True
    except ValueError:
        return False


def _sniff(path: Path, shown: str, fmt: FileFormat = FileFormat()) -> _Layout:
    """Find the header line (or the first data line), encoding, delimiter and decimal mark."""
    raw_lines, found, data_sample = _scan(path, shown, fmt)
    if found is None:
        raise _no_header_found(shown, raw_lines, fmt)
    head = b"".join(raw_lines)
    if b"\x00" in head:
        raise InputError(f"{shown}: not a text CSV file (binary content before the header)")
    try:
        head.decode("utf-8")
        encoding = "utf-8-sig"
    except UnicodeDecodeError:
        encoding = "latin-1"
    text_of = lambda b: b.decode("utf-8" if encoding == "utf-8-sig" else "latin-1", "replace")  # noqa: E731
    header_text = text_of(raw_lines[found]).rstrip("\r\n")
    if ";" in header_text and "," not in header_text:
        sep = ";"
        sample = b"".join(data_sample)
        decimal = "." if (b"." in sample and b"," not in sample) else ","
    elif "\t" in header_text and "," not in header_text:
        sep, decimal = "\t", "."
    else:
        sep, decimal = ",", "."
    cells = _split_line(header_text, sep, shown, found + 1)
    if fmt.header_row == 0:
        headers = [str(i + 1) for i in range(len(cells))]
        return _Layout(0, headers, sep, decimal, encoding, data_start=found)
    if fmt.header_row is None and cells and all(_is_number(c, decimal) for c in cells if c):
        raise InputError(
            f"{shown}: line {found + 1} holds only numbers, so it looks like data, not a header; "
            "it is not read as one (that would lose the first data row)",
            "if the file has no header, write header_row = 0 in [columns] and name the columns "
            "by number, e.g. time_s = { from = 1 }; tcamlab init KIND --csv FILE writes this for you",
        )
    units: list[str] = []
    if fmt.units_row:
        with open(path, "rb") as fh:
            line = b""
            for _ in range(fmt.units_row):
                line = fh.readline()
        units = _split_line(text_of(line).rstrip("\r\n"), sep, shown, fmt.units_row)
    data_start = max(found + 1, fmt.units_row)
    return _Layout(found + 1, cells, sep, decimal, encoding, data_start=data_start, units=units)


def _count_trailing_blank_lines(path: Path, size: int) -> int:
    """Blank lines at the end of the file that pandas would read as empty rows."""
    tail_len = min(size, 4096)
    with open(path, "rb") as fh:
        fh.seek(size - tail_len)
        tail = fh.read(tail_len)
    stripped = tail.rstrip(b" \t\r\n")
    if len(stripped) == 0 and tail_len < size:
        return 0  # more than 4 KiB of whitespace: leave it to the NaN check
    ws = tail[len(stripped) :]
    if not ws:
        return 0
    n_newlines = ws.count(b"\n")
    last = ws.rsplit(b"\n", 1)[-1] if n_newlines else ws
    partial = 1 if (n_newlines and last.strip(b"\r")) else 0
    return max(n_newlines - 1, 0) + partial


def _read_frame(path: Path, shown: str, layout: _Layout, usecols: list[int], dtype: Any) -> pd.DataFrame:
    """pandas C-engine read of the data rows of the selected columns."""
    last_exc: Exception | None = None
    encodings = [layout.encoding] + (["latin-1"] if layout.encoding != "latin-1" else [])
    for encoding in encodings:
        try:
            return pd.read_csv(
                path,
                sep=layout.sep,
                decimal=layout.decimal,
                header=None,
                names=list(range(len(layout.headers))),
                skiprows=layout.data_start,
                usecols=usecols,
                dtype=dtype,
                engine="c",
                encoding=encoding,
                skip_blank_lines=False,
                quotechar='"',
                index_col=False,
            )
        except UnicodeDecodeError as exc:
            last_exc = exc
            continue
        except pd.errors.EmptyDataError:
            return pd.DataFrame({c: pd.Series([], dtype=np.float64) for c in usecols})
        except (pd.errors.ParserError, csv.Error, OverflowError, MemoryError) as exc:
            raise InputError(
                f"{shown}: cannot parse the CSV: {' '.join(str(exc).split())}",
                "check delimiters and quotes; the file is read as it is, never modified",
            ) from None
    raise InputError(f"{shown}: cannot decode the file ({last_exc})", "save it as UTF-8") from None


def _locate_bad_cell(path: Path, shown: str, layout: _Layout, usecols: list[int]) -> pd.DataFrame:
    """Slow path: read as text, find the first non-numeric cell or convert all.

    Cells holding only whitespace count as blank (NaN).
    """
    try:
        text = _read_frame(path, shown, layout, usecols, dtype=str)
    except ValueError as exc:
        raise InputError(f"{shown}: cannot parse the CSV: {' '.join(str(exc).split())}") from None
    out = {}
    first_bad: tuple[int, int, str] | None = None
    for col in usecols:
        s = text[col]
        stripped = s.str.strip()
        if layout.decimal == ",":
            stripped = stripped.str.replace(",", ".", regex=False)
        blank = s.isna() | (stripped == "")
        values = pd.to_numeric(stripped.where(~blank), errors="coerce")
        bad = values.isna() & ~blank
        if bad.any():
            pos = int(np.flatnonzero(bad.to_numpy())[0])
            if first_bad is None or pos < first_bad[0]:
                first_bad = (pos, col, str(s.iloc[pos]))
        out[col] = values.to_numpy(dtype=np.float64, na_value=np.nan)
    if first_bad is not None:
        pos, col, value = first_bad
        value = value if len(value) <= 40 else value[:37] + "..."
        raise InputError(
            f"{shown}: line {layout.data_start + 1 + pos}, column {_column_label(layout, col)}: "
            f"non-numeric value {value!r}",
            "data rows must hold numbers only; '#' comments may appear only before the header",
        )
    return pd.DataFrame(out)


def read_run(
    path: str | os.PathLike,
    kind: str,
    columns: Mapping[str, Any] | None = None,
    *,
    drop_na: bool = False,
    max_bytes: int = DEFAULT_MAX_BYTES,
    shown: str | None = None,
    join: Mapping[str, Any] | None = None,
    only: tuple[str, ...] | None = None,
) -> RunData:
    """Read one rig CSV log into validated SI data.

    Parameters
    ----------
    path : path-like
        The CSV file. It is only read, never modified.
    kind : str
        ``"static"``, ``"dynamic"``, ``"sensing"`` or ``"curvature"``; sets the
        required and optional columns (:data:`REQUIRED`, :data:`OPTIONAL`).
    columns : mapping, optional
        The experiment file's ``[columns]`` table: canonical name -> header
        name, or -> ``{"from": header, "unit": unit, "scale": s, "offset": o}``
        (all but ``from`` optional). The value used is
        ``to_SI(raw * scale + offset, unit)``; ``unit`` defaults to the
        canonical column's unit. Columns not listed are looked up by their
        canonical name; optional columns that are absent are left out.
    drop_na : bool
        Drop rows with blank or NaN cells in the needed columns (counted in
        ``n_dropped``) instead of raising.
    max_bytes : int
        Refuse files larger than this [bytes]; default 2 GiB. The size is
        checked before anything is read.
    shown : str, optional
        How error messages name the file (default: ``str(path)``).
    join : mapping, optional
        A second instrument's file logged on its own clock: ``{"file": path,
        "columns": {time_s: ..., temperature_C: ...}, "offset_s": s, "shown": name}``.
        Its columns (all but ``time_s``) are linearly interpolated onto this
        file's time at (its time + ``offset_s``); rows outside its span are
        dropped and reported in :attr:`RunData.join`.
    only : tuple of str, optional
        Read just these canonical columns, all required (fit-spring reads a bare
        pull test's ``displacement_mm`` and ``force_N``; F = S delta needs no more).

    Returns
    -------
    RunData
        ``data`` has internal column names in SI, float64, a RangeIndex, and
        ``displacement`` re-zeroed to the first kept row.

    Raises
    ------
    InputError
        Missing, empty, oversized or unparsable file; header without data
        rows; missing required column; non-numeric, blank or non-finite
        cell; duplicated or decreasing time; negative resistance; temperature
        below absolute zero; force of the wrong sign in a pull test; fewer
        rows than :data:`MIN_ROWS` for the kind.
    """
    shown = str(path) if shown is None else shown
    if "\x00" in str(path):
        raise InputError(f"{shown!r}: not a file name (it holds a NUL character)")
    try:
        return _read_run(Path(path), shown, kind, columns, drop_na, max_bytes, join, only)
    except OSError as exc:  # unreadable, a FIFO that vanished, name too long ...
        raise InputError(
            f"{shown}: cannot read the file ({exc.strerror or exc})",
            "check that the file exists and is readable",
        ) from None


def _size_text(n: int) -> str:
    """Bytes as text: exact below 1 MiB, else in MiB/GiB."""
    if n < 1024**2:
        return f"{n} bytes"
    if n < 1024**3:
        return f"{n / 1024**2:.1f} MiB"
    return f"{n / 1024**3:.2f} GiB"


def _check_file(p: Path, shown: str, kind: str, max_bytes: int) -> int:
    """Refuse an unknown kind, a missing, special, oversized or empty file; the size [bytes]."""
    if kind not in REQUIRED:
        raise InputError(f"{shown}: unknown run kind {kind!r}", "one of " + ", ".join(KINDS))
    if not p.exists():
        raise InputError(f"{shown}: file not found", "check the run path in the experiment file")
    if not p.is_file():
        raise InputError(f"{shown}: not a regular file")
    size = p.stat().st_size
    if size > max_bytes:
        raise InputError(
            f"{shown}: file is {_size_text(size)}, larger than the limit of {_size_text(max_bytes)}",
            "if the file really is this large, raise the limit with --max-bytes N "
            "(library: read_run(..., max_bytes=N))",
        )
    if size == 0:
        raise InputError(f"{shown}: file is empty", "a run needs a header line and data rows")
    return size


def _column_label(layout: _Layout, col: int) -> str:
    """A column as messages name it: its header, or ``column N`` in a file without one."""
    return repr(layout.headers[col]) if layout.header_line else f"column {col + 1}"


_FOREIGN_UNITS = frozenset("rad mrad deg ° Hz kHz W mW J Pa kPa MPa g kg rpm".split())
"""Units of quantities no tcamlab column holds: a header carrying one is never proposed for a column."""


def _header_unit(header: str) -> tuple[str | None, bool]:
    """The unit a header states (``"Load [mN]"``, ``"angle_rad"``), and whether it was bracketed."""
    text = header.strip()
    if text[-1:] in ")]}" and any(b in text for b in "([{"):
        return text[max(text.rfind(b) for b in "([{") + 1 : -1].strip(), True
    for sep in ("/", "_", " "):
        if sep in text:
            return text.rsplit(sep, 1)[1].strip(), False
    return None, False


def _of_dimension(header: str, canon: str) -> bool:
    """Whether a header may hold ``canon``: no unit stated, or one of ``canon``'s dimension."""
    unit, bracketed = _header_unit(header)
    if not unit or unit == "%":
        return True
    key = unit_key(unit)
    if key is None:
        return not bracketed and unit not in _FOREIGN_UNITS
    return _dimension(key) == _dimension(VARIABLE_MAP[canon][1])


def _free_column_hint(canon: str, kind: str, layout: _Layout, taken: dict[int, str]) -> str:
    """Where a header-less file's column ``canon`` may be: a column number no other column takes."""
    free = [i + 1 for i in range(len(layout.headers)) if i not in taken]
    mapped = ", ".join(f"{i + 1} is {name}" for i, name in sorted(taken.items()))
    if not free:
        return (
            f"every one of its {len(layout.headers)} columns is mapped ({mapped}): a {kind} run needs a "
            f"{canon} column too; add it to the log and map it in [columns] by its number"
        )
    return f"map it by its number in [columns], e.g. {canon} = {{ from = {free[0]} }}" + (
        f" (columns are numbered from 1 at the left; {mapped})" if mapped else ""
    )


def _missing_column(
    shown: str, kind: str, layout: _Layout, spec: ColumnSpec, canon: str, taken: dict[int, str] | None = None
) -> InputError:
    """The error for a column the file lacks, proposing the ``[columns]`` line that maps a near header."""
    headers = layout.headers
    required = canon in REQUIRED[kind]
    what = "required" if required else "mapped"
    if isinstance(spec.header, int):
        return InputError(
            f"{shown}: {canon} is mapped to column {spec.header} but the file has {len(headers)} columns",
            "column numbers start at 1 at the left",
        )
    if not layout.header_line:
        return InputError(
            f"{shown}: the file has no header (header_row = 0), so {canon} needs a column number",
            _free_column_hint(canon, kind, layout, taken or {}),
        )
    near = close_matches(spec.header, [h for h in headers if _of_dimension(h, canon)])
    if near:
        entry = {"from": near[0]}
        said, _ = _header_unit(near[0])
        if spec.unit_given or spec.unit != VARIABLE_MAP[canon][1]:
            entry["unit"] = spec.unit
        elif said and unit_key(said) not in (None, unit_key(VARIABLE_MAP[canon][1])):
            # the header names its unit ("current_mA"): the line must say it, or the
            # column is read in the canonical unit, a factor of 1000 off without a word
            entry["unit"] = said
        if spec.scale != 1.0:
            entry["scale"] = spec.scale
        if spec.offset != 0.0:
            entry["offset"] = spec.offset
        hint = f"the file has {near[0]!r}; map it in the experiment file's [columns] as {_toml_entry(canon, entry)}"
    elif canon in headers:
        # a run logged with tcamlab's own names (a designed run) beside runs mapped from a lab's
        # headers: mapping this one globally would break the others
        hint = (
            f"the file has {canon!r} itself; give this run its own columns in runs, e.g. "
            f'{{ file = "{Path(shown).name}", columns = {{ {canon} = "{canon}" }} }} (the path as in runs)'
        )
    elif not required:
        # an optional channel only the new runs log (a designed run's load cell): a global
        # mapping reaches the old runs too
        hint = (
            f"if this run does not log {canon}, map it only for the runs that do, in their own "
            f'columns in runs, e.g. {{ file = "new.csv", columns = {{ {canon} = "{spec.header}" }} }}, '
            "and take it out of [columns]"
        )
    else:
        hint = _COLUMNS_HINT
    return InputError(
        f"{shown}: line {layout.header_line}: {what} column {spec.header!r}"
        + (f" (for {canon})" if spec.header != canon else "")
        + f" not found in the header of a {kind} run (headers: "
        + ", ".join(repr(h) for h in headers[:12])
        + (", ..." if len(headers) > 12 else "")
        + ")",
        hint,
    )


def _toml_entry(canon: str, entry: Mapping[str, Any]) -> str:
    """``canon = { from = "...", unit = "..." }`` as valid TOML."""
    parts = []
    for k, v in entry.items():
        text = (
            '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"' if isinstance(v, str) else f"{v:g}"
        )
        parts.append(f"{k} = {text}")
    return f"{canon} = {{ " + ", ".join(parts) + " }"


def _unit_from_row(shown: str, layout: _Layout, spec: ColumnSpec, idx: int) -> ColumnSpec:
    """The spec with the units row's unit when ``[columns]`` states none."""
    if spec.unit_given or not layout.units or idx >= len(layout.units):
        return spec
    written = layout.units[idx].strip().strip("()[]{} ")
    if not written:
        return spec
    unit = unit_key(written)
    dim = _dimension(VARIABLE_MAP[spec.canonical][1])
    if unit is None or _dimension(unit) != dim:
        what = f"which is not a {dim} unit tcamlab knows" if unit is None else f"a {_dimension(unit)} unit"
        raise InputError(
            f"{shown}: line {layout.header_line + 1}, column {_column_label(layout, idx)}: the units row "
            f"says {written!r}, {what}, but {spec.canonical} holds a {dim}" + unit_suggestion(written, dim),
            f'state the unit in [columns], e.g. {spec.canonical} = {{ from = ..., unit = "{VARIABLE_MAP[spec.canonical][1]}" }}',
        )
    return ColumnSpec(
        spec.canonical, spec.header, unit, spec.scale, spec.offset, spec.explicit, spec.clock, True
    )


def _select_columns(
    shown: str, kind: str, layout: _Layout, specs: dict, wanted=None, required=None
) -> dict[str, tuple[ColumnSpec, int]]:
    """Internal name -> (column spec, position in the file) of every column the kind reads
    (``wanted``, default all of the kind's; ``required``, default the kind's required ones)."""
    headers = layout.headers
    positions: dict[str, list[int]] = {}
    for i, h in enumerate(headers):
        positions.setdefault(h, []).append(i)
    selected: dict[str, tuple[ColumnSpec, int]] = {}
    wanted = REQUIRED[kind] + OPTIONAL[kind] if wanted is None else wanted
    required = REQUIRED[kind] if required is None else required
    taken = {
        s.header - 1: c for c, s in specs.items() if isinstance(s, ColumnSpec) and isinstance(s.header, int)
    }
    for canon in wanted:
        spec = specs.get(canon) or column_spec(kind, canon)
        if isinstance(spec.header, int):
            where = [spec.header - 1] if spec.header <= len(headers) else None
        else:
            where = positions.get(spec.header) if layout.header_line else None
        if where is None:
            if canon not in required and not spec.explicit:
                continue
            raise _missing_column(shown, kind, layout, spec, canon, taken)
        if len(where) > 1:
            raise InputError(
                f"{shown}: line {layout.header_line}: header {spec.header!r} appears in "
                f"columns {', '.join(str(i + 1) for i in where)}",
                f"name the column by its number in [columns], e.g. {canon} = {{ from = {where[0] + 1} }}",
            )
        selected[VARIABLE_MAP[canon][0]] = (_unit_from_row(shown, layout, spec, where[0]), where[0])
    return selected


def _clock_seconds(text: pd.Series, shown: str, layout: _Layout, col: int) -> np.ndarray:
    """Wall-clock time stamps as seconds from the first one; blank cells give NaN."""
    s = text.astype("string").str.strip()
    blank = s.isna() | (s == "")
    best = None
    for parse in (
        lambda x: pd.to_datetime(x, format="ISO8601", errors="coerce"),
        lambda x: pd.to_timedelta(x, errors="coerce"),
    ):
        try:
            t = parse(s.where(~blank).astype(object))
        except (ValueError, TypeError):
            continue
        bad = t.isna().to_numpy() & ~blank.to_numpy()
        if best is None or bad.sum() < best[1].sum():
            best = (t, bad)
    if best is None or best[1].any():
        pos = 0 if best is None else int(np.flatnonzero(best[1])[0])
        raise InputError(
            f"{shown}: line {layout.data_start + 1 + pos}, column {_column_label(layout, col)}: "
            f"{str(text.iloc[pos])!r} is not a time stamp",
            'unit = "datetime" reads time stamps like 2019-06-11 14:03:52.123456 or 14:03:52.1',
        )
    t = best[0]
    valid = np.flatnonzero(~blank.to_numpy())
    if valid.size == 0:
        return np.full(len(t), np.nan)
    delta = t - t.iloc[int(valid[0])]
    return (delta.dt.total_seconds() if hasattr(delta, "dt") else delta).to_numpy(
        dtype=np.float64, na_value=np.nan
    )


def _read_values(p: Path, shown: str, layout: _Layout, selected: dict, size: int) -> pd.DataFrame:
    """The selected columns' raw numbers, trailing blank lines dropped; refuses a header without data."""
    clocks = sorted({idx for spec, idx in selected.values() if spec.clock})
    usecols = sorted({idx for _, idx in selected.values()} - set(clocks))
    try:
        raw = _read_frame(p, shown, layout, usecols, dtype=np.float64)
    except ValueError:  # a cell that is not a number: find and name it
        raw = _locate_bad_cell(p, shown, layout, usecols)
    if clocks:
        text = _read_frame(p, shown, layout, clocks, dtype=str)
        for idx in clocks:
            raw[idx] = _clock_seconds(text[idx], shown, layout, idx)
    n_trailing = _count_trailing_blank_lines(p, size)
    if n_trailing:
        n_keep = len(raw) - n_trailing
        tail_blank = raw.iloc[max(n_keep, 0) :].isna().all(axis=1).all()
        if n_keep >= 0 and tail_blank:
            raw = raw.iloc[:n_keep]
    if len(raw) == 0:
        raise InputError(
            f"{shown}: line {layout.data_start}: header only, no data rows",
            "a run needs data rows after the header",
        )
    return raw


@dataclass
class _Where:
    """Names a cell of the file for error messages: the line as an editor shows it, the column."""

    shown: str
    layout: _Layout
    selected: dict
    kept_pos: np.ndarray

    def line(self, j: int) -> int:
        """Editor line of the j-th kept data row."""
        return self.layout.data_start + 1 + int(self.kept_pos[j])

    def column(self, name: str) -> str:
        spec = self.selected[name][0]
        return spec.label + (f" ({spec.canonical})" if spec.header != spec.canonical else "")

    def cell(self, j: int, name: str) -> str:
        return f"{self.shown}: line {self.line(j)}, column {self.column(name)}"


def _drop_blank(data: dict, where: _Where, drop_na: bool) -> tuple[dict, int]:
    """Refuse blank or NaN cells, or with ``drop_na`` drop their rows; (data, rows dropped)."""
    nan_mask = np.zeros(len(where.kept_pos), dtype=bool)
    for v in data.values():
        nan_mask |= np.isnan(v)
    if not nan_mask.any():
        return data, 0
    if not drop_na:
        pos = int(np.flatnonzero(nan_mask)[0])
        bad = next(n for n in data if np.isnan(data[n][pos]))
        n_bad = int(nan_mask.sum())
        raise InputError(
            f"{where.cell(pos, bad)}: blank or NaN cell" + (f" ({n_bad} rows have one)" if n_bad > 1 else ""),
            "fill the cell, or drop incomplete rows with drop_na=True (CLI: --drop-na)",
        )
    keep = ~nan_mask
    where.kept_pos = np.flatnonzero(keep)
    return {n: v[keep] for n, v in data.items()}, int(nan_mask.sum())


def _first_bad(mask: np.ndarray) -> int | None:
    return int(np.flatnonzero(mask)[0]) if mask.any() else None


def _check_values(data: dict, kind: str, where: _Where, n_dropped: int) -> None:
    """Refuse infinite values, too few rows, time that does not increase, impossible values."""
    for name in data:
        j = _first_bad(~np.isfinite(data[name]))
        if j is not None:
            raise InputError(
                f"{where.cell(j, name)}: non-finite value {data[name][j]!r}",
                "every cell must be a finite number",
            )
    n = len(where.kept_pos)
    if n < MIN_ROWS[kind]:
        raise InputError(
            f"{where.shown}: only {n} usable data row{'s' if n != 1 else ''}"
            + (f" ({n_dropped} dropped for blank cells)" if n_dropped else "")
            + f"; a {kind} run needs at least {MIN_ROWS[kind]}",
            "record a longer run",
        )
    if "time" in data:
        t = data["time"]
        dt = np.diff(t)
        j = _first_bad(~(dt > 0))
        if j is not None:
            j += 1
            what = "duplicated" if dt[j - 1] == 0 else "decreasing"
            backwards = bool(np.all(dt < 0))
            raise InputError(
                f"{where.cell(j, 'time')}: {what} time {t[j]:.9g} s after {t[j - 1]:.9g} s on line {where.line(j - 1)}",
                "the rows run backwards in time: sort them oldest first (a copy; the log stays as it is)"
                if backwards
                else "time must increase strictly from row to row; sort the rows by time, or split "
                "concatenated runs into separate files",
            )
    for name in _NONNEGATIVE:
        j = _first_bad(data[name] < 0) if name in data else None
        if j is not None:
            raise InputError(
                f"{where.cell(j, name)}: negative resistance {data[name][j]:.6g} ohm",
                "a resistance cannot be negative; check the column mapping and its unit",
            )
    j = _first_bad(data["temperature"] < ABSOLUTE_ZERO_C) if "temperature" in data else None
    if j is not None:
        raise InputError(
            f"{where.cell(j, 'temperature')}: temperature {data['temperature'][j]:.6g} degC is below "
            "absolute zero (-273.15 degC)",
            "check the temperature unit (degC, degF or K) in [columns]",
        )
    _check_hanging_load(data, kind, where)
    _check_kelvin(data, where)


def _check_hanging_load(data: dict, kind: str, where: _Where) -> None:
    """Refuse a hanging-load column whose mean does not pull (zero, or a sign flipped)."""
    if kind not in _HANGING_LOAD_KINDS or "load" not in data or not data["load"].size:
        return
    mean = float(np.mean(data["load"]))
    if mean > 0 or (mean == 0 and not _HANGING_LOAD_KINDS[kind]):
        return
    hint = "log the weight in newtons (m g), or leave the column out to use the rig's load_g"
    if mean < 0:
        hint = f"if the load cell reads tension as negative, map it in [columns] as {_flipped('load_N', where.selected['load'][0])}"
    raise InputError(
        f"{where.shown}: column {where.column('load')}: the hanging load averages {mean:.6g} N; "
        f"a hanging weight pulls, so it must be {'positive' if _HANGING_LOAD_KINDS[kind] else 'at least 0'}",
        hint,
    )


def _check_kelvin(data: dict, where: _Where) -> None:
    """Refuse a temperature column read as degC whose every row is above 200 degC: nylon
    melts near 260 degC, so such a log is almost surely in kelvin (293 K is 20 degC)."""
    if "temperature" not in data or not data["temperature"].size:
        return
    spec = where.selected["temperature"][0]
    t = data["temperature"]
    if spec.unit == "degC" and float(np.min(t)) > 200.0:
        entry = {"from": spec.header, "unit": "K"} | ({"scale": spec.scale} if spec.scale != 1.0 else {})
        raise InputError(
            f"{where.shown}: column {where.column('temperature')}: every temperature is above 200 degC "
            f"({float(np.min(t)):.5g} to {float(np.max(t)):.5g}); a twisted-and-coiled nylon fiber melts "
            "near 260 degC, so is this column in kelvin?",
            f"if it is, map it in [columns] as {_toml_entry('temperature_C', entry)}",
        )


def _read_columns(
    p: Path, shown: str, kind: str, columns, drop_na: bool, max_bytes: int, wanted=None, required=None
):
    """One file's selected columns in SI: (data, where, layout, selected, raw row count, rows dropped)."""
    size = _check_file(p, shown, kind, max_bytes)
    fmt, entries = file_format(columns, where=f"{shown}: [columns]")
    specs = {c: column_spec(kind, c, spec, where=f"{shown}: [columns]") for c, spec in entries.items()}
    layout = _sniff(p, shown, fmt)
    selected = _select_columns(shown, kind, layout, specs, wanted, required)
    raw = _read_values(p, shown, layout, selected, size)
    data = {name: spec.to_si(raw[idx].to_numpy(dtype=np.float64)) for name, (spec, idx) in selected.items()}
    where = _Where(shown, layout, selected, np.arange(len(raw)))
    data, n_dropped = _drop_blank(data, where, drop_na)
    return data, where, layout, selected, len(raw), n_dropped


def _join(data: dict, where: _Where, kind: str, join: Mapping[str, Any], drop_na: bool, max_bytes: int):
    """Interpolate a second instrument's columns onto the run's time; (data, join record, its columns).

    The second file's time plus ``offset_s`` is the run's time; rows of the run outside
    the second file's span are dropped (counted in the record), never extrapolated.
    """
    jp = Path(join["file"])
    jshown = str(join.get("shown", jp))
    _, entries = file_format(join.get("columns"), where=f"{jshown}: join columns")
    joined = tuple(c for c in entries if c != "time_s")
    if "time" not in data:
        raise InputError(
            f"{where.shown}: a run joined with {jshown} needs its own time_s column to join on",
            "map the run's time in [columns]; the two files are joined on time",
        )
    offset = float(join.get("offset_s", 0.0))
    jdata, jwhere, _, jsel, _, jblank = _read_columns(
        jp, jshown, kind, join.get("columns"), drop_na, max_bytes, ("time_s", *joined), ("time_s", *joined)
    )
    _check_values(jdata, kind, jwhere, 0)
    t, tj = data["time"], jdata["time"] + offset
    inside = (t >= tj[0]) & (t <= tj[-1])
    if not inside.any():
        raise InputError(
            f"{where.shown}: its time ({t[0]:.6g} to {t[-1]:.6g} s) and {jshown}'s time plus offset_s = "
            f"{offset:g} ({tj[0]:.6g} to {tj[-1]:.6g} s) do not overlap",
            "check offset_s in the run's join table: it is added to the joined file's time",
        )
    data = {k: v[inside] for k, v in data.items()}
    where.kept_pos = where.kept_pos[inside]
    names = [VARIABLE_MAP[c][0] for c in joined]
    for name in names:
        data[name] = np.interp(data["time"], tj, jdata[name])
        where.selected[name] = jsel[name]
    record = {
        "file": jshown,
        "sha256": sha256_file(jp),
        "offset_s": offset,
        "overlap_s": [float(data["time"][0]), float(data["time"][-1])],
        "rows_outside_overlap": int((~inside).sum()),
        "blank_rows_dropped": int(jblank),
        "joined_rows": int(tj.size),
        "columns": [VARIABLE_MAP[c][0] for c in joined],
        "resampling": "linear interpolation onto the run's time",
    }
    return data, record, {n: jsel[n] for n in names}


def _read_run(
    p: Path,
    shown: str,
    kind: str,
    columns: Mapping[str, Any] | None,
    drop_na: bool,
    max_bytes: int,
    join=None,
    only=None,
) -> RunData:
    """:func:`read_run` without the translation of OSError."""
    wanted = only
    if join:
        _, jentries = file_format(
            join.get("columns"), where=f"{join.get('shown', join['file'])}: join columns"
        )
        wanted = tuple(c for c in REQUIRED[kind] + OPTIONAL[kind] if c not in jentries or c == "time_s")
    data, where, layout, selected, n_raw, n_dropped = _read_columns(
        p, shown, kind, columns, drop_na, max_bytes, wanted, only
    )
    record, jsel = None, {}
    if join:
        data, record, jsel = _join(data, where, kind, join, drop_na, max_bytes)
    _check_values(data, kind, where, n_dropped)
    displacement_zero = 0.0
    if "displacement" in data:
        displacement_zero = float(data["displacement"][0])
        if displacement_zero != 0.0:
            data["displacement"] = data["displacement"] - displacement_zero
    if "force" in _kinds.get_kind(kind).tension_outputs:
        _check_pull_force(shown, data, selected)
    frame = pd.DataFrame(data)
    frame.index = pd.RangeIndex(len(frame))
    smoothed = {} if only else _smooth_slow_inputs(frame, kind)
    dropped = {"blank cells": n_dropped} if n_dropped else {}
    if record and record["rows_outside_overlap"]:
        dropped["outside the joined file's time span"] = record["rows_outside_overlap"]
    if record and record["blank_rows_dropped"]:
        dropped[f"blank cells in {record['file']}"] = record["blank_rows_dropped"]
    return RunData(
        path=p,
        kind=kind,
        data=frame,
        sha256=sha256_file(p),
        n_rows_raw=n_raw,
        n_dropped=n_dropped,
        source_columns={
            name: layout.headers[idx] if layout.header_line else f"column {idx + 1}"
            for name, (_, idx) in selected.items()
        }
        | {name: f"{record['file']}: {spec.header}" for name, (spec, _) in jsel.items()},
        header_line=layout.header_line,
        displacement_zero=displacement_zero,
        units={name: SI_UNITS[_dimension(spec.unit)] for name, (spec, _) in (selected | jsel).items()},
        source_units={name: _how_read(spec) for name, (spec, _) in (selected | jsel).items()},
        join=record,
        join_path=Path(join["file"]) if join else None,
        dropped=dropped,
        columns=_mapping({n: v for n, v in selected.items() if n not in jsel})
        | _mapping(jsel, record["file"] if record else None),
        smoothed=smoothed,
    )


def _smooth_slow_inputs(frame: pd.DataFrame, kind: str) -> dict[str, dict]:
    """Replace each noisy input of the kind that a slower instrument logged by its average over
    whole frames (:func:`tcamlab.signals.smooth_slow_input`, which says why); what was done,
    per column (:attr:`RunData.smoothed`)."""
    done = {}
    for col in _kinds.get_kind(kind).noisy_inputs:
        if col in frame:
            x, info = smooth_slow_input(frame[col].to_numpy(float))
            if info is not None:
                frame[col] = x
                done[col] = info
    return done


def column_option(text: str) -> tuple[str, Any]:
    """A command-line column mapping ``CANON=HEADER``, ``CANON=HEADER:UNIT`` or
    ``CANON=HEADER:UNIT:SCALE`` as a ``[columns]`` entry (``force_N=Load [mN]:mN`` -> ``("force_N", {"from": "Load [mN]", "unit": "mN"})``);
    a layout key takes a line number (``header_row=2``).

    Raises
    ------
    InputError
        Without ``=``.
    """
    canon, sep, header = text.partition("=")
    if not sep or not canon.strip() or not header.strip():
        raise InputError(
            f"--column {text!r}: expected CANON=HEADER or CANON=HEADER:UNIT",
            'e.g. --column "force_N=Load [mN]:mN" --column "displacement_mm=Extension (µm):um"',
        )
    if canon.strip() in FORMAT_KEYS:
        try:
            return canon.strip(), int(header)
        except ValueError:
            raise InputError(f"--column {text!r}: {canon.strip()} takes a line number") from None
    parts = header.rsplit(":", 2)
    if (
        len(parts) == 3
        and parts[0].strip()
        and unit_key(parts[1].strip())
        and _is_number(parts[2].strip(), ".")
    ):
        return canon.strip(), {"from": parts[0].strip(), "unit": parts[1].strip(), "scale": float(parts[2])}
    name, colon, unit = header.rpartition(":")
    if colon and name.strip() and unit_key(unit.strip()):
        return canon.strip(), {"from": name.strip(), "unit": unit.strip()}
    return canon.strip(), {"from": header.strip()}


def sign_flip_entry(run: RunData, canon: str) -> str:
    """The ``[columns]`` entry that reads a run's column ``canon`` with the opposite sign
    (``force_N = { from = "Load", unit = "mN", scale = -1 }``)."""
    internal = VARIABLE_MAP[canon][0]
    how = run.source_units.get(internal, VARIABLE_MAP[canon][1])
    unit, _, rest = how.partition(",")
    scale = 1.0
    if rest.strip().startswith("scale"):
        scale = float(rest.split()[1])
    entry: dict[str, Any] = {"from": run.source_columns.get(internal, canon)}
    if unit.strip() != VARIABLE_MAP[canon][1]:
        entry["unit"] = unit.strip()
    entry["scale"] = -scale
    return _toml_entry(canon, entry)


def _how_read(spec: ColumnSpec) -> str:
    """``"um"``, ``"mN, scale -1"``, ``"datetime"``: how a column's numbers were read."""
    text = "datetime" if spec.clock else spec.unit
    if spec.scale != 1.0:
        text += f", scale {spec.scale:g}"
    if spec.offset != 0.0:
        text += f", offset {spec.offset:g}"
    return text


def _check_pull_force(shown: str, data: dict[str, np.ndarray], selected: dict) -> None:
    """Flag a pull test whose force reads negative under load.

    A small negative reading at zero load (sensor offset, noise) is data. Only
    when most rows with positive displacement read a force below
    ``-0.05 * max|force|`` is the sign taken to be wrong.
    """
    force = data["force"]
    loaded = data["displacement"] > 0
    n_loaded = int(loaded.sum())
    fmax = float(np.max(np.abs(force))) if force.size else 0.0
    if n_loaded == 0 or fmax == 0.0:
        return
    negative = force[loaded] < -0.05 * fmax
    if int(negative.sum()) * 2 > n_loaded:
        spec = selected["force"][0]
        median = float(np.median(force[loaded]))
        raise InputError(
            f"{shown}: column {spec.label} (force_N): {int(negative.sum())} of {n_loaded} rows "
            f"with displacement > 0 read a negative force (median {median:.4g} N); a pull test "
            "stretches the sensor, so the force should be positive",
            f"if the load cell reads tension as negative, map it in [columns] as {_flipped('force_N', spec)}",
        )


def _flipped(canonical: str, spec) -> str:
    """The ``[columns]`` entry that reads ``spec``'s column with its sign flipped (TOML)."""
    entry: dict[str, Any] = {"from": spec.header}
    if spec.unit != VARIABLE_MAP[canonical][1] or spec.unit_given:
        entry["unit"] = spec.unit
    entry["scale"] = -spec.scale
    if spec.offset:
        entry["offset"] = -spec.offset
    return _toml_entry(canonical, entry)
