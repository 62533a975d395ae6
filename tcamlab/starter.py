"""``tcamlab init``: a starter experiment file written from a lab's own CSV log.

:func:`inspect_csv` reads the top of the file as an instrument wrote it (a
title row above the header, a units row under it, no header at all, headers
repeated in side-by-side blocks, wall-clock time stamps) and
:func:`recognise` names the tcamlab column each header holds from its words
and its unit (``"Extension (µm)"``, ``"Load [mN]"``, ``"Temp (F)"``,
``"R (Ohm)"``, ``"Axial force [N]"``). :func:`starter_text` writes the
experiment file: a ``[columns]`` mapping of every recognised channel, every
``[sample]`` and ``[rig]`` key the kind uses with its definition, unit, how to
measure it and a typical value, and, for what the file cannot tell,
placeholders (:data:`PLACEHOLDER`) that loading refuses, naming each key
(:func:`placeholders`), until they are filled in.
"""

from __future__ import annotations

import csv
import json
import os
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from tcamlab import io as tio
from tcamlab.errors import ConfigError, InputError
from tcamlab.kinds import KINDS, get_kind
from tcamlab.kinds.dynamic import stated_voltage_warning
from tcamlab.metrics import implausible_value_warnings
from tcamlab.params import RIG_KEYS, SAMPLE_KEYS
from tcamlab.text import did_you_mean

__all__ = [
    "PLACEHOLDER",
    "GUIDE",
    "CsvLayout",
    "inspect_csv",
    "split_header",
    "recognise",
    "candidates",
    "starter_text",
    "write_starter",
    "placeholders",
    "CheckReport",
    "check_experiment",
]

PLACEHOLDER = "FILL IN"
"""Start of every value ``tcamlab init`` could not know; loading refuses it."""

_SCAN_LINES = 200


@dataclass(frozen=True)
class Guide:
    """What a ``[sample]`` or ``[rig]`` key is, for the starter file's comments.

    Attributes
    ----------
    definition : str
        What the value is (with its symbol in the thesis).
    measure : str
        How a lab measures it.
    typical : str
        A typical value in the key's unit and where it comes from.
    fill : str
        ``"required"`` (a placeholder to fill in), ``"typical"`` (written with the
        typical value, to replace if measured) or ``"optional"`` (commented out).
    value : object
        The typical value written for ``"typical"`` and shown for ``"optional"``.
    """

    definition: str
    measure: str
    typical: str
    fill: str = "required"
    value: object = None


