"""tcamlab's one JSON conversion: numpy scalars and arrays to Python, NaN/inf to null.

Every JSON file and ``--json`` output goes through :func:`dumps_json`, so
none holds a bare ``NaN`` (not JSON) and identical inputs give identical bytes.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

import numpy as np

__all__ = ["json_float", "to_jsonable", "dumps_json"]


def json_float(x) -> float | None:
    """A JSON-safe float: None for NaN, inf or anything that is not a number."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def to_jsonable(obj):
    """obj with mapping keys as str, tuples and arrays as lists, numpy scalars as
    Python ones and non-finite floats as None; other values are left as they are."""
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return json_float(obj)
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    return obj


def dumps_json(obj, *, indent: int = 2, sort_keys: bool = True) -> str:
    """Deterministic JSON text of obj (converted by :func:`to_jsonable`), ending in a newline."""
    return json.dumps(to_jsonable(obj), indent=indent, sort_keys=sort_keys, allow_nan=False) + "\n"
