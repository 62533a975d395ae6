"""The virtual rig: synthetic runs with known causes, through the thesis model.

:func:`simulate` makes an experiment (CSV runs and an experiment file) of one
rig kind from a template experiment file. The *measured* columns are the
prediction of :func:`tcamlab.kinds.predict` -- with the active effect terms
of :mod:`tcamlab.effects` -- evaluated on the *exact* protocol inputs, then
passed through the measurement chain (noise, ADC quantisation, display
resolution). The logged inputs (temperature, resistance, ...) go through
their own chains. Without effects the thesis model is therefore exact up to
the measurement chain, and fitting it to the data leaves residuals at the
noise floor (:func:`noise_sd`).

The experiment file and the CSVs do not reveal which effects are active; the
truth (effects, their strength and physical values, per-run sample
parameters, noise levels, seed) goes to ``truth/<name>.truth.json``.

Protocols and measurement chains
--------------------------------

Every constant below is a module attribute; SI unless the name says otherwise.

==========================  ==================  =====================================================
constant                    value               reason
==========================  ==================  =====================================================
**static oven test** (thesis sec. 2.5.1)
OVEN_STEPS_C                25, 30, ... 150     5 degC oven steps from just above room temperature to
                                                150 degC (below the G_t' = 0 limit of ~160 degC):
                                                26 readings per run
OVEN_DWELL_S                300 s               reading taken after a 5 min dwell per step, long
                                                enough for the small oven to settle
OVEN_REGULATION_SD_C        0.3 degC            the oven holds its set point only to a few tenths
                                                of a degree; the actual (exact) temperature of each
                                                step is set point + N(0, 0.3)
THERMOMETER_SD_C            0.2 degC            thermocouple reader noise in the vent hole
THERMOMETER_RESOLUTION_C    0.1 degC            display resolution of the reader
LASER_NOISE_SD_M            5 um                analog noise of the laser displacement sensor
LASER_SPAN_M, ADC_BITS      10 mm, 10 bit       0..10 mm laser output read by the Arduino's 10-bit
                                                ADC: quantum 10 mm / 1023 = 9.78 um
LASER_TARE_SAMPLES          64                  the sketch zeroes on the mean of 64 readings at rest
                                                and logs that mean as row 0 (0.000 mm); later rows
                                                carry the tare error (about sd / 8) as an offset
LASER_LOG_RESOLUTION_M      1 um                displacement written with 3 decimals in mm
STATIC_RUNS                 3                   three repeats of the oven test
**dynamic voltage-step test** (thesis sec. 2.5.2)
PULSE_START_S               0.5 s               a quiet baseline before the pulse; the pulse voltage
                                                and duration come from the template's rig table
                                                (10 V for 1 s in the thesis)
DYNAMIC_RATE_HZ             100 Hz              Arduino logging rate
DYNAMIC_DURATION_S          10 s                long enough to see most of the cooling
TIMING_JITTER_PROB          0.03                the loop occasionally runs 1 ms early or late; the
                                                logged time is the Arduino's integer ``millis()``
                                                of the actual sample, so it is exact
(displacement)                                  the same laser chain as the static test
DYNAMIC_RUNS                3
**sensing pull test** (thesis sec. 3.3)
PULL_STEP_M                 2 mm                linear-actuator step
PULL_MAX_M                  50 mm               loading up to 50 mm, then unloading back to 0
PULL_DWELL_S                5 s                 dwell at each step (thesis protocol)
PULL_SPEED_M_PER_S          10 mm/s             actuator speed between steps (a step takes 0.2 s)
PULL_RATE_HZ                10 Hz               logging rate
ENCODER_RESOLUTION_M        0.01 mm             actuator encoder; the programmed positions are on
                                                its grid, so the logged position is exact
LOADCELL_SD_N               2 mN                LSP-5 load cell with its amplifier
LOADCELL_OFFSET_N           -0.4 mN             residual zero offset after taring
LOADCELL_SPAN_N, _BITS      +-0.5 N, 12 bit     amplifier span read by a 12-bit ADC: quantum
                                                1 N / 4095 = 0.244 mN
OHMMETER_SD_OHM             2 mohm              bench multimeter noise on a 10-30 ohm sensor
OHMMETER_RESOLUTION_OHM     1 mohm              its display resolution
SENSING_RUNS                3                   S is identified leave-one-run-out, so >= 2 runs
**curvature camera test** (thesis sec. 4.3)
CABLE_STEP_M, CABLE_MAX_M   1 mm, 10 mm         cable pulled by the same actuator: 11 poses
TIP_TO_BASE_CURVATURE       1.5                 assumption: the tip segment (EcoFlex 00-10) is
                                                softer than the base (00-30); the bending moment
                                                of the cable is the same in both, so curvature
                                                goes with compliance; 1.5 is a round ratio
                                                between the two grades' moduli
(neutral axis)              y_c = y_s = d1 / 2  cable and sensor placed symmetrically about the
                                                neutral axis (thesis sec. 4.3), which also makes
                                                the model's proportional cable sharing exact
CAMERA_SD_PER_M             0.2 1/m             curvature from the camera images (2e-4 per mm)
CAMERA_RESOLUTION_PER_M     0.001 1/m           written with 6 decimals in per_mm
(resistances)                                   two channels of the same multimeter as above
CURVATURE_RUNS              3
**per-run scatter** (relative sd)
actuators                   0.2 % twists,       re-mounting and slow annealing make repeats of the
                            0.2 % coil_length   same sample differ slightly; far below noise here
sensors                     0.05 % twists,      the same sensor is re-tested; its resistance map is
                            0.05 % coil_length  sensitive, so only a small scatter stays in noise
R0                          0 (optional)        the sensing file carries the true R0, so R0 must not
                                                scatter; pass ``scatter={"initial_resistance": ..}``
                                                when the pipeline takes R0 from each run's first row
**effect strengths**
DOMAIN_BACKOFF              0.9                 a strength the model's domain cannot reach (e.g. a
                                                steeper G(T) that makes G_t' <= 0 inside the
                                                protocol) is capped at 90 % of the largest valid
                                                parameter; the achieved strength is recorded
==========================  ==================  =====================================================

Curvature geometry: with both lines at d1/2 from the neutral axis, a pull c
bends segment i (length L_i, tip first) to kappa_i with
sum_i kappa_i (d1/2) L_i = c and kappa_tip / kappa_base = 1.5; the sensor
part stretches by delta_i = kappa_i (d1/2) L_i and reads
R_i = sensing.forward(delta_i) for a segment sensor whose fiber length and
twists are the whole sensor's scaled by L_i / L (S = rig.spring_constant).
The camera's ground truth is :func:`tcamlab.kinds.curvature.predict` of the
exact R_i and cable, so the model is exact without effects.

Effect strengths are in multiples of the noise floor of the primary measured
quantity (see :func:`simulate`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from tcamlab import __version__
from tcamlab import config as _config
from tcamlab import io as tio
from tcamlab.effects import NO_MODS, Effect, Mods, get_effect
from tcamlab.errors import ConfigError, TcamlabError
from tcamlab.jsonutil import dumps_json, to_jsonable
from tcamlab.kinds import REGISTRY, get_kind, predict
from tcamlab.models import sensing as _sensing
from tcamlab.params import RIG_KEYS, SAMPLE_KEYS, SILVER_TCR, Rig, Sample
from tcamlab.report.atomic import atomic_write_text
from tcamlab.text import public_command, simulate_command

__all__ = [
    "SimulationResult",
    "simulate",
    "noise_sd",
    "instrument_sd",
    "protocol",
    "exact_inputs",
    "scale_effect",
    "DEFAULT_RUNS",
    "DEFAULT_SCATTER",
]

# --- constants (see the module table) -------------------------------------------

OVEN_STEPS_C = tuple(float(t) for t in range(25, 151, 5))
OVEN_DWELL_S = 300.0
OVEN_REGULATION_SD_C = 0.3
THERMOMETER_SD_C = 0.2
THERMOMETER_RESOLUTION_C = 0.1

LASER_NOISE_SD_M = 5e-6
LASER_SPAN_M = 10e-3
ADC_BITS = 10
LASER_QUANTUM_M = LASER_SPAN_M / (2**ADC_BITS - 1)
LASER_TARE_SAMPLES = 64
LASER_LOG_RESOLUTION_M = 1e-6

PULSE_START_S = 0.5
DYNAMIC_RATE_HZ = 100
DYNAMIC_DURATION_S = 10.0
TIMING_JITTER_PROB = 0.03

PULL_STEP_M = 2e-3
PULL_MAX_M = 50e-3
PULL_DWELL_S = 5.0
PULL_SPEED_M_PER_S = 10e-3
PULL_RATE_HZ = 10
ENCODER_RESOLUTION_M = 1e-5
LOADCELL_SD_N = 2e-3
LOADCELL_OFFSET_N = -0.4e-3
LOADCELL_SPAN_N = (-0.5, 0.5)
LOADCELL_BITS = 12
LOADCELL_QUANTUM_N = (LOADCELL_SPAN_N[1] - LOADCELL_SPAN_N[0]) / (2**LOADCELL_BITS - 1)
OHMMETER_SD_OHM = 2e-3
OHMMETER_RESOLUTION_OHM = 1e-3

CABLE_STEP_M = 1e-3
CABLE_MAX_M = 10e-3
TIP_TO_BASE_CURVATURE = 1.5
CAMERA_SD_PER_M = 0.2
CAMERA_RESOLUTION_PER_M = 1e-3

DOMAIN_BACKOFF = 0.9
"""When a strength cannot be reached inside the model's domain (e.g. G_t' > 0 of
(2.13) for a steeper shear-modulus slope), the parameter is set to this fraction
of the largest valid value and the achieved strength is recorded."""

DEFAULT_RUNS = {k.name: k.default_runs for k in REGISTRY.values()}
"""Runs per simulated experiment unless ``n_runs`` is given (from the kind registry)."""

DEFAULT_SCATTER: dict[str, dict[str, float]] = {k.name: dict(k.default_scatter) for k in REGISTRY.values()}
"""Kind -> {SI field of Sample or Rig: relative sd} of the per-run scatter (from the kind registry)."""

SYNTHETIC_NOTE = (
    "Synthetic data made by the tcamlab virtual rig (tcamlab.rig): the thesis model "
    "evaluated on the exact protocol, then the measurement chains documented in "
    "tcamlab/rig.py. Not a laboratory measurement."
)


# --- results ---------------------------------------------------------------------


@dataclass(frozen=True)
class SimulationResult:
    """What :func:`simulate` wrote.

    Attributes
    ----------
    experiment_path : pathlib.Path
        ``out_dir/experiments/<name>.toml``.
    run_paths : tuple of pathlib.Path
        ``out_dir/raw/<name>_runN.csv``.
    truth_path : pathlib.Path
        ``out_dir/truth/<name>.truth.json``.
    truth : dict
        The content of the truth file.
    """

    experiment_path: Path
    run_paths: tuple[Path, ...]
    truth_path: Path
    truth: dict = field(default_factory=dict)


# --- protocols -------------------------------------------------------------------


def _check_kind(kind: str) -> None:
    get_kind(kind)


OVEN_PROGRAMS = ("heating", "heat-cool")
"""Static oven programs: the thesis's heating-only 25 -> 150 degC steps, or the
same steps up and back down to 25 degC (a cooling branch: 51 readings), the
experiment that separates sensor drift and thermal lag from temperature-only
effects."""


def protocol(kind: str, rig: Rig, rng: np.random.Generator, oven: str = "heating") -> pd.DataFrame:
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
    oven : {"heating", "heat-cool"}
        Static oven program (:data:`OVEN_PROGRAMS`).

    Returns
    -------
    pandas.DataFrame
        static: ``time``, ``temperature`` (the actual oven temperature);
        dynamic: ``time``, ``voltage``; sensing: ``time``, ``elongation``
        (sensor elongation programmed by the actuator); curvature: ``cable``.
    """
    _check_kind(kind)
    if kind == "static":
        steps = np.asarray(OVEN_STEPS_C)
        if oven == "heat-cool":
            steps = np.concatenate([steps, steps[-2::-1]])
        elif oven != "heating":
            raise ConfigError(f"unknown oven program {oven!r}", hint="one of " + ", ".join(OVEN_PROGRAMS))
        temp = steps + rng.normal(0.0, OVEN_REGULATION_SD_C, steps.size)
        return pd.DataFrame({"time": np.arange(steps.size) * OVEN_DWELL_S, "temperature": temp})
    if kind == "dynamic":
        n = int(round(DYNAMIC_DURATION_S * DYNAMIC_RATE_HZ))
        period_ms = int(round(1000 / DYNAMIC_RATE_HZ))
        u = rng.random(n)
        jitter = np.where(u < TIMING_JITTER_PROB / 2, -1, np.where(u > 1 - TIMING_JITTER_PROB / 2, 1, 0))
        jitter[0] = 0
        ms = np.arange(n) * period_ms + jitter
        nominal = np.arange(n) / DYNAMIC_RATE_HZ
        on = (nominal >= PULSE_START_S - 1e-9) & (nominal < PULSE_START_S + rig.pulse - 1e-9)
        volt = np.where(on, round(float(rig.voltage), 3), 0.0)
        return pd.DataFrame({"time": ms / 1000.0, "voltage": volt})
    if kind == "sensing":
        n_up = int(round(PULL_MAX_M / PULL_STEP_M))
        levels = np.concatenate([np.arange(n_up + 1), np.arange(n_up - 1, -1, -1)]) * PULL_STEP_M
        move = PULL_STEP_M / PULL_SPEED_M_PER_S
        # Knots of the piecewise-linear program: dwell at level 0, then move + dwell.
        kt, kx = [0.0, PULL_DWELL_S], [levels[0], levels[0]]
        for x in levels[1:]:
            kt += [kt[-1] + move, kt[-1] + move + PULL_DWELL_S]
            kx += [x, x]
        n = int(round(kt[-1] * PULL_RATE_HZ)) + 1
        t = np.arange(n) / PULL_RATE_HZ
        x = np.interp(t, kt, kx)
        x = np.round(x / ENCODER_RESOLUTION_M) * ENCODER_RESOLUTION_M
        return pd.DataFrame({"time": t, "elongation": x})
    n = int(round(CABLE_MAX_M / CABLE_STEP_M)) + 1
    return pd.DataFrame({"cable": np.arange(n) * CABLE_STEP_M})


