"""One virtual-rig run, step by step, each step the kind's own (:mod:`tcamlab.kinds`).

These are thin public functions that look the kind up with
:func:`tcamlab.kinds.get_kind`; the per-kind work lives in the kind modules.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind
from tcamlab.params import Rig, Sample

__all__ = [
    "protocol",
    "designed_programs",
    "designed_channels",
    "program_options",
    "exact_inputs",
    "instrument_sd",
    "true_options",
    "measure",
]


def program_options(kind: str, **options) -> dict[str, Any]:
    """The protocol options ``kind`` takes, out of ``options`` (others are ignored: a dynamic run has no oven)."""
    return {k: v for k, v in options.items() if k in get_kind(kind).program_options}


def designed_programs(kind: str, experiment) -> list[dict] | None:
    """Each run's program options from the experiment file's ``[protocol]`` table (a designed
    protocol, ``tcamlab design``; docs/design.md), or None when the file has none.

    The table is read by the kind's own ``protocol_runs`` (beside its ``protocol``).
    """
    table = (getattr(experiment, "raw", None) or {}).get("protocol")
    if table is None:
        return None
    if table.get("kind", kind) != kind:
        where = Path(getattr(experiment, "path", "") or "").name
        raise ConfigError(
            f"{where + ': ' if where else ''}[protocol]: a {table.get('kind')!r} protocol in a {kind!r} experiment",
            f'kind = "{kind}" in [protocol] (a protocol table is for the experiment\'s own rig)',
        )
    module = importlib.import_module(get_kind(kind).protocol.__module__)
    reader = getattr(module, "protocol_runs", None)
    if reader is None:
        raise ConfigError(f"[protocol]: the {kind} rig takes no designed protocol")
    return _in_file(experiment, reader, dict(table), experiment.rig)


def _in_file(experiment, fn, *args):
    """``fn(*args)``, a ConfigError's message led by the experiment file's name (the one line
    then says which file's ``[protocol]`` table holds the bad value)."""
    try:
        return fn(*args)
    except ConfigError as exc:
        path = getattr(experiment, "path", None)
        if path is None or exc.message.startswith(f"{Path(path).name}: "):
            raise
        raise ConfigError(f"{Path(path).name}: {exc.message}", exc.hint) from None


def designed_channels(kind: str, experiment) -> tuple[str, ...]:
    """The model's predictions a designed protocol asks the rig to log beyond the kind's own
    columns (``[protocol]`` ``channels``, read by the kind's ``protocol_channels``: a voltage-step
    test's current and temperature); empty without such a table or where the kind logs no more.
    """
    table = (getattr(experiment, "raw", None) or {}).get("protocol") or {}
    if "channels" not in table:
        return ()
    module = importlib.import_module(get_kind(kind).protocol.__module__)
    reader = getattr(module, "protocol_channels", None)
    if reader is None:
        return ()
    return tuple(_in_file(experiment, _channels, reader, table["channels"]))


def _channels(reader, channels) -> tuple[str, ...]:
    if not isinstance(channels, list) or not all(isinstance(c, str) for c in channels):
        raise ConfigError(
            f"[protocol]: channels must be a list of column names, got {channels!r}",
            'e.g. channels = ["time_s", "voltage_V", "displacement_mm"]',
        )
    return tuple(reader(list(channels)))


def protocol(kind: str, rig: Rig, rng: np.random.Generator, **options) -> pd.DataFrame:
    """The exact programmed quantities of one run (SI, internal names).

    Parameters
    ----------
    kind : str
        Rig kind.
    rig : Rig
        Rig parameters (voltage and pulse of the dynamic test).
    rng : numpy.random.Generator
        Draws the oven regulation error (static) and the timing jitter
        (dynamic); the sensing and curvature programs are deterministic.
    **options
        Program options (static ``oven``: "heating" or "heat-cool", see
        :data:`tcamlab.kinds.static.OVEN_PROGRAMS`); those a kind does not
        take are ignored.

    Returns
    -------
    pandas.DataFrame
        static: ``time``, ``temperature`` (the actual oven temperature);
        dynamic: ``time``, ``voltage``; sensing: ``time``, ``elongation``
        (sensor elongation programmed by the actuator); curvature: ``cable``.
    """
    return get_kind(kind).protocol(rig, rng, **program_options(kind, **options))


def exact_inputs(
    kind: str, sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS
) -> pd.DataFrame:
    """The exact input columns of :func:`tcamlab.kinds.predict` for a protocol [SI].

    Static and dynamic inputs are the protocol itself; the sensing input is
    the stretched sensor's resistance; the curvature inputs are the cable and
    each segment's resistance (see the kind modules).
    """
    return get_kind(kind).exact_inputs(sample, rig, proto, mods)


def instrument_sd(kind: str, noise_scale: float = 1.0) -> dict[str, float]:
    """Standard deviation of each logged column's measurement chain (SI).

    Noise and quantisation (uniform, q / sqrt(12)) together; columns that are
    logged exactly (time, commanded voltage, programmed cable pull) are 0.
    """
    return get_kind(kind).instrument_sd(float(noise_scale))


def true_options(kind: str, sample: Sample, rig: Rig, data: pd.DataFrame) -> dict[str, Any]:
    """Keyword options of :func:`tcamlab.kinds.predict` for a run's (true) rig, by the kind's rule."""
    return dict(get_kind(kind).run_options(sample, rig, data).options)


def measure(
    kind: str,
    inputs: pd.DataFrame,
    outputs: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    noise_scale: float,
    **options,
) -> pd.DataFrame:
    """Logged columns [SI, internal names] from the exact inputs and outputs, through the kind's chains.

    ``options``: ``noisy_zero=True`` zeroes each zeroed channel on one noisy
    reading; the kind's ``measure`` then puts each channel's zero error [SI]
    in the result's ``attrs["zero_error"]`` {logged column: error}.
    """
    return get_kind(kind).measure(inputs, outputs, rng, float(noise_scale), **options)
