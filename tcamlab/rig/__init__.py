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

The rig can also lie like a real lab (both off by default): with
``parameter_error`` the true parameters are drawn away from the stated ones
by their stated sds (:mod:`.lies`), and with ``noisy_zero`` each run is
zeroed on one noisy reading (the kinds' ``measure``); only the truth file
says so.

Everything that differs between rig kinds is the kind's own
(:class:`tcamlab.kinds.Kind`: ``protocol``, ``exact_inputs``, ``measure``,
``instrument_sd``, the written columns and rig fields, the scatter); this
package only runs the steps: :mod:`.runs` (one run by its kind),
:mod:`.scatter` (per-run true parameters), :mod:`.strength` (noise floor and
effect strengths), :mod:`.writers` (CSV, experiment and truth files).

Protocols and measurement chains
--------------------------------

Every constant below is an attribute of the module its name is prefixed with
(``static.`` etc. are :mod:`tcamlab.kinds.static` etc., ``instruments.`` is
:mod:`tcamlab.instruments`, ``strength.`` is :mod:`tcamlab.rig.strength`);
SI unless the name says otherwise. The instrument chains are shared by the
kinds that use the same instrument.

=====================================  ==================  =====================================================
constant                               value               reason
=====================================  ==================  =====================================================
**static oven test** (thesis sec. 2.5.1)
static.OVEN_STEPS_C                    25, 30, ... 150     5 degC oven steps from just above room temperature to
                                                           150 degC (below the G_t' = 0 limit of ~160 degC):
                                                           26 readings per run
static.OVEN_DWELL_S                    300 s               reading taken after a 5 min dwell per step, long
                                                           enough for the small oven to settle
static.OVEN_REGULATION_SD_C            0.3 degC            the oven holds its set point only to a few tenths
                                                           of a degree; the actual (exact) temperature of each
                                                           step is set point + N(0, 0.3)
instruments.THERMOMETER_SD_C           0.2 degC            thermocouple reader noise in the vent hole
instruments.THERMOMETER_RESOLUTION_C   0.1 degC            display resolution of the reader
instruments.LASER_NOISE_SD_M           5 um                analog noise of the laser displacement sensor
instruments.LASER_SPAN_M, ADC_BITS     10 mm, 10 bit       0..10 mm laser output read by the Arduino's 10-bit
                                                           ADC: quantum 10 mm / 1023 = 9.78 um
                                                           (instruments.LASER_QUANTUM_M)
instruments.LASER_TARE_SAMPLES         64                  the sketch zeroes on the mean of 64 readings at rest
                                                           and logs that mean as row 0 (0.000 mm); later rows
                                                           carry the tare error (about sd / 8) as an offset;
                                                           ``noisy_zero``: row 0 is one reading, the offset
                                                           is about one noise sd
instruments.LASER_LOG_RESOLUTION_M     1 um                displacement written with 3 decimals in mm
static.KIND.default_runs               3                   three repeats of the oven test
**dynamic voltage-step test** (thesis sec. 2.5.2)
dynamic.PULSE_START_S                  0.5 s               a quiet baseline before the pulse; the pulse voltage
                                                           and duration come from the template's rig table
                                                           (10 V for 1 s in the thesis)
dynamic.DYNAMIC_RATE_HZ                100 Hz              Arduino logging rate
dynamic.DYNAMIC_DURATION_S             10 s                long enough to see most of the cooling
dynamic.TIMING_JITTER_PROB             0.03                the loop occasionally runs 1 ms early or late; the
                                                           logged time is the Arduino's integer ``millis()``
                                                           of the actual sample, so it is exact
(displacement)                                             the same laser chain as the static test
(current_A, temperature_C)                                 only where a [protocol] table's channels ask:
                                                           instruments.current_sense (0.05 mA, 12 bit over
                                                           0.4 A) and the thermometer above
dynamic.KIND.default_runs              3
**sensing pull test** (thesis sec. 3.3)
sensing.PULL_STEP_M                    2 mm                linear-actuator step
sensing.PULL_MAX_M                     50 mm               loading up to 50 mm, then unloading back to 0
sensing.PULL_DWELL_S                   5 s                 dwell at each step (thesis protocol)
sensing.PULL_SPEED_M_PER_S             10 mm/s             actuator speed between steps (a step takes 0.2 s)
sensing.PULL_RATE_HZ                   10 Hz               logging rate
instruments.ENCODER_RESOLUTION_M       0.01 mm             actuator encoder; the programmed positions are on
                                                           its grid, so the logged position is exact
instruments.LOADCELL_SD_N              2 mN                LSP-5 load cell with its amplifier
instruments.LOADCELL_OFFSET_N          -0.4 mN             residual zero offset after taring; ``noisy_zero``:
                                                           minus one reading's noise, redrawn per run
instruments.LOADCELL_SPAN_N, _BITS     +-0.5 N, 12 bit     amplifier span read by a 12-bit ADC: quantum
                                                           1 N / 4095 = 0.244 mN
instruments.OHMMETER_SD_OHM            2 mohm              bench multimeter noise on a 10-30 ohm sensor
instruments.OHMMETER_RESOLUTION_OHM    1 mohm              its display resolution
sensing.KIND.default_runs              3                   S is identified leave-one-run-out, so >= 2 runs
sensing.KIND.simulation_rig_defaults   S of thesis-tcs     the default noise floor's S (the preset leaves S to
                                                           be identified)
**curvature camera test** (thesis sec. 4.3)
curvature.CABLE_STEP_M, CABLE_MAX_M    1 mm, 10 mm         cable pulled by the same actuator: 11 poses
curvature.TIP_TO_BASE_CURVATURE        1.5                 assumption: the tip segment (EcoFlex 00-10) is
                                                           softer than the base (00-30); the bending moment
                                                           of the cable is the same in both, so curvature
                                                           goes with compliance; 1.5 is a round ratio
                                                           between the two grades' moduli
(neutral axis)                         y_c = y_s = d1 / 2  cable and sensor placed symmetrically about the
                                                           neutral axis (thesis sec. 4.3), which also makes
                                                           the model's proportional cable sharing exact
instruments.CAMERA_SD_PER_M            0.2 1/m             curvature from the camera images (2e-4 per mm)
instruments.CAMERA_RESOLUTION_PER_M    0.001 1/m           written with 6 decimals in per_mm
(resistances)                                              two channels of the same multimeter as above
curvature.KIND.default_runs            3
**self-sensing powered run** (truth: :mod:`.selfsensing`)
selfsensing.RATE_HZ                    100 Hz              logging rate; one run holds every protocol, 50 s
selfsensing.SEGMENTS                   2+12+12+12+12 s     rest at the probe, voltage steps, PWM, sine, chirp
selfsensing.PROBE_V                    1.5 V               probe between heating phases: a current to read R
selfsensing.STEP_LEVELS_V              4 V, 6 V            3 s each; 6 V on 40 ohm is ~100 K at steady state
selfsensing.PWM_V, _HZ, _DUTY          6 V, 1 Hz, 0.5      PWM drive
selfsensing.SINE_MEAN_V, _AMP_V        3.5 V, 2.5 V        sine at 0.25 Hz; chirp 0.05 -> 1 Hz
selfsensing.RIDER_KG                   5 g                 rider put on the 50 g hanger at a uniform random
                                                           time in RIDER_WINDOW_S = 15-35 s: the load changes
selfsensing.CURRENT_SD_A               0.05 mA             0.1 ohm shunt into an INA219-class monitor
selfsensing.CURRENT_SPAN_A, _BITS      0.4 A, 12 bit       current ADC: quantum 98 uA
selfsensing.VOLTAGE_SD_V               5 mV                voltage divider and ADC input noise
selfsensing.VOLTAGE_SPAN_V, _BITS      12 V, 12 bit        voltage ADC: quantum 2.9 mV
(displacement, load)                                       the laser chain above; the logged weight is exact
**per-run scatter** (relative sd, ``KIND.default_scatter`` of each kind module)
actuators                              0.2 % twists,       re-mounting and slow annealing make repeats of the
                                       0.2 % coil_length   same sample differ slightly; far below noise here
sensors                                0.05 % twists,      the same sensor is re-tested; its resistance map is
                                       0.05 % coil_length  sensitive, so only a small scatter stays in noise
R0                                     0 (optional)        the sensing file carries the true R0, so R0 must not
                                                           scatter; pass ``scatter={"initial_resistance": ..}``
                                                           when the pipeline takes R0 from each run's first row
                                                           (curvature: one draw per segment,
                                                           ``KIND.segment_rig_fields``)
**effect strengths**
strength.DOMAIN_BACKOFF                0.9                 a strength the model's domain cannot reach (e.g. a
                                                           steeper G(T) that makes G_t' <= 0 inside the
                                                           protocol) is capped at 90 % of the largest valid
                                                           parameters; the achieved strength is recorded