def _segment_curvatures(cable: np.ndarray, rig: Rig) -> np.ndarray:
    """Neutral-axis curvature of each segment (tip first) for a cable pull [1/m]."""
    lengths = np.asarray(rig.segment_lengths, float)
    ratio = np.ones(lengths.size)
    ratio[0] = TIP_TO_BASE_CURVATURE
    y_c = rig.sensor_offset / 2.0
    base = cable / (y_c * float(np.sum(ratio * lengths)))
    return ratio[:, None] * base[None, :]


def _initial_resistances(rig: Rig, kind: str) -> tuple[float, ...]:
    r0 = rig.initial_resistance
    if isinstance(r0, tuple):
        return r0
    if kind == "curvature":
        return tuple(float(r0) for _ in rig.segment_lengths)
    return (float(r0),)


def _options(kind: str, sample: Sample, rig: Rig, data: pd.DataFrame) -> dict[str, Any]:
    """Keyword options of :func:`tcamlab.kinds.predict` for a run's (true) rig, by the kind's rule."""
    return dict(get_kind(kind).run_options(sample, rig, data).options)


def exact_inputs(
    kind: str, sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS
) -> pd.DataFrame:
    """The exact input columns of :func:`tcamlab.kinds.predict` for a protocol.

    Static and dynamic inputs are the protocol itself. The sensing input is
    the resistance of the sensor stretched by the programmed elongation
    (:func:`tcamlab.models.sensing.forward`), times ``1 + TCR dT`` when the
    sensor is off its R0 temperature (``mods.temperature_offset``). The
    curvature inputs are the cable pull and each segment's resistance from
    the geometry of the module docstring.
    """
    if kind in ("static", "dynamic"):
        return proto.copy()
    kw = sample.sensor_kwargs()
    if kind == "sensing":
        if rig.spring_constant is None or rig.initial_resistance is None:
            raise ConfigError(
                "sensing simulation needs spring_constant_N_per_m and "
                "initial_resistance_ohm in the template's [rig]"
            )
        r = _sensing.forward(
            proto["elongation"].to_numpy(float), _initial_resistances(rig, kind)[0], rig.spring_constant, **kw
        )
        r = r * (1.0 + SILVER_TCR * mods.temperature_offset)
        return pd.DataFrame({"time": proto["time"].to_numpy(float), "resistance": r})
    if rig.spring_constant is None or rig.initial_resistance is None:
        raise ConfigError(
            "curvature simulation needs spring_constant_N_per_m and "
            "initial_resistance_ohm in the template's [rig]"
        )
    cable = proto["cable"].to_numpy(float)
    lengths = np.asarray(rig.segment_lengths, float)
    if lengths.size != 2:
        raise ConfigError(
            "the curvature rig simulates a two-segment robot", hint="segment_lengths_mm = [tip, base]"
        )
    kappa = _segment_curvatures(cable, rig)
    elong = kappa * (rig.sensor_offset / 2.0) * lengths[:, None]
    r0s = _initial_resistances(rig, kind)
    out = {"cable": cable}
    for i, length in enumerate(lengths):
        ratio = length / sample.coil_length
        out[f"r{i + 1}"] = _sensing.forward(
            elong[i],
            r0s[i],
            rig.spring_constant,
            kw["fiber_diameter"],
            kw["fiber_length"] * ratio,
            length,
            kw["coil_diameter"],
            kw["twists"] * ratio,
            kw["youngs_modulus"],
            kw["thread_plies"],
            kw["max_volume_fraction"],
        )
    return pd.DataFrame(out)