GUIDE: dict[str, Guide] = {
    "fiber_diameter_mm": Guide(
        "diameter of the twisted fiber (thread) before coiling, d0 [mm]",
        "micrometer or microscope on a twisted, uncoiled length; mean of 5 readings",
        "0.17 (thesis actuator), 0.4 (thesis sensor)",
    ),
    "fiber_length_mm": Guide(
        "length of the twisted fiber that forms the coil, l [mm]; NOT the coil's length",
        "mark the fiber before coiling and measure it straight",
        "95 (thesis actuator), 328 (thesis sensor); longer than coil_length_mm",
    ),
    "coil_length_mm": Guide(
        "length of the coiled actuator or sensor between the clamps at rest, L [mm]",
        "calipers between the clamps under the test's resting load",
        "20 (thesis actuator), 90 (thesis sensor); sin(alpha0) = L / l",
    ),
    "coil_diameter_mm": Guide(
        "OUTSIDE diameter of the coil, D [mm] (not the mean diameter)",
        "calipers or microscope across the coil",
        "0.36 (thesis actuator), 0.8 (thesis sensor); larger than fiber_diameter_mm",
    ),
    "twists": Guide(
        "total number of turns inserted into the fiber over its whole length l [turns] "
        "(a count, not turns per metre)",
        "count the twisting motor's revolutions until the fiber coiled",
        "150 (thesis actuator, 95 mm), 750 (thesis sensor, 328 mm)",
    ),
    "youngs_modulus_GPa": Guide(
        "Young's modulus of the fiber, E [GPa]",
        "tensile test of the untwisted fiber, or the supplier's datasheet",
        "3.45 (nylon 6,6, thesis sec. 3.3)",
        "typical",
        3.45,
    ),
    "thread_plies": Guide(
        "number of plies in the thread [-]", "count them under a microscope", "2 (thesis)", "typical", 2
    ),
    "max_volume_fraction": Guide(
        "maximum fiber volume fraction V_fmax [-]",
        "literature: 0.887 for hexagonally packed round filaments",
        "0.887 (thesis sec. 2.5.1)",
        "typical",
        0.887,
    ),
    "radial_cte_per_K": Guide(
        "radial thermal expansion coefficient of the fiber, rho [1/K], positive when it swells on heating",
        "literature or thermomechanical analysis; tcamlab calibrate identifies it from oven tests",
        "8.1e-5 (nylon 6,6, thesis sec. 2.5.1)",
        "typical",
        8.1e-5,
    ),
    "shear_modulus_slope_MPa_per_K": Guide(
        "drop of the fiber's shear modulus per kelvin, eq. (2.13) [MPa/K]",
        "torsional DMA sweep, or tcamlab calibrate on oven tests",
        "1.11 (thesis sec. 2.3.3)",
        "typical",
        1.11,
    ),
    "load_g": Guide("hanging mass during the test [g]", "weigh it with its hook", "50 (thesis)"),
    "ambient_C": Guide(
        "ambient (reference) temperature T_a [degC]", "thermometer next to the rig", "20 (thesis)"
    ),
    "voltage_V": Guide(
        "step voltage applied across the actuator [V]", "the supply's setting, checked with a meter", "10"
    ),
    "pulse_s": Guide("duration of the voltage pulse [s]", "the controller's setting", "1 (thesis)"),
    "resistance_ohm": Guide(
        "electrical resistance of the actuator, R [ohm]",
        "ohmmeter across the clamped actuator at room temperature",
        "40 (thesis)",
    ),
    "thermal_mass_J_per_K": Guide(
        "thermal mass, C_th [J/K]",
        "mass x specific heat, or tcamlab calibrate on step responses",
        "0.0266 +- 0.00845 (thesis [22])",
        "typical",
        0.0266,
    ),
    "heat_loss_W_per_K": Guide(
        "heat loss coefficient, lambda [W/K]",
        "steady temperature rise at a known power, or tcamlab calibrate",
        "0.00893 +- 0.01615 (thesis [22])",
        "typical",
        0.00893,
    ),
    "damping_N_s_per_m": Guide(
        "damping coefficient, b [N s/m]",
        "tcamlab calibrate on step responses",
        "0.84 +- 0.12 (thesis [22])",
        "typical",
        0.84,
    ),
    "initial_resistance_ohm": Guide(
        "resistance of the unloaded sensor, R0 [ohm]",
        "ohmmeter at rest; left out, tcamlab takes the mean of each run's leading rows at rest",
        "30",
        "optional",
        30.0,
    ),
    "spring_constant_N_per_m": Guide(
        "spring constant S of F = S delta [N/m]",
        "tcamlab fit-spring on pull tests; left out, a sensing run's S is identified on the other runs",
        "4.7 (sensor), 14.1 (one 30 mm robot segment)",
        "optional",
        4.7,
    ),
    "sensor_offset_mm": Guide(
        "distance from the embedded sensor to the tendon cable, d1 [mm]",
        "calipers on the cast robot",
        "9 (thesis sec. 4.3)",
    ),
    "segment_lengths_mm": Guide(
        "rest lengths of the robot's sensor segments, tip first [mm]",
        "calipers on the cast robot",
        "[30, 30] (thesis sec. 4.3)",
    ),
    "tcr_per_K": Guide(
        "temperature coefficient of the coating's resistance, TCR [1/K] (self-sensing)",
        "an oven test of R against temperature with the muscle unloaded",
        "0.0038 (bulk silver; thin coatings are often lower)",
        "typical",
        0.0038,
    ),
    "heater_tcr_per_K": Guide(
        "temperature coefficient beta of the actuator's resistance, R(T) = R (1 + beta dT) [1/K]",
        "log current_A with the voltage and run tcamlab calibrate, or an oven test of R",
        "0 (the thesis's constant R); silver's 0.0038 for a silver-coated thread",
        "optional",
        0.0,
    ),
    "lead_resistance_ohm": Guide(
        "resistance of the unheated leads and contacts in series with the muscle, R_lead [ohm] (self-sensing)",
        "ohmmeter across the leads with the muscle shorted; left out, tcamlab calibrate fits it (prior 0 +- 0.3 ohm)",
        "0.2-0.5",
        "optional",
        0.0,
    ),
    "stretch_factor": Guide(
        "factor on chapter 3's stretch sensitivity of the resistance, k_s [-] (self-sensing)",
        "tcamlab calibrate on runs with the laser; 1 is the thesis's map",
        "1 (0.8-1.2)",
        "optional",
        1.0,
    ),
}
"""Experiment-file key -> :class:`Guide`."""

_UNCERTAINTY = {"thermal_mass_J_per_K": 0.00845, "heat_loss_W_per_K": 0.01615, "damping_N_s_per_m": 0.12}

# Words of a header, lowercased, that name a quantity (first match wins, longest first).
_WORDS: dict[str, tuple[str, ...]] = {
    "time": ("time", "zeit", "elapsed", "reltime", "timestamp", "date", "clock", "t"),
    "temperature": ("temperature", "temperatur", "temp", "thermocouple", "tc", "oven", "t_c"),
    "displacement": (
        "displacement",
        "weg",
        "extension",
        "elongation",
        "contraction",
        "stroke",
        "strain",
        "dehnung",
        "standardweg",
        "traversenweg",
        "position",
        "gap",
        "length",
        "laser",
        "disp",
        "deflection",
        "dl",
        "x",
    ),
    "force": ("force", "load", "tension", "kraft", "standardkraft", "fz", "f"),
    "resistance": ("resistance", "widerstand", "res", "r"),
    "voltage": ("voltage", "volt", "u", "v"),
    "current": ("current", "i"),
    "load": ("load", "weight", "hanging load"),  # self-sensing: the hanging weight [N]
    "cable": ("cable", "tendon", "pull"),
    "r1": ("r1", "resistance1", "resistance 1"),
    "r2": ("r2", "resistance2", "resistance 2"),
    "kappa1": ("kappa1", "curvature1", "curvature 1", "k1"),
    "kappa2": ("kappa2", "curvature2", "curvature 2", "k2"),
}

STRAIN_WORDS = ("strain", "dehnung")
"""Words of a header naming a strain (English, German testing-machine exports): a column without a
length unit is then a strain of the coil length."""

_UNIT_IN_HEADER = re.compile(r"^(?P<name>.*?)\s*[\(\[\{](?P<unit>[^\)\]\}]*)[\)\]\}]\s*$")


