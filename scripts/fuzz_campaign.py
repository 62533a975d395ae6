#!/usr/bin/env python
"""Fuzz campaign over tcamlab's input readers (CSV logs and experiment TOML files).

Every generated input must either load (``tcamlab.io.read_run`` /
``tcamlab.config.load_experiment``) or raise one of tcamlab's own errors
(:class:`tcamlab.errors.TcamlabError` subclasses).  Any other exception is a
finding: it is printed with the input that caused it and saved under
``--findings`` so it can be replayed.

Inputs are structured mutations of the shipped sample files (``raw/*.csv``,
``experiments/*.toml``): truncation, byte flips, random unicode, huge
numbers, NaN/inf, swapped and duplicated columns, changed delimiters and
encodings, BOMs, comment lines, NUL bytes, for TOML also retyped values,
typos in keys, unknown keys, wrong kinds, bad run paths and random
``[columns]`` tables.  With ``--pipeline-every N`` every N-th input that
loads is also run through ``tcamlab.validation.validate`` (no Monte Carlo),
so model code sees odd but valid data too.

Each input is reproducible from ``(--seed, index)``.

Usage::

    python scripts/fuzz_campaign.py --n 12000 --seed 1 --findings /tmp/fuzz
    python scripts/fuzz_campaign.py --replay 1:4711        # one input again, with traceback
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tcamlab import io as tio  # noqa: E402
from tcamlab.config import load_experiment  # noqa: E402
from tcamlab.errors import TcamlabError  # noqa: E402

KINDS = tio.KINDS

# --- seeds -------------------------------------------------------------------------


def _seed_csvs(max_lines: int = 80) -> dict[str, list[str]]:
    """Kind -> sample CSV texts (cut to max_lines so each read stays fast)."""
    out: dict[str, list[str]] = {k: [] for k in KINDS}
    for p in sorted((ROOT / "raw").glob("*.csv")):
        kind = p.stem.split("_")[0]
        if kind in out:
            lines = p.read_text(encoding="utf-8").splitlines(keepends=True)
            out[kind].append("".join(lines[:max_lines]))
    return out


def _seed_tomls() -> dict[str, str]:
    return {p.stem: p.read_text(encoding="utf-8") for p in sorted((ROOT / "experiments").glob("*.toml"))}


# --- generators of odd values -------------------------------------------------------

ODD_CELLS = [
    "",
    " ",
    "NaN",
    "nan",
    "NA",
    "N/A",
    "null",
    "None",
    "inf",
    "-inf",
    "+inf",
    "Infinity",
    "1e308",
    "-1e308",
    "1e309",
    "1e400",
    "-1e400",
    "1e-400",
    "4.9e-324",
    "9" * 400,
    "0x10",
    "1_000",
    "--1",
    "+-1",
    "1e",
    "e5",
    ".",
    "-",
    "+",
    "1,5",
    "1.5.5",
    "١٢٣",
    "\u00a0",
    "\u2212" + "1",
    "1\u00a0000",
    "TRUE",
    "#",
    '"',
    '""',
    "'",
    ";",
    "\t",
    "\x00",
    "\ufeff",
    "°",
    "µ",
    "\U0001f600",
    "=1+1",
    "@SUM(A1)",
    "<script>",
    "%s%n",
    "\\",
    "0",
    "-0",
    "1e-3",
    "-1e-3",
    "12345678901234567890",
    "3.4028235e38",
    "-273.16",
    "-1000",
]

ODD_TEXT = [
    "",
    " ",
    "x",
    "\x00",
    "\ufeff",
    "é",
    "°C",
    "<b>",
    "\U0001f600",
    "a\nb",
    "\\u0000",
    "=cmd",
    "../",
    "/",
    "C:\\x",
    "\u202e",
    "\ud7ff",
    "a" * 300,
]


def _rand_unicode(rng: random.Random, n: int) -> str:
    chars = []
    for _ in range(n):
        r = rng.random()
        if r < 0.4:
            chars.append(chr(rng.randint(0x20, 0x7E)))
        elif r < 0.6:
            chars.append(chr(rng.randint(0, 0x1F)))
        elif r < 0.8:
            chars.append(chr(rng.randint(0xA0, 0x2FFF)))
        else:
            c = rng.randint(0x3000, 0x10FFFF)
            if 0xD800 <= c <= 0xDFFF:
                c = 0xFFFD
            chars.append(chr(c))
    return "".join(chars)


def _odd_number(rng: random.Random) -> str:
    r = rng.random()
    if r < 0.3:
        return rng.choice(ODD_CELLS)
    if r < 0.5:
        return repr(rng.choice([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, 0.0, -0.0]))
    if r < 0.7:
        return str(rng.randint(-(10 ** rng.randint(1, 30)), 10 ** rng.randint(1, 30)))
    if r < 0.9:
        return f"{rng.uniform(-1, 1) * 10 ** rng.randint(-30, 30):.6g}"
    return _rand_unicode(rng, rng.randint(0, 6))


# --- CSV mutations ------------------------------------------------------------------

CSV_MILD = [
    "semicolon_comma",
    "semicolon_point",
    "tab",
    "bom",
    "crlf",
    "comments",
    "extra_col",
    "scale_values",
    "neg_values",
    "reverse_rows",
    "dup_row",
    "swap_cols",
    "latin1",
    "trailing_sep",
    "blank_lines",
    "drop_rows",
]
"""Mutations that often keep a file readable, so later checks and models see odd data."""


def _split(text: str) -> tuple[list[str], list[list[str]]]:
    lines = text.splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:] if line]
    return header, rows


def _join(header, rows, sep=",", eol="\n") -> str:
    return eol.join([sep.join(header)] + [sep.join(r) for r in rows]) + eol


def csv_mutations(rng: random.Random, text: str) -> tuple[bytes, dict]:
    """Apply 1-3 structured mutations to a CSV text; returns bytes and the steps."""
    header, rows = _split(text)
    steps: list[str] = []
    sep, eol, encoding, bom, prefix_bytes = ",", "\n", "utf-8", False, b""
    raw_post: list = []
    mild = rng.random() < 0.35
    for _ in range(rng.randint(1, 3)):
        op = (
            rng.choice(CSV_MILD)
            if mild
            else rng.choice(
                [
                    "cell",
                    "cell",
                    "cell",
                    "cells",
                    "swap_cols",
                    "dup_header",
                    "drop_col",
                    "rename_col",
                    "case_header",
                    "extra_col",
                    "drop_rows",
                    "dup_row",
                    "reverse_rows",
                    "shuffle_rows",
                    "no_rows",
                    "header_only",
                    "semicolon_comma",
                    "semicolon_point",
                    "tab",
                    "bom",
                    "latin1",
                    "utf16",
                    "crlf",
                    "comments",
                    "blank_lines",
                    "short_row",
                    "long_row",
                    "quote",
                    "truncate",
                    "byte_flip",
                    "insert_bytes",
                    "nul",
                    "unicode_header",
                    "huge_line",
                    "empty",
                    "whitespace",
                    "neg_values",
                    "scale_values",
                    "only_comments",
                    "time_dup",
                    "trailing_sep",
                ]
            )
        )
        steps.append(op)
        if op == "cell" and rows:
            r = rng.randrange(len(rows))
            c = rng.randrange(len(rows[r])) if rows[r] else 0
            if rows[r]:
                rows[r][c] = _odd_number(rng)
        elif op == "cells" and rows:
            c = rng.randrange(len(header))
            v = _odd_number(rng)
            for r in rows:
                if c < len(r) and rng.random() < 0.5:
                    r[c] = v
        elif op == "swap_cols" and len(header) > 1:
            a, b = rng.sample(range(len(header)), 2)
            header[a], header[b] = header[b], header[a]
        elif op == "dup_header" and header:
            header[rng.randrange(len(header))] = rng.choice(header)
        elif op == "drop_col" and header:
            c = rng.randrange(len(header))
            header.pop(c)
            for r in rows:
                if c < len(r):
                    r.pop(c)
        elif op == "rename_col" and header:
            c = rng.randrange(len(header))
            h = header[c]
            header[c] = h[:-1] if len(h) > 1 and rng.random() < 0.5 else h + rng.choice(["_", "x", " ", "s"])
        elif op == "case_header" and header:
            c = rng.randrange(len(header))
            header[c] = header[c].upper()
        elif op == "extra_col":
            header.insert(rng.randint(0, len(header)), rng.choice(ODD_TEXT + ["junk", "time_s"]))
            for r in rows:
                r.insert(min(len(r), rng.randint(0, len(r))), _odd_number(rng))
        elif op == "drop_rows" and rows:
            keep = rng.randint(0, len(rows))
            rows = rows[:keep]
        elif op == "dup_row" and rows:
            r = rng.randrange(len(rows))
            rows.insert(r, list(rows[r]))
        elif op == "reverse_rows":
            rows.reverse()
        elif op == "shuffle_rows":
            rng.shuffle(rows)
        elif op == "no_rows":
            rows = []
        elif op == "header_only":
            rows = []
            eol = rng.choice(["\n", ""])
        elif op == "semicolon_comma":
            sep = ";"
            rows = [[c.replace(".", ",") for c in r] for r in rows]
        elif op == "semicolon_point":
            sep = ";"
        elif op == "tab":
            sep = "\t"
        elif op == "bom":
            bom = True
        elif op == "latin1":
            encoding = "latin-1"
            header[0] = header[0] + "°"
        elif op == "utf16":
            encoding = "utf-16"
        elif op == "crlf":
            eol = "\r\n"
        elif op == "comments":
            prefix_bytes += rng.choice([b"# rig 3\n", b"#a,b,c\n", b"# \xb0C\n", b"#\n\n# x\n"])
        elif op == "blank_lines" and rows:
            for _ in range(rng.randint(1, 3)):
                rows.insert(rng.randint(0, len(rows)), [""])
        elif op == "short_row" and rows:
            r = rng.randrange(len(rows))
            rows[r] = rows[r][: rng.randint(0, max(len(rows[r]) - 1, 0))]
        elif op == "long_row" and rows:
            r = rng.randrange(len(rows))
            rows[r] = rows[r] + [_odd_number(rng) for _ in range(rng.randint(1, 4))]
        elif op == "quote" and rows:
            r = rng.randrange(len(rows))
            if rows[r]:
                c = rng.randrange(len(rows[r]))
                rows[r][c] = rng.choice(['"', '"1', '1"', '"1,2"', '""""', '"a\nb"'])
        elif op == "neg_values" and rows:
            c = rng.randrange(len(header))
            for r in rows:
                if c < len(r) and r[c] and not r[c].startswith("-"):
                    r[c] = "-" + r[c]
        elif op == "scale_values" and rows:
            c = rng.randrange(len(header))
            f = rng.choice([1e-300, 1e300, -1.0, 0.0, 1e6])
            for r in rows:
                if c < len(r):
                    try:
                        r[c] = repr(float(r[c]) * f)
                    except ValueError:
                        pass
        elif op == "only_comments":
            header, rows = ["# only a comment"], []
        elif op == "time_dup" and len(rows) > 2 and "time_s" in header:
            c = header.index("time_s")
            r = rng.randrange(1, len(rows))
            if c < len(rows[r]) and c < len(rows[r - 1]):
                rows[r][c] = rows[r - 1][c]
        elif op == "trailing_sep":
            header = header + [""]
            rows = [r + [""] for r in rows]
        elif op in (
            "truncate",
            "byte_flip",
            "insert_bytes",
            "nul",
            "huge_line",
            "empty",
            "whitespace",
            "unicode_header",
        ):
            raw_post.append(op)
    text_out = _join(header, rows, sep, eol)
    if "unicode_header" in raw_post:
        text_out = _rand_unicode(rng, rng.randint(1, 20)) + sep + text_out
    if encoding == "utf-16":
        data = text_out.encode("utf-16")
    else:
        data = (
            text_out.encode(encoding, errors="replace")
            if encoding == "latin-1"
            else text_out.encode("utf-8", errors="surrogatepass")
        )
    data = prefix_bytes + data
    if bom:
        data = b"\xef\xbb\xbf" + data
    for op in raw_post:
        if op == "truncate" and data:
            data = data[: rng.randint(0, len(data))]
        elif op == "byte_flip" and data:
            b = bytearray(data)
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(b))
                b[i] = rng.randrange(256)
            data = bytes(b)
        elif op == "insert_bytes":
            i = rng.randint(0, len(data))
            data = data[:i] + bytes(rng.randrange(256) for _ in range(rng.randint(1, 16))) + data[i:]
        elif op == "nul":
            i = rng.randint(0, len(data))
            data = data[:i] + b"\x00" + data[i:]
        elif op == "huge_line":
            i = data.find(b"\n") + 1
            data = data[:i] + b"1" * rng.choice([10_000, 200_000]) + b"\n" + data[i:]
        elif op == "empty":
            data = b""
        elif op == "whitespace":
            data = rng.choice([b"\n", b"   ", b"\r\n\r\n", b"\t\n \n"])
    return data, {"steps": steps, "mild": mild}