# --- measurement chains ------------------------------------------------------------


def _quantise(x, q):
    return np.round(np.asarray(x, float) / q) * q


def instrument_sd(kind: str, noise_scale: float = 1.0) -> dict[str, float]:
    """Standard deviation of each logged column's measurement chain (SI).

    Noise and quantisation (uniform, q / sqrt(12)) together; columns that are
    logged exactly (time, commanded voltage, programmed cable pull) are 0.
    """
    _check_kind(kind)
    ns = float(noise_scale)

    def chain(sd, *quanta):
        return math.sqrt((ns * sd) ** 2 + sum(q * q / 12.0 for q in quanta))

    laser = chain(LASER_NOISE_SD_M, LASER_QUANTUM_M, LASER_LOG_RESOLUTION_M)
    ohm = chain(OHMMETER_SD_OHM, OHMMETER_RESOLUTION_OHM)
    if kind == "static":
        return {
            "time": 0.0,
            "temperature": chain(THERMOMETER_SD_C, THERMOMETER_RESOLUTION_C),
            "displacement": laser,
        }
    if kind == "dynamic":
        return {"time": 0.0, "voltage": 0.0, "displacement": laser}
    if kind == "sensing":
        return {
            "time": 0.0,
            "displacement": chain(0.0, ENCODER_RESOLUTION_M),
            "force": chain(LOADCELL_SD_N, LOADCELL_QUANTUM_N),
            "resistance": ohm,
        }
    cam = chain(CAMERA_SD_PER_M, CAMERA_RESOLUTION_PER_M)
    return {"cable": 0.0, "r1": ohm, "r2": ohm, "kappa1": cam, "kappa2": cam}