def split_header(header: str) -> tuple[str, str | None]:
    """A header's name and unit: ``"Load [mN]"`` -> ``("Load", "mN")``.

    Units are read in brackets (``()``, ``[]``, ``{}``), after a slash or
    ``in`` (``"Force/N"``, ``"Force in N"``) or as the canonical suffix
    (``"temperature_C"``); ``unit`` is None when there is none.
    """
    text = header.strip()
    m = _UNIT_IN_HEADER.match(text)
    if m and m.group("name"):
        return m.group("name").strip(), m.group("unit").strip()
    for sep in ("/", " in "):
        if sep in text:
            name, unit = text.rsplit(sep, 1)
            if tio.unit_key(unit.strip()) or unit.strip() == "%":
                return name.strip(), unit.strip()
    if text in tio.VARIABLE_MAP:
        return text, tio.VARIABLE_MAP[text][1]
    return text, None


def _tokens(name: str) -> list[str]:
    return [w for w in re.split(r"[^a-z0-9]+", name.lower()) if w]


def _word_match(name: str, quantity: str) -> int:
    """How well a header's name names a quantity: 2 whole name, 1 a word of it, 0 not at all."""
    low, tokens = name.lower().strip(), _tokens(name)
    joined = "".join(tokens)
    for w in _WORDS[quantity]:
        if low == w or joined == w.replace(" ", ""):
            return 2
    return int(any(w in tokens or (len(w) > 3 and w in low) for w in _WORDS[quantity]))


@dataclass(frozen=True)
class Recognised:
    """What one column of the file holds."""

    canonical: str
    unit: str | None
    note: str = ""


def candidates(kind: str, header: str, unit_text: str | None, cells: list[str]) -> list[Recognised]:
    """The canonical columns a header may hold in a run of ``kind``, best first.

    Parameters
    ----------
    kind : str
        Run kind.
    header : str
        The header's name without its unit.
    unit_text : str or None
        The unit as written (``"µm"``, ``"Ohm"``, ``"%"``), or None.
    cells : list of str
        The column's first data cells (wall-clock time stamps are recognised as time).
    """
    k = get_kind(kind)
    canon = list(k.required_columns + k.optional_columns)
    unit = tio.unit_key(unit_text) if unit_text else None
    dim = tio.UNITS[unit][0] if unit else None
    if "time_s" in canon and _is_clock(cells[:50]):
        return [Recognised("time_s", "datetime", "wall-clock time stamps, made seconds from the first row")]
    scored = []
    dims = [tio.UNITS[tio.VARIABLE_MAP[c][1]][0] for c in canon]
    for c, c_dim in zip(canon, dims):
        if dim is not None and dim != c_dim:
            continue
        score = 10 if header.strip() == c else 2 * _word_match(header, tio.VARIABLE_MAP[c][0])
        if header.strip() == "T":  # physics' convention: t is time, T temperature
            score = 4 if c == "temperature_C" else (0 if c == "time_s" else score)
        # a unit of the only column of its dimension names it ("Weg [µm]" in an oven test)
        score += (1 + (dims.count(dim) == 1)) if dim == c_dim else 0
        if score >= 2:
            scored.append((-score, canon.index(c), c))
    out = []
    for _, _, c in sorted(scored):
        if c == "displacement_mm" and (
            unit_text == "%" or (dim is None and any(w in header.lower() for w in STRAIN_WORDS))
        ):
            # a strain: its scale to mm needs the coil length, which the log does not hold
            out.append(Recognised(c, "%" if unit_text == "%" else "strain", "a strain of the coil length"))
        elif unit_text is None or unit is not None:
            out.append(Recognised(c, unit or tio.VARIABLE_MAP[c][1]))
    return out


def recognise(kind: str, header: str, unit_text: str | None, cells: list[str]) -> Recognised | None:
    """The best of :func:`candidates`, or None."""
    found = candidates(kind, header, unit_text, cells)
    return found[0] if found else None


def _is_clock(cells: list[str]) -> bool:
    """True when the cells are wall-clock time stamps (``2019-06-11 14:03:52.123``, ``14:03:52``)."""
    cells = [c.strip() for c in cells if c and c.strip()]
    if not cells or not all(":" in c for c in cells):
        return False
    try:
        pd.to_datetime(pd.Series(cells), format="ISO8601")
        return True
    except (ValueError, TypeError):
        pass
    try:
        pd.to_timedelta(pd.Series(cells))
        return True
    except (ValueError, TypeError):
        return False


# --- reading the top of the file -------------------------------------------------------


@dataclass
class CsvLayout:
    """How the file is laid out, as :func:`inspect_csv` found it.

    Attributes
    ----------
    header_row : int
        1-based line of the header; 0 when the file has none.
    units_row : int
        1-based line of a units row under the header; 0 when none.
    headers : list of str
        The header cells (``"column 3"`` for a file without a header).
    units : list of str or None
        Each column's unit as written (from the units row or the header), or None.
    sample : list of list of str
        The first data rows' cells.
    title_rows : list of str
        Lines above the header that are not ``#`` comments (an instrument's title).
    skip_rows : int
        Lines to skip above the data of a file without a header that has a title.
    """

    header_row: int
    units_row: int
    headers: list[str]
    units: list[str | None]
    sample: list[list[str]]
    title_rows: list[str] = field(default_factory=list)
    skip_rows: int = 0