def random_columns(rng: random.Random, kind: str) -> dict | None:
    """Sometimes a random [columns] table (valid or not) for read_run."""
    if rng.random() < 0.7:
        return None
    allowed = tio.REQUIRED[kind] + tio.OPTIONAL[kind]
    out = {}
    for _ in range(rng.randint(1, 3)):
        canon = rng.choice(list(allowed) + ["bogus", "time_s"])
        r = rng.random()
        if r < 0.3:
            out[canon] = rng.choice(ODD_TEXT + [canon])
        elif r < 0.9:
            spec: dict = {"from": rng.choice([canon, "x", ""] + ODD_TEXT)}
            if rng.random() < 0.5:
                spec["unit"] = rng.choice(list(tio.UNITS) + ["furlong", "", "MM"])
            if rng.random() < 0.4:
                spec["scale"] = rng.choice([0, 0.0, -1, 1e308, math.nan, math.inf, "2", True, 1e-3])
            if rng.random() < 0.4:
                spec["offset"] = rng.choice([0, -273.15, 1e308, math.nan, -math.inf, None, [1]])
            if rng.random() < 0.1:
                spec["bogus"] = 1
            out[canon] = spec
        else:
            out[canon] = rng.choice([3, None, [1, 2], True, 1.5])
    return out