def _laser(disp: np.ndarray, rng: np.random.Generator, ns: float) -> np.ndarray:
    """Laser + 10-bit ADC + tare chain; row 0 is the tare (0 exactly)."""
    rest = 0.5 * LASER_SPAN_M + rng.uniform(-0.5e-3, 0.5e-3)
    top = 2**ADC_BITS - 1

    def codes(x):
        return np.clip(np.round((rest + x) / LASER_QUANTUM_M), 0, top)

    tare = codes(
        np.full(LASER_TARE_SAMPLES, 0.0) + ns * rng.normal(0.0, LASER_NOISE_SD_M, LASER_TARE_SAMPLES)
    ).mean()
    reading = codes(disp + ns * rng.normal(0.0, LASER_NOISE_SD_M, disp.size))
    out = (reading - tare) * LASER_QUANTUM_M
    out[0] = 0.0
    return _quantise(out, LASER_LOG_RESOLUTION_M)


def _measure(
    kind: str,
    inputs: pd.DataFrame,
    outputs: Mapping[str, np.ndarray],
    rng: np.random.Generator,
    noise_scale: float,
) -> pd.DataFrame:
    """Logged columns (internal names, SI) from the exact inputs and outputs."""
    ns = float(noise_scale)

    def ohmmeter(r):
        return _quantise(r + ns * rng.normal(0.0, OHMMETER_SD_OHM, r.size), OHMMETER_RESOLUTION_OHM)

    if kind == "static":
        temp = inputs["temperature"].to_numpy(float)
        temp = _quantise(temp + ns * rng.normal(0.0, THERMOMETER_SD_C, temp.size), THERMOMETER_RESOLUTION_C)
        disp = _laser(np.asarray(outputs["displacement"], float), rng, ns)
        return pd.DataFrame(
            {"time": inputs["time"].to_numpy(float), "temperature": temp, "displacement": disp}
        )
    if kind == "dynamic":
        disp = _laser(np.asarray(outputs["displacement"], float), rng, ns)
        return pd.DataFrame(
            {
                "time": inputs["time"].to_numpy(float),
                "voltage": inputs["voltage"].to_numpy(float),
                "displacement": disp,
            }
        )
    if kind == "sensing":
        disp = _quantise(outputs["displacement"], ENCODER_RESOLUTION_M)
        force = np.asarray(outputs["force"], float)
        reading = force + LOADCELL_OFFSET_N + ns * rng.normal(0.0, LOADCELL_SD_N, force.size)
        code = np.clip(np.round((reading - LOADCELL_SPAN_N[0]) / LOADCELL_QUANTUM_N), 0, 2**LOADCELL_BITS - 1)
        force = code * LOADCELL_QUANTUM_N + LOADCELL_SPAN_N[0]
        res = ohmmeter(inputs["resistance"].to_numpy(float))
        return pd.DataFrame(
            {"time": inputs["time"].to_numpy(float), "displacement": disp, "force": force, "resistance": res}
        )
    r1 = ohmmeter(inputs["r1"].to_numpy(float))
    r2 = ohmmeter(inputs["r2"].to_numpy(float))
    out = {"cable": inputs["cable"].to_numpy(float), "r1": r1, "r2": r2}
    for q in ("kappa1", "kappa2"):
        k = np.asarray(outputs[q], float)
        out[q] = _quantise(k + ns * rng.normal(0.0, CAMERA_SD_PER_M, k.size), CAMERA_RESOLUTION_PER_M)
    return pd.DataFrame(out)


