"""Static oven test (thesis section 2.5.1): displacement against temperature.

The model is the static equilibrium of section 2.3 with the constant-G shear
modulus (2.12) or its temperature-dependent form G(T) (2.13); effect terms of
:class:`tcamlab.effects.Mods` that act here: shear_slope_extra, coil_shear_slope,
youngs_modulus_slope, glass_gain/glass_temperature, lag_tau, drift.

The virtual rig's oven test (:func:`protocol`, :func:`measure`): 5 degC oven
steps from 25 to 150 degC, read after a dwell, logged by the thermocouple
reader and the laser chain of :mod:`tcamlab.instruments`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab import instruments
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError
from tcamlab.kinds import CalibrationParam, Kind, RunOptions, no_extras, no_section
from tcamlab.kinds import protocol_values as pv
from tcamlab.models import static as _static
from tcamlab.params import THESIS_TCA, Rig, Sample
from tcamlab.report.document import Figure
from tcamlab.report.figures import legend_label, new_figure
from tcamlab.signals import LINEAR_BETWEEN_ROWS, clock, first_order_lag, moving_average

TEMPERATURE_BAND_EDGES_C = (25, 50, 75, 100, 125, 150)
"""Edges of the temperature bands the diagnosis reports residuals in [degC]."""

OVEN_STEPS_C = tuple(float(t) for t in range(25, 151, 5))
"""Oven set points [degC]: 5 degC steps from just above room temperature to 150
degC (below the G_t' = 0 limit of ~160 degC), 26 readings per run."""
OVEN_DWELL_S = 300.0
"""Dwell per step before the reading [s], long enough for the small oven to settle."""
OVEN_REGULATION_SD_C = 0.3
"""The oven holds its set point only to a few tenths of a degree [degC]."""
OVEN_PROGRAMS = ("heating", "heat-cool")
"""Static oven programs: the thesis's heating-only 25 -> 150 degC steps, or the
same steps up and back down to 25 degC (a cooling branch: 51 readings), the
experiment that separates sensor drift and thermal lag from temperature-only
effects."""


def predict(
    sample: Sample, rig: Rig, data: pd.DataFrame, mods: Mods = NO_MODS, *, constant_g: bool = False
) -> dict[str, np.ndarray]:
    """Static oven test: displacement from the first row against temperature.

    Parameters
    ----------
    sample, rig :
        Sample and rig (load, ambient = reference temperature) [SI].
    data : DataFrame
        ``temperature`` [degC], optional ``time`` [s] and ``load`` [N] (the hanging
        weight of each row, logged where runs are made at several loads; else the rig's).
    mods : Mods
        Effect terms (shear_slope_extra, coil_shear_slope, youngs_modulus_slope, glass_*, lag_tau,
        lag_conductance_tc, drift).
    constant_g : bool
        Use the constant-G model of (2.12) (slope 0) instead of the sample's G(T).

    Returns
    -------
    dict
        ``displacement`` [m], zero at the first row.
    """
    t = clock(data)
    hold = "midpoint" if data.attrs.get(LINEAR_BETWEEN_ROWS) == "linear" else "end"
    temp = first_order_lag(
        data["temperature"].to_numpy(float), t, mods.lag_tau, mods.lag_conductance_tc, rig.ambient, hold
    )
    dT = temp - rig.ambient
    kw = sample.model_kwargs()
    kw["shear_modulus_slope"] = (0.0 if constant_g else kw["shear_modulus_slope"]) + mods.shear_slope_extra
    if mods.glass_gain:
        above = np.maximum(0.0, temp - mods.glass_temperature)
        strain = dT + mods.glass_gain * above
        safe = np.where(np.abs(dT) > 1e-12, dT, 1.0)
        kw["radial_cte"] = np.where(np.abs(dT) > 1e-12, sample.radial_cte * strain / safe, sample.radial_cte)
    force = data["load"].to_numpy(float) if "load" in data else rig.force
    delta = _static.displacement(
        dT,
        force,
        youngs_modulus_slope=mods.youngs_modulus_slope,
        coil_shear_slope=mods.coil_shear_slope,
        **kw,
    )
    disp = delta - delta[0] + mods.drift * t
    return {"displacement": disp}


def run_options(sample: Sample, rig: Rig, data: pd.DataFrame, **_) -> RunOptions:
    """The static model needs no per-run constant beyond the sample and the rig."""
    return RunOptions()


def regimes(data: pd.DataFrame, quantity: str, frames=()) -> dict[str, np.ndarray]:
    """Temperature band and heating / steady / cooling phase of every row."""
    n = len(data)
    T = data["temperature"].to_numpy(float)
    edges = TEMPERATURE_BAND_EDGES_C
    band = np.full(n, "", dtype=object)
    lo_edge = np.concatenate(([-np.inf], edges))
    for a, b in zip(lo_edge[:-1], lo_edge[1:]):
        lbl = f"<{b} degC" if not np.isfinite(a) else f"{a}-{b} degC"
        band[(T >= a) & (T < b)] = lbl
    band[T >= edges[-1]] = f">={edges[-1]} degC"
    t = data["time"].to_numpy(float) if "time" in data else np.arange(n, dtype=float)
    k = max(3, n // 20)
    slope = np.gradient(moving_average(T, k), t) if n > 2 else np.zeros(n)
    tol = 0.05 * np.quantile(np.abs(slope), 0.95) if n > 2 else 0.0
    phase = np.where(np.abs(slope) <= tol, "steady", np.where(slope > 0, "heating", "cooling"))
    return {"temperature band": band, "phase": phase.astype(object)}


def figures(result) -> list[Figure]:
    """Displacement against temperature for both models, as thesis figure 2.7."""
    fig, ax = new_figure()
    for p in result.predictions:
        t = p.data["temperature"].to_numpy()
        name = legend_label(p.name)
        (line,) = ax.plot(t, p.data["displacement"] * 1e3, "o", ms=3, label=f"{name} measured")
        ax.plot(
            t,
            p.predicted["G(T)"]["displacement"] * 1e3,
            "-",
            color=line.get_color(),
            label=f"{name} G(T) model",
        )
        ax.plot(
            t,
            p.predicted["constant-G"]["displacement"] * 1e3,
            "--",
            color=line.get_color(),
            alpha=0.7,
            label=f"{name} constant-G model",
        )
    ax.set_xlabel("temperature [°C]")
    ax.set_ylabel("displacement [mm]")
    ax.legend(fontsize=6, ncol=2)
    caption = (
        "Displacement against temperature: measured (points), G(T) model (solid) and "
        "constant-G model (dashed), as in thesis figure 2.7."
    )
    return [Figure(fig, caption, alt="static validation plot")]


# --- virtual rig ---------------------------------------------------------------------------


SECOND_LOAD_FACTOR = 1.5
"""The second condition of a two-condition experiment (:data:`tcamlab.kinds.CONDITIONS`): the
oven program at 1.5 x the stated load, logged as ``load_N``. The coil's compliance terms
(f11 F) scale with the load and the torque terms do not, so G(T) of the coil, E(T) and the
calibrated rho and G_t slope act differently at the two loads (thesis 2.9-2.13)."""


def protocol(
    rig: Rig,
    rng: np.random.Generator,
    *,
    oven: str = "heating",
    condition: int | None = None,
    load_N: float | None = None,
    set_points_C: tuple[float, float, float] | None = None,
    dwell_s: float | None = None,
) -> pd.DataFrame:
    """The exact oven program of one run.

    Parameters
    ----------
    rig : Rig
        ``load`` [kg]: logged per row (``load`` [N]) when ``condition`` is given.
    rng : numpy.random.Generator
        Draws the regulation error of each step, N(0, :data:`OVEN_REGULATION_SD_C`).
    oven : {"heating", "heat-cool"}
        Oven program (:data:`OVEN_PROGRAMS`).
    condition : {None, 0, 1}
        None: the stated load, not logged. 0 or 1: the stated load or
        :data:`SECOND_LOAD_FACTOR` times it, logged.
    load_N : float, optional
        The hanging weight of this run [N], logged (a designed protocol's ``loads_g``).
    set_points_C : (first, last, step), optional
        Oven set points [degC] (default :data:`OVEN_STEPS_C`).
    dwell_s : float, optional
        Dwell per step [s] (default :data:`OVEN_DWELL_S`).

    Returns
    -------
    pandas.DataFrame
        ``time`` [s] (one reading per dwell), ``temperature`` [degC] (the
        actual oven temperature: set point + regulation error), ``load`` [N] with a condition.
    """
    steps = np.asarray(OVEN_STEPS_C) if set_points_C is None else set_points(*set_points_C)
    if oven == "heat-cool":
        steps = np.concatenate([steps, steps[-2::-1]])
    elif oven != "heating":
        raise ConfigError(f"unknown oven program {oven!r}", hint="one of " + ", ".join(OVEN_PROGRAMS))
    temp = steps + rng.normal(0.0, OVEN_REGULATION_SD_C, steps.size)
    dwell = OVEN_DWELL_S if dwell_s is None else float(dwell_s)
    out = pd.DataFrame({"time": np.arange(steps.size) * dwell, "temperature": temp})
    if load_N is not None:
        out["load"] = float(load_N)
    elif condition is not None:
        out["load"] = rig.force * (SECOND_LOAD_FACTOR if condition else 1.0)
    return out


def set_points(first: float, last: float, step: float) -> np.ndarray:
    """Oven set points [degC] from ``first`` to ``last`` (included) in steps of ``step``."""
    if not (step > 0 and last > first):
        raise ConfigError(f"oven set points {first} to {last} degC in {step} degC steps: none")
    return np.arange(float(first), float(last) + step / 2.0, float(step))


PROTOCOL_KEYS = ("kind", "loads_g", "oven", "temperature_C", "step_C", "dwell_s", "runs", "channels")

STATIC_CHANNELS = ("time_s", "temperature_C", "load_N", "displacement_mm")
"""Columns an oven run logs (a ``[protocol]`` table's ``channels`` lists them)."""

KIND_REQUIRED = ("temperature_C", "displacement_mm")
"""Of those, the ones every static run must log."""
"""Keys of a static ``[protocol]`` table (docs/design.md)."""

MAX_OVEN_C = 170.0
"""Highest oven set point a design may propose [degC]: nylon 6,6 keeps well below its
softening range there, and the model's G_t' limit (~160 degC at the thesis values) usually
comes first (:func:`design_menu` stays :data:`G_LIMIT_MARGIN_C` below it)."""

G_LIMIT_MARGIN_C = 5.0
"""A design's hottest set point stays this far below the temperature where G_t' of (2.13)
reaches zero at the stated values [K]; each hypothesis is checked over the range as well."""


def protocol_runs(table: dict, rig: Rig) -> list[dict]:
    """Each run's :func:`protocol` options from a ``[protocol]`` table (docs/design.md).

    Runs cycle through ``loads_g`` (grams; the stated load when absent), all with the
    table's oven program, set points (``temperature_C`` = [first, last], ``step_C``) and dwell.
    """
    unknown = sorted(set(table) - set(PROTOCOL_KEYS))
    if unknown:
        raise ConfigError(
            f"[protocol]: unknown key {unknown[0]!r}", "allowed keys: " + ", ".join(PROTOCOL_KEYS)
        )
    loads = [
        g * 1e-3 for g in pv.positive_list(table, "loads_g", [rig.load * 1e3], "e.g. loads_g = [50.0, 100.0]")
    ]
    from tcamlab.io import ABSOLUTE_ZERO_C  # io reads the kinds' registry at import

    span = [OVEN_STEPS_C[0], OVEN_STEPS_C[-1]]
    first, last = pv.number_pair(table, "temperature_C", span, "e.g. temperature_C = [25.0, 150.0]")
    if not first > ABSOLUTE_ZERO_C:
        raise ConfigError(
            f"[protocol]: temperature_C starts below absolute zero ({first:g} degC)",
            "e.g. temperature_C = [25.0, 150.0]",
        )
    step = pv.positive(table, "step_C", OVEN_STEPS_C[1] - OVEN_STEPS_C[0], "e.g. step_C = 5.0")
    # the last set point is the stated one: a step that does not divide the range would overshoot it
    pv.levels(
        (last - first) / step,
        "temperature_C's range over step_C",
        "e.g. temperature_C = [25.0, 150.0] with step_C = 5.0",
    )
    n = pv.runs(table, len(loads))
    oven = pv.choice(table, "oven", "heating", OVEN_PROGRAMS)
    dwell = pv.bounded(table, "dwell_s", OVEN_DWELL_S, 1.0, pv.MAX_RUN_S, "e.g. dwell_s = 300.0")
    logged = pv.channels(table, STATIC_CHANNELS, KIND_REQUIRED, list(STATIC_CHANNELS), "the oven rig")
    if len(set(loads)) > 1 and "load_N" not in logged:
        # without the column every run is read at load_g: the second load would be lost
        raise ConfigError(
            f"[protocol]: channels leaves out load_N while loads_g lists {len(set(loads))} loads: each "
            "run's load must be logged, or every run is read at [rig] load_g",
            "e.g. channels = [" + ", ".join(f'"{c}"' for c in STATIC_CHANNELS) + "]",
        )
    return [
        {
            "oven": oven,
            "load_N": rig.force * loads[k % len(loads)] / rig.load,
            "set_points_C": (first, last, step),
            "dwell_s": dwell,
        }
        for k in range(n)
    ]


GLASS_WINDOW_C = (35.0, 60.0)
"""Oven range [degC] around nylon 6,6's glass transition (about 45 degC, the
glass-transition effect's knee): steps of 1 degC there locate a change of slope that 5 degC
steps over 25-150 degC show at two or three readings."""


def design_menu(sample: Sample, rig: Rig) -> list[tuple[str, dict]]:
    """Candidate protocols of a static oven test [(name, ``[protocol]`` table)].

    The thesis's program (one load, heating, 25-150 degC, 300 s dwell) and its changes: a
    second hanging load (1.5 x, 2 x), a heat-cool program, a wider temperature range
    (capped at :data:`MAX_OVEN_C` and :data:`G_LIMIT_MARGIN_C` below the G_t' = 0
    temperature at the stated values), a longer dwell, finer steps (2.5 degC over the range,
    or 1 degC over :data:`GLASS_WINDOW_C`). Each runs twice per load.
    """
    g = _static.shear_modulus_of(sample)
    rise = float(_static.max_temperature_rise(g, sample.shear_modulus_slope))
    top = float(min(MAX_OVEN_C, 5.0 * np.floor((rig.ambient + rise - G_LIMIT_MARGIN_C) / 5.0)))
    g0 = round(rig.load * 1e3, 3)
    base = {
        "kind": "static",
        "loads_g": [g0],
        "oven": "heating",
        "temperature_C": [25.0, 150.0],
        "step_C": 5.0,
        "dwell_s": OVEN_DWELL_S,
        "runs": 2,
        "channels": list(STATIC_CHANNELS),
    }
    menu = [("repeat (same protocol)", base)]
    for f in (1.5, 2.0):
        menu.append((f"second load {f:g}x", {**base, "loads_g": [g0, round(f * g0, 3)], "runs": 4}))
    menu.append(("heat-cool", {**base, "oven": "heat-cool"}))
    if top > 150.0:
        menu.append((f"wider range to {top:.0f} degC", {**base, "temperature_C": [25.0, top]}))
    menu.append(("longer dwell 900 s", {**base, "dwell_s": 900.0}))
    menu.append(("finer steps 2.5 degC", {**base, "step_C": 2.5}))
    lo, hi = GLASS_WINDOW_C
    menu.append((f"1 degC steps {lo:g}-{hi:g} degC", {**base, "temperature_C": [lo, hi], "step_C": 1.0}))
    menu.append(
        (
            "second load 1.5x, heat-cool",
            {**base, "loads_g": [g0, round(1.5 * g0, 3)], "oven": "heat-cool", "runs": 4},
        )
    )
    return menu


def exact_inputs(sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS) -> pd.DataFrame:
    """The model's exact inputs: the oven program itself (``time`` [s], ``temperature`` [degC],
    ``load`` [N] of a two-condition run)."""
    return proto.copy()


def instrument_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of each logged column's chain [SI]: time exact, thermometer, load (a known weight:
    exact), laser."""
    return {
        "time": 0.0,
        "temperature": instruments.thermometer_sd(noise_scale),
        "load": 0.0,
        "displacement": instruments.laser_sd(noise_scale),
    }


def measure(
    inputs: pd.DataFrame, outputs: dict, rng: np.random.Generator, noise_scale: float, *, noisy_zero=False
) -> pd.DataFrame:
    """Logged ``time`` [s], ``temperature`` [degC] (thermometer) and ``displacement`` [m] (laser).

    ``noisy_zero``: the laser zeroes on the first reading
    (:func:`tcamlab.instruments.laser_zeroed`); its zero error [m] is in
    ``attrs["zero_error"]["displacement"]``.
    """
    temp = instruments.thermometer(inputs["temperature"].to_numpy(float), rng, noise_scale)
    disp, zero = instruments.laser_zeroed(
        np.asarray(outputs["displacement"], float), rng, noise_scale, noisy_zero=noisy_zero
    )
    out = pd.DataFrame({"time": inputs["time"].to_numpy(float), "temperature": temp, "displacement": disp})
    if "load" in inputs:  # a known hanging weight: logged exactly
        out.insert(2, "load", inputs["load"].to_numpy(float))
    out.attrs["zero_error"] = {"displacement": zero}
    return out


RHO_ZERO_SD = 0.3 * THESIS_TCA.sample["radial_cte"].value
"""Prior sd of rho [1/K] where the file states 0 and no sd: 30 % of the thesis's |rho|."""

SLOPE_ZERO_SD = 0.3 * THESIS_TCA.sample["shear_modulus_slope"].value
"""Prior sd of the G_t slope [Pa/K] where the file states 0 (the thesis's constant-G model
(2.12)) and no sd: 30 % of the thesis's 1.11 MPa/K."""

# rho and the G_t slope are fitted in linear coordinates: 0 is a legitimate statement of
# either (constant G, no radial swelling) and a logarithm is undefined there.
CALIBRATION = (
    CalibrationParam(
        "radial_cte",
        "sample",
        "rho",
        "1/K",
        0.3,
        "an oven test at a second load (rho and G_t act differently with load)",
        positive=False,
        zero_sd=RHO_ZERO_SD,
    ),
    CalibrationParam(
        "shear_modulus_slope",
        "sample",
        "G_t slope",
        "Pa/K",
        0.3,
        "an oven test over a wider temperature range, or at a second load",
        positive=False,
        zero_sd=SLOPE_ZERO_SD,
    ),
    CalibrationParam(
        "youngs_modulus",
        "sample",
        "E",
        "Pa",
        0.2,
        "a tensile test of the straight fiber, or a sensing pull test",
    ),
)
"""Calibratable parameters of the oven test (default prior sd: 30 % for rho and the
G_t slope, 20 % for E)."""


KIND = Kind(
    name="static",
    description="static oven test (thesis section 2.5.1): displacement against temperature, "
    "constant-G model (2.12) and G(T) model (2.13)",
    required_columns=KIND_REQUIRED,
    optional_columns=("time_s", "load_N"),
    min_rows=3,
    inputs=("temperature",),
    outputs=("displacement",),
    tension_outputs=(),
    variants={"G(T)": {}, "constant-G": {"constant_g": True}},
    predict=predict,
    run_options=run_options,
    needs_training=False,
    validation_extras=no_extras,
    x_column="temperature",
    regimes=regimes,
    shared_inputs=("temperature", "load"),
    report_rig_fields=("load", "ambient"),
    figures=figures,
    extras_section=no_section,
    preset=THESIS_TCA,
    logged_columns=("time", "temperature", "load", "displacement"),
    decimals={"time_s": 0, "temperature_C": 1, "load_N": 6, "displacement_mm": 3},
    written_rig_fields=("load", "ambient"),
    hidden_rig_fields=(),
    default_runs=3,
    default_scatter={"twists": 2e-3, "coil_length": 2e-3},
    noisy_inputs=("temperature",),
    strength_quantities=("displacement",),
    protocol=protocol,
    benchmark_program={"oven": "heat-cool"},
    # 10 % of rho; 5 % of E: E 15 % low already takes G_t' of (2.13) to 0 inside the oven range
    benchmark_uncertainty={"radial_cte": 8.1e-6, "youngs_modulus": 0.1725e9},
    benchmark_pairs=(
        ("glass-transition", "displacement-drift"),
        ("oven-thermal-lag", "youngs-modulus-temperature"),
    ),
    program_options=("oven", "condition", "load_N", "set_points_C", "dwell_s"),
    exact_inputs=exact_inputs,
    instrument_sd=instrument_sd,
    measure=measure,
    simulation_rig_defaults={},
    segment_rig_fields=(),
    coil_length_rig_fields=(),
    calibration=CALIBRATION,
    nuisance_zeros=("displacement",),
)