def _number(cell: str) -> bool:
    try:
        float(cell.strip().replace(",", "."))
        return True
    except ValueError:
        return False


def _lines(path: Path) -> list[str]:
    """The first lines of the file as text (UTF-8, else Latin-1), BOM removed."""
    try:
        with open(path, "rb") as fh:
            head = b"".join(fh.readline() for _ in range(_SCAN_LINES))
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    if b"\x00" in head:
        raise InputError(f"{path}: not a text CSV file (NUL byte)", "name the CSV log the instrument wrote")
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = head.decode("latin-1")
    return text.splitlines()


def _delimiter(lines: list[str]) -> str:
    """Tab, semicolon or comma: the first that splits every one of the last lines the same number
    of times (a semicolon file with decimal commas splits on ';', not on its commas)."""
    tail = lines[-20:]
    for sep in ("\t", ";", ","):
        counts = {line.count(sep) for line in tail}
        if len(counts) == 1 and counts != {0}:
            return sep
    return ","


def inspect_csv(path: str | os.PathLike) -> CsvLayout:
    """Find the header, a units row, title rows and the first data rows of a CSV log.

    The data's width is the most common number of cells among the lines read;
    the header is the first line of that width with a non-numeric cell, a units
    row the next such line whose cells are units; a file whose first line of
    that width holds only numbers has no header (``header_row = 0``).

    Raises
    ------
    InputError
        No data rows, or a file that is not text.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: file not found", "name the CSV log the instrument wrote")
    lines = _lines(p)
    sep = _delimiter([ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")] or [""])
    rows = []
    for n, line in enumerate(lines, start=1):
        cells = [c.strip() for c in next(csv.reader([line], delimiter=sep, skipinitialspace=True), [])]
        while cells and not cells[-1]:
            cells.pop()  # trailing separators: a title row "Export 2019,," has one cell
        if cells and not cells[0].startswith("#"):
            rows.append((n, cells))
    if not rows:
        raise InputError(f"{p}: no rows found", "a run needs data rows")
    widths = Counter(len(r) for _, r in rows)
    width = max(widths, key=lambda w: (widths[w], w))
    wide = [(n, r) for n, r in rows if len(r) == width]
    first_data = next((k for k, (_, r) in enumerate(wide) if _datalike(r)), None)
    if first_data is None:
        raise InputError(f"{p}: no data rows found in the first {_SCAN_LINES} lines", "a run needs data rows")
    data = [r for _, r in wide[first_data:]]
    heads = wide[:first_data]  # full-width lines above the data: header, then maybe units
    if not heads:
        start = wide[first_data][0]
        titles = [",".join(r) for n, r in rows if n < start]
        layout = CsvLayout(0, 0, [f"column {i + 1}" for i in range(width)], [None] * width, data, titles)
        layout.skip_rows = start - 1 if titles else 0
        return layout
    header_n, header = heads[-1]
    units_row = 0
    if len(heads) > 1 and _units_like(heads[-1][1]):
        units_row = heads[-1][0]
        header_n, header = heads[-2]
    split = [split_header(h) for h in header]
    units: list[str | None] = [u for _, u in split]
    if units_row:
        cells = [c.strip("()[]{} ") for c in heads[-1][1]]
        units = [c if c else u for c, u in zip(cells, units)]
    titles = [",".join(r) for n, r in rows if n < header_n]
    return CsvLayout(header_n, units_row, list(header), units, data, titles)


_STAMP = re.compile(r"^[\d\-/:.T ]*\d[\d\-/:.T ]*$")


def _datalike(cells: list[str]) -> bool:
    """Most cells numbers or time stamps (a data row, not a header, title or units row): more
    than half of the filled cells, so that a text column beside the data (an operator's
    initials on every row) does not hide every row."""
    filled = [c for c in cells if c]
    numeric = sum(bool(_number(c) or _STAMP.match(c)) for c in filled)
    return numeric * 2 > len(filled) > 0


def _units_like(cells: list[str]) -> bool:
    """At least half of the filled cells are units (``s``, ``[µm]``, ``(N)``, ``%``)."""
    filled = [c.strip("()[]{} ") for c in cells if c]
    return sum(bool(tio.unit_key(c)) or c == "%" for c in filled) * 2 >= len(filled) > 0


# --- the mapping ---------------------------------------------------------------------


@dataclass
class ColumnMapping:
    """The starter's ``[columns]``: entries, notes and what was left out."""

    entries: dict[str, dict] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    unused: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)


def _cells(layout: CsvLayout, i: int) -> list[str]:
    return [r[i] for r in layout.sample if i < len(r)]


def _values(cells: list[str]) -> np.ndarray:
    out = []
    for c in cells:
        try:
            out.append(float(c.replace(",", ".")))
        except ValueError:
            continue
    return np.asarray(out, dtype=float)


DISPLACEMENT_CONVENTION = (
    "tcamlab's displacement_mm is positive when the sample gets longer, so a TCA contracting "
    "(heated, or powered) gives negative values"
)
"""The sign convention of ``displacement_mm`` (docs/data_contract.md), stated by ``init``."""

_DRIVERS = {"static": "temperature", "dynamic": "voltage", "selfsensing": "voltage"}
"""Kind -> the quantity whose rise makes its TCA contract (heating, or the voltage that heats it)."""