def noise_sd(
    kind: str, sample: Sample | None = None, rig: Rig | None = None, *, noise_scale: float = 1.0
) -> dict[str, float]:
    """Noise floor of each quantity of a rig kind (SI).

    For a measured output (displacement, force, kappa1, kappa2) it is the
    standard deviation expected of ``data - model(logged inputs)`` with the
    thesis model exact: the output's own chain (:func:`instrument_sd`) plus
    the logged inputs' noise propagated through the model (linearised,
    mean square over the default protocol; first row and later rows
    perturbed separately, since displacement is taken from the first row).
    For a logged input it is that input's chain. This is the unit of effect
    strengths and of the noise-floor checks.

    Parameters
    ----------
    kind : str
        Rig kind.
    sample, rig : optional
        Default: the thesis preset of the kind.
    noise_scale : float
        Multiplies every instrument noise sd (not the quantisation).

    Returns
    -------
    dict
        Quantity (internal name) -> sd [SI].
    """
    _check_kind(kind)
    preset = get_kind(kind).preset
    sample = preset.build_sample() if sample is None else sample
    if rig is None:
        rig = preset.build_rig()
        if kind == "sensing":
            # S is not part of the thesis-tcs preset (it is identified from pull
            # tests); the default noise floor uses the simulation template's value.
            from tcamlab.params import THESIS_TCS_SPRING_CONSTANT

            rig = rig.replace(spring_constant=THESIS_TCS_SPRING_CONSTANT.value)
    inst = instrument_sd(kind, noise_scale)
    out = dict(inst)
    noisy = get_kind(kind).noisy_inputs
    if not noisy:
        return out
    proto = protocol(kind, rig, np.random.default_rng(0))
    inputs = exact_inputs(kind, sample, rig, proto)
    opts = _options(kind, sample, rig, inputs)
    base = predict(kind, sample, rig, inputs, **opts)
    var = {q: np.zeros(len(inputs)) for q in get_kind(kind).outputs}
    first = np.zeros(len(inputs))
    first[0] = 1.0
    for col in noisy:
        h = inst[col]
        for mask in (first, 1.0 - first):
            pert = inputs.copy()
            pert[col] = pert[col].to_numpy(float) + h * mask
            moved = predict(kind, sample, rig, pert, **opts)
            for q in var:
                var[q] += (np.asarray(moved[q]) - np.asarray(base[q])) ** 2
    for q in get_kind(kind).outputs:
        out[q] = float(math.sqrt(inst[q] ** 2 + float(np.mean(var[q]))))
    return out


# --- effect strengths --------------------------------------------------------------


def _gap(kind, sample, rig, proto, mods, opts) -> dict[str, np.ndarray]:
    """Effect prediction minus baseline prediction, on the exact inputs the effect makes."""
    inputs = exact_inputs(kind, sample, rig, proto, mods)
    eff = predict(kind, sample, rig, inputs, mods, **opts)
    base = predict(kind, sample, rig, inputs, NO_MODS, **opts)
    return {q: np.asarray(eff[q], float) - np.asarray(base[q], float) for q in get_kind(kind).outputs}


def _normalised_rms(gap: Mapping[str, np.ndarray], sd: Mapping[str, float], quantities) -> float:
    """sqrt of the mean over quantities and rows of (gap / sd)^2."""
    return float(math.sqrt(np.mean(np.concatenate([(gap[q] / sd[q]) ** 2 for q in quantities]))))