# --- TOML mutations -----------------------------------------------------------------

TOML_MILD = [
    "sample_value",
    "rig_value",
    "uncertainty",
    "thresholds",
    "runs",
    "preset",
    "kind",
    "bom",
    "columns",
]

TOML_VALUES = [
    '""',
    '"x"',
    "0",
    "-1",
    "1e400",
    "nan",
    "inf",
    "-inf",
    "+nan",
    "true",
    "false",
    "[]",
    "[1, 2]",
    '["a", 1]',
    "{}",
    '{ from = "x" }',
    "1979-05-27T07:32:00Z",
    "1979-05-27",
    "07:32:00",
    "9223372036854775807",
    "-9223372036854775808",
    "0x7fffffff",
    "0b101",
    "1_000",
    "3.4e38",
    '"\\u0000"',
    '"<script>alert(1)</script>"',
    '"=cmd|x"',
    '"\U0001f600"',
    "'''lit'''",
    '"""multi\nline"""',
    "[[1], [2]]",
    "-0.0",
    "1e-320",
    "12345678901234567890123",
]


def _toml_value(rng: random.Random) -> str:
    r = rng.random()
    if r < 0.6:
        return rng.choice(TOML_VALUES)
    if r < 0.8:
        return f"{rng.uniform(-1, 1) * 10 ** rng.randint(-20, 20):.6g}"
    return (
        '"'
        + _rand_unicode(rng, rng.randint(0, 8)).replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        + '"'
    )


