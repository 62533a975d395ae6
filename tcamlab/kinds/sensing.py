"""Sensing pull test (thesis section 3.3): displacement and force from resistance.

The model inverts (3.1)-(3.7): the fiber diameter from the resistance, the
torque (3.3), then delta (1 - S f11) = -f12 tau for the physical root, and
F = S delta. Effect terms of :class:`tcamlab.effects.Mods` that act here:
slack, hysteresis, relaxation(_tau), temperature_offset, stiffening.

One rule chooses the constants of every run, for validation, diagnosis and
the virtual rig alike (:func:`run_options`):

- S: the rig's ``spring_constant`` if stated, else identified by
  :func:`tcamlab.fitting.fit_spring` on training data that never include the
  run itself (validation: the other runs; diagnosis: the fold's training rows).
- R0: the rig's ``initial_resistance`` if stated, else the mean of the run's
  leading rows at rest (:func:`tcamlab.kinds.rest_rows`).

The virtual rig's pull test (:func:`protocol`, :func:`measure`): the linear
actuator steps the sensor to 50 mm and back, dwelling at each step; the
encoder, load cell and multimeter of :mod:`tcamlab.instruments` log it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab import instruments
from tcamlab.effects import NO_MODS, SLACK_RAMP, Mods
from tcamlab.errors import ConfigError, InputError, ModelDomainError
from tcamlab.kinds import CalibrationParam, Kind, RunOptions, rest_rows, stated_source
from tcamlab.kinds import protocol_values as pv
from tcamlab.models import sensing as _sens
from tcamlab.params import SILVER_TCR, THESIS_TCS, THESIS_TCS_SPRING_CONSTANT, Rig, Sample
from tcamlab.report.document import Cell, Figure, Section, Table
from tcamlab.report.figures import legend_label, new_figure
from tcamlab.signals import clock, time_in_dwell, unloading_mask

FORCE_BANDS = 4
"""The diagnosis reports sensing residuals in this many force bands (quartiles)."""

PULL_STEP_M = 2e-3
"""Linear-actuator step [m]."""
PULL_MAX_M = 50e-3
"""Loading up to this elongation, then unloading back to 0 [m]."""
PULL_DWELL_S = 5.0
"""Dwell at each step [s] (thesis protocol)."""
PULL_SPEED_M_PER_S = 10e-3
"""Actuator speed between steps [m/s] (a step takes 0.2 s)."""
PULL_RATE_HZ = 10
"""Logging rate [Hz]."""


def predict(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    spring_constant: float,
    initial_resistance: float,
) -> dict[str, np.ndarray]:
    """Pull test: displacement and force from resistance, (3.1)-(3.7), F = S delta.

    Parameters
    ----------
    data : DataFrame
        ``resistance`` [ohm], optional ``time`` [s].
    spring_constant : float
        S [N/m].
    initial_resistance : float
        R0 [ohm].
    mods : Mods
        slack(_length), hysteresis, relaxation(_tau), temperature_offset, stiffening.

    Returns
    -------
    dict
        ``displacement`` [m], ``force`` [N].
    """
    if "resistance" not in data:
        raise InputError(
            "sensing model: no resistance column (a pull program, not a log)",
            hint="the resistance a program gives comes from tcamlab.kinds.sensing.exact_inputs",
        )
    r = data["resistance"].to_numpy(float)
    if mods.temperature_offset:
        r = r / (1.0 + SILVER_TCR * mods.temperature_offset)
    delta, _ = _sens.invert(r, initial_resistance, spring_constant, **sample.sensor_kwargs())
    if mods.hysteresis:
        unloading = unloading_mask(data["resistance"].to_numpy(float))
        ramp = np.clip(delta / SLACK_RAMP, 0.0, 1.0)
        delta = delta + mods.hysteresis * np.where(unloading, 1.0, -1.0) * ramp
    force = spring_constant * delta * (1.0 + mods.stiffening * delta)
    if mods.relaxation:
        dwell = time_in_dwell(data["resistance"].to_numpy(float), clock(data))
        force = force * (1.0 - mods.relaxation * (1.0 - np.exp(-dwell / mods.relaxation_tau)))
    disp = delta + mods.slack * np.clip(delta / (SLACK_RAMP + mods.slack_length), 0.0, 1.0)
    return {"displacement": disp, "force": force}


def identify_spring(training) -> float:
    """S [N/m] by least squares on (DataFrame, row mask) pairs, one load-cell zero F0 per run.

    Each run is tared on its own, so its zero is a nuisance: a fit through the origin
    turned the bundled -0.34 mN tare into a 0.3 % low S whose interval excluded the truth.
    """
    from tcamlab.fitting import fit_spring_runs

    runs = [
        (f"run{k}", d["displacement"].to_numpy(float)[m], d["force"].to_numpy(float)[m])
        for k, (d, m) in enumerate(training)
    ]
    return float(fit_spring_runs(runs, by_branch=False).pooled.spring_constant)


def initial_resistance(
    rig: Rig, data: pd.DataFrame, column: str = "resistance", provenance=None
) -> tuple[float, str]:
    """R0 [ohm] of one resistance channel and where it came from (the module's rule;
    ``provenance``, the experiment's, tells a preset's R0 from the file's)."""
    if rig.initial_resistance is not None:
        r0 = rig.initial_resistance
        return float(r0[0] if isinstance(r0, tuple) else r0), stated_source(provenance, "initial_resistance")
    rows = rest_rows(KIND, data)
    value = float(data[column].to_numpy(float)[rows].mean())
    return value, "first row of the run" if rows.size == 1 else f"mean of the {rows.size} rows at rest"


def run_options(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    *,
    training=None,
    training_runs=(),
    where="",
    provenance=None,
    for_report=False,
) -> RunOptions:
    """S and R0 of one run by the module's rule, with their sources.

    Parameters
    ----------
    training : list of (DataFrame, row mask), optional
        Data S may be identified on when the rig does not state it; None
        leaves S out of the options (the caller fits it as a nuisance).
    training_runs : sequence of str
        Names of the training runs, for the source text.
    where : str
        Prefix of error messages (the experiment file).
    for_report : bool
        Also check the conditioning of the sensing equation (raises
        ModelDomainError where it has no physical root).
    """
    r0, r0_source = initial_resistance(rig, data, provenance=provenance)
    options = {"initial_resistance": r0}
    info = {"initial_resistance_ohm": r0, "initial_resistance_source": r0_source}
    if rig.spring_constant is not None:
        s_val = float(rig.spring_constant)
        source = stated_source(provenance, "spring_constant")
    elif training is None:
        return RunOptions(options, info)
    elif not training:
        raise InputError(
            f"{where}: sensing validation needs a spring constant; with one run "
            "it cannot be identified without using the run being validated",
            hint="set spring_constant_N_per_m in [rig], or add a second run",
        )
    else:
        s_val = identify_spring(training)
        source = "identified leave-one-run-out from " + ", ".join(training_runs)
    options["spring_constant"] = s_val
    info = {"spring_constant_N_per_m": s_val, "spring_constant_source": source, **info}
    if for_report:
        cond = _sens.conditioning(s_val, **sample.sensor_kwargs())
        info.update(conditioning=cond.status, margin_1_minus_S_f11=cond.margin)
        if cond.status != "ok":
            info["note"] = f"sensing inversion {cond.describe()}"
    return RunOptions(options, info)


def regimes(data: pd.DataFrame, quantity: str, frames=()) -> dict[str, np.ndarray]:
    """Force band (quartiles of all runs' force) and loading / unloading branch of every row.

    ``frames`` are all runs of the experiment, whose pooled force sets the band edges.
    """
    n = len(data)
    f = data["force"].to_numpy(float)
    pooled = np.concatenate([d["force"].to_numpy(float) for d in frames]) if len(frames) else f
    edges = np.quantile(pooled, np.linspace(0.0, 1.0, FORCE_BANDS + 1))
    idx = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, FORCE_BANDS - 1)
    names = [f"F quartile {j + 1}" for j in range(FORCE_BANDS)]
    band = np.full(n, "", dtype=object)
    band[:] = [names[j] for j in idx]
    branch = np.where(unloading_mask(data["resistance"].to_numpy(float)), "unloading", "loading")
    return {"force band": band, "branch": branch.astype(object)}