def scale_effect(
    kind: str,
    name: str,
    strength: float | Mapping[str, Any],
    sample: Sample,
    rig: Rig,
    proto: pd.DataFrame,
    sd: Mapping[str, float],
    *,
    also_valid_for: tuple = (),
) -> dict[str, Any]:
    """Find an effect's parameter for a strength in noise-sd units.

    Parameters
    ----------
    kind, name : str
        The effect (:func:`tcamlab.effects.get_effect`).
    strength : float or {"value": x}
        Target RMS gap between the effect's prediction and the baseline
        prediction over ``proto``, in multiples of the noise sd of the
        primary quantity (its sign picks the direction of the parameter
        along +scale); or the parameter value itself.
    sample, rig : the template's sample and rig.
    proto : pandas.DataFrame
        The protocol (:func:`protocol`) of the first run.
    sd : mapping
        :func:`noise_sd` of the kind.
    also_valid_for : sequence of (Sample, Rig, DataFrame)
        Further runs (true sample, rig, protocol) on which the model must
        stay in its domain at the chosen value (the other runs' scatter).

    Returns
    -------
    dict
        ``name``, ``requested_strength``, ``parameters`` {Mods field: SI value},
        ``achieved_strength``, ``quantities`` (those the strength refers to),
        ``limited_by`` (None, ``"bound"`` or ``"domain"``).
    """
    effect: Effect = get_effect(name, kind)
    opts = _options(kind, sample, rig, proto)
    param = effect.params[0]

    def metric_at(value, quantities):
        mods = effect.mods([value])
        for s_k, r_k, p_k in also_valid_for:
            _gap(kind, s_k, r_k, p_k, mods, _options(kind, s_k, r_k, p_k))  # raises outside the domain
        return _normalised_rms(_gap(kind, sample, rig, proto, mods, opts), sd, quantities)

    def pick_quantities(value):
        prim = get_kind(kind).strength_quantities
        if prim is not None:
            return prim
        gap = _gap(kind, sample, rig, proto, effect.mods([value]), opts)
        scores = [(_normalised_rms(gap, sd, (q,)), q) for q in get_kind(kind).outputs]
        best = max(scores, key=lambda s: s[0])
        return (best[1],)

    if isinstance(strength, Mapping):
        if "value" not in strength:
            raise ConfigError(f"effect {name!r}: give a strength or {{'value': x}}")
        values = np.atleast_1d(np.asarray(strength["value"], float))
        mods = effect.mods(values)
        quantities = pick_quantities(float(values[0]))
        achieved = _normalised_rms(_gap(kind, sample, rig, proto, mods, opts), sd, quantities)
        return {
            "name": name,
            "requested_strength": None,
            "parameters": {p.field: float(v) for p, v in zip(effect.params, values)},
            "fixed": dict(effect.fixed),
            "achieved_strength": achieved,
            "quantities": list(quantities),
            "limited_by": None,
        }

    target = abs(float(strength))
    direction = 1.0 if float(strength) >= 0 else -1.0
    bound = param.upper if direction > 0 else param.lower
    if direction * bound <= 0:
        sign = "negative" if direction < 0 else "positive"
        raise ConfigError(
            f"effect {name!r} cannot take a {sign} parameter (bounds {param.lower:g}..{param.upper:g})"
        )
    trial = direction * min(param.scale, abs(bound))
    quantities = pick_quantities(trial)
    limited = None
    if target == 0:
        value = 0.0
    else:

        def f(v):
            return metric_at(v, quantities) - target

        lo, hi = 0.0, trial
        while True:
            try:
                f_hi = f(hi)
            except TcamlabError:
                # Past the model's domain: find the largest valid value.
                ok, bad = lo, hi
                for _ in range(60):
                    mid = 0.5 * (ok + bad)
                    try:
                        f(mid)
                        ok = mid
                    except TcamlabError:
                        bad = mid
                # Keep 10 % inside the domain edge, so that the model stays valid on
                # the noisy logged inputs too (static: ~2 K of temperature headroom).
                ok = ok * DOMAIN_BACKOFF
                hi, f_hi, limited = ok, f(ok), "domain"
                if f_hi < 0:
                    break
            if f_hi >= 0:
                limited = None
                break
            if hi == bound:
                limited = "bound"
                break
            lo = hi
            hi = hi * 2.0
            if abs(hi) >= abs(bound):
                hi = bound
        if limited is None:
            value = float(brentq(f, lo, hi, xtol=1e-14 * abs(param.scale), rtol=1e-10, maxiter=200))
        else:
            value = float(hi)
    achieved = metric_at(value, quantities) if value != 0 else 0.0
    return {
        "name": name,
        "requested_strength": float(strength),
        "parameters": {param.field: value},
        "fixed": dict(effect.fixed),
        "achieved_strength": float(achieved),
        "quantities": list(quantities),
        "limited_by": limited,
    }


# --- scatter -------------------------------------------------------------------------

_SAMPLE_FIELDS = set(Sample.__dataclass_fields__)
_RIG_SCALARS = {
    "load",
    "ambient",
    "voltage",
    "pulse",
    "resistance",
    "thermal_mass",
    "heat_loss",
    "damping",
    "initial_resistance",
    "spring_constant",
    "sensor_offset",
}