=====================================  ==================  =====================================================

The curvature geometry is documented in :mod:`tcamlab.kinds.curvature`.

Effect strengths are in multiples of the noise floor of the primary measured
quantity (see :func:`simulate`); an effect's parameters are scaled together
along their ``scale`` vector (:func:`scale_effect`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from tcamlab import config as tconfig
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError, ModelDomainError
from tcamlab.instruments import LASER_QUANTUM_M
from tcamlab.jsonutil import dumps_json, to_jsonable
from tcamlab.kinds import REGISTRY, get_kind, predict
from tcamlab.kinds.static import OVEN_PROGRAMS
from tcamlab.params import Rig, Sample
from tcamlab.report.atomic import atomic_write_text
from tcamlab.rig.lies import draw_parameters, stated_sds
from tcamlab.rig.offlibrary import apply_form, get_form, scale_form
from tcamlab.rig.runs import (
    designed_channels,
    designed_programs,
    exact_inputs,
    instrument_sd,
    measure,
    program_options,
    protocol,
    true_options,
)
from tcamlab.rig.scatter import rig_truth, scattered
from tcamlab.rig.strength import DOMAIN_BACKOFF, noise_sd, resolve_effect, scale_effect
from tcamlab.rig.writers import GENERATOR, SYNTHETIC_NOTE, experiment_doc, format_csv, mods_truth
from tcamlab.text import public_command, shown_path, simulate_command

__all__ = [
    "CONDITIONS",
    "SimulationResult",
    "simulate",
    "same_truth",
    "with_hidden_rig",
    "noise_sd",
    "instrument_sd",
    "protocol",
    "exact_inputs",
    "scale_effect",
    "resolve_effect",
    "DEFAULT_RUNS",
    "DEFAULT_SCATTER",
    "DOMAIN_BACKOFF",
    "OVEN_PROGRAMS",
    "SYNTHETIC_NOTE",
    "LASER_QUANTUM_M",
]

DEFAULT_RUNS = {k.name: k.default_runs for k in REGISTRY.values()}
"""Runs per simulated experiment unless ``n_runs`` is given (from the kind registry)."""

DEFAULT_SCATTER: dict[str, dict[str, float]] = {k.name: dict(k.default_scatter) for k in REGISTRY.values()}
"""Kind -> {SI field of Sample or Rig: relative sd} of the per-run scatter (from the kind registry)."""


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
        The content of the truth file: ``kind``, ``seed``, ``command`` (with
        the effects and the lies), ``effects`` {name: {requested_strength,
        parameters {Mods field: SI value}, fixed, achieved_strength,
        quantities, limited_by}}, ``mods`` (the combined non-default Mods
        fields), ``scatter``, ``noise_sd`` (:func:`noise_sd`),
        ``instrument_sd``, the template's (stated) sample and rig, and
        ``runs`` [{file, sample, rig}] with each run's true (scattered)
        parameters, SI. With a parameter error also ``parameter_error``,
        ``parameter_offsets``, ``stated_sd`` {field: sd} and
        ``true_parameters`` {field: {table, stated, sd, true, z, offset_sd,
        distribution}} (:func:`tcamlab.rig.lies.draw_parameters`); with
        ``noisy_zero`` also ``noisy_zero`` and each run's ``zero_error``
        {logged column: the constant its rows carry, logged = true +
        zero_error + noise [SI]}.
    """

    experiment_path: Path
    run_paths: tuple[Path, ...]
    truth_path: Path
    truth: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Plan:
    """The checked arguments of one :func:`simulate` call."""

    kind: str
    exp: Any  # tcamlab.config.Experiment
    template_arg: Any
    seed: int
    n_runs: int
    noise_scale: float
    scatter: dict[str, float]
    name: str
    out: Path
    program: dict[str, Any]
    conditions: int
    command: str
    true_sample: Sample
    true_rig: Rig
    true_parameters: dict[str, dict] | None
    lies: dict[str, Any]
    designed: tuple = ()
    """Each run's program options from the template's ``[protocol]`` table (cycled), or empty."""
    channels: tuple = ()
    """The predictions the protocol's ``channels`` add to each run's log (a voltage-step test's
    ``current``), or empty."""


@dataclass(frozen=True)
class _Run:
    """One run's random stream, exact protocol and true (scattered) sample and rig."""

    rng: np.random.Generator
    proto: Any  # pandas.DataFrame
    sample: Sample
    rig: Rig


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
    parameter_error: float = 0.0,
    parameter_offsets: Mapping[str, float] | None = None,
    uncertainty: Mapping[str, Any] | None = None,
    noisy_zero: bool = False,
    offlibrary: Mapping[str, float] | None = None,
    conditions: int = 1,
) -> SimulationResult:
    """Simulate an experiment of one rig kind and write it like a lab would.

    Parameters
    ----------
    kind : str
        ``"static"``, ``"dynamic"``, ``"sensing"`` or ``"curvature"``.
    template : Experiment or path-like
        Template experiment file (``load_experiment(..., require_runs=False)``): the
        stated sample and rig (sensing S is the template's, never written out).
    seed : int
        Seed of every random draw; same seed and arguments, same bytes.
    out_dir : path-like
        Gets ``raw/<name>_runN.csv``, ``experiments/<name>.toml``, ``truth/<name>.truth.json``.
    effects : mapping, optional
        Effect -> strength (noise sds, :func:`scale_effect`) or ``{"value": x}`` (SI). Names joined
        by ``+`` act as one (:func:`resolve_effect`); several are scaled one by one, then combined.
    n_runs : int, optional
        Runs (default :data:`DEFAULT_RUNS`).
    scatter : mapping, optional
        {SI field: relative sd} of the per-run scatter (default :data:`DEFAULT_SCATTER`; ``{}``: none).
    noise_scale : float
        Multiplies every instrument noise sd.
    name : str, optional
        Output name (default: the template's file stem).
    command : str, optional
        The truth file's command line (``[synthetic]``: :func:`tcamlab.text.public_command` of it).
    oven : {"heating", "heat-cool"}
        Static oven program (:data:`OVEN_PROGRAMS`); kinds without an oven ignore it.
    parameter_error : float
        F [-]: every parameter with a stated sd (``[rig.uncertainty]``, ``[sample.uncertainty]``,
        ``uncertainty``) gets a TRUE value drawn with the stated mean and F stated sds
        (:mod:`tcamlab.rig.lies`), used by every run; the experiment file keeps the stated
        values. 0 (default): the stated values are the truth.
    parameter_offsets : mapping, optional
        {SI field: d}: the true value is exactly stated + d sd (tests).
    uncertainty : mapping, optional
        {SI field: sd [SI]}: sds the template does not state (drawn, never written).
    noisy_zero : bool
        Zero each run on one noisy reading, not the averaged tare; zero errors go to the truth.
    offlibrary : mapping, optional
        {form: strength} of :mod:`tcamlab.rig.offlibrary`, applied after the effects (truth: ``offlibrary``).
    conditions : {1, 2}
        2: runs alternate between the stated condition and the kind's second one (run 1, 3, ...
        the stated; static: a second load, dynamic: a second voltage; :data:`CONDITIONS`), the
        experiment that tells a parameter error from an effect that acts differently there.

    Returns
    -------
    SimulationResult
        The paths written and the truth.
    """
    lies = _lies(parameter_error, parameter_offsets, uncertainty, noisy_zero)
    plan = _plan(
        kind,
        template,
        seed,
        out_dir,
        effects,
        n_runs,
        scatter,
        noise_scale,
        name,
        command,
        oven,
        lies,
        conditions,
    )
    runs = _draw_runs(plan)
    sd = _strength_floor(plan)
    with _designed_range(plan):
        effect_truth, mods = _scale_effects(plan, effects or {}, runs, sd)
        forms = _scale_forms(plan, offlibrary or {}, runs, sd, mods)
    run_paths, runs_truth = _write_runs(plan, runs, mods, forms)
    exp_path = _write_experiment(plan, run_paths)
    truth = _truth(plan, effect_truth, mods, sd, runs_truth, forms)
    truth_path = plan.out / "truth" / f"{plan.name}.truth.json"
    atomic_write_text(truth_path, dumps_json(truth, sort_keys=False))
    return SimulationResult(exp_path, tuple(run_paths), truth_path, truth)