def validation_extras(experiment, predictions, **_) -> tuple[list, dict]:
    """The spring constant, R0 and conditioning used for every run; a note where ill-conditioned."""
    notes = [f"{p.name}: {p.info['note']}" for p in predictions if "note" in p.info]
    table = {p.name: {k: v for k, v in p.info.items() if k != "note"} for p in predictions}
    return notes, {"spring_constant": table}


def figures(result) -> list[Figure]:
    """Force and displacement against resistance, as thesis figures 3.3 and 3.4."""
    figs = []
    for q, unit, factor, label in (("force", "N", 1.0, "Force"), ("displacement", "mm", 1e3, "Displacement")):
        fig, ax = new_figure()
        for p in result.predictions:
            r = p.data["resistance"].to_numpy()
            name = legend_label(p.name)
            (line,) = ax.plot(r, p.data[q] * factor, "o", ms=2, label=f"{name} measured")
            ax.plot(
                r, p.predicted["thesis"][q] * factor, "-", color=line.get_color(), lw=1, label=f"{name} model"
            )
        ax.set_xlabel("resistance [ohm]")
        ax.set_ylabel(f"{q} [{unit}]")
        ax.legend(fontsize=6, ncol=2)
        caption = f"{label} against resistance: measured and predicted (thesis figures 3.3/3.4)."
        figs.append(Figure(fig, caption, alt=f"sensing {q} plot"))
    return figs


