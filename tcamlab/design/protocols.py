"""Candidate protocols of a kind's rig: the kind's menu, each protocol's runs and its cost.

The menus belong to the kinds (``design_menu`` beside each kind's ``protocol`` in
:mod:`tcamlab.kinds.static` and :mod:`tcamlab.kinds.dynamic`); so does the reading of a
``[protocol]`` table into runs (``protocol_runs``, which the virtual rig uses too) and into the
predictions its ``channels`` add to the kind's outputs (``protocol_channels``, with each added
chain's sd in ``channel_sd``; a kind without them logs its outputs only).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np
import pandas as pd

from tcamlab.errors import ConfigError
from tcamlab.kinds import get_kind

__all__ = [
    "Protocol",
    "menu",
    "kind_module",
    "protocol_frames",
    "model_inputs",
    "cost_minutes",
    "protocol_quantities",
    "channel_noise",
    "RUN_SETUP_S",
]


RUN_SETUP_S = 300.0
"""Rig time to set up one run [s]: mount the sample, hang the load, zero the laser."""


@dataclass(frozen=True)
class Protocol:
    """One candidate protocol.

    Attributes
    ----------
    name : str
        What changes, in words (``second load 1.5x``).
    table : dict
        Its ``[protocol]`` table (docs/design.md).
    """

    name: str
    table: dict


def kind_module(kind: str):
    """The module of a kind (where its ``protocol``, ``protocol_runs`` and ``design_menu`` live)."""
    return importlib.import_module(get_kind(kind).protocol.__module__)


def menu(kind: str, sample, rig) -> list[Protocol]:
    """The kind's candidate protocols (its ``design_menu``); ConfigError for a kind without one."""
    make = getattr(kind_module(kind), "design_menu", None)
    if make is None:
        raise ConfigError(
            f"design: the {kind} rig has no menu of protocols yet",
            "kinds with a menu: static, dynamic, sensing, curvature, selfsensing",
        )
    return [Protocol(name, table) for name, table in make(sample, rig)]


def protocol_quantities(kind: str, table: dict) -> tuple[str, ...]:
    """The predictions a protocol logs: the kind's outputs, then those its ``channels`` add (the
    kind's ``protocol_channels``: a voltage-step run's ``current`` and ``temperature``); the
    outputs alone for a kind without it or a table without ``channels``."""
    outputs = tuple(get_kind(kind).outputs)
    reader = getattr(kind_module(kind), "protocol_channels", None)
    if reader is None or "channels" not in table:
        return outputs
    added = [q for q in reader(list(table["channels"])) if q not in outputs]
    return outputs + tuple(dict.fromkeys(added))


def channel_noise(kind: str, quantities, noise: dict) -> dict[str, float]:
    """``noise`` [SI] with the sd of each of ``quantities`` it lacks: the chain the protocol adds
    (the kind's ``channel_sd``, the virtual rig's instrument at its stated noise). A quantity
    the diagnosis scored keeps its noise floor."""
    missing = [q for q in quantities if q not in noise]
    if not missing:
        return dict(noise)
    sd = getattr(kind_module(kind), "channel_sd", lambda: {})()
    unknown = [q for q in missing if q not in sd]
    if unknown:
        raise ConfigError(f"design: no noise floor or instrument sd for {unknown[0]!r} on the {kind} rig")
    return {**noise, **{q: float(sd[q]) for q in missing}}


def protocol_frames(kind: str, rig, table: dict, seed: int = 0) -> list[pd.DataFrame]:
    """The exact inputs of each run of a protocol [SI, internal names], as the rig programs them
    (the oven's regulation error and the logger's jitter drawn with ``seed``)."""
    mod = kind_module(kind)
    rng = np.random.default_rng(seed)
    return [mod.protocol(rig, rng, **opts) for opts in mod.protocol_runs(table, rig)]


def model_inputs(kind: str, sample, rig, frames: list[pd.DataFrame]) -> list[pd.DataFrame]:
    """Each run's exact model inputs under its program [SI, internal names]: the program itself
    (static, dynamic) or the resistances the sensor reads under it (sensing, curvature), by the
    kind's ``exact_inputs`` at ``sample`` and ``rig``, the same for every hypothesis."""
    k = get_kind(kind)
    return [k.exact_inputs(sample, rig, f) for f in frames]


def cost_minutes(frames: list[pd.DataFrame], kind: str) -> float:
    """Rig time of the protocol's runs [min]: each run's logged span, its setup
    (:data:`RUN_SETUP_S`) and, for the voltage step, the cool-down between runs."""
    extra = getattr(kind_module(kind), "RUN_OVERHEAD_S", 0.0)
    total = 0.0
    for f in frames:
        t = f["time"].to_numpy(float)
        step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        total += float(t[-1] - t[0]) + step + RUN_SETUP_S + extra
    return total / 60.0