# --- the steps of simulate ----------------------------------------------------------------


def _lies(parameter_error, parameter_offsets, uncertainty, noisy_zero) -> dict[str, Any]:
    """The rig's lies, as :func:`simulate` got them (:mod:`tcamlab.rig.lies`)."""
    return {
        "parameter_error": parameter_error,
        "parameter_offsets": dict(parameter_offsets or {}),
        "uncertainty": dict(uncertainty or {}),
        "noisy_zero": bool(noisy_zero),
    }


CONDITIONS = {"static": "a second load (1.5 x, logged as load_N)", "dynamic": "a second voltage (0.8 x)"}
"""The second condition of each kind that has one (``simulate(conditions=2)``)."""


SENSOR_KEYS = {"spring_constant": "spring_constant_N_per_m", "initial_resistance": "initial_resistance_ohm"}
"""The [rig] keys of a sensor's (or self-sensing muscle's) true S [N/m] and R0 [ohm], which
a sensing, curvature or self-sensing simulation needs (a lab's experiment file may leave them out: the diagnosis reads them)."""


def _check_template(kind: str, exp) -> None:
    """Refuse a template of another kind, or a sensing, curvature or self-sensing one without
    the sensor's (muscle's) S and R0 (naming the file and the keys, with the shipped template's values as an example)."""
    if exp.kind != kind:
        raise ConfigError(f"{exp.path}: template is a {exp.kind!r} experiment, not {kind!r}")
    if kind not in ("sensing", "curvature", "selfsensing"):
        return
    missing = [key for f, key in SENSOR_KEYS.items() if getattr(exp.rig, f, None) is None]
    if not missing:
        return
    from tcamlab.templates import TEMPLATES

    shipped = tconfig.load_experiment(TEMPLATES / f"{kind}.toml", require_runs=False).rig
    example = " and ".join(
        f"{key} = {getattr(shipped, f):g}" for f, key in SENSOR_KEYS.items() if key in missing
    )
    part = "muscle" if kind == "selfsensing" else "sensor"
    raise ConfigError(
        f"{shown_path(exp.path)}: the {kind} virtual rig needs the {part}'s {' and '.join(missing)} "
        "in [rig] (the true S and R0 it simulates)",
        f"add to its [rig] your {part}'s values, e.g. {example}",
    )