def extras_section(result) -> Section:
    """The spring constant, R0 and conditioning of every run, as a report section."""
    rows = [
        [
            name,
            i["spring_constant_N_per_m"],
            i["spring_constant_source"],
            i["initial_resistance_ohm"],
            i["initial_resistance_source"],
            Cell(i["conditioning"], "pass" if i["conditioning"] == "ok" else "warn"),
            i["margin_1_minus_S_f11"],
        ]
        for name, i in result.extras["spring_constant"].items()
    ]
    return Section(
        "Spring constant and conditioning",
        tables=[
            Table(
                ["run", "S [N/m]", "S from", "R0 [ohm]", "R0 from", "conditioning", "1 − S f11"],
                rows,
                caption="Spring constant used for each run (never identified on the run "
                "it validates) and the margin of the sensing equation",
            )
        ],
    )


# --- virtual rig ---------------------------------------------------------------------------


def protocol(
    rig: Rig,
    rng: np.random.Generator,
    *,
    pull_max_m: float = PULL_MAX_M,
    step_m: float = PULL_STEP_M,
    speed_m_per_s: float = PULL_SPEED_M_PER_S,
    dwell_s: float = PULL_DWELL_S,
    cycles: int = 1,
) -> pd.DataFrame:
    """The exact pull program of one run (deterministic; ``rig`` and ``rng`` are unused).

    Without options it is the thesis's program: 0 to :data:`PULL_MAX_M` and back in
    :data:`PULL_STEP_M` steps at :data:`PULL_SPEED_M_PER_S`, dwelling :data:`PULL_DWELL_S`
    at each level. A designed protocol (:func:`protocol_runs`) sets the options.

    Parameters
    ----------
    pull_max_m : float
        Largest elongation [m], a whole number of steps.
    step_m : float
        Actuator step [m].
    speed_m_per_s : float
        Actuator speed between levels [m/s].
    dwell_s : float
        Dwell at each level [s].
    cycles : int
        Loading-unloading cycles, each from 0 up to ``pull_max_m`` and back to 0.

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``elongation`` [m]: the sensor elongation programmed by
        the actuator, on its encoder grid, so the logged position is exact.
    """
    n_up = int(round(pull_max_m / step_m))
    down = np.concatenate([np.arange(1, n_up + 1), np.arange(n_up - 1, -1, -1)])
    levels = np.concatenate([[0], *[down] * int(cycles)]) * step_m
    move = step_m / speed_m_per_s
    # Knots of the piecewise-linear program: dwell at level 0, then move + dwell.
    kt, kx = [0.0, dwell_s], [levels[0], levels[0]]
    for x in levels[1:]:
        kt += [kt[-1] + move, kt[-1] + move + dwell_s]
        kx += [x, x]
    n = int(round(kt[-1] * PULL_RATE_HZ)) + 1
    t = np.arange(n) / PULL_RATE_HZ
    x = np.interp(t, kt, kx)
    return pd.DataFrame({"time": t, "elongation": instruments.encoder(x)})


