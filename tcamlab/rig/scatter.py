"""Per-run scatter of the virtual rig: each run's true sample and rig.

Repeats of one sample differ slightly (re-mounting, slow annealing); the rig
draws each run's true parameters as the template's times ``1 + N(0, rel sd)``.
What is per-kind (per-segment fields, lengths that follow the coil length)
comes from the kind registry (:class:`tcamlab.kinds.Kind`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind
from tcamlab.params import Rig, Sample

__all__ = ["SAMPLE_FIELDS", "RIG_SCALARS", "TRUTH_RIG_FIELDS", "scattered", "rig_truth"]

SAMPLE_FIELDS = frozenset(Sample.__dataclass_fields__)
"""Sample fields a scatter may name."""

RIG_SCALARS = frozenset(Rig.__dataclass_fields__) - {"uncertainty", "segment_lengths"}
"""Rig fields a scatter may name (scalars; a kind's segment fields may become tuples)."""

TRUTH_RIG_FIELDS = tuple(sorted(RIG_SCALARS | {"segment_lengths"}))
"""Rig fields recorded in the truth file, in file order."""


def _draw(base, rel: float, per_segment: bool, segments: int, rng: np.random.Generator):
    """``base`` times (1 + rel N(0, 1)): one draw per element of a tuple or, per segment, of a scalar."""
    if isinstance(base, tuple):
        return tuple(float(b) * (1.0 + rel * rng.normal()) for b in base)
    if per_segment:
        return tuple(float(base) * (1.0 + rel * rng.normal()) for _ in range(segments))
    return base * (1.0 + rel * rng.normal())


def scattered(
    kind: str, sample: Sample, rig: Rig, scatter: Mapping[str, float], rng: np.random.Generator
) -> tuple[Sample, Rig]:
    """One run's true sample and rig: each listed field times (1 + N(0, rel sd)).

    Parameters
    ----------
    kind : str
        Rig kind (its segment fields and coil-length fields).
    sample, rig :
        The template's sample and rig [SI].
    scatter : mapping
        SI field of Sample or Rig -> relative sd [-]; drawn in sorted field order.
    rng : numpy.random.Generator
        The run's stream.

    Returns
    -------
    (Sample, Rig)
        The run's true parameters [SI].
    """
    k = get_kind(kind)
    s_changes: dict[str, float] = {}
    r_changes: dict[str, Any] = {}
    for fld in sorted(scatter):
        rel = float(scatter[fld])
        if fld in SAMPLE_FIELDS:
            if fld == "thread_plies":
                raise ConfigError("scatter: thread_plies is a count and cannot scatter")
            s_changes[fld] = getattr(sample, fld) * (1.0 + rel * rng.normal())
        elif fld in RIG_SCALARS:
            base = getattr(rig, fld)
            if base is not None:
                per_segment = fld in k.segment_rig_fields
                r_changes[fld] = _draw(base, rel, per_segment, len(rig.segment_lengths), rng)
        else:
            raise ConfigError(
                f"scatter: unknown field {fld!r}",
                hint="SI field names of Sample or Rig, e.g. twists, coil_length",
            )
    if "coil_length" in s_changes:
        ratio = s_changes["coil_length"] / sample.coil_length
        for fld in k.coil_length_rig_fields:
            r_changes[fld] = tuple(x * ratio for x in getattr(rig, fld))
    return sample.replace(**s_changes), rig.replace(**r_changes)


def rig_truth(rig: Rig) -> dict[str, Any]:
    """The rig fields the truth file records, {field: SI value}."""
    return {f: getattr(rig, f) for f in TRUTH_RIG_FIELDS}