def _plan(
    kind,
    template,
    seed,
    out_dir,
    effects,
    n_runs,
    scatter,
    noise_scale,
    name,
    command,
    oven,
    lies,
    conditions=1,
) -> _Plan:
    """Check the arguments of :func:`simulate` and settle its defaults."""
    get_kind(kind)
    if conditions not in (1, 2):
        raise ConfigError(f"conditions must be 1 or 2, got {conditions!r}")
    if conditions == 2 and kind not in CONDITIONS:
        raise ConfigError(
            f"the {kind} rig has no second condition",
            hint="conditions = 1, or a kind with one: "
            + "; ".join(f"{k}: {v}" for k, v in CONDITIONS.items()),
        )
    if isinstance(template, tconfig.Experiment):
        exp, template_arg = template, template.path
    else:
        exp, template_arg = tconfig.load_experiment(template, require_runs=False), template
    _check_template(kind, exp)
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    designed = designed_programs(kind, exp) or []
    n = (len(designed) or DEFAULT_RUNS[kind]) if n_runs is None else int(n_runs)
    if n < 1:
        raise ConfigError(f"n_runs must be at least 1, got {n_runs!r}")
    if noise_scale < 0 or not math.isfinite(noise_scale):
        raise ConfigError(f"noise_scale must be finite and >= 0, got {noise_scale!r}")
    name = exp.name if name is None else str(name)
    program = program_options(kind, oven=oven)
    if command is None:
        # The truth file keeps the effects; the experiment file gets public_command.
        strengths = {k: (v["value"] if isinstance(v, Mapping) else v) for k, v in (effects or {}).items()}
        command = simulate_command(
            kind,
            template_arg,
            seed,
            out_dir,
            runs=n_runs,
            name=None if name == exp.name else name,
            noise_scale=noise_scale,
            effects=strengths,
            parameter_error=lies["parameter_error"],
            noisy_zero=lies["noisy_zero"],
            conditions=conditions,
            **program,
        )
    true_sample, true_rig, true_parameters = _true_parameters(kind, exp, int(seed), lies)
    return _Plan(
        kind=kind,
        exp=exp,
        template_arg=template_arg,
        seed=int(seed),
        n_runs=n,
        noise_scale=noise_scale,
        scatter=dict(DEFAULT_SCATTER[kind] if scatter is None else scatter),
        name=name,
        out=Path(out_dir),
        program=program,
        conditions=int(conditions),
        command=command,
        true_sample=true_sample,
        true_rig=true_rig,
        true_parameters=true_parameters,
        lies=lies,
        designed=tuple(designed),
        channels=designed_channels(kind, exp),
    )