PROTOCOL_KEYS = (
    "kind",
    "pull_mm",
    "step_mm",
    "speeds_mm_per_s",
    "dwell_s",
    "cycles",
    "runs",
    "channels",
)
"""Keys of a sensing ``[protocol]`` table (docs/design.md). The model has no temperature
input (only the ``ambient-temperature`` effect's constant offset), so a logged temperature
is not a protocol option."""

KIND_COLUMNS = ("time_s", "displacement_mm", "force_N", "resistance_ohm")
"""Columns a pull test logs (a ``[protocol]`` table's ``channels``); all but time required."""

MAX_CYCLES = 10
"""Most loading-unloading cycles a run may program [-]."""

PULL_LIMIT_MARGIN = 0.8
"""A design's largest pull stays below this share of :func:`elongation_limit` [-]."""

LIMIT_TOLERANCE_M = 1e-5
"""Resolution of :func:`elongation_limit`'s bisection [m]."""

RUN_OVERHEAD_S = 0.0
"""Rig time per run beyond its logged span and setup [s]: none, the sensor is at rest again."""


def elongation_limit(sample: Sample, rig: Rig) -> float:
    """Largest elongation the chapter-3 map (3.1)-(3.7) admits at the stated values [m].

    The forward map has a physical coil diameter only while the fiber has thinned by less
    than half (:func:`tcamlab.models.sensing.forward`), and the coil straightens at l - L;
    the limit is found by bisection on (0, l - L). It grows with S, so where the rig does
    not state S it is taken at S = 0 (the conservative side).
    """
    kw = sample.sensor_kwargs()
    s_val = 0.0 if rig.spring_constant is None else float(rig.spring_constant)
    lo, hi = 0.0, float(kw["fiber_length"] - kw["coil_length"])
    while hi - lo > LIMIT_TOLERANCE_M:
        mid = 0.5 * (lo + hi)
        try:
            _sens.forward(np.array([mid]), 1.0, s_val, **kw)
            lo = mid
        except ModelDomainError:
            hi = mid
    return lo


def protocol_runs(table: dict, rig: Rig) -> list[dict]:
    """Each run's :func:`protocol` options from a ``[protocol]`` table (docs/design.md).

    Runs cycle through ``speeds_mm_per_s`` (the thesis's 10 mm/s when absent), all with the
    table's largest pull ``pull_mm``, ``step_mm``, ``dwell_s`` and ``cycles``; mm are
    converted to m here. Unknown keys and bad values raise ConfigError naming the key.
    """
    unknown = sorted(set(table) - set(PROTOCOL_KEYS))
    if unknown:
        raise ConfigError(
            f"[protocol]: unknown key {unknown[0]!r}", "allowed keys: " + ", ".join(PROTOCOL_KEYS)
        )
    pull = pv.positive(table, "pull_mm", PULL_MAX_M * 1e3, "e.g. pull_mm = 50.0") * 1e-3
    step = pv.positive(table, "step_mm", PULL_STEP_M * 1e3, "e.g. step_mm = 2.0") * 1e-3
    steps = pv.levels(
        pull / step,
        f"pull_mm ({pull * 1e3:g}) over step_mm ({step * 1e3:g})",
        "e.g. pull_mm = 50.0 with step_mm = 2.0",
    )
    speeds = table.get("speeds_mm_per_s", [PULL_SPEED_M_PER_S * 1e3])
    hint = "e.g. speeds_mm_per_s = [10.0, 2.5]"
    if not isinstance(speeds, list) or not speeds:
        raise ConfigError("[protocol]: speeds_mm_per_s must be a list of speeds [mm/s]", hint)
    speeds = [pv.bounded({"speeds_mm_per_s": v}, "speeds_mm_per_s", 0, 1e-3, 1e3, hint) for v in speeds]
    common = {
        "pull_max_m": pull,
        "step_m": step,
        "dwell_s": pv.bounded(table, "dwell_s", PULL_DWELL_S, 0.0, 3600.0, "e.g. dwell_s = 5.0"),
        "cycles": pv.whole(table, "cycles", 1, MAX_CYCLES, "e.g. cycles = 3"),
    }
    # each cycle goes up and back down in ``steps`` steps, dwelling at each
    per_cycle = 2.0 * (steps * common["dwell_s"] + pull / (min(speeds) * 1e-3))
    pv.run_length(
        common["cycles"] * per_cycle,
        "cycles, pull_mm, step_mm, dwell_s and speeds_mm_per_s",
        "e.g. speeds_mm_per_s = [10.0] with dwell_s = 5.0",
    )
    pv.channels(table, KIND_COLUMNS, KIND_COLUMNS[1:], list(KIND_COLUMNS), "the pull-test rig")
    n = pv.runs(table, len(speeds))
    return [{**common, "speed_m_per_s": speeds[k % len(speeds)] * 1e-3} for k in range(n)]