def _driver_column(kind: str, layout: CsvLayout, i: int) -> np.ndarray | None:
    """The values of the column a ``kind`` run's contraction follows, row by row beside column ``i``."""
    quantity = _DRIVERS.get(kind)
    for j, header in enumerate(layout.headers):
        name, _ = split_header(header) if layout.header_row else ("", None)
        if quantity and j != i and name and _word_match(name, quantity):
            return _paired(layout, j, i)
    return None


def _paired(layout: CsvLayout, j: int, i: int) -> np.ndarray:
    """Rows of columns j and i where both read a number, as a (rows, 2) array."""
    out = []
    for row in layout.sample:
        try:
            out.append((float(row[j].replace(",", ".")), float(row[i].replace(",", "."))))
        except (IndexError, ValueError):
            continue
    return np.asarray(out, dtype=float).reshape(-1, 2)


def _strain_sign(kind: str, layout: CsvLayout, i: int) -> tuple[str, str]:
    """The sign of a strain column's scale ("" or "-") and why: checked against the data."""
    pairs = _driver_column(kind, layout, i)
    if pairs is not None and len(pairs) >= 3 and np.ptp(pairs[:, 0]) > 0 and np.ptp(pairs[:, 1]) > 0:
        r = float(np.corrcoef(pairs[:, 0], pairs[:, 1])[0, 1])
        if abs(r) >= 0.5:
            rises = "rises" if r > 0 else "falls"
            what = f"it {rises} as the {_DRIVERS[kind]} rises"
            return (
                ("-", f"{what}: it counts contraction as positive")
                if r > 0
                else ("", f"{what}: shorter is negative")
            )
    v = _values(_cells(layout, i))
    if kind in _DRIVERS and v.size >= 3:
        d = v - v[0]
        if (d < 0).sum() > 2 * (d > 0).sum():
            return "", "it falls from its first row, as a TCA contracting: shorter is negative"
        if (d > 0).sum() > 2 * (d < 0).sum() and "contract" in layout.headers[i].lower():
            return (
                "-",
                "it rises from its first row and its header says contraction: it counts contraction as positive",
            )
    if "contract" in layout.headers[i].lower():
        return (
            "-",
            "its header says contraction (not checked against the data): it counts contraction as positive",
        )
    return "", "assumed to read longer as positive (not checked against the data)"


def _entry(kind: str, layout: CsvLayout, i: int, rec: Recognised, by_position: bool) -> tuple[dict, str]:
    """One ``[columns]`` entry and its comment."""
    header = layout.headers[i]
    entry: dict = {"from": i + 1 if by_position else header}
    note = rec.note
    if rec.unit in ("%", "strain"):
        sign, why = _strain_sign(kind, layout, i)
        per = " / 100" if rec.unit == "%" else ""
        entry["unit"] = "mm"
        entry["scale"] = f"{PLACEHOLDER}: {sign}coil_length_mm{per} (a strain of the coil length -> mm)"
        note = (
            f"a strain{' in %' if per else ''}: scale = {sign}coil_length_mm{per}, as {why}; "
            f"{DISPLACEMENT_CONVENTION}; samples of other lengths: a per-run scale in runs"
        )
    else:
        entry["unit"] = rec.unit
    if tio.VARIABLE_MAP[rec.canonical][0] in get_kind(kind).tension_outputs:
        v = _values(_cells(layout, i))
        if v.size and (v < 0).sum() > 2 * (v > 0).sum():
            entry["scale"] = -1
            note = "tension reads negative in this log: scale = -1 makes a pull positive"
    return entry, note


def map_columns(kind: str, layout: CsvLayout) -> ColumnMapping:
    """The ``[columns]`` of a run of ``kind`` for a file laid out as ``layout``."""
    k = get_kind(kind)
    repeated = len(set(layout.headers)) < len(layout.headers) or layout.header_row == 0
    out = ColumnMapping()
    for i, header in enumerate(layout.headers):
        name, unit_in_header = split_header(header) if layout.header_row else ("", None)
        unit_text = layout.units[i] or unit_in_header
        found = [
            r for r in candidates(kind, name, unit_text, _cells(layout, i)) if r.canonical not in out.entries
        ]
        if not found or layout.header_row == 0:
            out.unused.append(f"{header!r} (column {i + 1})" if layout.header_row else header)
            continue
        rec = found[0]
        entry, note = _entry(kind, layout, i, rec, repeated)
        out.entries[rec.canonical] = entry
        out.notes[rec.canonical] = note or f"read as {tio.VARIABLE_MAP[rec.canonical][0]}"
    for c in k.required_columns:
        if c not in out.entries:
            out.missing.append(c)
            what = "column number" if repeated else "header"
            out.entries[c] = {
                "from": f"{PLACEHOLDER}: {what} of the {tio.VARIABLE_MAP[c][0]} column",
                "unit": tio.VARIABLE_MAP[c][1],
            }
            out.notes[c] = "not recognised in the log: name its column and check the unit"
    return out


# --- the text -------------------------------------------------------------------------


def _toml(v) -> str:
    """A TOML value: strings as basic strings (JSON escapes are TOML's), numbers, lists, inline tables."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):  # DEL is the one control character JSON leaves and TOML refuses
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    items = ", ".join(f"{k} = {_toml(x)}" for k, x in v.items())
    return "{ " + items + " }"


REQUIRED_RIG_KEYS = {"selfsensing": ("spring_constant_N_per_m",)}
"""[rig] keys a kind cannot run without that other kinds may leave out (their "optional"
guide): a self-sensing muscle's S maps R to delta, and no log gives it."""