def _true_parameters(kind: str, exp, seed: int, lies: Mapping[str, Any]) -> tuple[Sample, Rig, dict | None]:
    """The true sample and rig behind the stated ones, and their record (None: no parameter error)."""
    error = lies["parameter_error"]
    if not (isinstance(error, (int, float)) and math.isfinite(error) and error >= 0):
        raise ConfigError(f"parameter_error must be finite and >= 0, got {error!r}")
    if not error and not lies["parameter_offsets"]:
        return exp.sample, exp.rig, None
    sds = stated_sds(exp, lies["uncertainty"])
    return draw_parameters(
        kind, exp.sample, exp.rig, sds, error=float(error), offsets=lies["parameter_offsets"], seed=seed
    )


def _draw_runs(plan: _Plan) -> list[_Run]:
    """Each run's stream, protocol and true parameters.

    One stream per run, drawn in a fixed order: protocol, scatter, then
    (later, in :func:`_write_runs`) noise.
    """
    rngs = [np.random.default_rng([plan.seed, k]) for k in range(plan.n_runs)]
    # The program is the lab's: commanded from the stated rig.
    conds = [{"condition": k % plan.conditions} if plan.conditions > 1 else {} for k in range(plan.n_runs)]
    if plan.designed:  # a designed protocol: each run's own program, cycled
        conds = [plan.designed[k % len(plan.designed)] for k in range(plan.n_runs)]
    protos = [protocol(plan.kind, plan.exp.rig, rng, **{**plan.program, **c}) for rng, c in zip(rngs, conds)]
    trues = [scattered(plan.kind, plan.true_sample, plan.true_rig, plan.scatter, rng) for rng in rngs]
    return [_Run(rng, p, s, r) for rng, p, (s, r) in zip(rngs, protos, trues)]