def design_menu(sample: Sample, rig: Rig) -> list[tuple[str, dict]]:
    """Candidate protocols of a sensing pull test [(name, ``[protocol]`` table)].

    The thesis's pull (0-50 mm and back in 2 mm steps at 10 mm/s, 5 s dwell) repeated, and
    its changes: a larger pull (1.5 x in whole steps, kept below :data:`PULL_LIMIT_MARGIN` of
    :func:`elongation_limit` at the stated values), three loading-unloading cycles, a
    second pull rate (0.25 x), a finer step (1 mm) and a longer dwell (4 x). Two runs each,
    two per speed for the second rate.
    """
    step_mm = PULL_STEP_M * 1e3
    top = PULL_LIMIT_MARGIN * elongation_limit(sample, rig) * 1e3
    pull = round(float(step_mm * np.floor(min(1.5 * PULL_MAX_M * 1e3, top) / step_mm)), 3)
    v0 = round(PULL_SPEED_M_PER_S * 1e3, 3)
    base = {
        "kind": "sensing",
        "pull_mm": round(PULL_MAX_M * 1e3, 3),
        "step_mm": step_mm,
        "speeds_mm_per_s": [v0],
        "dwell_s": PULL_DWELL_S,
        "cycles": 1,
        "runs": 2,
        "channels": list(KIND_COLUMNS),
    }
    menu = [("repeat (same protocol)", base)]
    if pull > base["pull_mm"]:
        menu.append((f"larger pull range 1.5x, to {pull:g} mm", {**base, "pull_mm": pull}))
    menu.append(("3 loading-unloading cycles", {**base, "cycles": 3}))
    menu.append(("second pull rate 0.25x", {**base, "speeds_mm_per_s": [v0, round(0.25 * v0, 3)], "runs": 4}))
    menu.append(("finer step 1 mm", {**base, "step_mm": 1.0}))
    menu.append(("longer dwell 4x", {**base, "dwell_s": 4.0 * PULL_DWELL_S}))
    return menu


def exact_inputs(sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS) -> pd.DataFrame:
    """The exact resistance of the sensor stretched by the programmed elongation.

    :func:`tcamlab.models.sensing.forward` with the rig's S and R0, times
    ``1 + TCR dT`` when the sensor is off its R0 temperature
    (``mods.temperature_offset`` [K]).

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``resistance`` [ohm].
    """
    if rig.spring_constant is None or rig.initial_resistance is None:
        raise ConfigError(
            "sensing simulation needs spring_constant_N_per_m and initial_resistance_ohm in the template's [rig]"
        )
    r0, _ = initial_resistance(rig, proto)
    r = _sens.forward(proto["elongation"].to_numpy(float), r0, rig.spring_constant, **sample.sensor_kwargs())
    r = r * (1.0 + SILVER_TCR * mods.temperature_offset)
    return pd.DataFrame({"time": proto["time"].to_numpy(float), "resistance": r})


def instrument_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of each logged column's chain [SI]: time exact, encoder, load cell, multimeter."""
    return {
        "time": 0.0,
        "displacement": instruments.encoder_sd(),
        "force": instruments.load_cell_sd(noise_scale),
        "resistance": instruments.ohmmeter_sd(noise_scale),
    }


