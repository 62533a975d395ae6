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

__all__ = ["MAX_RUNS", "positive", "whole", "runs", "positive_list", "number_pair", "choice"]

MAX_RUNS = 1000
"""Most runs a ``[protocol]`` table may ask for (a typo guard, not a rig limit)."""


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)


def positive(table: dict, key: str, default: float, hint: str) -> float:
    """A positive finite number from the table (or ``default``), else ConfigError naming the key."""
    value = table.get(key, default)
    if not _is_number(value) or not value > 0:
        raise ConfigError(f"[protocol]: {key} must be a positive number, got {value!r}", hint)
    return float(value)


def whole(table: dict, key: str, default: int, top: int, hint: str) -> int:
    """An integer 1..top from the table (or ``default``), else ConfigError naming the key."""
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
        raise ConfigError(f"[protocol]: {key} must be an integer from 1 to {top}, got {value!r}", hint)
    return int(value)


def runs(table: dict, default: int) -> int:
    """The table's ``runs``: an integer from 1 to :data:`MAX_RUNS` (or ``default``)."""
    return whole(table, "runs", default, MAX_RUNS, "runs to make, e.g. runs = 2")


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