def _strength_floor(plan: _Plan) -> dict[str, float]:
    """The noise floor of the template; with the noise off, strengths still refer to the nominal floor."""
    sample, rig = plan.exp.sample, plan.exp.rig
    sd = noise_sd(plan.kind, sample, rig, noise_scale=plan.noise_scale)
    if plan.noise_scale == 0:
        sd = noise_sd(plan.kind, sample, rig)
    return sd


def _scale_effects(
    plan: _Plan, effects: Mapping[str, Any], runs: list[_Run], sd: Mapping[str, float]
) -> tuple[dict[str, dict], Mods]:
    """({effect: its truth}, the combined Mods): each effect scaled on the first run, valid on all."""
    sample, rig = plan.true_sample, plan.true_rig
    others = tuple((r.sample, r.rig, r.proto) for r in runs)
    effect_truth: dict[str, dict] = {}
    mods = NO_MODS
    for ename, strength in effects.items():
        info = scale_effect(plan.kind, ename, strength, sample, rig, runs[0].proto, sd, also_valid_for=others)
        effect_truth[ename] = {k: v for k, v in info.items() if k != "name"}
        eff = resolve_effect(ename, plan.kind)
        mods = eff.mods([info["parameters"][p.field] for p in eff.params], mods)
    return effect_truth, mods


def _scale_forms(plan: _Plan, offlibrary: Mapping[str, float], runs: list[_Run], sd, mods: Mods) -> list:
    """[(form, its truth)] of the out-of-library forms, each scaled on the first run (on top of the effects)."""
    out = []
    sample, rig, proto = plan.true_sample, plan.true_rig, runs[0].proto
    for name, strength in offlibrary.items():
        form = get_form(name, plan.kind)
        inputs = exact_inputs(plan.kind, sample, rig, proto, mods)
        opts = true_options(plan.kind, sample, rig, inputs)
        outputs = predict(plan.kind, sample, rig, inputs, mods, **opts)
        out.append(
            (form, scale_form(form, _strength(strength), plan.kind, sample, rig, inputs, outputs, opts, sd))
        )
    return out


def _strength(strength):
    return strength if isinstance(strength, Mapping) else float(strength)


