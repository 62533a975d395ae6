"""A virtual rig that lies like a real lab: true parameters off their stated values.

A lab states its rig and sample parameters with an uncertainty
(``[rig.uncertainty]``, and ``[sample.uncertainty]`` where the experiment
file has one); the real values lie somewhere inside it. With a parameter
error F (:func:`tcamlab.rig.simulate` ``parameter_error``) the rig draws
each stated parameter's TRUE value from a distribution with the stated value
as its mean and F stated sds as its sd (z ~ N(0, 1): one seeded draw per
parameter, from a stream keyed by the seed and the field's name, so neither
the runs' noise nor another parameter's draw depends on which parameters are
stated):

- a positive parameter is log-normal, so it stays positive:
  true = exp(mu + s z), s^2 = ln(1 + (F sd / stated)^2), mu = ln(stated) - s^2 / 2
  (the moment-matched form of the dynamic Monte Carlo band,
  :func:`tcamlab.models.dynamic.lognormal_draws`; for F sd << stated it is
  stated + F z sd);
- a parameter that may take any sign (:data:`SIGNED_FIELDS`, or a stated
  value <= 0) is normal: true = stated + F z sd.

Explicit offsets (``parameter_offsets``, for tests) are exact: true =
stated + d sd, refused where that leaves a positive parameter <= 0.

Every run is made with the true values (and the per-run scatter on top);
the experiment file keeps the stated ones, and only the truth file records
the draw (:func:`draw_parameters`).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind
from tcamlab.params import Rig, Sample
from tcamlab.rig.scatter import RIG_SCALARS, SAMPLE_FIELDS

__all__ = ["SIGNED_FIELDS", "LIES_STREAM", "stated_sds", "draw_parameters"]

SIGNED_FIELDS = frozenset({"ambient", "radial_cte", "shear_modulus_slope"})
"""Fields drawn from a normal distribution (they may take any sign or be zero)."""

LIES_STREAM = (0x11E5, 1)
"""Keys a parameter's stream after the seed, before the CRC-32 of its name (the runs use ``[seed, k]``)."""

_RIG_FIELDS = RIG_SCALARS | {"segment_lengths"}


def _sample_uncertainty(exp) -> Mapping[str, Any]:
    """The experiment's ``[sample.uncertainty]`` in SI ({} for an object without one)."""
    return dict(getattr(exp, "sample_uncertainty", None) or {})