def _set_key(lines: list[str], table: str, key: str, value: str) -> None:
    """Set ``key = value`` in ``table`` (replacing the key if present, adding the table if not)."""
    if table not in lines:
        lines += ["", table, f"{key} = {value}"]
        return
    start = lines.index(table) + 1
    end = next((i for i in range(start, len(lines)) if lines[i].startswith("[")), len(lines))
    for i in range(start, end):
        if lines[i].split("=", 1)[0].strip() == key:
            lines[i] = f"{key} = {value}"
            return
    lines.insert(start, f"{key} = {value}")


def toml_mutations(rng: random.Random, text: str, run_names: list[str]) -> tuple[bytes, dict]:
    lines = text.splitlines()
    steps: list[str] = []
    raw_post: list[str] = []
    mild = rng.random() < 0.35
    for _ in range(rng.randint(1, 3)):
        op = (
            rng.choice(TOML_MILD)
            if mild
            else rng.choice(
                [
                    "value",
                    "value",
                    "value",
                    "typo_key",
                    "unknown_key",
                    "delete_line",
                    "dup_line",
                    "kind",
                    "runs",
                    "runs",
                    "columns",
                    "columns",
                    "thresholds",
                    "sample_value",
                    "rig_value",
                    "uncertainty",
                    "preset",
                    "drop_table",
                    "swap_lines",
                    "truncate",
                    "byte_flip",
                    "unicode",
                    "nul",
                    "latin1",
                    "bom",
                    "table_header",
                    "deep",
                    "dotted",
                    "empty",
                ]
            )
        )
        steps.append(op)
        kv = [i for i, line in enumerate(lines) if "=" in line and not line.startswith("[")]
        if op == "value" and kv:
            i = rng.choice(kv)
            k = lines[i].split("=", 1)[0]
            lines[i] = f"{k}= {_toml_value(rng)}"
        elif op == "typo_key" and kv:
            i = rng.choice(kv)
            k, v = lines[i].split("=", 1)
            k = k.strip()
            j = rng.randrange(len(k)) if k else 0
            k2 = (k[:j] + k[j + 1 :]) if rng.random() < 0.5 else (k[:j] + rng.choice("aexs_") + k[j:])
            lines[i] = f"{k2 or 'x'} ={v}"
        elif op == "unknown_key":
            i = rng.randint(0, len(lines))
            key = rng.choice(["bogus", "Kind", "run", "titel", "x.y", '"a b"'])
            lines.insert(i, f"{key} = {_toml_value(rng)}")
        elif op == "delete_line" and lines:
            lines.pop(rng.randrange(len(lines)))
        elif op == "dup_line" and lines:
            i = rng.randrange(len(lines))
            lines.insert(i, lines[i])
        elif op == "kind":
            kv_kind = [i for i, line in enumerate(lines) if line.startswith("kind")]
            new = rng.choice([f'"{k}"' for k in KINDS] + ['"Static"', '"x"', "1", '""'])
            if kv_kind:
                lines[kv_kind[0]] = f"kind = {new}"
        elif op == "runs":
            idx = [i for i, line in enumerate(lines) if line.startswith("runs")]
            choice = rng.choice(
                [
                    "[]",
                    '[""]',
                    '["."]',
                    '[".."]',
                    '["../raw"]',
                    '["/nonexistent.csv"]',
                    '["../raw/none.csv"]',
                    "[1]",
                    '"../raw/x.csv"',
                    "[[]]",
                    '["../raw/' + rng.choice(run_names) + '"]',
                    '["../raw/' + rng.choice(run_names) + '", "../raw/' + rng.choice(run_names) + '"]',
                    '["../raw/\\u0000.csv"]',
                    '["' + "a" * 5000 + '"]',
                    '["../raw/*.csv"]',
                    '["C:\\\\x.csv"]',
                    '["~/x.csv"]',
                    '["../experiments/static.toml"]',
                ]
            )
            if idx:
                lines[idx[0]] = f"runs = {choice}"
        elif op == "columns":
            canon = rng.choice(
                [
                    "time_s",
                    "temperature_C",
                    "displacement_mm",
                    "force_N",
                    "resistance_ohm",
                    "voltage_V",
                    "r1_ohm",
                    "kappa1_per_mm",
                    "bogus",
                    "current_A",
                ]
            )
            spec = rng.choice(
                [
                    '"x"',
                    f'"{canon}"',
                    "3",
                    "[]",
                    '{ from = "x" }',
                    f'{{ from = "{canon}" }}',
                    f'{{ from = "{canon}", unit = "{rng.choice(list(tio.UNITS) + ["furlong"])}" }}',
                    f'{{ from = "{canon}", scale = {rng.choice(["0", "-1", "nan", "inf", "1e308", "2"])} }}',
                    f'{{ from = "{canon}", offset = {rng.choice(["nan", "-inf", "1e308", "-273.15", "true"])} }}',
                    f'{{ from = "{canon}", units = "mm" }}',
                    '{ unit = "mm" }',
                    "{}",
                    f'{{ from = "{canon}", from2 = 1 }}',
                    '{ from = "" }',
                    "{ from = 3 }",
                ]
            )
            _set_key(lines, "[columns]", canon, spec)
        elif op == "thresholds":
            key = rng.choice(
                [
                    "rmse_mm",
                    "r2_min",
                    "bias_N",
                    "x",
                    "rmse",
                    "nrmse_per_mm",
                    "max_abs_ohm",
                    "rmse_furlong",
                    '""',
                ]
            )
            _set_key(
                lines,
                "[thresholds]",
                key,
                _toml_value(rng) if rng.random() < 0.5 else f"{rng.uniform(0, 2):.3g}",
            )
        elif op in ("sample_value", "rig_value", "uncertainty"):
            from tcamlab.params import RIG_KEYS, SAMPLE_KEYS

            keys = list(SAMPLE_KEYS) if op == "sample_value" else list(RIG_KEYS)
            table = {"sample_value": "[sample]", "rig_value": "[rig]", "uncertainty": "[rig.uncertainty]"}[op]
            key = rng.choice(keys)
            val = rng.choice(
                [
                    _toml_value(rng),
                    "0",
                    "-1",
                    "1e9",
                    "1e-9",
                    "0.5",
                    "2",
                    "1.0001",
                    "[30, 30]",
                    "[0]",
                    "[]",
                    "[1e308, 1e308]",
                ]
                + [f"{rng.uniform(0.01, 300):.4g}"] * 6
            )
            if key == "segment_lengths_mm" and rng.random() < 0.7:
                val = f"[{rng.uniform(1, 90):.3g}, {rng.uniform(1, 90):.3g}]"
            _set_key(lines, table, key, val)
        elif op == "preset":
            idx = [i for i, line in enumerate(lines) if line.startswith("preset")]
            new = rng.choice(['"thesis-tca"', '"thesis-tcs"', '"thesis-robot"', '"thesis"', "1", '""'])
            if idx:
                lines[idx[0]] = f"preset = {new}"
        elif op == "drop_table":
            tables = [i for i, line in enumerate(lines) if line.startswith("[")]
            if tables:
                i = rng.choice(tables)
                j = next((k for k in tables if k > i), len(lines))
                del lines[i:j]
        elif op == "swap_lines" and len(lines) > 1:
            a, b = rng.sample(range(len(lines)), 2)
            lines[a], lines[b] = lines[b], lines[a]
        elif op == "table_header":
            lines.insert(
                rng.randint(0, len(lines)),
                rng.choice(
                    [
                        "[sample]",
                        "[rig]",
                        "[[runs]]",
                        "[columns]",
                        "[]",
                        "[a.b.c]",
                        "[rig.uncertainty.x]",
                        "[synthetic]",
                        "[thresholds]",
                    ]
                ),
            )
        elif op == "deep":
            lines.append("x = " + "[" * 200 + "]" * 200)
        elif op == "dotted":
            lines.append(
                rng.choice(
                    [
                        "sample.preset = 1",
                        "rig.load_g.x = 1",
                        "columns.time_s.from = 3",
                        "synthetic = 1",
                        "runs.x = 1",
                        "notes = []",
                    ]
                )
            )
        else:
            raw_post.append(op)
    data = ("\n".join(lines) + "\n").encode("utf-8", errors="surrogatepass")
    for op in raw_post:
        if op == "truncate" and data:
            data = data[: rng.randint(0, len(data))]
        elif op == "byte_flip" and data:
            b = bytearray(data)
            for _ in range(rng.randint(1, 6)):
                i = rng.randrange(len(b))
                b[i] = rng.randrange(256)
            data = bytes(b)
        elif op == "unicode":
            i = rng.randint(0, len(data))
            data = data[:i] + _rand_unicode(rng, rng.randint(1, 10)).encode("utf-8") + data[i:]
        elif op == "nul":
            i = rng.randint(0, len(data))
            data = data[:i] + b"\x00" + data[i:]
        elif op == "latin1":
            data = data.replace(b"(synthetic)", "(synth\u00e9tic)".encode("latin-1"))
        elif op == "bom":
            data = b"\xef\xbb\xbf" + data
        elif op == "empty":
            data = b""
    return data, {"steps": steps, "mild": mild}