def with_hidden_rig(experiment, truth: Mapping[str, Any]):
    """``experiment`` with the rig values a simulated experiment file keeps hidden (a sensing
    rig's S and R0, never written out) taken from ``truth``'s template, so the virtual rig can
    run a protocol file made from it (values the file states are kept)."""
    hidden = {
        k: v
        for k, v in (truth.get("template_rig") or {}).items()
        if v is not None and hasattr(experiment.rig, k) and getattr(experiment.rig, k) is None
    }
    if not hidden:
        return experiment
    return dataclasses.replace(experiment, rig=experiment.rig.replace(**hidden))


def same_truth(truth: Mapping[str, Any]) -> dict[str, Any]:
    """:func:`simulate`'s arguments that rebuild the muscle of an earlier simulation from its
    truth file: its effects at their parameter values [SI] and its out-of-library forms at
    their amplitudes (not at a strength, which depends on the protocol), its true parameters as
    exact offsets from the stated ones, its zeros, scatter and noise. A designed protocol
    simulated with them is the same muscle measured again (new noise from the new seed).

    Parameters
    ----------
    truth : mapping
        A truth file's content (``truth/NAME.truth.json``).
    """
    try:
        kind = truth["kind"]
        effects = {
            name: {"value": [info["parameters"][p.field] for p in resolve_effect(name, kind).params]}
            for name, info in (truth.get("effects") or {}).items()
        }
        out: dict[str, Any] = {
            "effects": effects,
            "offlibrary": {
                n: {"amplitude": f["amplitude"]} for n, f in (truth.get("offlibrary") or {}).items()
            },
            "scatter": dict(truth.get("scatter") or {}),
            "noise_scale": float(truth.get("noise_scale", 1.0)),
            "noisy_zero": bool(truth.get("noisy_zero", False)),
        }
        if truth.get("true_parameters"):
            out["parameter_offsets"] = {f: v["offset_sd"] for f, v in truth["true_parameters"].items()}
            out["uncertainty"] = dict(truth.get("stated_sd") or {})
    except (KeyError, TypeError, AttributeError) as exc:
        raise ConfigError(
            f"truth file: no {exc} where a truth file of tcamlab simulate has one",
            hint="pass the truth/NAME.truth.json that tcamlab simulate wrote",
        ) from None
    return out


def _write_runs(plan: _Plan, runs: list[_Run], mods: Mods, forms=()) -> tuple[list[Path], list[dict]]:
    """Predict, measure and write each run's CSV; (paths, each run's truth).

    Every run is made before any is written: a run the model refuses (a designed load the
    coil cannot hold) leaves no partial experiment behind."""
    logs = [_measure_run(plan, run, mods, forms) for run in runs]
    paths, truths = [], []
    for k, (run, logged) in enumerate(zip(runs, logs)):
        fname = f"{plan.name}_run{k + 1}.csv"
        path = plan.out / "raw" / fname
        atomic_write_text(path, format_csv(plan.kind, logged))
        paths.append(path)
        truth = {"file": f"raw/{fname}", "sample": run.sample.model_kwargs(), "rig": rig_truth(run.rig)}
        if plan.lies["noisy_zero"]:
            truth["zero_error"] = dict(logged.attrs.get("zero_error", {}))
        truths.append(truth)
    return paths, truths


@contextlib.contextmanager
def _designed_range(plan: _Plan):
    """A model error under a designed protocol names the file's ``[protocol]`` table: the
    program, not the rig keys the model's own hint names, asked for it. One under drawn
    true parameters names the draw: the model's hint (a log's units, the file's keys) is
    about a file this command wrote itself."""
    try:
        yield
    except ModelDomainError as exc:
        error = plan.lies["parameter_error"]
        if not plan.designed and (error or plan.lies["parameter_offsets"]):
            drawn = f"--parameter-error {error:g}" if error else "the parameter offsets"
            raise ModelDomainError(
                f"the true parameters drawn off the stated ones ({drawn}) make a muscle the model "
                f"cannot run on this protocol: {exc.message}",
                "another --seed draws other true parameters, or a smaller --parameter-error",
            ) from None
        if not plan.designed:
            raise
        raise ModelDomainError(
            f"{plan.exp.path.name}: [protocol]: a run it asks for is outside the model's range: {exc.message}",
            "lower the [protocol] table's loads_g, voltages, temperatures, pull_mm or cable_mm",
        ) from None