def _scattered(
    kind: str, sample: Sample, rig: Rig, scatter: Mapping[str, float], rng: np.random.Generator
) -> tuple[Sample, Rig]:
    """One run's true sample and rig: each listed field times (1 + N(0, rel sd))."""
    s_changes: dict[str, float] = {}
    r_changes: dict[str, Any] = {}
    for fld in sorted(scatter):
        rel = float(scatter[fld])
        if fld in _SAMPLE_FIELDS:
            if fld == "thread_plies":
                raise ConfigError("scatter: thread_plies is a count and cannot scatter")
            s_changes[fld] = getattr(sample, fld) * (1.0 + rel * rng.normal())
        elif fld in _RIG_SCALARS:
            base = getattr(rig, fld)
            if base is None:
                continue
            if fld == "initial_resistance" and kind == "curvature":
                r_changes[fld] = tuple(float(base) * (1.0 + rel * rng.normal()) for _ in rig.segment_lengths)
            else:
                r_changes[fld] = base * (1.0 + rel * rng.normal())
        else:
            raise ConfigError(
                f"scatter: unknown field {fld!r}",
                hint="SI field names of Sample or Rig, e.g. twists, coil_length",
            )
    if kind == "curvature" and "coil_length" in s_changes:
        # The embedded sensor spans the segments: they change length with it.
        k = s_changes["coil_length"] / sample.coil_length
        r_changes["segment_lengths"] = tuple(x * k for x in rig.segment_lengths)
    return sample.replace(**s_changes), rig.replace(**r_changes)


# --- writing -------------------------------------------------------------------------


def _lab(value: float, factor: float) -> float:
    return float(f"{value / factor:.12g}")


def _format_csv(kind: str, logged: pd.DataFrame) -> str:
    canon = tio.internal_to_canonical(logged[list(get_kind(kind).logged_columns)])
    cols = []
    for name in canon.columns:
        dec = get_kind(kind).decimals[name]
        vals = np.round(canon[name].to_numpy(float), dec) + 0.0
        cols.append([f"{v:.{dec}f}" for v in vals])
    lines = [",".join(canon.columns)]
    lines += [",".join(row) for row in zip(*cols)]
    return "\n".join(lines) + "\n"


def _experiment_doc(
    kind: str, exp, name: str, run_names: list[str], seed: int, command: str
) -> dict[str, Any]:
    sample = exp.sample
    sample_table: dict[str, Any] = {}
    if exp.preset:
        sample_table["preset"] = exp.preset
    for key, (si, factor) in SAMPLE_KEYS.items():
        v = getattr(sample, si)
        sample_table[key] = int(v) if key == "thread_plies" else _lab(v, factor)
    si_to_key = {si: (key, factor) for key, (si, factor) in RIG_KEYS.items()}
    rig_table: dict[str, Any] = {}
    for fld in get_kind(kind).written_rig_fields:
        v = getattr(exp.rig, fld)
        if v is None:
            continue
        key, factor = si_to_key[fld]
        rig_table[key] = [_lab(x, factor) for x in v] if isinstance(v, tuple) else _lab(v, factor)
    unc = {}
    for fld, v in sorted(exp.rig.uncertainty.items()):
        if fld in get_kind(kind).hidden_rig_fields or fld not in si_to_key:
            continue
        key, factor = si_to_key[fld]
        unc[key] = [_lab(x, factor) for x in v] if isinstance(v, tuple) else _lab(v, factor)
    if unc:
        rig_table["uncertainty"] = unc
    doc: dict[str, Any] = {
        "kind": kind,
        "title": exp.title,
        "runs": [f"../raw/{r}" for r in run_names],
        "notes": SYNTHETIC_NOTE,
        "synthetic": {"generator": f"tcamlab simulate {__version__}", "seed": int(seed), "command": command},
        "sample": sample_table,
        "rig": rig_table,
    }
    if exp.thresholds:
        doc["thresholds"] = dict(exp.thresholds)
    return doc


# --- simulate --------------------------------------------------------------------------