# --- running one input --------------------------------------------------------------


class Lab:
    """A scratch copy of experiments/ and raw/ (cut short) that inputs are written into."""

    def __init__(self, root: Path):
        self.root = root
        (root / "experiments").mkdir(parents=True)
        (root / "raw").mkdir()
        self.csvs = _seed_csvs()
        for kind, texts in self.csvs.items():
            for i, text in enumerate(texts):
                (root / "raw" / f"{kind}_run{i + 1}.csv").write_text(text, encoding="utf-8")
        self.tomls = _seed_tomls()
        self.run_names = sorted(p.name for p in (root / "raw").glob("*.csv"))


def one_input(lab: Lab, seed: int, index: int) -> dict:
    """Generate input ``index`` and run it; returns a record (never raises)."""
    rng = random.Random(f"{seed}:{index}")
    work = lab.root / "work"
    work.mkdir(exist_ok=True)
    record: dict = {"index": index}
    if rng.random() < 0.55:
        kind = rng.choice(KINDS)
        base = rng.choice(lab.csvs[kind])
        data, info = csv_mutations(rng, base)
        read_kind = kind if rng.random() < 0.9 else rng.choice(KINDS)
        columns = random_columns(rng, read_kind)
        drop_na = rng.random() < 0.5
        path = work / rng.choice(["run.csv", "r<b>.csv", "=x.csv", "r un.csv", "é.csv"])
        path.write_bytes(data)
        record.update(type="csv", kind=read_kind, columns=repr(columns), drop_na=drop_na, **info)

        def call():
            return tio.read_run(
                path,
                read_kind,
                columns,
                drop_na=drop_na,
                max_bytes=rng.choice([tio.DEFAULT_MAX_BYTES] * 30 + [64]),
            )
    else:
        name = rng.choice(sorted(lab.tomls))
        data, info = toml_mutations(rng, lab.tomls[name], lab.run_names)
        path = lab.root / "experiments" / "fuzz.toml"
        path.write_bytes(data)
        expected = rng.choice([None] * 12 + list(KINDS))
        record.update(type="toml", base=name, expected_kind=expected, **info)

        def call():
            exp = load_experiment(path, expected_kind=expected)
            return exp.read_runs(drop_na=rng.random() < 0.5)

    record["input"] = data
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = call()
        record["outcome"] = "ok"
        record["result"] = out
    except TcamlabError as exc:
        record["outcome"] = "error"
        msg = exc.one_line()
        record["error_type"] = type(exc).__name__
        record["message"] = msg
        if "\n" in msg:
            record["outcome"] = "crash"
            record["exception"] = "multi-line TcamlabError message"
            record["traceback"] = msg
    except RecursionError as exc:  # pragma: no cover - recorded like any crash
        record.update(
            outcome="crash", exception=f"RecursionError: {exc}", traceback=traceback.format_exc(limit=-6)
        )
    except Exception as exc:
        record.update(
            outcome="crash",
            exception=f"{type(exc).__name__}: {exc}"[:500],
            traceback=traceback.format_exc(limit=-6),
        )
    return record