def _parameter_lines(key: str, unit: str, required_by: str = "") -> list[str]:
    g = GUIDE[key]
    lines = [f"# {key}: {g.definition}", f"#   measure: {g.measure}", f"#   typical: {g.typical}"]
    if required_by:
        lines.append(f"{key} = {_toml(f'{PLACEHOLDER}: {unit}')}   # required by a {required_by} run")
    elif g.fill == "typical":
        lines.append(f"{key} = {_toml(g.value)}   # typical value: replace it if you measured it")
    elif g.fill == "optional":
        lines.append(f"# {key} = {_toml(g.value)}   # optional: uncomment and set it if you know it")
    else:
        lines.append(f"{key} = {_toml(f'{PLACEHOLDER}: {unit}')}")
    return lines + [""]


def _rig_keys(kind: str) -> list[str]:
    si_to_key = {si: key for key, (si, _) in RIG_KEYS.items()}
    return [si_to_key[f] for f in get_kind(kind).report_rig_fields]


def _column_lines(kind: str, layout: CsvLayout, m: ColumnMapping) -> list[str]:
    lines = [
        "[columns]",
        "# The log's own headers and units -> tcamlab's columns: value = convert(raw * scale + offset, unit).",
        "# `from` is the header as written, or the column number (1 = first column).",
    ]
    if layout.title_rows and layout.header_row:
        lines.append(f"header_row = {layout.header_row}   # the lines above the header are a title")
    if layout.header_row == 0:
        lines.append("header_row = 0   # no header in this log: every column is named by its number")
        if layout.skip_rows:
            lines.append(f"skip_rows = {layout.skip_rows}   # the lines above the data are a title")
        first = layout.sample[0] if layout.sample else []
        lines.append(
            "# first data row: " + ", ".join(f"column {i + 1} = {_toml(c)}" for i, c in enumerate(first))
        )
    if layout.units_row:
        lines.append(f"units_row = {layout.units_row}   # the line under the header holds units")
    if len(set(layout.headers)) < len(layout.headers) and layout.header_row:
        lines.append("# headers repeat (side-by-side blocks): the first block is mapped by column number")
    for c, entry in m.entries.items():
        lines.append(f"{c} = {_toml(entry)}   # {m.notes[c]}")
    k = get_kind(kind)
    optional = [c for c in k.optional_columns if c not in m.entries]
    if optional:
        lines.append("# optional columns of a " + kind + " run, not found: " + ", ".join(optional))
    if m.unused:
        lines.append(f"# not used by a {kind} run: " + ", ".join(m.unused))
    return lines + [""]


def starter_text(kind: str, csv_path: str | os.PathLike, out_path: str | os.PathLike) -> str:
    """The starter experiment file for a run of ``kind`` logged in ``csv_path``.

    Parameters
    ----------
    kind : str
        Run kind.
    csv_path : path-like
        The lab's CSV log.
    out_path : path-like
        Where the file will be written (``runs`` is relative to its folder).

    Returns
    -------
    str
        TOML text with comments; loading it refuses every :data:`PLACEHOLDER` left.
    """
    from tcamlab import __version__

    if kind not in KINDS:
        raise ConfigError(f"unknown kind {kind!r}{did_you_mean(kind, KINDS)}", "one of " + ", ".join(KINDS))
    csv_path, out_path = Path(csv_path), Path(out_path)
    layout = inspect_csv(csv_path)
    m = map_columns(kind, layout)
    run = Path(os.path.relpath(csv_path.resolve(), out_path.resolve().parent)).as_posix()
    lines = [
        f"# Starter experiment file written by `tcamlab init {kind}` (tcamlab {__version__}) from {csv_path.name}.",
        f'# Replace every "{PLACEHOLDER}" value: `tcamlab validate` refuses the file, naming each key, until',
        "# none is left. The comment above each key says what it is, how to measure it, a typical value.",
        f"kind = {_toml(kind)}",
        f"title = {_toml(csv_path.stem + ' (edit this title)')}",
        f"runs = [{_toml(run)}]   # more runs of this sample: add their files (same [columns])",
        "",
        *_column_lines(kind, layout, m),
        "[sample]   # no preset: every key is this sample's own",
    ]
    for key, (_, _) in SAMPLE_KEYS.items():
        lines += _parameter_lines(key, _unit_of(key))
    lines.append("[rig]")
    rig_keys = _rig_keys(kind)
    for key in rig_keys:
        lines += _parameter_lines(
            key, _unit_of(key), kind if key in REQUIRED_RIG_KEYS.get(kind, ()) else False
        )
    unc = {k: v for k, v in _UNCERTAINTY.items() if k in rig_keys}
    if unc:
        lines.append("[rig.uncertainty]   # standard deviations of the typical values above (thesis)")
        lines += [f"{k} = {_toml(v)}" for k, v in unc.items()] + [""]
    return "\n".join(lines).rstrip("\n") + "\n"


def _unit_of(key: str) -> str:
    words = key.split("_")
    for i in range(1, len(words)):
        tail = "_".join(words[i:])
        if tail in {"mm", "GPa", "per_K", "MPa_per_K", "g", "C", "V", "s", "ohm", "J_per_K", "W_per_K"}:
            return tail.replace("_per_", "/").replace("per_", "1/").replace("C", "degC")
        if tail in {"N_s_per_m", "N_per_m"}:
            return tail.replace("_per_", "/").replace("_", " ")
    return "a number" if key != "twists" else "turns (a count)"


