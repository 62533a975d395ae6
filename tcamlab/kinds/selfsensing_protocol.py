"""The self-sensing rig's program: the commanded voltage and hanging mass of one powered run,
its options, and the menu ``tcamlab design`` ranks.

One run holds every protocol of the bench in order (:data:`SEGMENTS`): a quiet start at the
probe voltage, voltage steps, PWM, a sine and a chirp, with a rider put on the hanger at a
random time (the load changes, so the thermal model alone cannot predict the displacement).
:mod:`tcamlab.kinds.selfsensing` runs it through the virtual rig. :func:`protocol`'s options
change the probe voltage, the rider (its mass and when it goes on), each segment's length,
a held probe at the end and a square ripple on the probe; without options it is the program
above, byte for byte. A ``[protocol]`` table (docs/design.md) is read into each run's options
by :func:`protocol_runs`; :func:`design_menu` lists the candidates, each within the sample's
limits (:func:`program_limit`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab.errors import ConfigError
from tcamlab.kinds import protocol_values as pv
from tcamlab.params import Rig, Sample

RATE_HZ = 100
"""Logging rate of the powered run [Hz]."""
PROBE_V = 1.5
"""Probe voltage between heating phases [V]: keeps a current to read R (about 35 mA, 6 K of self-heating)."""
SEGMENTS = (
    ("rest", 2.0),
    ("steps", 12.0),
    ("pwm", 12.0),
    ("sine", 12.0),
    ("chirp", 12.0),
)
"""Protocol segments and their durations [s], in order."""
STEP_LEVELS_V = (4.0, 6.0)
"""Voltage steps, each 3 s on then 3 s at the probe [V] (6 V on 40 ohm: about 100 K at steady state)."""
PWM_V, PWM_HZ, PWM_DUTY = 6.0, 1.0, 0.5
"""PWM amplitude [V], frequency [Hz] and duty cycle [-]."""
SINE_MEAN_V, SINE_AMP_V, SINE_HZ = 3.5, 2.5, 0.25
"""Sine voltage: mean [V], amplitude [V], frequency [Hz]."""
CHIRP_F0_HZ, CHIRP_F1_HZ = 0.05, 1.0
"""Chirp of the same mean and amplitude, linear from f0 to f1 over its segment [Hz]."""
RIDER_KG = 5e-3
"""Mass of the rider put on the hanger during the run [kg] (5 g, a tenth of the load)."""
RIDER_WINDOW_S = (15.0, 35.0)
"""The rider goes on at a uniform random time in this window [s]."""


SEGMENT_NAMES = ("rest", "steps", "pwm", "sine", "chirp", "hold")
"""Segments a program may hold, in this order; ``hold`` (a held probe after the chirp) is off
by default. Each one's duration is the ``[protocol]`` key ``NAME_s``."""
PROBE_SEGMENTS = ("steps", "pwm", "hold")
"""Segments whose rows between heating phases sit at the probe (where a ripple goes)."""
RIPPLE_HZ = 0.5
"""Frequency of the square probe ripple when one is asked for [Hz]."""

PROBE_MIN_V = 0.5
"""Lowest probe voltage [V]: about 12 mA through the loaded muscle, ten times the current
below which R = V / I is not read (:data:`tcamlab.kinds.selfsensing.MIN_CURRENT_A`)."""
PROBE_MAX_V = 2.5
"""Highest probe voltage [V]: below half the top drive (6 V), so its phases still read as
heating (the kind's regimes: heating above twice the probe); 2.5 V heats the muscle by about
17 K."""
DRIVER_MAX_V = 12.0
"""Highest voltage the driver puts out and the voltage ADC reads [V]."""
MAX_SEGMENT_S = 600.0
"""Longest segment a program may hold [s]."""
RUN_OVERHEAD_S = 120.0
"""Rig time per run beyond its logged span and setup [s]: the muscle cools back to the
probe's steady temperature before the next run's rest rows (40 time constants of 3 s)."""
LIMIT_STRIDE = 10
""":func:`program_limit` runs the rig's model on every 10th row (10 Hz): three times faster,
and the hottest temperature of the template's programs is the same to 1e-9 K (the thermal time
constant is 3 s, the drive's edges fall on the 0.1 s grid)."""
PROGRAM_OPTIONS = ("probe_v", "rider_kg", "rider_window_s", "segments", "ripple_v", "ripple_hz")
"""Options of :func:`protocol` [SI], which the virtual rig passes on."""
PROTOCOL_KEYS = (
    "kind",
    "probe_V",
    "rider_g",
    "rider_s",
    *(f"{name}_s" for name in SEGMENT_NAMES),
    "ripple_V",
    "ripple_Hz",
    "runs",
    "channels",
)
"""Keys of a selfsensing ``[protocol]`` table (docs/design.md)."""
CHANNELS = ["time_s", "voltage_V", "current_A", "load_N", "displacement_mm"]
"""The logged columns of a run (the laser only validates)."""
REQUIRED_CHANNELS = ("time_s", "voltage_V", "current_A", "displacement_mm")
"""Columns every self-sensing run logs (the kind's required columns; the load is optional)."""