def pipeline_check(lab: Lab, record: dict) -> dict | None:
    """Run validation on inputs that loaded; returns a crash record or None."""
    from tcamlab import validation

    if record["type"] != "toml":
        return None
    path = lab.root / "experiments" / "fuzz.toml"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            exp = load_experiment(path)
            validation.validate(exp, mc_draws=0)
    except TcamlabError:
        return None
    except Exception as exc:
        return {
            "exception": f"{type(exc).__name__}: {exc}"[:500],
            "traceback": traceback.format_exc(limit=-6),
        }
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=12000, help="number of generated inputs")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--findings", type=Path, default=None, help="folder for crashing inputs")
    ap.add_argument(
        "--pipeline-every",
        type=int,
        default=0,
        help="also validate every N-th experiment that loads (0: never)",
    )
    ap.add_argument("--json", type=Path, default=None, help="write the summary as JSON")
    ap.add_argument("--replay", default=None, help="SEED:INDEX of one input to rerun")
    args = ap.parse_args(argv)

    tmp = Path(tempfile.mkdtemp(prefix="tcamlab-fuzz-"))
    try:
        lab = Lab(tmp / "lab")
        if args.replay:
            seed, index = (int(x) for x in args.replay.split(":"))
            rec = one_input(lab, seed, index)
            print(
                json.dumps(
                    {k: (v if k != "input" else repr(v[:2000])) for k, v in rec.items() if k != "result"},
                    indent=2,
                    default=str,
                )
            )
            return 1 if rec["outcome"] == "crash" else 0
        counts: Counter = Counter()
        kinds: Counter = Counter()
        errors: Counter = Counter()
        crashes: list[dict] = []
        signatures: Counter = Counter()
        loaded_tomls = 0
        pipeline_runs = 0
        t0 = time.perf_counter()
        for i in range(args.n):
            rec = one_input(lab, args.seed, i)
            counts[rec["outcome"]] += 1
            kinds[rec["type"]] += 1
            if rec["outcome"] == "error":
                errors[rec["error_type"]] += 1
            if rec["outcome"] == "ok" and rec["type"] == "toml":
                loaded_tomls += 1
                if args.pipeline_every and loaded_tomls % args.pipeline_every == 0:
                    pipeline_runs += 1
                    bad = pipeline_check(lab, rec)
                    if bad:
                        rec = {**rec, "outcome": "crash", "stage": "validate", **bad}
                        counts["pipeline crash"] += 1
            if rec["outcome"] == "crash":
                sig = (
                    rec["exception"].split(":")[0]
                    + " @ "
                    + rec["traceback"].strip().splitlines()[-3].strip()[:120]
                )
                signatures[sig] += 1
                if signatures[sig] <= 3:
                    crashes.append(rec)
                    print(
                        f"CRASH #{i} ({rec['type']}, {rec.get('steps')}): {rec['exception']}", file=sys.stderr
                    )
                    print(f"  input: {rec['input'][:300]!r}", file=sys.stderr)
                    if args.findings:
                        args.findings.mkdir(parents=True, exist_ok=True)
                        ext = "csv" if rec["type"] == "csv" else "toml"
                        (args.findings / f"crash-{args.seed}-{i}.{ext}").write_bytes(rec["input"])
                        (args.findings / f"crash-{args.seed}-{i}.txt").write_text(
                            json.dumps(
                                {k: v for k, v in rec.items() if k not in ("input", "result")},
                                indent=2,
                                default=str,
                            )
                        )
            if (i + 1) % 1000 == 0:
                print(f"{i + 1} inputs, {dict(counts)}, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        elapsed = time.perf_counter() - t0
        summary = {
            "inputs": args.n,
            "seed": args.seed,
            "by_type": dict(kinds),
            "outcomes": dict(counts),
            "tcamlab_errors": dict(errors),
            "experiments_validated": pipeline_runs,
            "crash_signatures": dict(signatures),
            "seconds": round(elapsed, 1),
        }
        print(json.dumps(summary, indent=2))
        if args.json:
            args.json.write_text(json.dumps(summary, indent=2) + "\n")
        return 1 if signatures else 0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
