"""The rig-kind registry: everything that differs between rig kinds, one module per kind.

Each module of this package defines one :class:`Kind` (``KIND``). Code
elsewhere looks a kind up with :func:`get_kind` instead of branching on its
name, so an unknown kind fails here, once, with a :class:`ConfigError`, and a
new rig kind is one new module (plus its preset, templates and sample data)
added to :data:`REGISTRY`. ``tests/test_kinds.py`` checks, in the manner of
python-control's ``kwargs_test.py``, that every registered kind fills in
every part consistently.

===========  ============================  ==============================
kind         inputs                        predicted
===========  ============================  ==============================
static       temperature (time)            displacement
dynamic      time, voltage                 displacement (temperature)
sensing      resistance (time)             displacement, force
curvature    cable, r1, r2                 kappa1, kappa2
selfsensing  time, voltage, current        displacement (temperature)
===========  ============================  ==============================
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from tcamlab.errors import ConfigError

if TYPE_CHECKING:  # the registry stays cheap to import: the CLI lists kinds for --help
    import numpy as np
    import pandas as pd

    from tcamlab.effects import Mods
    from tcamlab.params import Preset, Rig, Sample

__all__ = [
    "Kind",
    "CalibrationParam",
    "RunOptions",
    "REGISTRY",
    "KINDS",
    "get_kind",
    "predict",
    "no_extras",
    "no_section",
    "rest_rows",
    "rest_reading",
    "scored_quantities",
    "step_rows",
    "stated_source",
    "run_scatter",
]


@dataclass(frozen=True)
class RunOptions:
    """The per-run constants a prediction needs beyond sample and rig, and where they came from.

    Attributes
    ----------
    options : dict
        Keyword options of the kind's ``predict`` (e.g. ``spring_constant``
        [N/m], ``initial_resistance`` [ohm]).
    info : dict
        The same values in lab units with their sources, for the report.
    """

    options: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CalibrationParam:
    """One parameter ``tcamlab calibrate`` identifies from a kind's logs.

    Attributes
    ----------
    field : str
        SI field of :class:`~tcamlab.params.Sample` or :class:`~tcamlab.params.Rig`.
    where : str
        ``"sample"`` (shared by experiments of one sample) or ``"rig"`` (per experiment).
    symbol : str
        The thesis symbol, for reports (``"C_th"``).
    unit : str
        SI unit of the field (``"J/K"``).
    default_sd : float
        Relative prior sd [-] used when the experiment file states no uncertainty
        (the prior sd is ``default_sd * |stated value|``).
    pinned_by : str
        The experiment that would pin the parameter when the logs do not, in words.
    positive : bool
        Fitted as its logarithm (a Gaussian prior in log space, sd_log = sd / value).
    needs : tuple of str
        Columns of which some run must log at least one for the parameter to be calibrated
        (dynamic R: ``current`` or ``resistance``; a shared parameter, so one run's reading
        pins it for all); without them it stays at its stated value. Empty: always calibrated.
    zero_sd : float or None
        Prior sd [SI] when the stated value is 0 and the file states no sd (a relative
        default means nothing there; dynamic beta). Relative sds are then relative to it.
    effect : str or None
        The effect-library effect this parameter is (dynamic beta: ``resistance-temperature``).
        The diagnosis keeps such a parameter out of its recalibration, so the effect stays a
        candidate of its own.
    read_at_rest : tuple of str
        Logged columns that read the parameter itself in a run's rows at rest
        (:func:`rest_reading`): the curvature rig's ohmmeters read R0 while the cable is
        slack, because the model's straight body has its sensors at rest length. Their
        mean is a measurement of the parameter, which calibration multiplies into its
        prior (:class:`tcamlab.calibration.problem.Spec`). Empty: none.
    """

    field: str
    where: str
    symbol: str
    unit: str
    default_sd: float
    pinned_by: str
    positive: bool = True
    needs: tuple[str, ...] = ()
    zero_sd: float | None = None
    effect: str | None = None
    read_at_rest: tuple[str, ...] = ()


@dataclass(frozen=True)
class Kind:
    """One rig kind: its data contract, its model and its virtual rig.

    Attributes
    ----------
    name : str
        The ``kind`` of experiment files.
    description : str
        One sentence for reports: the test, its thesis section and the models.
    required_columns, optional_columns : tuple of str
        Canonical CSV columns (``tcamlab.io.VARIABLE_MAP`` keys) a run must / may have.
    min_rows : int
        Fewest data rows a run needs to be fitted.
    inputs, outputs : tuple of str
        Internal (SI) columns the model reads and the columns it predicts.
    tension_outputs : tuple of str
        Outputs logged as a tension, positive when loaded (checked for the sign on reading).
    variants : mapping of str to dict
        Model variants validated -> extra ``predict`` options; the first is
        the primary model, the one thresholds apply to.
    predict : callable
        ``predict(sample, rig, data, mods=NO_MODS, **options) -> {quantity: ndarray}`` [SI].
    run_options : callable
        ``run_options(rig, data, training, label) -> RunOptions``: the one rule
        choosing S and R0 for a run, shared by validation, diagnosis and the
        virtual rig. ``training`` is a list of (DataFrame, row mask) the
        spring constant may be identified on (never the run's own rows).
    needs_training : bool
        Whether ``run_options`` identifies a constant from training data when
        the rig does not state it (sensing S).
    validation_extras : callable
        ``validation_extras(experiment, predictions, *, mc_draws, seed, call)
        -> (notes, extras)``: what validation adds for this kind (the dynamic
        Monte Carlo band, the sensing spring-constant table); ``call(run, fn,
        *args)`` runs a model and names the run in its errors.
    x_column : str
        Internal column the diagnosis plots residuals against.
    regimes : callable
        ``regimes(data, quantity, frames) -> {group: labels per row}``; ``frames``
        are all runs of the experiment (for bands over their pooled values).
    shared_inputs : tuple of str
        Inputs that set a row's operating point (runs agreeing on them are replicates).
    report_rig_fields : tuple of str
        Rig fields listed in the report's parameter table.
    figures : callable
        ``figures(result) -> list of report Figure`` for a ValidationResult.
    extras_section : callable
        ``extras_section(result) -> report Section or None``: the kind's own
        section of the validation report (from ``validation_extras``).
    preset : Preset
        The thesis preset of this rig's sample and rig.
    logged_columns : tuple of str
        Internal columns the virtual rig writes, in file order.
    decimals : mapping of str to int
        Decimals the virtual rig writes per canonical column.
    written_rig_fields : tuple of str
        Rig fields the virtual rig writes to its experiment file.
    hidden_rig_fields : tuple of str
        Rig fields the virtual rig never writes (sensing S: to be identified).
    default_runs : int
        Runs per simulated experiment.
    default_scatter : mapping of str to float
        SI field of Sample or Rig -> relative sd of the per-run scatter.
    noisy_inputs : tuple of str
        Logged inputs whose noise propagates into the model's outputs.
    strength_quantities : tuple of str or None
        Quantities an effect strength refers to (None: whichever the effect moves most).
    protocol : callable
        ``protocol(rig, rng, **options) -> DataFrame``: the exact programmed
        quantities of one virtual-rig run [SI, internal names].
    benchmark_program : mapping of str to Any
        Protocol options of the diagnosis benchmark's cases (static: the heat-cool oven, whose
        cooling branch separates drift and thermal lag from temperature-only effects).
    benchmark_pairs : tuple of (str, str)
        Representative pairs of this kind's effects for the benchmark's two-effect cases (one
        pair with distinct signatures, one more look-alike where the kind has one).
    benchmark_uncertainty : mapping of str to float
        SI field -> sd [SI] that the benchmark's lying null cases draw true parameters with
        where the template states no uncertainty (what a lab believes of its own values).
    program_options : tuple of str
        Keyword options ``protocol`` takes (static: ``oven``); the rig passes
        only these.
    exact_inputs : callable
        ``exact_inputs(sample, rig, proto, mods) -> DataFrame``: the exact
        input columns of ``predict`` for a protocol [SI].
    instrument_sd : callable
        ``instrument_sd(noise_scale) -> {column: sd}``: sd of each logged
        column's measurement chain [SI] (:mod:`tcamlab.instruments`).
    measure : callable
        ``measure(inputs, outputs, rng, noise_scale) -> DataFrame``: the
        logged columns [SI] from the exact inputs and model outputs.
    simulation_rig_defaults : mapping of str to Any
        Rig fields [SI] the virtual rig's default noise floor sets on top of
        the preset (sensing S, which the preset leaves to be identified).
    segment_rig_fields : tuple of str
        Rig fields holding one value per robot segment: a stated scalar
        scatters independently per segment (curvature R0).
    coil_length_rig_fields : tuple of str
        Rig length fields that scale with the sample's coil length when it
        scatters (curvature segment lengths: the sensor spans the segments).
    calibration : tuple of CalibrationParam
        The parameters ``tcamlab calibrate`` identifies from this kind's logs.
    nuisance_zeros : tuple of str
        Measured quantities whose zero (tare) is a per-run nuisance offset in
        calibration: the logged first row or tare carries the instrument's noise.
    run_reproducibility : mapping of str to float
        Sample field -> relative sd [-] of each run's departure from the shared value
        (re-mounting, annealing): calibration treats it as a per-run random effect
        (:mod:`tcamlab.calibration.problem`). Empty: runs share the sample exactly.
    fit_block : int
        Rows averaged into one residual by the fits of ``calibrate`` and ``diagnose``
        (:func:`tcamlab.signals.block_means`; 1: row by row). For a kind whose outputs are
        read from noisy inputs through a gain every parameter moves, so that a row-by-row fit
        gains by shrinking that gain (errors in variables).
    rest_rule : callable or None
        ``rest_rule(data) -> row indices`` at rest, for a kind whose rows need not come in
        time order (curvature: the rows at the smallest cable pull, wherever they are);
        None: the leading rows (:func:`rest_rows`).
    rest_also : tuple of str
        Logged columns besides the inputs that must also stay at their first value for a row
        to be at rest (:func:`rest_rows`): a pull test's displacement, which the machine
        drives, moves from the first row while the resistance is still within its noise.
    """

    name: str
    description: str
    required_columns: tuple[str, ...]
    optional_columns: tuple[str, ...]
    min_rows: int
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    tension_outputs: tuple[str, ...]
    variants: Mapping[str, Mapping[str, Any]]
    predict: Callable[..., dict]
    run_options: Callable[..., RunOptions]
    needs_training: bool
    validation_extras: Callable[..., tuple[list, dict]]
    x_column: str
    regimes: Callable[..., dict]
    shared_inputs: tuple[str, ...]
    report_rig_fields: tuple[str, ...]
    figures: Callable[..., list]
    extras_section: Callable[..., Any]
    preset: Preset
    logged_columns: tuple[str, ...]
    decimals: Mapping[str, int]
    written_rig_fields: tuple[str, ...]
    hidden_rig_fields: tuple[str, ...]
    default_runs: int
    default_scatter: Mapping[str, float]
    noisy_inputs: tuple[str, ...]
    strength_quantities: tuple[str, ...] | None
    protocol: Callable[..., pd.DataFrame]
    program_options: tuple[str, ...]
    benchmark_program: Mapping[str, Any]
    benchmark_pairs: tuple[tuple[str, str], ...]
    benchmark_uncertainty: Mapping[str, float]
    exact_inputs: Callable[..., pd.DataFrame]
    instrument_sd: Callable[..., dict]
    measure: Callable[..., pd.DataFrame]
    simulation_rig_defaults: Mapping[str, Any]
    segment_rig_fields: tuple[str, ...]
    coil_length_rig_fields: tuple[str, ...]
    calibration: tuple[CalibrationParam, ...]
    nuisance_zeros: tuple[str, ...]
    run_reproducibility: Mapping[str, float] = field(default_factory=dict)
    fit_block: int = 1
    rest_also: tuple[str, ...] = ()
    rest_rule: Callable[..., Any] | None = None

    @property
    def primary(self) -> str:
        """The primary model variant."""
        return next(iter(self.variants))


REST_TOLERANCE = 0.02
"""Inputs within this fraction of their range of the first row count as "at rest" (and within
:data:`REST_NOISE_SDS` of their noise, :func:`rest_tolerance`)."""

REST_NOISE_SDS = 8.0
"""An input moved once it is more than this many of its noise sds (robust, from second
differences) from the first row, or one step of its quantisation when that is larger: the
difference of two readings at rest has sd sqrt(2) sigma and stays within 5.7 of its sds in
all but about 1 of 10^8 rows. Without it a pull that starts at the first row, 38 um a row
over a 60 mm range, counted 33 moving rows as "at rest" and biased the R0 read from them."""


def no_extras(experiment, predictions, **_) -> tuple[list, dict]:
    """``validation_extras`` of a kind that adds nothing to its validation."""
    return [], {}


def no_section(result) -> None:
    """``extras_section`` of a kind whose validation report has no section of its own."""
    return None


def scored_quantities(kind: Kind, prediction: dict, frames, every: bool = True) -> tuple[str, ...]:
    """The quantities a fit scores: the kind's outputs, then every other column the model predicts
    that every run logs (the voltage-step test's ``temperature``, ``current``, ``resistance``),
    in the prediction's order. An input is never one, even where the model passes it through.

    Parameters
    ----------
    kind : Kind
    prediction : dict
        One run's prediction (its keys are what the model predicts).
    frames : sequence of DataFrame
        The runs' data, SI column names.
    every : bool
        True: a column every run logs; False: a column any run logs (each run is then scored on
        the columns it has, :meth:`tcamlab.diagnosis.problem.Problem.logs`).
    """
    has = all if every else any
    extra = [
        q
        for q in prediction
        if q not in kind.outputs and q not in kind.inputs and has(q in d for d in frames)
    ]
    return tuple(kind.outputs) + tuple(extra)


def step_rows(kind: Kind, data: pd.DataFrame):
    """Rows next to a step of a commanded input that is piecewise constant (the voltage of a
    voltage-step test; :func:`tcamlab.signals.step_rows`), which noise floors leave out: the
    residual jumps there by what the model misses of the step response. A measured input
    (:attr:`Kind.noisy_inputs`) changes by its noise and quantisation, and does not count.

    Parameters
    ----------
    kind : Kind
    data : DataFrame
        One run, SI column names.
    """
    from tcamlab import signals

    commanded = [c for c in kind.inputs if c != "time" and c not in kind.noisy_inputs and c in data]
    return signals.step_rows([data[c] for c in commanded])


STILL_NOISE_SDS = 12.0
"""An input whose whole range is within this many of its noise sds (robust, from second
differences) and within 5 % of its magnitude never moved: the range of a held 1.5 V probe
logged with 5 mV of noise over 2,000 rows is about 7 sds, and the 2 % rule on that range
found one row at rest in a self-sensing log that only probes."""


def _still(x, span: float) -> bool:
    import numpy as np

    from tcamlab.signals import robust_second_difference_sigma

    ok = x[np.isfinite(x)]
    if ok.size < 3 or not span > 0:
        return True
    sd = robust_second_difference_sigma(ok)
    return bool(span <= STILL_NOISE_SDS * sd and span <= 0.05 * float(np.max(np.abs(ok))))


def rest_tolerance(x, span: float) -> float:
    """Largest distance [x's unit] from the first row at which an input with range ``span`` is
    still at rest: :data:`REST_TOLERANCE` of the range, or :data:`REST_NOISE_SDS` noise sds (at
    least one quantisation step) when that is smaller."""
    import numpy as np

    from tcamlab.signals import robust_second_difference_sigma

    ok = np.asarray(x, float)
    ok = ok[np.isfinite(ok)]
    steps = np.abs(np.diff(ok))
    steps = steps[steps > 0]
    step = float(steps.min()) if steps.size else 0.0
    # the noise where the rest is: a log noisy at rest and exact after (a commanded pulse)
    # has no noise in most of its second differences
    sd = np.nanmax(
        [robust_second_difference_sigma(ok), robust_second_difference_sigma(ok[:REST_HEAD_ROWS]), 0.0]
    )
    return min(REST_TOLERANCE * span, max(REST_NOISE_SDS * sd, step))


REST_HEAD_ROWS = 50
"""Leading rows whose second differences also give an input's noise for :func:`rest_tolerance`."""


def rest_rows(kind: Kind, data: pd.DataFrame) -> np.ndarray:
    """Indices of the leading rows whose inputs stay at their first value.

    An input is at rest while it is within :func:`rest_tolerance` of the first row's value
    (2 % of its range, or 8 noise sds when smaller); time does not count, and the kind's
    ``rest_also`` columns count as inputs. An input that never moves (:func:`_still`)
    leaves every row at rest. At least the first row.
    """
    import numpy as np

    from tcamlab.errors import InputError

    if kind.rest_rule is not None:
        try:
            return kind.rest_rule(data)
        except InputError:
            pass  # no row at rest by the kind's rule: the leading rows, as for every kind
    first_move = len(data)
    for c in kind.inputs + kind.rest_also:
        if c == "time" or c not in data:
            continue
        x = data[c].to_numpy(float)
        span = float(np.nanmax(x) - np.nanmin(x))
        still = _still(x, span)
        moved = np.flatnonzero(np.abs(x - x[0]) > rest_tolerance(x, span)) if not still else np.array([], int)
        if moved.size:
            first_move = min(first_move, int(moved[0]))
    return np.arange(max(first_move, 1))


def rest_reading(kind: Kind, runs, columns) -> tuple[float, float] | None:
    """Mean of ``columns`` over every run's rows at rest (:func:`rest_rows`) and its sd [their unit].

    The sd of the mean counts runs, not rows: readings at rest vary from run to run
    (temperature, a re-mounted sensor) more than within a run, so it is the spread of the
    readings over the square root of the number of runs. A handful of readings
    underestimates a spread as often as not (six readings of a 2 mOhm meter spread 1 mOhm
    and made a stated R0 look 2.5 sds off), so the spread is at least the columns' own
    noise over the whole run (the robust sd of their second differences over sqrt(6),
    blind to the few kinks where a pull starts or turns; median over runs and columns)
    and at least their logging step over sqrt(12). None with fewer than two readings or a missing column.

    Parameters
    ----------
    kind : Kind
    runs : sequence of DataFrame
        The runs' logs [SI].
    columns : sequence of str
        Internal column names (e.g. ``("r1", "r2")``).
    """
    import numpy as np

    from tcamlab.io.quantisation import logging_step
    from tcamlab.signals import mad_scale

    values, steps, noise = [], [0.0], []
    for data in runs:
        if not all(c in data for c in columns):
            return None
        rows = rest_rows(kind, data)
        for c in columns:
            x = data[c].to_numpy(float)
            values.append(x[rows])
            steps.append((logging_step(x) or 0.0) / math.sqrt(12.0))
            d2 = np.diff(x[np.isfinite(x)], 2)
            noise.append(mad_scale(d2) / math.sqrt(6.0) if d2.size >= 3 else np.nan)
    x = np.concatenate(values) if values else np.array([])
    x = x[np.isfinite(x)]
    if x.size < 2:
        return None
    noise = [v for v in noise if np.isfinite(v)]
    floor = max(max(steps), float(np.median(noise)) if noise else 0.0)
    sd = max(float(np.std(x, ddof=1)), floor)
    if not sd > 0:
        return None
    return float(np.mean(x)), sd / math.sqrt(len(runs))


def stated_source(provenance, name: str) -> str:
    """Where a stated rig value came from, for reports: "experiment file", or the preset's
    provenance prefixed "preset" (a value the file does not state is not the file's)."""
    source = (provenance or {}).get(name, "experiment file")
    return (
        source if source == "experiment file" or source.startswith("tcamlab default") else f"preset: {source}"
    )


KINDS: tuple[str, ...] = ("static", "dynamic", "sensing", "curvature", "selfsensing")
"""The kinds of run tcamlab knows, in the order reports list them: the name of each is
the name of its module in this package, which defines ``KIND``. Registering a new rig
kind is adding its module and its name here."""

_LOADED: dict[str, Kind] = {}


def run_scatter(experiment) -> dict[str, float]:
    """{sample field: relative sd} a run may depart from the shared sample by: the file's
    ``[sample.run_to_run]``, else the kind's :attr:`Kind.run_reproducibility` (zeros dropped).
    Calibration and the diagnosis's gap test profile these departures out of each run."""
    stated = getattr(experiment, "run_to_run", None)
    scatter = get_kind(experiment.kind).run_reproducibility if stated is None else stated
    return {k: float(v) for k, v in dict(scatter).items() if v > 0}


def require_hanging_load(sample, rig, what: str, where: str = "", logged: bool = False) -> None:
    """Refuse a hanging load that does not outweigh the muscle: the dynamic model (2.19) and the
    self-sensing estimator take the load as the moving mass with the muscle's own neglected.

    Raises
    ------
    InputError
        ``rig.load`` [kg] not above 0, or, where the run does not log the load (``logged``
        False: the stated load is then the model's), not above the fiber's own mass
        (:func:`tcamlab.models.coil.fiber_mass`); the message names ``where`` (the experiment
        file) and ``what`` (the run's kind).
    """
    from tcamlab.errors import InputError
    from tcamlab.models.coil import fiber_mass

    own = float(fiber_mass(sample.fiber_diameter, sample.fiber_length))
    if rig.load > (0.0 if logged else own):
        return
    if logged:  # the logged load is the model's; load_g is only the first row's prior
        raise InputError(
            f"{where + ': ' if where else ''}{what} run: rig load_g = {rig.load * 1e3:g} g must be above 0 "
            "(with load_N logged it is the estimator's prior at the first row)",
            hint="set load_g in [rig] to the hanging load in grams, e.g. load_g = 50",
        )
    raise InputError(
        f"{where + ': ' if where else ''}{what} run: rig load_g = {rig.load * 1e3:g} g does not outweigh the "
        f"muscle itself (about {own * 1e3:.2g} g of fiber); the moving mass is the hanging load with the "
        "muscle's own mass neglected, so it must be heavier",
        hint="set load_g in [rig] to the hanging load in grams, e.g. load_g = 50",
    )


def get_kind(name: str) -> Kind:
    """The registered :class:`Kind` called ``name``; the one place an unknown kind fails.

    Kind modules are imported on first use, so listing :data:`KINDS` costs nothing.

    Raises
    ------
    ConfigError
        ``name`` is not a registered kind.
    """
    if not isinstance(name, str) or name not in KINDS:
        raise ConfigError(f"unknown kind {name!r}", hint="one of " + ", ".join(KINDS))
    if name not in _LOADED:
        kind = importlib.import_module(f"tcamlab.kinds.{name}").KIND
        if kind.name != name:
            raise ConfigError(f"tcamlab.kinds.{name} defines kind {kind.name!r}")
        _LOADED[name] = kind
    return _LOADED[name]


def __getattr__(attr: str):
    # REGISTRY is built on first access, like the kinds themselves.
    if attr == "REGISTRY":
        return {name: get_kind(name) for name in KINDS}
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


def predict(
    kind: str, sample: Sample, rig: Rig, data: pd.DataFrame, mods: Mods | None = None, **options
) -> dict:
    """Predict a run's measured columns with the model of ``kind`` (see the module table).

    Parameters
    ----------
    kind : str
        Registered kind.
    sample, rig :
        Sample and rig [SI].
    data : DataFrame
        The run's input columns [SI, internal names].
    mods : Mods, optional
        Effect terms (default, or all zero: the thesis model).
    **options
        The kind's per-run options (:attr:`Kind.run_options`, :attr:`Kind.variants`).
    """
    if mods is None:
        return get_kind(kind).predict(sample, rig, data, **options)
    return get_kind(kind).predict(sample, rig, data, mods, **options)