@dataclass(frozen=True)
class Starter:
    """What :func:`write_starter` wrote."""

    path: Path
    mapped: dict[str, dict]
    unused: list[str]
    placeholders: list[str]
    signs: list[str] = field(default_factory=list)
    """Each sign the mapping assumed, with the convention and what in the data it rests on."""


def write_starter(
    kind: str, csv_path: str | os.PathLike, out_path: str | os.PathLike | None = None
) -> Starter:
    """Write the starter experiment file; never over an existing file.

    Parameters
    ----------
    kind : str
        Run kind.
    csv_path : path-like
        The lab's CSV log.
    out_path : path-like, optional
        Default ``experiments/<csv stem>.toml``.

    Raises
    ------
    ConfigError
        The output exists (it is never overwritten), or the kind is unknown.
    InputError
        The CSV cannot be read.
    """
    import tomllib

    csv_path = Path(csv_path)
    out = Path(out_path) if out_path is not None else Path("experiments") / f"{csv_path.stem}.toml"
    if out.exists():
        raise ConfigError(
            f"{out}: already exists; tcamlab init never overwrites a file",
            "pick another name with --out experiments/NAME.toml, or move the old file away",
        )
    text = starter_text(kind, csv_path, out)
    mapping = map_columns(kind, inspect_csv(csv_path))
    signs = [f"{c}: {n}" for c, n in mapping.notes.items() if DISPLACEMENT_CONVENTION in n]
    doc = tomllib.loads(text)  # the starter must always be valid TOML
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with open(out, "x", encoding="utf-8") as fh:
            fh.write(text)
    except FileExistsError:
        raise ConfigError(f"{out}: already exists; tcamlab init never overwrites a file") from None
    return Starter(out, dict(doc.get("columns", {})), mapping.unused, placeholders(doc), signs)


def placeholders(doc, prefix: str = "") -> list[str]:
    """Dotted keys of a parsed experiment file whose value is still a :data:`PLACEHOLDER`."""
    out: list[str] = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        key = f"{prefix}[{k}]" if isinstance(k, int) else (f"{prefix}.{k}" if prefix else str(k))
        if isinstance(v, str) and v.strip().upper().startswith(PLACEHOLDER):
            out.append(key)
        elif isinstance(v, (dict, list)):
            out += placeholders(v, key)
    return out


# --- check: a dry run of an experiment file --------------------------------------------


@dataclass
class RunCheck:
    """What one run's file gives: the column mapping, its first rows in SI, or its problem."""

    file: str
    rows: int = 0
    mapping: list[str] = field(default_factory=list)
    head: list[str] = field(default_factory=list)
    problem: str | None = None


@dataclass
class CheckReport:
    """What ``tcamlab check`` found (:func:`check_experiment`)."""

    path: str
    kind: str = "?"
    runs: list[RunCheck] = field(default_factory=list)
    parameters: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        """The report as text lines."""
        out = [f"{self.path}: {self.kind} experiment, {len(self.runs)} run{'s' * (len(self.runs) != 1)}"]
        for r in self.runs:
            out.append(f"run {r.file}" + (f": {r.rows} rows" if r.rows else ""))
            out += [f"  {m}" for m in r.mapping] + [f"  {h}" for h in r.head]
        if self.parameters:
            out.append("parameters (value in the key's unit, where it comes from):")
            out += [f"  {p}" for p in self.parameters]
        out += [f"warning: {w}" for w in self.warnings]
        out += [f"problem: {p}" for p in self.problems] or ["no problems found"]
        return out


def _run_check(run, rows: int) -> RunCheck:
    from tcamlab.text import shown_path

    rc = RunCheck(shown_path(run.path), rows=len(run.data))
    for name, header in run.source_columns.items():
        q = tio.INTERNAL_TO_CANONICAL[name]
        rc.mapping.append(
            f"{q:<16s} <- {header!r} [{run.source_units.get(name, '')}] -> {name} [{run.units.get(name, '')}]"
        )
    if run.join:
        j = run.join
        rc.mapping.append(
            f"joined {j['file']} ({j['joined_rows']} rows) on time + offset_s {j['offset_s']:g} s: overlap "
            f"{j['overlap_s'][0]:.6g} to {j['overlap_s'][1]:.6g} s, {j['rows_outside_overlap']} rows outside "
            f"it dropped, {j['resampling']}"
        )
    head = run.data.head(rows)
    rc.head.append("first rows in SI: " + ", ".join(f"{c} [{run.units.get(c, '')}]" for c in head.columns))
    rc.head += ["  " + ", ".join(f"{v:.6g}" for v in row) for row in head.to_numpy()]
    return rc


def _parameter_lines_of(exp) -> list[str]:
    from tcamlab.units import PARAMETER_UNITS

    out = []
    rig_fields = get_kind(exp.kind).report_rig_fields
    for where, obj in (("sample", exp.sample), ("rig", exp.rig)):
        for name, source in exp.provenance.items():
            if name.startswith("sd(") or not hasattr(obj, name) or name not in PARAMETER_UNITS:
                continue
            if where == "rig" and name not in rig_fields:
                continue  # a rig value this kind's models do not use
            value = getattr(obj, name)
            if value is None:
                continue
            unit, factor = PARAMETER_UNITS[name]
            shown = (
                [round(v * factor, 12) for v in value]
                if isinstance(value, tuple)
                else f"{value * factor:.6g}"
            )
            out.append(f"{where}.{name} = {shown} {unit}  ({source})")
    return out


