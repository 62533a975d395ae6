"""Which protocols of a menu the sample has already been through.

A protocol is no harsher than the runs already made when each of its runs is matched by one
run made: no higher peak of any programmed condition (oven temperature [degC], load [N],
voltage [V], pull [m]) and, where it applies a voltage, no longer time under it [s]. The
sample survived those runs, so the model's domain at a fit (G_t' <= 0, no equilibrium, a coil
the fit closes) says nothing about whether it survives such a protocol: that is the fit's
shortcoming near the edge of its domain, not the sample's.
"""

from __future__ import annotations

import numpy as np

from tcamlab.errors import ConfigError, InputError

__all__ = ["exposure", "no_harsher", "runs_made", "PEAK_TOLERANCE"]

PEAK_TOLERANCE = 0.01
"""Relative margin [-] within which a peak counts as the same: the oven's regulation error,
the logger's noise and set points rounded in the file (1 % is 1.5 K at 150 degC)."""

_IN_THE_LOG = {"elongation": "displacement"}
"""A program column -> the logged column that records it where the names differ."""

_FROM_THE_RIG = {"load": "force"}
"""A program column -> the rig's stated value a run without it ran at (the hanging load's
weight [N])."""


def runs_made(experiment) -> list:
    """The logged data of the experiment's runs [SI, internal names] (empty when they cannot be
    read: the design then counts the repeat alone as already run)."""
    try:
        return [r.data for r in experiment.read_runs(drop_na=True)]
    except (InputError, ConfigError, OSError, ValueError):
        return []


def _on_time(t: np.ndarray, v: np.ndarray) -> float:
    """Time [s] at or above half the peak |v| (a pulse's length; a train's pulses summed)."""
    if t.size < 2:
        return 0.0
    peak = float(np.max(np.abs(v)))
    on = np.abs(v[:-1]) >= 0.5 * peak if peak > 0 else np.zeros(t.size - 1, bool)
    return float(np.sum(np.diff(t)[on]))


def exposure(frame, rig, columns) -> dict[str, float]:
    """A run's conditions: the peak |value| of each program column in ``columns`` [SI] (NaN
    where the run neither logs it nor the rig states it) and ``voltage_on`` [s] where a voltage
    is programmed (:func:`_on_time`)."""
    out = {}
    for c in columns:
        name = c if c in frame else _IN_THE_LOG.get(c, c)
        if name in frame:
            x = np.asarray(frame[name], float)
            out[c] = float(np.nanmax(np.abs(x))) if x.size else float("nan")
        elif c in _FROM_THE_RIG and getattr(rig, _FROM_THE_RIG[c], None) is not None:
            out[c] = abs(float(getattr(rig, _FROM_THE_RIG[c])))
        else:
            out[c] = float("nan")
    if "voltage" in columns:
        has = "voltage" in frame and "time" in frame
        t = np.asarray(frame["time"], float) if has else np.zeros(0)
        out["voltage_on"] = _on_time(t, np.asarray(frame["voltage"], float)) if has else float("nan")
    return out


def _covered(new: dict, old: dict, step: float) -> bool:
    """Whether a run with conditions ``new`` is no harsher than one with ``old`` (``step``: the
    old run's sampling interval [s], the resolution of its time under voltage)."""
    for c, v in new.items():
        w = old.get(c, float("nan"))
        if not np.isfinite(w):
            return False
        margin = step if c == "voltage_on" else 0.0
        if v > w * (1.0 + PEAK_TOLERANCE) + margin:
            return False
    return True


def no_harsher(frames, made, rig) -> bool:
    """Whether every run of a protocol (its programs, ``frames`` [SI]) is no harsher than one
    of the runs ``made`` (their logs [SI]); False when no run was made."""
    columns = sorted({c for f in frames for c in f.columns if c != "time"})
    old = []
    for d in made:
        t = np.asarray(d["time"], float) if "time" in d else np.zeros(0)
        step = float(np.max(np.diff(t))) if t.size > 1 else 0.0
        old.append((exposure(d, rig, columns), step))
    return bool(made) and all(any(_covered(exposure(f, rig, columns), o, s) for o, s in old) for f in frames)