def simulate(
    kind: str,
    template,
    *,
    seed: int,
    out_dir,
    effects: Mapping[str, Any] | None = None,
    n_runs: int | None = None,
    scatter: Mapping[str, float] | None = None,
    noise_scale: float = 1.0,
    name: str | None = None,
    command: str | None = None,
    oven: str = "heating",
) -> SimulationResult:
    """Simulate an experiment of one rig kind and write it like a lab would.

    Parameters
    ----------
    kind : str
        ``"static"``, ``"dynamic"``, ``"sensing"`` or ``"curvature"``.
    template : Experiment or path-like
        Template experiment file (``load_experiment(..., require_runs=False)``);
        its sample and rig are the truth (sensing: S comes from the
        template's ``spring_constant_N_per_m`` and is not written out).
    seed : int
        Seed of every random draw; same seed and arguments, same bytes.
    out_dir : path-like
        Writes ``raw/<name>_runN.csv``, ``experiments/<name>.toml`` and
        ``truth/<name>.truth.json`` under it.
    effects : mapping, optional
        Effect name -> strength (float, in noise sd of the primary quantity,
        see :func:`scale_effect`) or ``{"value": x}`` (the parameter in SI).
        Several effects are scaled one by one and then combined.
    n_runs : int, optional
        Runs (default :data:`DEFAULT_RUNS`).
    scatter : mapping, optional
        SI field of Sample or Rig -> relative sd of its per-run scatter
        (default :data:`DEFAULT_SCATTER`; ``{}`` for none).
    noise_scale : float
        Multiplies every instrument noise sd.
    name : str, optional
        Output name (default: the template's file stem).
    command : str, optional
        The command line recorded in ``[synthetic]`` (``--effect`` options
        are removed there, kept in the truth file).
    oven : {"heating", "heat-cool"}
        Static oven program (:data:`OVEN_PROGRAMS`); ignored for other kinds.

    Returns
    -------
    SimulationResult
        ``truth`` (also written to the truth file) holds ``kind``, ``seed``,
        ``command`` (with the effects), ``effects`` {name: {requested_strength,
        parameters {Mods field: SI value}, fixed, achieved_strength, quantities,
        limited_by}}, ``mods`` (the combined non-default Mods fields),
        ``scatter``, ``noise_sd`` (:func:`noise_sd`), ``instrument_sd``, the
        template's sample and rig, and ``runs`` [{file, sample, rig}] with
        each run's true (scattered) parameters, SI.
    """
    _check_kind(kind)
    if isinstance(template, _config.Experiment):
        exp, template_arg = template, template.path
    else:
        exp, template_arg = _config.load_experiment(template, require_runs=False), template
    if exp.kind != kind:
        raise ConfigError(f"{exp.path}: template is a {exp.kind!r} experiment, not {kind!r}")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    n = DEFAULT_RUNS[kind] if n_runs is None else int(n_runs)
    if n < 1:
        raise ConfigError(f"n_runs must be at least 1, got {n_runs!r}")
    if noise_scale < 0 or not math.isfinite(noise_scale):
        raise ConfigError(f"noise_scale must be finite and >= 0, got {noise_scale!r}")
    scatter = dict(DEFAULT_SCATTER[kind] if scatter is None else scatter)
    name = exp.name if name is None else str(name)
    out = Path(out_dir)
    # The truth file keeps the effects; the experiment file gets public_command.
    full_command_truth = full_command = command
    if command is None:
        strengths = {k: (v["value"] if isinstance(v, Mapping) else v) for k, v in (effects or {}).items()}
        full_command = full_command_truth = simulate_command(
            kind,
            template_arg,
            seed,
            out_dir,
            runs=n_runs,
            name=None if name == exp.name else name,
            noise_scale=noise_scale,
            oven=oven if kind == "static" else "heating",
            effects=strengths,
        )

    sample0, rig0 = exp.sample, exp.rig
    # One stream per run, drawn in a fixed order: protocol, scatter, then noise.
    rngs = [np.random.default_rng([int(seed), k]) for k in range(n)]
    protos = [protocol(kind, rig0, rngs[k], oven) for k in range(n)]
    trues = [_scattered(kind, sample0, rig0, scatter, rngs[k]) for k in range(n)]
    sd = noise_sd(kind, sample0, rig0, noise_scale=noise_scale)
    if noise_scale == 0:
        sd = noise_sd(kind, sample0, rig0)  # strengths still refer to the nominal floor

    effect_truth: dict[str, dict] = {}
    mods = NO_MODS
    for ename, strength in (effects or {}).items():
        info = scale_effect(
            kind,
            ename,
            strength,
            sample0,
            rig0,
            protos[0],
            sd,
            also_valid_for=tuple((s_k, r_k, p_k) for (s_k, r_k), p_k in zip(trues, protos)),
        )
        effect_truth[ename] = {k: v for k, v in info.items() if k != "name"}
        eff = get_effect(ename, kind)
        mods = eff.mods([info["parameters"][p.field] for p in eff.params], mods)

    run_names, run_paths, runs_truth = [], [], []
    for k in range(n):
        rng = rngs[k]
        sample_k, rig_k = trues[k]
        inputs = exact_inputs(kind, sample_k, rig_k, protos[k], mods)
        outputs = predict(kind, sample_k, rig_k, inputs, mods, **_options(kind, sample_k, rig_k, inputs))
        logged = _measure(kind, inputs, outputs, rng, noise_scale)
        fname = f"{name}_run{k + 1}.csv"
        path = out / "raw" / fname
        atomic_write_text(path, _format_csv(kind, logged))
        run_names.append(fname)
        run_paths.append(path)
        runs_truth.append(
            {
                "file": f"raw/{fname}",
                "sample": sample_k.model_kwargs(),
                "rig": {f: getattr(rig_k, f) for f in sorted(_RIG_SCALARS | {"segment_lengths"})},
            }
        )

    exp_path = out / "experiments" / f"{name}.toml"
    doc = _experiment_doc(kind, exp, name, run_names, int(seed), public_command(full_command))
    _config.write_experiment(exp_path, doc)

    truth = to_jsonable(
        {
            "kind": kind,
            "name": name,
            "seed": int(seed),
            "generator": f"tcamlab simulate {__version__}",
            "command": full_command_truth,
            "template": str(template_arg),
            "n_runs": n,
            "noise_scale": float(noise_scale),
            "effects": effect_truth,
            "mods": {
                f: getattr(mods, f)
                for f in Mods.__dataclass_fields__
                if getattr(mods, f) != getattr(NO_MODS, f)
            },
            "scatter": scatter,
            "noise_sd": sd,
            "instrument_sd": instrument_sd(kind, noise_scale),
            "template_sample": sample0.model_kwargs(),
            "template_rig": {f: getattr(rig0, f) for f in sorted(_RIG_SCALARS | {"segment_lengths"})},
            "runs": runs_truth,
        }
    )
    truth_path = out / "truth" / f"{name}.truth.json"
    atomic_write_text(truth_path, dumps_json(truth, sort_keys=False))
    return SimulationResult(exp_path, tuple(run_paths), truth_path, truth)