def measure(
    inputs: pd.DataFrame, outputs: dict, rng: np.random.Generator, noise_scale: float, *, noisy_zero=False
) -> pd.DataFrame:
    """Logged ``time`` [s], ``displacement`` [m] (encoder), ``force`` [N] (load cell), ``resistance`` [ohm].

    ``noisy_zero``: the load cell is tared on one noisy reading, so its zero
    offset is redrawn for the run (:func:`tcamlab.instruments.load_cell_tare`,
    drawn before the readings); the offset [N] is in
    ``attrs["zero_error"]["force"]``. The encoder is exact and R is not zeroed.
    """
    disp = instruments.encoder(outputs["displacement"])
    offset = instruments.load_cell_tare(rng, noise_scale) if noisy_zero else instruments.LOADCELL_OFFSET_N
    force = instruments.load_cell(np.asarray(outputs["force"], float), rng, noise_scale, offset=offset)
    res = instruments.ohmmeter(inputs["resistance"].to_numpy(float), rng, noise_scale)
    out = pd.DataFrame(
        {"time": inputs["time"].to_numpy(float), "displacement": disp, "force": force, "resistance": res}
    )
    out.attrs["zero_error"] = {"force": offset}
    return out


CALIBRATION = (
    CalibrationParam(
        "spring_constant", "rig", "S", "N/m", 1.0, "a pull test logging force over a wider stretch"
    ),
    CalibrationParam("initial_resistance", "rig", "R0", "ohm", 0.05, "more rows at rest before the pull"),
    CalibrationParam("youngs_modulus", "sample", "E", "Pa", 0.2, "a tensile test of the straight fiber"),
)
"""Calibratable parameters of the pull test (S: a weak 100 % prior, it is usually not
stated; R0: 5 %, the rest rows fix it; E: 20 %)."""


KIND = Kind(
    name="sensing",
    description="sensing pull test (thesis section 3.3): displacement and force predicted from "
    "resistance, (3.1)-(3.7) with F = S delta",
    required_columns=KIND_COLUMNS[1:],
    optional_columns=("time_s", "temperature_C"),
    min_rows=3,
    inputs=("resistance",),
    # the machine drives the displacement: it moves first, while R is still within its noise
    rest_also=("displacement",),
    outputs=("displacement", "force"),
    tension_outputs=("force",),
    variants={"thesis": {}},
    predict=predict,
    run_options=run_options,
    needs_training=True,
    validation_extras=validation_extras,
    x_column="time",
    regimes=regimes,
    shared_inputs=("resistance",),
    report_rig_fields=("ambient", "initial_resistance", "spring_constant"),
    figures=figures,
    extras_section=extras_section,
    preset=THESIS_TCS,
    logged_columns=("time", "displacement", "force", "resistance"),
    decimals={"time_s": 1, "displacement_mm": 2, "force_N": 6, "resistance_ohm": 3},
    written_rig_fields=("ambient", "initial_resistance"),
    hidden_rig_fields=("spring_constant",),
    default_runs=3,
    default_scatter={"twists": 5e-4, "coil_length": 5e-4},
    noisy_inputs=("resistance",),
    strength_quantities=None,
    protocol=protocol,
    benchmark_program={},
    # 10 % of E (the E x0.85 and x1.15)
    benchmark_uncertainty={"youngs_modulus": 0.345e9},
    benchmark_pairs=(("initial-slack", "stress-relaxation"), ("hysteresis", "stiffening-spring")),
    program_options=("pull_max_m", "step_m", "speed_m_per_s", "dwell_s", "cycles"),
    exact_inputs=exact_inputs,
    instrument_sd=instrument_sd,
    measure=measure,
    # S is not part of the thesis-tcs preset (it is identified from pull tests);
    # the default noise floor uses the simulation template's value.
    simulation_rig_defaults={"spring_constant": THESIS_TCS_SPRING_CONSTANT.value},
    segment_rig_fields=(),
    coil_length_rig_fields=(),
    calibration=CALIBRATION,
    nuisance_zeros=("force",),
    # each pull test re-mounts the sensor: twists and coil length differ by about 0.05 % a
    # run (the virtual rig's default_scatter models the same); R0 and E are pinned to 0.03 %
    # or better, so calibration must not treat the runs as sharing one geometry exactly
    run_reproducibility={"twists": 5e-4, "coil_length": 5e-4},
)
