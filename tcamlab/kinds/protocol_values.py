"""Values of a ``[protocol]`` table, read with the key named in any error.

A protocol file is written by ``tcamlab design`` but edited by hand and run by rigs that are
not tcamlab's, so every value is checked where it is read: a string where a number belongs, a
number where a list belongs, an empty list, a zero or negative load, a run count that is not
a whole number. Each reader raises :class:`tcamlab.errors.ConfigError` naming the key, what it
must be and what it got, with a hint that is itself a valid value.
"""

from __future__ import annotations

import math

from tcamlab.errors import ConfigError

__all__ = [
    "MAX_RUNS",
    "MAX_RUN_S",
    "MAX_LEVELS",
    "positive",
    "bounded",
    "whole",
    "runs",
    "positive_list",
    "number_pair",
    "choice",
    "levels",
    "run_length",
    "channels",
]

MAX_RUNS = 1000
"""Most runs a ``[protocol]`` table may ask for (a typo guard, not a rig limit)."""

MAX_RUN_S = 86400.0
"""Longest run a ``[protocol]`` table may ask for [s]: a day. A typo guard that also keeps a
run's log within memory (a sensing pull at 1e-6 mm/s asked for 50 million s and filled 23 GB
before the kernel stopped it)."""

MAX_LEVELS = 1000
"""Most set points, pull steps or bending levels in one run (a typo guard: an oven step of
1e-4 degC asked for 2.5 million set points)."""


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


def positive(table: dict, key: str, default: float, hint: str) -> float:
    """A positive finite number from the table (or ``default``), else ConfigError naming the key."""
    value = table.get(key, default)
    if not _is_number(value) or not value > 0:
        raise ConfigError(f"[protocol]: {key} must be a positive number, got {value!r}", hint)
    return float(value)


def bounded(table: dict, key: str, default: float, lo: float, hi: float, hint: str) -> float:
    """A finite number from ``lo`` to ``hi`` from the table (or ``default``), else ConfigError."""
    value = table.get(key, default)
    if not _is_number(value) or not lo <= value <= hi:
        raise ConfigError(f"[protocol]: {key} must be a number from {lo:g} to {hi:g}, got {value!r}", hint)
    return float(value)


def levels(count: float, what: str, hint: str) -> int:
    """``count`` levels (set points, steps, poses) as a whole number up to :data:`MAX_LEVELS`,
    else ConfigError saying ``what`` asked for them."""
    if not abs(count - round(count)) <= 1e-6 * max(1.0, abs(count)):
        raise ConfigError(f"[protocol]: {what} is not a whole number of steps ({count:.6g})", hint)
    if not 1 <= round(count) <= MAX_LEVELS:
        raise ConfigError(f"[protocol]: {what} asks for {count:.6g} steps; at most {MAX_LEVELS}", hint)
    return int(round(count))


def run_length(seconds: float, what: str, hint: str) -> None:
    """ConfigError when a run would last longer than :data:`MAX_RUN_S`."""
    if not seconds <= MAX_RUN_S:
        raise ConfigError(
            f"[protocol]: {what} make a run of {seconds:.3g} s, longer than a day ({MAX_RUN_S:g} s)", hint
        )


def channels(table: dict, logged, required, default, rig: str = "this rig") -> list[str]:
    """The table's ``channels`` (or ``default``): a list of distinct column names, each one the
    ``rig`` logs (``logged``), with every one of ``required``; else ConfigError naming the column."""
    value = table.get("channels", default)
    example = "e.g. channels = [" + ", ".join(f'"{c}"' for c in default) + "]"
    if not isinstance(value, list) or not all(isinstance(c, str) for c in value):
        raise ConfigError(f"[protocol]: channels must be a list of column names, got {value!r}", example)
    for c in value:
        if c not in logged:
            raise ConfigError(
                f"[protocol]: channels: {c!r} is not a column {rig} logs (it logs {', '.join(logged)})",
                example,
            )
    missing = [c for c in required if c not in value]
    twice = sorted({c for c in value if value.count(c) > 1})
    if missing or twice:
        what = f"lacks {', '.join(map(repr, missing))}" if missing else f"lists {twice[0]!r} twice"
        raise ConfigError(f"[protocol]: channels {what}", example)
    return list(value)


def whole(table: dict, key: str, default: int, top: int, hint: str) -> int:
    """An integer 1..top from the table (or ``default``), else ConfigError naming the key."""
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
        raise ConfigError(f"[protocol]: {key} must be an integer from 1 to {top}, got {value!r}", hint)
    return int(value)


def runs(table: dict, default: int) -> int:
    """The table's ``runs``: an integer from 1 to :data:`MAX_RUNS` (or ``default``), and at
    least ``default``, the length of the list the runs cycle through (fewer would leave its
    last entries unrun without a word)."""
    n = whole(table, "runs", default, MAX_RUNS, f"runs to make, e.g. runs = {max(default, 2)}")
    if n < default:
        raise ConfigError(
            f"[protocol]: runs = {n} is fewer than the {default} conditions the runs cycle through "
            "(loads, voltages, speeds or probes): the last would not be run (use it or a multiple)",
            f"e.g. runs = {default}",
        )
    return n


def positive_list(table: dict, key: str, default: list, hint: str) -> list[float]:
    """A non-empty list of positive finite numbers (or ``default``), else ConfigError naming the key."""
    value = table.get(key, default)
    if not isinstance(value, list) or not value or not all(_is_number(v) and v > 0 for v in value):
        raise ConfigError(
            f"[protocol]: {key} must be a non-empty list of positive numbers, got {value!r}", hint
        )
    return [float(v) for v in value]


def number_pair(table: dict, key: str, default: list, hint: str) -> tuple[float, float]:
    """[first, last], two finite numbers with first < last (or ``default``), else ConfigError."""
    value = table.get(key, default)
    if (
        not isinstance(value, list)
        or len(value) != 2
        or not all(_is_number(v) for v in value)
        or not value[0] < value[1]
    ):
        raise ConfigError(f"[protocol]: {key} must be [first, last], two numbers rising, got {value!r}", hint)
    return float(value[0]), float(value[1])


def choice(table: dict, key: str, default: str, allowed, hint: str | None = None) -> str:
    """One of ``allowed`` (or ``default``), else ConfigError naming the key and the choices."""
    value = table.get(key, default)
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(
            f"[protocol]: {key} must be one of {', '.join(map(repr, allowed))}, got {value!r}",
            hint or f'{key} = "{allowed[0]}"',
        )
    return value