def _segment_voltage(name: str, tau: np.ndarray, duration: float, probe_v: float = PROBE_V) -> np.ndarray:
    """Commanded voltage of one protocol segment at local times ``tau`` [s] from its start [V];
    ``probe_v`` [V] between heating phases, and throughout ``rest`` and ``hold``."""
    if name == "steps":
        half = duration / (2 * len(STEP_LEVELS_V))
        k = np.minimum((tau // (2 * half)).astype(int), len(STEP_LEVELS_V) - 1)
        on = (tau % (2 * half)) < half
        return np.where(on, np.asarray(STEP_LEVELS_V)[k], probe_v)
    if name == "pwm":
        return np.where((tau * PWM_HZ) % 1.0 < PWM_DUTY, PWM_V, probe_v)
    if name == "sine":
        return SINE_MEAN_V + SINE_AMP_V * np.sin(2 * np.pi * SINE_HZ * tau)
    if name == "chirp":
        phase = 2 * np.pi * (CHIRP_F0_HZ * tau + 0.5 * (CHIRP_F1_HZ - CHIRP_F0_HZ) / duration * tau**2)
        return SINE_MEAN_V + SINE_AMP_V * np.sin(phase)
    return np.full(tau.shape, probe_v)


def protocol(
    rig: Rig,
    rng: np.random.Generator | None,
    *,
    probe_v: float = PROBE_V,
    rider_kg: float = RIDER_KG,
    rider_window_s: tuple[float, float] = RIDER_WINDOW_S,
    segments: tuple = SEGMENTS,
    ripple_v: float = 0.0,
    ripple_hz: float = RIPPLE_HZ,
) -> pd.DataFrame:
    """The commanded voltage and hanging mass of one run.

    Parameters
    ----------
    rig : Rig
        ``load`` [kg] before the rider goes on.
    rng : numpy.random.Generator or None
        Draws the time the rider goes on (uniform in ``rider_window_s``; None: its middle).
    probe_v : float
        Probe voltage at rest and between heating phases [V].
    rider_kg : float
        Mass of the rider [kg] (0: none; negative: taken off the hanger).
    rider_window_s : (float, float)
        The rider goes on at a uniform random time in it [s] (equal ends: at that time).
    segments : tuple of (str, float)
        Segments (:data:`SEGMENT_NAMES`) and their durations [s], in order.
    ripple_v, ripple_hz : float
        Square ripple of +-``ripple_v`` [V] at ``ripple_hz`` [Hz] on the probe rows after the
        rest (the rest rows set R0 and the rest temperature, so they stay plain).

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``voltage`` [V] (held, 1 mV steps of the driver), ``load_mass`` [kg].
    """
    total = sum(d for _, d in segments)
    t = np.arange(int(round(total * RATE_HZ))) / RATE_HZ
    v = np.empty(t.size)
    ripple = np.zeros(t.size, bool)
    start = 0.0
    for name, duration in segments:
        m = (t >= start - 1e-9) & (t < start + duration - 1e-9)
        v[m] = _segment_voltage(name, t[m] - start, duration, probe_v)
        if ripple_v and name in PROBE_SEGMENTS:
            ripple |= m & (v == probe_v)
        start += duration
    if ripple_v:
        t0 = dict(segments).get("rest", 0.0)
        v = np.where(ripple, probe_v + np.where(((t - t0) * ripple_hz) % 1.0 < 0.5, ripple_v, -ripple_v), v)
    # always drawn, so the run's later draws (the rig's scatter) come from the same stream
    on = float(rng.uniform(*rider_window_s)) if rng is not None else 0.5 * sum(rider_window_s)
    mass = np.where(t >= on, rig.load + rider_kg, rig.load)
    return pd.DataFrame({"time": t, "voltage": np.round(v, 3), "load_mass": mass})


def _number(table: dict, key: str, default: float, lo: float, hi: float, hint: str) -> float:
    """A finite number lo <= x <= hi from the table (or the default), else ConfigError naming the key."""
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        raise ConfigError(f"[protocol]: {key} must be a number from {lo:g} to {hi:g}, got {value!r}", hint)
    return float(value)


def _segments(table: dict) -> tuple:
    """(name, duration [s]) of each segment from the ``NAME_s`` keys, zero-length ones left out."""
    defaults = {**dict.fromkeys(SEGMENT_NAMES, 0.0), **dict(SEGMENTS)}
    out = []
    for name in SEGMENT_NAMES:
        d = _number(
            table, f"{name}_s", defaults[name], 0.0, MAX_SEGMENT_S, f"the default is {defaults[name]:g} s"
        )
        if name == "rest" and d < 1.0:
            raise ConfigError(
                f"[protocol]: rest_s must be at least 1 s, got {d:g}",
                "the rest rows set R0 and the rest temperature",
            )
        if d > 0:
            out.append((name, d))
    return tuple(out)


def _rider_window(table: dict, rest: float, total: float) -> tuple[float, float]:
    """The rider's window [s] from ``rider_s`` (a time or [first, last]), after the rest and in the run."""
    value = table.get("rider_s", list(RIDER_WINDOW_S))
    ends = value if isinstance(value, list) else [value]
    hint = (
        f"a time or [first, last] in s, from the end of the rest ({rest:g} s) to the run's end ({total:g} s)"
    )
    if len(ends) not in (1, 2):
        raise ConfigError(f"[protocol]: rider_s must be a time or [first, last], got {value!r}", hint)
    ends = [_number({"rider_s": x}, "rider_s", 0.0, rest, total, hint) for x in ends]
    if ends[-1] < ends[0]:
        raise ConfigError(
            f"[protocol]: rider_s must be [first, last] with first <= last, got {value!r}", hint
        )
    return (ends[0], ends[-1])


def protocol_runs(table: dict, rig: Rig) -> list[dict]:
    """Each run's :func:`protocol` options from a ``[protocol]`` table (docs/design.md).

    Runs cycle through ``probe_V`` (the default 1.5 V when absent), all with the table's
    rider (``rider_g`` [g] at ``rider_s`` [s]), segment durations (``rest_s`` ... ``hold_s``)
    and ripple (``ripple_V`` [V] at ``ripple_Hz`` [Hz]); g are converted to kg here. An empty
    table is the default program. Unknown keys and bad values raise ConfigError naming the key.
    """
    unknown = sorted(set(table) - set(PROTOCOL_KEYS))
    if unknown:
        raise ConfigError(
            f"[protocol]: unknown key {unknown[0]!r}", "allowed keys: " + ", ".join(PROTOCOL_KEYS)
        )
    # the estimator reads V and I, the laser scores it: none may be left out
    pv.channels(table, CHANNELS, REQUIRED_CHANNELS, list(CHANNELS), "the self-sensing rig")
    hint = f"probe voltages from {PROBE_MIN_V:g} to {PROBE_MAX_V:g} V, e.g. [1.5, 2.5]"
    probes = table.get("probe_V", [PROBE_V])
    if not isinstance(probes, list) or not probes:
        raise ConfigError(f"[protocol]: probe_V must be a list of voltages [V], got {probes!r}", hint)
    probes = [_number({"probe_V": x}, "probe_V", 0.0, PROBE_MIN_V, PROBE_MAX_V, hint) for x in probes]
    load_g = rig.load * 1e3
    rider_g = _number(
        table,
        "rider_g",
        RIDER_KG * 1e3,
        -0.9 * load_g,
        10.0 * load_g,
        f"a positive tension: at most 90 % of the {load_g:g} g load taken off",
    )
    segments = _segments(table)
    window = _rider_window(table, segments[0][1], sum(d for _, d in segments))
    room = min(min(probes) - PROBE_MIN_V, PROBE_MAX_V - max(probes))
    ripple_v = _number(
        table, "ripple_V", 0.0, 0.0, room, f"the probe +- the ripple within {PROBE_MIN_V:g}-{PROBE_MAX_V:g} V"
    )
    common = {
        "rider_kg": rider_g / 1000.0,
        "rider_window_s": window,
        "segments": segments,
        "ripple_v": ripple_v,
        "ripple_hz": _number(table, "ripple_Hz", RIPPLE_HZ, 1e-3, RATE_HZ / 4, "e.g. 0.5 Hz"),
    }
    runs = pv.runs(table, len(probes))
    return [{"probe_v": probes[k % len(probes)], **common} for k in range(runs)]


def program_limit(sample: Sample, rig: Rig, table: dict, seed: int = 0) -> str | None:
    """Why a ``[protocol]`` table is out of the sample's limits at the stated values, or None.

    Each distinct run (one per probe voltage) is run through the rig's model
    (:func:`tcamlab.rig.selfsensing.powered_run`, every :data:`LIMIT_STRIDE` th row) at the
    stated sample and rig. Limits: every commanded voltage within the driver's 0 to
    :data:`DRIVER_MAX_V`; a positive hanging mass; the hottest predicted temperature at most
    :data:`tcamlab.kinds.static.MAX_OVEN_C` and :data:`tcamlab.kinds.static.G_LIMIT_MARGIN_C`
    below the one where G_t' of (2.13) reaches zero; the coil open (its length above the solid
    length n d0). Without R0 or S stated the model cannot run, and only the voltages and the
    mass are checked.
    """
    from tcamlab.kinds.static import G_LIMIT_MARGIN_C, MAX_OVEN_C
    from tcamlab.models import static as st
    from tcamlab.rig.selfsensing import powered_run  # the rig package imports the kind registry

    kw = sample.model_kwargs()
    gt = st.shear_modulus_of(sample)
    rise = float(st.max_temperature_rise(gt, sample.shear_modulus_slope))
    hottest_ok = min(MAX_OVEN_C, rig.ambient + rise - G_LIMIT_MARGIN_C)
    solid = (
        float(st.n_coils(kw["fiber_length"], kw["coil_length"], kw["coil_diameter"])) * kw["fiber_diameter"]
    )
    runs = {o["probe_v"]: o for o in protocol_runs(table, rig)}.values()
    for opts in runs:
        f = protocol(rig, np.random.default_rng(seed), **opts)
        v, mass = f["voltage"].to_numpy(float), f["load_mass"].to_numpy(float)
        if v.min() < 0.0 or v.max() > DRIVER_MAX_V:
            return f"{v.max():.2f} V, beyond the driver's 0-{DRIVER_MAX_V:g} V"
        if mass.min() <= 0.0:
            return "the hanging mass is not positive (the muscle would go slack)"
        if rig.initial_resistance is None or rig.spring_constant is None:
            continue
        k = LIMIT_STRIDE
        run = powered_run(sample, rig, f["time"].to_numpy(float)[::k], v[::k], mass[::k])
        hot = float(np.max(run.temperature))
        if hot > hottest_ok:
            return f"{hot:.0f} degC predicted, above the {hottest_ok:.0f} degC limit (G_t' > 0, {MAX_OVEN_C:g} degC)"
        shortest = sample.coil_length + float(np.min(run.extension))
        if shortest <= solid:
            return f"the coil closes ({shortest * 1e3:.2f} mm of coil, {solid * 1e3:.2f} mm solid)"
    return None


def design_menu(sample: Sample, rig: Rig) -> list[tuple[str, dict]]:
    """Candidate protocols of a self-sensing powered run [(name, ``[protocol]`` table)].

    The default program repeated, and its changes: a second probe voltage (2.5 V, runs
    alternating), a larger and a smaller load step (the rider 2 x and 0.5 x), a load step on
    a held probe (a 10 s hold after the chirp, the rider on in its middle: the load changes
    with no heating), a square probe ripple (+-0.5 V at 0.5 Hz: a change of power at the
    probe splits the load from a thermal-scale error, docs/selfsensing.md "Observability"),
    and longer heating steps (2 x: 6 s each). Two runs each. An entry beyond the sample's
    limits at the stated values (:func:`program_limit`) is left out.
    """
    base = {
        "kind": "selfsensing",
        "probe_V": [PROBE_V],
        "rider_g": round(RIDER_KG * 1e3, 3),
        "rider_s": list(RIDER_WINDOW_S),
        **{f"{name}_s": d for name, d in SEGMENTS},
        "hold_s": 0.0,
        "ripple_V": 0.0,
        "ripple_Hz": RIPPLE_HZ,
        "runs": 2,
        "channels": list(CHANNELS),
    }
    end = sum(d for _, d in SEGMENTS)
    second = round(min(2.0 * PROBE_V, PROBE_MAX_V), 3)
    changes = [
        (f"second probe voltage {second:g} V", {"probe_V": [PROBE_V, second]}),
        (f"load step 2x, {2 * base['rider_g']:g} g rider", {"rider_g": 2 * base["rider_g"]}),
        (f"load step 0.5x, {0.5 * base['rider_g']:g} g rider", {"rider_g": 0.5 * base["rider_g"]}),
        ("load step on a held probe, 10 s hold", {"hold_s": 10.0, "rider_s": end + 5.0}),
        ("probe ripple +-0.5 V at 0.5 Hz", {"ripple_V": 0.5}),
        ("longer heating steps 2x, 6 s each", {"steps_s": 2.0 * dict(SEGMENTS)["steps"]}),
    ]
    menu = [("repeat (same protocol)", base)]
    for name, change in changes:
        table = {**base, **change}
        if program_limit(sample, rig, table) is None:
            menu.append((name, table))
    return menu