def stated_sds(exp, extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Stated standard deviations of an experiment's parameters, {SI field: sd} [SI].

    A rig sd counts only for a field the kind's experiment file states
    (:attr:`tcamlab.kinds.Kind.written_rig_fields`, or a hidden one such as
    sensing S that the template states): the thesis-tca preset carries the sds
    of C_th, lambda and b into the static test too, whose model never reads them.

    Parameters
    ----------
    exp : Experiment
        The template: ``rig.uncertainty``, and its sample uncertainty when the
        configuration provides one (``exp.sample_uncertainty``).
    extra : mapping, optional
        More sds [SI] for fields of Sample or Rig the file does not state (a
        lab's belief it did not write down); they override the file's.

    Raises
    ------
    ConfigError
        An unknown field, a count (``thread_plies``) or a negative sd.
    """
    k = get_kind(exp.kind)
    used = set(k.written_rig_fields) | set(k.hidden_rig_fields)
    rig_sds = {f: v for f, v in exp.rig.uncertainty.items() if f in used}
    out = {**_sample_uncertainty(exp), **rig_sds, **(extra or {})}
    for fld, sd in out.items():
        if fld not in SAMPLE_FIELDS | _RIG_FIELDS or fld == "thread_plies":
            raise ConfigError(
                f"parameter uncertainty: {fld!r} is not a drawable field of Sample or Rig",
                hint="SI field names, e.g. thermal_mass, youngs_modulus",
            )
        if any(not (math.isfinite(x) and x >= 0) for x in np.atleast_1d(np.asarray(sd, float))):
            raise ConfigError(f"parameter uncertainty: sd of {fld} = {sd!r} must be finite and >= 0")
    return out


def _true_value(fld: str, stated: float, sd: float, z: float, error: float, offset) -> tuple[float, str]:
    """(true value [SI], distribution) of one scalar: an exact offset in sds, else drawn with F = error."""
    if offset is not None:
        true = stated + float(offset) * sd
        if stated > 0 and fld not in SIGNED_FIELDS and true <= 0:
            raise ConfigError(f"parameter offsets: {fld} {offset:+g} sds makes it {true:g}, not positive")
        return true, "exact offset"
    if not error:
        return stated, "stated"
    if fld in SIGNED_FIELDS or stated <= 0:
        return stated + error * z * sd, "normal"
    s2 = math.log1p((error * sd / stated) ** 2)
    return math.exp(math.log(stated) - s2 / 2 + math.sqrt(s2) * z), "log-normal"


def _entry(fld: str, table: str, stated, sd, z, error: float, offset) -> dict[str, Any]:
    """The truth record of one field (scalar or per-segment tuple) and its true value."""
    if isinstance(stated, tuple):
        sds = sd if isinstance(sd, tuple) else (sd,) * len(stated)
        parts = [_entry(fld, table, float(v), float(s), x, error, offset) for v, s, x in zip(stated, sds, z)]
        rec = {k: [p[k] for p in parts] for k in ("stated", "sd", "true", "z", "offset_sd")}
        return {"table": table, **rec, "distribution": parts[0]["distribution"]}
    true, dist = _true_value(fld, float(stated), float(sd), float(z), error, offset)
    return {
        "table": table,
        "stated": float(stated),
        "sd": float(sd),
        "true": true,
        "z": float(z) + 0.0,
        "offset_sd": (true - stated) / sd + 0.0 if sd > 0 else 0.0,
        "distribution": dist,
    }


def draw_parameters(
    kind: str,
    sample: Sample,
    rig: Rig,
    sds: Mapping[str, Any],
    *,
    error: float,
    offsets: Mapping[str, float] | None,
    seed: int,
) -> tuple[Sample, Rig, dict[str, dict]]:
    """The true sample and rig, drawn away from the stated ones, and their truth record.

    Parameters
    ----------
    kind : str
        Rig kind (its rig fields that follow the coil length).
    sample, rig :
        The stated sample and rig [SI].
    sds : mapping
        {SI field: stated sd} (:func:`stated_sds`); fields whose stated value
        is None (not used by this rig) are skipped.
    error : float
        F [-]: each true value has the stated mean and F stated sds as its sd.
    offsets : mapping, optional
        {SI field: d}: exact offsets in stated sds, true = stated + d sd,
        instead of a draw.
    seed : int
        The simulation seed (a field's stream is ``[seed, *LIES_STREAM, crc32(field)]``).

    Returns
    -------
    (Sample, Rig, dict)
        The true parameters [SI] and ``{field: {table, stated, sd, true, z,
        offset_sd, distribution}}``: the normal deviate z of the draw (0 for
        an exact offset) and the true value's distance from the stated one
        in stated sds, (true - stated) / sd (= F z for a normal draw).
    """
    offsets = dict(offsets or {})
    unknown = sorted(set(offsets) - set(sds))
    if unknown:
        raise ConfigError(
            f"parameter offsets: {', '.join(unknown)} have no stated uncertainty",
            hint="stated fields: " + (", ".join(sorted(sds)) or "none (add [rig.uncertainty])"),
        )
    record: dict[str, dict] = {}
    s_changes: dict[str, Any] = {}
    r_changes: dict[str, Any] = {}
    for fld in sorted(sds):
        table, owner, changes = (
            ("sample", sample, s_changes) if fld in SAMPLE_FIELDS else ("rig", rig, r_changes)
        )
        stated = getattr(owner, fld)
        n = len(stated) if isinstance(stated, tuple) else 1
        rng = np.random.default_rng([int(seed), *LIES_STREAM, zlib.crc32(fld.encode())])
        z = rng.normal(size=n)
        if stated is None:
            continue
        offset = offsets.get(fld)
        if offset is not None:
            z = np.zeros(n)
        zs = tuple(z) if isinstance(stated, tuple) else z[0]
        rec = _entry(fld, table, stated, sds[fld], zs, float(error), offset)
        record[fld] = rec
        changes[fld] = tuple(rec["true"]) if isinstance(stated, tuple) else rec["true"]
    if "coil_length" in s_changes:
        ratio = s_changes["coil_length"] / sample.coil_length
        for fld in get_kind(kind).coil_length_rig_fields:
            if fld not in r_changes:
                r_changes[fld] = tuple(x * ratio for x in getattr(rig, fld))
    return sample.replace(**s_changes), rig.replace(**r_changes), record