def _measure_run(plan: _Plan, run: _Run, mods: Mods, forms) -> pd.DataFrame:
    """One run's logged table: the true response under its program, measured."""
    kind = plan.kind
    with _designed_range(plan):
        inputs = exact_inputs(kind, run.sample, run.rig, run.proto, mods)
        opts = true_options(kind, run.sample, run.rig, inputs)
        outputs = predict(kind, run.sample, run.rig, inputs, mods, **opts)
    for form, info in forms:
        inputs, outputs = apply_form(
            form, info["amplitude"], kind, run.sample, run.rig, inputs, outputs, opts
        )
    zero = {"noisy_zero": True} if plan.lies["noisy_zero"] else {}
    extra = {"channels": plan.channels} if plan.channels else {}
    return measure(kind, inputs, outputs, run.rng, plan.noise_scale, **zero, **extra)


def _write_experiment(plan: _Plan, run_paths: list[Path]) -> Path:
    """Write ``experiments/<name>.toml`` (no effects in it) and return its path."""
    path = plan.out / "experiments" / f"{plan.name}.toml"
    names = [p.name for p in run_paths]
    doc = experiment_doc(plan.kind, plan.exp, names, plan.seed, public_command(plan.command))
    if plan.designed and plan.exp.runs:
        # A protocol file lists the runs so far: the experiment to diagnose again is them and these.
        doc["runs"] = _runs_so_far(plan.exp, path.parent.resolve()) + doc["runs"]
    tconfig.write_experiment(path, doc)
    return path


def _runs_so_far(exp, here: Path) -> list:
    """The experiment's runs as the written experiment file lists them (paths relative to
    ``here``, its folder): each keeps its own column layout and join, since the simulated runs
    beside them are written with the canonical headers and the file has no ``[columns]``."""
    table = exp.raw.get("columns") or {}
    entries = exp.raw.get("runs") or []
    joins = exp.run_joins or (None,) * len(exp.runs)
    out: list = []
    for path, entry, join in zip(exp.runs, entries, joins):
        rel = Path(os.path.relpath(path, here)).as_posix()
        own = entry if isinstance(entry, Mapping) else {}
        columns = tconfig.merge_run_columns(table, own.get("columns") or {})
        if not columns and join is None:
            out.append(rel)
            continue
        run: dict[str, Any] = {"file": rel}
        if columns:
            run["columns"] = columns
        if join is not None:
            run["join"] = {**dict(own["join"]), "file": Path(os.path.relpath(join["file"], here)).as_posix()}
        out.append(run)
    return out


def _template_label(template) -> str:
    """How the truth file names its template: a shipped one by its kind (what ``--experiment``
    accepts, the same on every machine), any other by the path as given."""
    from tcamlab.templates import TEMPLATES

    path = Path(template)
    if path.parent.resolve() == TEMPLATES and path.suffix == ".toml":
        return path.stem
    return str(template)


def _truth(
    plan: _Plan, effect_truth: dict, mods: Mods, sd: Mapping[str, float], runs_truth: list[dict], forms=()
) -> dict[str, Any]:
    """The truth file's content (JSON-ready)."""
    truth = {
        "kind": plan.kind,
        "name": plan.name,
        "seed": plan.seed,
        "generator": GENERATOR,
        "command": plan.command,
        "template": _template_label(plan.template_arg),
        "n_runs": plan.n_runs,
        "noise_scale": float(plan.noise_scale),
        "effects": effect_truth,
        "mods": mods_truth(mods),
        "scatter": plan.scatter,
        "noise_sd": sd,
        "instrument_sd": instrument_sd(plan.kind, plan.noise_scale),
        "template_sample": plan.exp.sample.model_kwargs(),
        "template_rig": rig_truth(plan.exp.rig),
        "runs": runs_truth,
    }
    if forms:
        truth["offlibrary"] = {f.name: info for f, info in forms}
    return to_jsonable({**truth, **_lies_truth(plan)})


def _lies_truth(plan: _Plan) -> dict[str, Any]:
    """The truth file's record of the rig's lies (nothing when it tells the truth)."""
    out: dict[str, Any] = {}
    if plan.true_parameters is not None:
        out["parameter_error"] = float(plan.lies["parameter_error"])
        out["parameter_offsets"] = plan.lies["parameter_offsets"]
        out["stated_sd"] = {f: v["sd"] for f, v in plan.true_parameters.items()}
        out["true_parameters"] = plan.true_parameters
    if plan.lies["noisy_zero"]:
        out["noisy_zero"] = True
    return out