def _warnings(exp, runs) -> list[str]:
    """Values that load but cannot be: a coil longer than its straight fiber or shorter than
    nothing, an input that never changes."""
    out = []
    s = exp.sample
    for r in runs:
        d = r.data
        if "displacement" in d:
            lo, hi = float(d["displacement"].min()), float(d["displacement"].max())
            if hi > s.fiber_length - s.coil_length or -lo > s.coil_length:
                out.append(
                    f"{r.path.name}: displacement spans {1e3 * lo:.4g} to {1e3 * hi:.4g} mm, but a "
                    f"{1e3 * s.coil_length:.4g} mm coil of {1e3 * s.fiber_length:.4g} mm fiber can only "
                    "move within that length: check the displacement unit and scale, and the lengths"
                )
        for name in get_kind(exp.kind).inputs:
            if name in d and float(np.ptp(d[name].to_numpy())) == 0.0:
                out.append(f"{r.path.name}: {name} never changes, so the model has nothing to follow")
        out += [w.message for w in implausible_value_warnings(r.path.name, r.data)]
    if exp.kind == "dynamic":
        out += [w for w in [stated_voltage_warning(exp.rig, runs)] if w]
    return out + _below_ambient(exp, runs)


BELOW_AMBIENT_K = 10.0
"""A logged temperature this far [K] below the stated ambient is a warning: the models count
every rise from ambient_C, and a test does not start colder than its room."""


def _below_ambient(exp, runs) -> list[str]:
    """A run whose logged temperature falls :data:`BELOW_AMBIENT_K` below ``[rig] ambient_C``."""
    out = []
    ambient = exp.rig.ambient
    for r in runs:
        if "temperature" not in r.data:
            continue
        low = float(np.nanmin(r.data["temperature"].to_numpy(float), initial=np.inf))
        if low < ambient - BELOW_AMBIENT_K:
            out.append(
                f"{r.path.name}: temperature falls to {low:.4g} degC, {ambient - low:.3g} K below the "
                f"stated ambient_C = {ambient:g} degC, the reference every modelled rise counts from: "
                "is ambient_C the room's temperature at the start of the run?"
            )
    return out


def _check_protocol(exp, report: CheckReport) -> None:
    """A ``[protocol]`` table (a designed protocol) read as the virtual rig would read it: a bad
    value is a problem here too, not only when a rig runs the file."""
    from tcamlab.errors import TcamlabError
    from tcamlab.rig.runs import designed_channels, designed_programs

    if "protocol" not in (exp.raw or {}):
        return
    try:
        designed_programs(exp.kind, exp)
        designed_channels(exp.kind, exp)
    except TcamlabError as exc:
        report.problems.append(exc.one_line())


def check_experiment(path: str | os.PathLike, rows: int = 3, *, drop_na: bool = False) -> CheckReport:
    """Load an experiment file and read its runs without writing anything; every problem at once.

    Parameters
    ----------
    path : path-like
        The experiment file.
    rows : int
        First rows of each run shown in SI.
    drop_na : bool
        Drop rows with blank cells (:func:`tcamlab.io.read_run`), as validate would.

    Returns
    -------
    CheckReport
        The mapping, units and first rows of each run, every parameter with its source,
        warnings, and the problems (the file's, then each run's).
    """
    from tcamlab.config import load_experiment
    from tcamlab.errors import TcamlabError

    report = CheckReport(str(path))
    try:
        exp = load_experiment(path)
    except TcamlabError as exc:
        report.problems.append(exc.one_line())
        return report
    report.kind = exp.kind
    report.parameters = _parameter_lines_of(exp)
    _check_protocol(exp, report)
    columns = exp.run_columns or (exp.columns,) * len(exp.runs)
    joins = exp.run_joins or (None,) * len(exp.runs)
    read = []
    from tcamlab.text import shown_path

    for p, cols, join in zip(exp.runs, columns, joins):
        try:
            run = tio.read_run(p, exp.kind, cols, join=join, drop_na=drop_na, shown=shown_path(p))
        except TcamlabError as exc:  # every run is read: all problems at once
            report.runs.append(RunCheck(shown_path(p), problem=exc.one_line()))
            report.problems.append(exc.one_line())
            continue
        read.append(run)
        report.runs.append(_run_check(run, rows))
    report.warnings = _warnings(exp, read)
    _check_run_rules(exp, read, report)
    return report


def _check_run_rules(exp, runs, report: CheckReport) -> None:
    """Each run through the kind's per-run rule (:attr:`tcamlab.kinds.Kind.run_options`: the
    hanging load, the sampling, R0), as every command applies it: what they would refuse is a
    problem here too. A constant identified on training runs (sensing S) is identified on all
    of them here: validate leaves each run out of its own, but calibrate fits on one run."""
    from tcamlab.errors import TcamlabError

    kind = get_kind(exp.kind)
    training = [(r.data, np.ones(len(r.data), dtype=bool)) for r in runs]
    for run in runs:
        try:
            kind.run_options(
                exp.sample, exp.rig, run.data, where=exp.path.name, provenance=exp.provenance,
                training=training, training_runs=[r.path.stem for r in runs],
            )  # fmt: skip
        except TcamlabError as exc:
            line = exc.one_line()
            if line not in report.problems:  # a rule of the file, not of the run, fails once
                report.problems.append(line)
