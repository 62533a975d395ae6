"""Self-sensing powered run (thesis sec. 5.2 future work): displacement from V and I.

A TCA is heated by its own current under a hanging load; the rig logs
``time_s``, ``voltage_V``, ``current_A``, optionally ``load_N`` (the hanging
weight, when logged) and a reference laser ``displacement_mm`` used only to
validate. The prediction is the self-sensed displacement, made in one place,
:func:`predict_displacement` ("open-loop inversion"; the causal EKF of
:mod:`tcamlab.estimation.observer` is the estimator for live use and closed loop): R = V / I and P = V I from the logged channels; T from the electro-thermal
model (2.18) driven by P, starting at the steady temperature of the rest rows'
probe power; delta from inverting the combined model R(T, delta)
(:mod:`tcamlab.models.selfsensing`) at that T; the displacement is delta minus
the statics' rest extension ((2.10)-(2.11) at the rest temperature under the
first row's load: ``load_N`` when logged, else the rig's). Rows whose current is
below :data:`MIN_CURRENT_A` hold the last estimate (causal). It uses the load
only for that reference and never the laser, but it trusts the thermal model's T: an error
of 1 K reads as 0.36 % of R, about 150 um of displacement for the template's muscle.

R0 (``initial_resistance_ohm``) is chapter 3's: unloaded, at ambient. When the
file does not state it, it is the mean R of the rest rows divided by the model's
g(x_rest) and thermal factor at the rest temperature.

The virtual rig (:func:`exact_inputs`, :func:`measure`, and the program :func:`protocol` of
:mod:`tcamlab.kinds.selfsensing_protocol`) runs every protocol in one run: a quiet start at the probe
voltage, voltage steps, PWM, a sine and a chirp, with a rider put on the hanger
at a random time (the load changes, so the thermal model alone cannot predict
the displacement). The truth is :func:`tcamlab.rig.selfsensing.powered_run`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab import instruments
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConvergenceError, InputError, ModelDomainError
from tcamlab.kinds import CalibrationParam, Kind, RunOptions, require_hanging_load, rest_rows, stated_source
from tcamlab.kinds.selfsensing_protocol import (  # noqa: F401  (the program's names stay importable here)
    CHIRP_F0_HZ,
    CHIRP_F1_HZ,
    PROBE_V,
    PROGRAM_OPTIONS,
    PWM_DUTY,
    PWM_HZ,
    PWM_V,
    RATE_HZ,
    RIDER_KG,
    RIDER_WINDOW_S,
    SEGMENTS,
    SINE_AMP_V,
    SINE_HZ,
    SINE_MEAN_V,
    STEP_LEVELS_V,
    protocol,
)
from tcamlab.models import selfsensing as ssm
from tcamlab.models import static
from tcamlab.params import G_ACCEL, THESIS_TCA, Rig, Sample
from tcamlab.report.document import Figure, Section, Table
from tcamlab.report.figures import legend_label, new_figure

MIN_CURRENT_A = 1e-3
"""Below this current R = V / I is not read; the estimate is held [A]."""
CONTACT_ITERATIONS = 12
"""Secant steps that undo the inter-coil contact factor in the inversion."""

CURRENT_SD_A = instruments.CURRENT_SENSE_SD_A
"""Noise of the current-sense chain [A] (:data:`tcamlab.instruments.CURRENT_SENSE_SD_A`)."""
CURRENT_SPAN_A, CURRENT_BITS = instruments.CURRENT_SENSE_SPAN_A, instruments.CURRENT_SENSE_BITS
"""Span and resolution of the current ADC (:mod:`tcamlab.instruments`)."""
VOLTAGE_SD_V = 5e-3
"""Noise of the voltage divider and ADC input [V]."""
VOLTAGE_SPAN_V, VOLTAGE_BITS = 12.0, 12
"""Voltage ADC span and resolution: quantum 12 V / 4095 = 2.9 mV."""


def _quantise(x, span, bits):
    q = span / (2**bits - 1)
    return np.clip(np.round(np.asarray(x, float) / q), 0, 2**bits - 1) * q


def _rest_extension(sample: Sample, rig: Rig, temperature: float, mass: float) -> float:
    return float(static.displacement(temperature - rig.ambient, mass * G_ACCEL, **sample.model_kwargs()))


def _model_kwargs(sample: Sample, rig: Rig, r0: float, tcr: float) -> dict:
    return dict(
        initial_resistance=r0,
        reference_temperature=rig.ambient,
        tcr=tcr,
        radial_cte=sample.radial_cte,
        spring_constant=rig.spring_constant,
        **sample.sensor_kwargs(),
    )


def _readable(current: np.ndarray, what: str = "the run") -> np.ndarray:
    """Rows whose current reads R (:data:`MIN_CURRENT_A`); InputError when there is none."""
    ok = np.abs(current) >= MIN_CURRENT_A
    if not ok.any():
        raise InputError(
            f"selfsensing: no row of {what} carries {MIN_CURRENT_A * 1e3:g} mA or more, so R = V / I "
            "cannot be read",
            hint="keep a probe voltage on between heating phases, and check the current column's unit",
        )
    return ok


def _law_hint(rig: Rig, r0: float) -> str:
    """The hint of a resistance the law cannot invert: the [rig] values it was read with."""
    return (
        f"the muscle's R = V / I - R_lead is read with initial_resistance_ohm = {r0:.4g}, "
        f"lead_resistance_ohm = {rig.lead_resistance:g}, tcr_per_K = {rig.tcr:g}, tcr2_per_K2 = "
        f"{rig.tcr2:g} and stretch_factor = {rig.stretch_factor:g} in [rig]: check them, and the "
        "current column's unit"
    )


LEAD_SHARE_MAX = 0.5
"""Largest share of the logged V / I [-] the leads and contacts may take: beyond it the wires
would out-resist the muscle they feed (41.5 of 41.9 ohm left the coil 0.4 ohm, and the EKF
1.9e7 % of the stroke off)."""


def _check_lead(lead: float, r: np.ndarray) -> None:
    """ModelDomainError naming ``lead_resistance_ohm`` when the leads would take more than
    :data:`LEAD_SHARE_MAX` of the logged V / I [ohm] somewhere."""
    low = float(np.min(r)) if r.size else np.inf
    if lead > 0 and not lead <= LEAD_SHARE_MAX * low:
        raise ModelDomainError(
            f"selfsensing: rig lead_resistance_ohm = {lead:g} is more than {LEAD_SHARE_MAX:.0%} of the "
            f"logged V / I, as low as {low:.4g} ohm: the leads would out-resist the muscle",
            hint="R_lead is the leads' and contacts' share of V / I, a fraction of an ohm on most "
            "rigs (a four-wire reading gives it); e.g. lead_resistance_ohm = 0.3",
        )


def predict_displacement(
    sample: Sample, rig: Rig, data: pd.DataFrame, mods: Mods = NO_MODS, *, initial_resistance: float
) -> dict[str, np.ndarray]:
    """The self-sensed displacement and temperature of a run: open-loop inversion (module docstring).

    Parameters
    ----------
    data : DataFrame
        ``time`` [s], ``voltage`` [V], ``current`` [A].
    initial_resistance : float
        R0 of chapter 3 (unloaded, at ambient) [ohm].
    mods : Mods
        contact_slope, contact_onset, r0_drift, tcr_extra (undone in the inversion).

    Returns
    -------
    dict
        ``displacement`` [m] (from the statics' rest extension), ``temperature`` [degC].

    Raises
    ------
    InputError
        When no row carries the current needed to read R.
    """
    t = data["time"].to_numpy(float)
    v = data["voltage"].to_numpy(float)
    i = data["current"].to_numpy(float)
    ok = _readable(i)
    lead = rig.lead_resistance
    _check_lead(lead, v[ok] / i[ok])
    p = np.where(ok, v * i - lead * i * i, 0.0)  # only the muscle heats
    rest = rest_rows(KIND, data)
    t0 = ssm.rest_temperature(float(np.mean(p[rest])), rig.heat_loss, rig.ambient)
    temp = ssm.temperature_from_power(
        t, p, thermal_mass=rig.thermal_mass, heat_loss=rig.heat_loss, ambient=rig.ambient, initial=t0
    )
    r = np.where(ok, v / np.where(ok, i, 1.0), np.nan)
    r = (pd.Series(r).ffill().bfill().to_numpy() - lead) / (1.0 + mods.r0_drift * (t - t[0]))
    kw = _model_kwargs(sample, rig, initial_resistance, rig.tcr + mods.tcr_extra)
    r = linear_coating(r, temp - rig.ambient, kw["tcr"], rig.tcr2)
    try:
        delta = invert_muscle(r, temp, kw, rig.stretch_factor)
    except (ModelDomainError, ConvergenceError) as exc:
        raise type(exc)(f"selfsensing: {exc.message}", _law_hint(rig, initial_resistance)) from None
    # the model's rest extension, not the rest rows' mean of delta: that mean would cancel a
    # common error of R, hiding it from the noise floor and the nuisance zero alike
    mass = float(data["load"].iloc[0]) / G_ACCEL if "load" in data else rig.load
    x_rest = _rest_extension(sample, rig, t0, mass)
    if mods.contact_slope:
        delta = _undo_contact(r, temp, delta, x_rest, mods, kw, rig.stretch_factor)
    return {"displacement": delta - x_rest, "temperature": temp}


def linear_coating(r_muscle, rise, tcr: float, tcr2: float = 0.0) -> np.ndarray:
    """The muscle's R [ohm] as the linear law would give it at the same T and extension.

    R_muscle carries the coating factor 1 + TCR dT + tcr2 dT^2; chapter 3's inversion knows
    1 + TCR dT, so R is scaled by their ratio. ``rise`` dT = T - T_a [K], ``tcr`` [1/K],
    ``tcr2`` [1/K^2]; with ``tcr2`` 0 the readings come back unchanged (the same array).
    """
    if not tcr2:
        return r_muscle
    dT = np.asarray(rise, float)
    linear = 1.0 + tcr * dT
    bent = linear + tcr2 * dT * dT
    if np.any(bent <= 0):
        k = int(np.argmin(bent))
        raise ModelDomainError(
            f"selfsensing: rig tcr2_per_K2 = {tcr2:g} /K^2 with tcr_per_K = {tcr:g} /K leaves "
            f"the coating no resistance {float(dT.flat[k]):.1f} K above ambient (1 + TCR dT + "
            f"tcr2 dT^2 = {float(bent.flat[k]):.3g})",
            hint="tcr2_per_K2 is a small bend of R(T), |tcr2| dT^2 well below TCR dT "
            "(e.g. tcr2_per_K2 = 2e-6); check its sign and unit",
        )
    return np.asarray(r_muscle, float) * linear / bent


def invert_muscle(r_muscle, temperature, kw: dict, stretch_factor: float = 1.0) -> np.ndarray:
    """delta [m] from the muscle's R [ohm] (the leads' taken off) at T [degC], with k_s.

    The law R_muscle = R0 (1 + k_s (g - 1)) heat(T) is chapter 3's R0 g heat once R_muscle
    is mapped to R0 heat + (R_muscle - R0 heat) / k_s, which
    :func:`tcamlab.models.selfsensing.invert_displacement` inverts; ``kw`` as its keywords,
    ``stretch_factor`` k_s [-] (1: no mapping).
    """
    r = np.asarray(r_muscle, float)
    if stretch_factor != 1.0:
        heat = ssm.coating_factor(temperature, kw["reference_temperature"], kw["tcr"]) * ssm.swelling_factor(
            temperature, kw["reference_temperature"], kw["radial_cte"]
        )
        r0_heat = kw["initial_resistance"] * heat
        r = r0_heat + (r - r0_heat) / stretch_factor
    return ssm.invert_displacement(r, temperature, **kw)


def _undo_contact(r, temp, delta, x_rest, mods, kw, stretch_factor=1.0):
    """delta solving delta = F(delta) = invert(R / contact(delta)) row by row, by secant steps.

    R stays monotone in delta (contact lowers R as contraction does), but a plain
    fixed-point pass has the gain -contact_slope / (d ln g / d delta), beyond 1 in size
    for slopes above about 24 /m with the template's muscle, so the secant step is used;
    rows out of contact are already solved (F is constant there).
    """
    zero_t = np.zeros_like(delta)

    def phi(d):
        return d - invert_muscle(r / ssm.effect_factor(zero_t, x_rest - d, mods), temp, kw, stretch_factor)

    a, pa = delta, phi(delta)
    b = a - pa
    pb = phi(b)
    for _ in range(CONTACT_ITERATIONS):
        step = pb - pa
        live = np.abs(step) > 1e-15
        c = np.where(live, b - pb * (b - a) / np.where(live, step, 1.0), b)
        a, pa, b = b, pb, c
        pb = phi(b)
        if np.max(np.abs(pb)) < 1e-12:
            break
    return b


WITHHELD = "EKF (load withheld)"
"""The variant that runs the causal EKF with a logged ``load_N`` withheld (as if not logged)."""
LOGGED = "EKF (causal)"
"""The variant that runs the causal EKF with the load as a measurement where ``load_N`` is logged."""

ESTIMATORS = ("inversion", "ekf")
"""``predict``'s estimators: the open-loop inversion (primary) and the causal EKF."""


def predict(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    initial_resistance: float,
    estimator: str = "inversion",
    use_load: bool = True,
) -> dict[str, np.ndarray]:
    """Self-sensed displacement from voltage and current.

    ``estimator="inversion"`` (the primary model, :func:`predict_displacement`) is the
    open-loop inversion: the rig's effect strengths, the calibration and the diagnosis compare
    a model with the logs, and a filter's lag after an unannounced load step is not a model
    error. ``"ekf"`` is the causal EKF of :mod:`tcamlab.estimation.observer` (the load as a
    measurement where ``load_N`` is logged, else unknown), which ``validate`` reports beside
    it as the variant "EKF (causal)" (README "Self-sensing").

    ``mods``: contact_slope (inter-coil contact), r0_drift (R0 drift), tcr_extra
    (a TCR other than the stated one). ``use_load=False`` withholds a logged ``load`` [N]
    (the variant "EKF (load withheld)"): the run is read as if the column were not logged.
    """
    if not use_load and "load" in data:
        data = data.drop(columns=["load"])
    if estimator == "ekf":
        from tcamlab.estimation.observer import predict_displacement as ekf_displacement

        _readable(data["current"].to_numpy(float))  # the same one-line error as the inversion
        return ekf_displacement(
            sample,
            rig,
            data,
            mods,
            initial_resistance=initial_resistance,
            lead_resistance=rig.lead_resistance,
            stretch_factor=rig.stretch_factor,
            tcr2=rig.tcr2,
        )
    if estimator != "inversion":
        raise ValueError(f"selfsensing estimator {estimator!r}: one of {', '.join(ESTIMATORS)}")
    return predict_displacement(sample, rig, data, mods, initial_resistance=initial_resistance)


def initial_resistance(sample: Sample, rig: Rig, data: pd.DataFrame, provenance=None) -> tuple[float, str]:
    """R0 [ohm] (unloaded, at ambient) and its source: stated, else from the rest rows."""
    if rig.initial_resistance is not None:
        return float(rig.initial_resistance), stated_source(provenance, "initial_resistance")
    rows = rest_rows(KIND, data)
    v, i = data["voltage"].to_numpy(float)[rows], data["current"].to_numpy(float)[rows]
    ok = _readable(i, what="the rest rows")
    lead = rig.lead_resistance
    r_rest = float(np.mean(v[ok] / i[ok])) - lead
    t0 = ssm.rest_temperature(float(np.mean(v * i - lead * i * i)), rig.heat_loss, rig.ambient)
    mass = float(data["load"].iloc[0]) / G_ACCEL if "load" in data else rig.load
    x_rest = _rest_extension(sample, rig, t0, mass)
    unit = float(ssm.resistance(t0, x_rest, **_model_kwargs(sample, rig, 1.0, rig.tcr)))  # g heat
    heat = float(
        ssm.coating_factor(t0, rig.ambient, rig.tcr) * ssm.swelling_factor(t0, rig.ambient, sample.radial_cte)
    )
    unit = heat + rig.stretch_factor * (unit - heat)  # (1 + k_s (g - 1)) heat
    return r_rest / unit, f"(mean R of the {rows.size} rows at rest - R_lead) / model R/R0 there"


def run_options(
    sample: Sample, rig: Rig, data: pd.DataFrame, *, provenance=None, where="", **_
) -> RunOptions:
    """R0 of the run by the module's rule, with its source; ``where`` (the experiment file)
    prefixes the errors.

    Raises
    ------
    InputError
        Without a spring constant S: chapter 3's map from R to delta needs it; or without a
        hanging load: the estimator's moving mass is the load (the muscle's own is neglected).
    """
    at = f"{where}: " if where else ""
    require_hanging_load(sample, rig, "selfsensing", where, logged="load" in data.columns)
    _check_sampling(rig, data, at)
    if rig.spring_constant is None:
        raise InputError(
            f"{at}selfsensing run needs the muscle's spring constant S (chapter 3's R-to-delta map)",
            hint="set spring_constant_N_per_m in [rig] (tcamlab fit-spring on a pull test of the muscle)",
        )
    r0, source = initial_resistance(sample, rig, data, provenance)
    return RunOptions(
        # not "initial_resistance_ohm": validation's rest-row check compares that key with the
        # logged R at rest, and this R0 is the unloaded, cold one
        {"initial_resistance": r0},
        {"unloaded_resistance_ohm": r0, "unloaded_resistance_source": source},
    )


def _check_sampling(rig: Rig, data: pd.DataFrame, at: str) -> None:
    """Refuse a run whose rows are further apart than the muscle's thermal time constant
    C_th/lambda: the estimator cannot follow the temperature between them, and a time column
    in ms read as s (rows 10 s apart) kept the filter's sub-steps busy for minutes."""
    t = data["time"].to_numpy(float)
    if t.size < 2 or not (rig.thermal_mass > 0 and rig.heat_loss > 0):
        return
    step, tau = float(np.median(np.diff(t))), rig.thermal_mass / rig.heat_loss
    if step > tau:
        raise InputError(
            f"{at}selfsensing run: its rows are {step:.4g} s apart, longer than the muscle's thermal "
            f"time constant C_th/lambda = {tau:.3g} s: the estimator cannot follow the temperature "
            "between rows",
            hint='check the time column\'s unit in [columns], e.g. time_s = { from = "Time (ms)", unit = "ms" }, '
            "and thermal_mass_J_per_K and heat_loss_W_per_K in [rig] (the thesis muscle: 0.0266 and 0.00893)",
        )


def regimes(data: pd.DataFrame, quantity: str, frames=()) -> dict[str, np.ndarray]:
    """Drive of every row: heating (above twice the rest voltage) or probe."""
    v = data["voltage"].to_numpy(float)
    probe = float(np.median(v[rest_rows(KIND, data)]))
    return {"drive": np.where(v > 2.0 * max(probe, 1e-9), "heating", "probe").astype(object)}


def published_metrics(error, measured, stroke: float | None = None) -> dict[str, float]:
    """Mean error, sd and 95 % interval of the error, and the stroke, in mm (van der Weijde 2017's format).

    Parameters
    ----------
    error : ndarray
        Predicted - measured displacement [m] (finite rows).
    measured : ndarray
        Measured displacement [m] (its range is the stroke unless ``stroke`` is given).
    stroke : float, optional
        The stroke [m], the denominator of the percentages: for pooled runs the mean of
        the runs' own ranges (a range over runs would mix their zeros).
    """
    e = np.asarray(error, float) * 1e3
    lo, hi = np.percentile(e, [2.5, 97.5])
    stroke = (float(np.ptp(np.asarray(measured, float))) if stroke is None else float(stroke)) * 1e3
    return {
        "stroke_mm": stroke,
        "mean_error_mm": float(e.mean()),
        "sd_error_mm": float(e.std(ddof=1)) if e.size > 1 else float("nan"),
        "interval95_lo_mm": float(lo),
        "interval95_hi_mm": float(hi),
        "interval95_width_mm": float(hi - lo),
        "mean_error_of_stroke": float(e.mean() / stroke) if stroke else float("nan"),
        "interval95_of_stroke": float((hi - lo) / stroke) if stroke else float("nan"),
        "n": int(e.size),
    }


def _run_errors(p, variant: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(error [m], measured [m], stroke [m]) of one run and variant: error = self-sensed - laser
    after the run's zero; the stroke is the range of the measurement as logged (its zero added
    back) over the rows with an error."""
    m = p.data["displacement"].to_numpy(float)
    zero = getattr(p, "zeros", {}).get("displacement")
    logged = m + (zero.value if zero is not None and np.isfinite(zero.value) else 0.0)
    e = np.asarray(p.predicted[variant]["displacement"], float) - m
    ok = np.isfinite(e)
    return e, m, (float(np.ptp(logged[ok])) if ok.any() else float("nan"))


def _published(predictions, variant: str) -> dict:
    """{runs {name: published_metrics}, pooled} of one variant. Each run's stroke is the range
    of its measurement as logged (its zero added back); the pooled stroke is their mean."""
    runs, errs, meas, strokes = {}, [], [], []
    for p in predictions:
        e, m, stroke = _run_errors(p, variant)
        ok = np.isfinite(e)
        strokes.append(stroke)
        runs[p.name] = published_metrics(e[ok], m[ok], stroke)
        errs.append(e[ok])
        meas.append(m[ok])
    pooled = published_metrics(np.concatenate(errs), np.concatenate(meas), float(np.nanmean(strokes)))
    return {"runs": runs, "pooled": pooled}


LOAD_CHANGE_REL = 0.02
"""A logged load further than this fraction of its value at rest from it has changed [-]
(the rig's 5 g rider is 10 % of the 50 g load)."""
LOAD_CHANGE_MIN_N = 1e-3
"""... and further than this [N], so that a load cell's noise is not a change."""


def heating_only_rows(data: pd.DataFrame) -> tuple[int, str]:
    """Rows of a run's heating-only part, the leading rows before the first load change.

    With ``load`` logged [N]: the rows before the first one whose load is further than
    max(:data:`LOAD_CHANGE_REL` |F_rest|, :data:`LOAD_CHANGE_MIN_N`) from the median of the
    rows at rest. Without it (not logged, or ``--ignore load_N``) the change cannot be seen
    without the truth, so the part is the rows before the drive first falls back to the probe
    after its first heating phase (:func:`regimes`): rest and the first heating pulse, on
    which the load is assumed not to change (the rig's rider goes on 15-35 s into the run,
    after the steps). No change (or no heating pulse that ends): the whole run.

    Returns
    -------
    tuple of (int, str)
        The number of leading rows, and the rule that ended them, for the report.
    """
    n = len(data)
    t = data["time"].to_numpy(float)
    if "load" in data:
        f = data["load"].to_numpy(float)
        ref = float(np.nanmedian(f[rest_rows(KIND, data)]))
        tol = max(LOAD_CHANGE_REL * abs(ref), LOAD_CHANGE_MIN_N)
        moved = np.flatnonzero(np.isfinite(f) & (np.abs(f - ref) > tol))
        if not moved.size:
            return n, "no load change logged: the whole run"
        return int(moved[0]), f"the logged load_N changes at {t[moved[0]]:.2f} s"
    heating = regimes(data, "displacement")["drive"] == "heating"
    first = np.flatnonzero(heating)
    back = np.flatnonzero(~heating[first[0] :]) if first.size else np.array([], int)
    if not back.size:
        return n, "load not logged and no heating pulse ends: the whole run"
    k = int(first[0] + back[0])
    return k, f"load not logged: rest and the first heating pulse, to {t[k]:.2f} s"


PARTS = ("whole_run", "heating_only", "heating_only_own_stroke")
"""The parts of a run the estimator is scored on with the load logged and withheld: the whole
run and its heating-only part against the run's stroke, and the heating-only part against its
own stroke (the range of the laser over those rows: the thermal stroke, which a rider's step
does not inflate)."""
LOAD_CASES = {"load_logged": LOGGED, "load_withheld": WITHHELD}
"""Load case -> the EKF variant run in it."""


def _case_errors(p, variant: str, k: int) -> dict:
    """Part -> (finite error [m], measured [m], stroke [m]) of one run and variant."""
    e, m, stroke = _run_errors(p, variant)
    out = {}
    for part, rows in zip(PARTS, (slice(None), slice(0, k), slice(0, k))):
        ok = np.isfinite(e[rows])
        own = float(np.ptp(m[rows][ok])) if ok.sum() >= 2 else float("nan")
        out[part] = (e[rows][ok], m[rows][ok], own if part == "heating_only_own_stroke" else stroke)
    return out


def _cell(error, measured, stroke) -> dict | None:
    """published_metrics of one part, None with fewer than two rows."""
    return published_metrics(error, measured, stroke) if np.size(error) >= 2 else None


def estimator_without_help(predictions) -> dict:
    """The causal EKF with the load logged and withheld, over the whole run and its heating-only
    part (:func:`heating_only_rows`), per run and pooled, in the published format.

    The whole run and the heating-only part are against the run's whole stroke (the range of the
    laser displacement as logged), and the heating-only part once more against its own stroke
    (:data:`PARTS`); the pooled stroke is the mean of the runs' strokes, the pooled error the
    runs' errors together. A run that does not log ``load_N`` has no "load logged" case (None),
    and the pooled "load logged" case pools the runs that do.

    ``laser_at_rest`` is the reference's own floor: the 95 % interval of the laser over the runs'
    rest rows (each about its mean: the muscle is still there), and that width as a fraction of
    each case's and part's pooled stroke. No estimator's interval against this laser can be
    narrower; on a short part (the first pulse, 0.15 mm) it can be most of the interval.

    Returns
    -------
    dict
        ``runs`` {name: {logs_load, heating_only_rows, heating_only_rule, load_logged,
        load_withheld}}, ``pooled`` {load_logged, load_withheld}; each case {part:
        published_metrics or None}; ``laser_at_rest`` {interval95_width_mm, n, load_logged,
        load_withheld}, each case {part: width / pooled stroke} or None.
    """
    runs, pool = {}, {case: {part: [] for part in PARTS} for case in LOAD_CASES}
    at_rest = []
    for p in predictions:
        laser = p.data["displacement"].to_numpy(float)[rest_rows(KIND, p.data)]
        laser = laser[np.isfinite(laser)]
        if laser.size >= 2:  # one row about its own mean would read as a noiseless laser
            at_rest.append(laser - laser.mean())
        k, rule = heating_only_rows(p.data)
        t = p.data["time"].to_numpy(float)
        entry = {
            "logs_load": "load" in p.data,
            "heating_only_rows": k,
            "heating_only_until_s": float(t[k]) if k < t.size else None,
            "heating_only_rule": rule,
        }
        for case, variant in LOAD_CASES.items():
            if case == "load_logged" and not entry["logs_load"]:
                entry[case] = None
                continue
            errs = _case_errors(p, variant, k)
            entry[case] = {part: _cell(*errs[part]) for part in PARTS}
            for part in PARTS:
                pool[case][part].append(errs[part])
        runs[p.name] = entry
    pooled = {}
    for case, block in pool.items():
        if not block[PARTS[0]]:
            pooled[case] = None
            continue
        pooled[case] = {
            part: _cell(
                *(np.concatenate([x[i] for x in block[part]]) for i in (0, 1)),
                _mean_stroke([x[2] for x in block[part]]),
            )
            for part in PARTS
        }
    rest = np.concatenate(at_rest) if at_rest else np.array([])
    floor = _laser_floor(rest, pool)
    return {
        "runs": runs,
        "pooled": pooled,
        "laser_at_rest": floor,
        "beyond_laser": beyond_laser(pooled, floor),
    }


def beyond_laser(pooled: dict, floor: dict) -> dict:
    """The pooled 95 % intervals net of the laser's own: sqrt(I^2 - I_laser^2) per case and part
    [fraction of the stroke], or None where there is no floor or no cell.

    Why: the error is self-sensed minus laser, so its interval holds the laser's noise, and on a
    small stroke that noise is most of it (an independent generator's heating-only run: 11.2 %
    against a laser alone at 10.7 % of its 0.18 mm stroke). Where the estimator's error and the
    laser's noise are independent and near normal, widths add in quadrature; the net width is then
    the estimator's own (that run: 3.3 %, against 2.8 % measured on the generator's noise-free
    truth). An interval narrower than the floor (a correlated or non-normal noise) nets to 0.
    """
    out = {}
    for case, parts in pooled.items():
        cut = (floor or {}).get(case)
        if parts is None or not cut:
            out[case] = None
            continue
        out[case] = {
            part: (
                float(np.sqrt(max(parts[part]["interval95_of_stroke"] ** 2 - cut[part] ** 2, 0.0)))
                if parts.get(part) is not None and cut.get(part) is not None
                and np.isfinite(parts[part]["interval95_of_stroke"])
                else None
            )
            for part in PARTS
        }  # fmt: skip
    return out


def _mean_stroke(strokes) -> float:
    """Mean of the runs' strokes [m], NaN where none is finite (an estimator with no finite row)."""
    s = np.asarray(strokes, float)
    return float(np.mean(s[np.isfinite(s)])) if np.isfinite(s).any() else float("nan")


FLOOR_MIN_ROWS = 40
"""Fewest rest rows (all runs) the laser's 95 % interval at rest is read on: with fewer, its 2.5 %
and 97.5 % percentiles are the extreme rows themselves."""


def _laser_floor(rest: np.ndarray, pool: dict) -> dict:
    """The laser's 95 % interval at rest [mm] and as a fraction of each pooled stroke."""
    if rest.size < FLOOR_MIN_ROWS:  # too few rest rows to read a 95 % interval on: no floor
        return {"interval95_width_mm": None, "n": int(rest.size), **dict.fromkeys(pool)}
    lo, hi = np.percentile(rest, [2.5, 97.5])
    width = float(hi - lo)
    out = {"interval95_width_mm": width * 1e3, "n": int(rest.size)}
    for case, block in pool.items():
        strokes = {part: _mean_stroke([x[2] for x in block[part]]) if block[part] else 0.0 for part in PARTS}
        out[case] = (
            {part: width / st if st > 0 else None for part, st in strokes.items()}
            if block[PARTS[0]]
            else None
        )
    return out


def validation_extras(experiment, predictions, **_) -> tuple[list, dict]:
    """The published format per run and pooled, for every estimator: mean error and 95 %
    interval over the stroke (``published_format`` is the primary's)."""
    by_variant = {v: _published(predictions, v) for v in KIND.variants}
    notes = []
    for v, info in by_variant.items():
        pooled = info["pooled"]
        notes.append(
            f"{v}, pooled: mean error {pooled['mean_error_mm']:.3g} mm, 95% interval "
            f"{pooled['interval95_width_mm']:.3g} mm over a {pooled['stroke_mm']:.3g} mm stroke "
            f"({100 * pooled['interval95_of_stroke']:.3g}%); published inductive self-sensing: -0.27 mm, "
            "2.14 mm over 10-30 mm (van der Weijde et al. 2017)"
        )
    notes += _stated_load_notes(experiment, predictions)
    extras = {
        "warnings": off_target_warnings(by_variant, predictions),
        "published_format": by_variant[KIND.primary],
        "published_format_by_estimator": by_variant,
        "ekf_with_and_without_load": estimator_without_help(predictions),
    }
    return notes, extras


ESTIMATOR_TARGETS = {LOGGED: (0.02, 0.10), WITHHELD: (0.03, 0.15)}
"""Largest |mean error| and 95 % interval width, as fractions of a run's own stroke, of each
estimator with the load logged and withheld: the targets its benchmark holds it to
(bench/bench_selfsensing_calibrated.py), from the 7-21 % of inductive self-sensing
(van der Weijde et al. 2017). A run beyond them is a warning, not a pass."""


def off_target_warnings(by_variant: dict, predictions) -> list:
    """An ``estimator-off-target`` warning per run and estimator beyond
    :data:`ESTIMATOR_TARGETS` (the logged-load one only on runs that log the load)."""
    from tcamlab.metrics import SanityWarning

    logged = {p.name for p in predictions if "load" in p.data}
    out = []
    for variant, (mean_max, width_max) in ESTIMATOR_TARGETS.items():
        for run, m in (by_variant.get(variant) or {}).get("runs", {}).items():
            mean, width = m["mean_error_of_stroke"], m["interval95_of_stroke"]
            if (variant == LOGGED and run not in logged) or not (abs(mean) > mean_max or width > width_max):
                continue
            msg = (
                f"{variant}: {run}: mean error {100 * mean:+.3g} %, 95 % interval {100 * width:.3g} % of "
                f"its {m['stroke_mm']:.3g} mm stroke, beyond the estimator's targets "
                f"({100 * mean_max:g} % and {100 * width_max:g} %)"
            )
            values = {"mean_of_stroke": mean, "interval95_of_stroke": width, "model": variant}
            out.append(SanityWarning("estimator-off-target", msg, "displacement_mm", run, values))
    return out


STATED_LOAD_TOLERANCE = 0.05
"""A run whose logged load at rest differs from ``load_g`` by more than this fraction (and 3 mN)
is noted: the EKF with the load withheld starts from ``load_g``, so its figures carry that
prior's error (a file stating 60 g beside a logged 50 g put the withheld estimate 0.9 mm off)."""


def _stated_load_notes(experiment, predictions) -> list[str]:
    """A note per run whose logged load at rest is not the stated ``load_g``, and one when no run
    logs the load and the file states none (the preset's or tcamlab's load is then used)."""
    stated = experiment.rig.load * G_ACCEL
    out = []
    for p in predictions:
        if "load" not in p.data:
            continue
        logged = float(np.median(p.data["load"].to_numpy(float)[rest_rows(KIND, p.data)]))
        if abs(logged - stated) > max(STATED_LOAD_TOLERANCE * stated, 3e-3):
            out.append(
                f"{p.name}: the logged load at rest is {logged:.4g} N ({logged / G_ACCEL * 1e3:.4g} g) but "
                f"[rig] load_g = {experiment.rig.load * 1e3:g} g; the EKF with the load withheld starts "
                "from load_g, so its figures on this run include that difference (set load_g to the load at rest "
                "where it is known, or read them as a test of a wrong prior)"
            )
    in_file = "load_g" in ((getattr(experiment, "raw", None) or {}).get("rig") or {})
    if not in_file and not any("load" in p.data for p in predictions):
        out.append(
            f"no run logs the load and the file states no load_g: the EKF's load prior and moving mass "
            f"are {experiment.rig.load * 1e3:g} g from the preset or tcamlab's default (state load_g in "
            "[rig] as the load hung at the start)"
        )
    return out


def figures(result) -> list[Figure]:
    """Both traces against time; the error against time and against displacement."""
    figs = []
    fig, ax = new_figure()
    for p in result.predictions:
        t, name = p.data["time"].to_numpy(), legend_label(p.name)
        (line,) = ax.plot(t, p.data["displacement"] * 1e3, ".", ms=1, label=f"{name} laser")
        ax.plot(
            t,
            p.predicted[KIND.primary]["displacement"] * 1e3,
            "-",
            color=line.get_color(),
            lw=0.8,
            label=f"{name} self-sensed",
        )
        ekf = p.predicted.get("EKF (causal)")
        if ekf is not None:
            ax.plot(t, ekf["displacement"] * 1e3, "--", color=line.get_color(), lw=0.8, label=f"{name} EKF")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement [mm]")
    # upper left: the muscle rests there before its load and heating raise it ("best" put the
    # legend over the traces)
    ax.legend(fontsize=6, ncol=1, loc="upper left")
    figs.append(
        Figure(
            fig,
            "Displacement against time: laser (points), self-sensed by the open-loop inversion "
            "(line) and by the causal EKF (dashed).",
            alt="self-sensing traces",
        )
    )
    for x_name, label in (("time", "time [s]"), ("displacement", "laser displacement [mm]")):
        fig, ax = new_figure()
        for p in result.predictions:
            x = p.data[x_name].to_numpy() * (1e3 if x_name == "displacement" else 1.0)
            e = (p.predicted[KIND.primary]["displacement"] - p.data["displacement"].to_numpy()) * 1e3
            ax.plot(x, e, ".", ms=1, label=legend_label(p.name))
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_xlabel(label)
        ax.set_ylabel("error (self-sensed - laser) [mm]")
        ax.legend(fontsize=6)
        figs.append(
            Figure(fig, f"Self-sensing error against {label.split(' [')[0]}.", alt=f"error against {x_name}")
        )
    return figs + [f for f in (without_help_figure(result),) if f is not None]


def without_help_figure(result) -> Figure | None:
    """The causal EKF's error against time with the load withheld (solid) and logged (dotted),
    a vertical line where each run's heating-only part ends; None without the two variants."""
    preds = [p for p in result.predictions if WITHHELD in p.predicted and LOGGED in p.predicted]
    if not preds:
        return None
    fig, ax = new_figure()
    for p in preds:
        t, name = p.data["time"].to_numpy(float), legend_label(p.name)
        m = p.data["displacement"].to_numpy(float)
        (line,) = ax.plot(t, (p.predicted[WITHHELD]["displacement"] - m) * 1e3, "-", lw=0.9, zorder=3)
        line.set_label(f"{name} load withheld")
        if "load" in p.data:
            e = (p.predicted[LOGGED]["displacement"] - m) * 1e3
            ax.plot(t, e, ":", color=line.get_color(), lw=1.0, zorder=2, label=f"{name} load logged")
        k, _ = heating_only_rows(p.data)
        if k < t.size:
            ax.axvline(t[k], color=line.get_color(), lw=0.6, ls="--", zorder=1)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("EKF error (self-sensed - laser) [mm]")
    ax.legend(fontsize=6, ncol=2)
    return Figure(
        fig,
        "Error of the causal EKF against time, with the load withheld (solid) and logged (dotted); "
        "each dashed vertical line ends that run's heating-only part (table in \"Self-sensing error "
        'in the published format").',
        alt="EKF error with the load logged and withheld",
    )


def _pair(cell: dict | None) -> str:
    """``"-0.21 % / 1.25 %"``: mean error / 95 % interval, both as % of the stroke, each number
    held to its % by a no-break space (a narrow table column breaks there otherwise); "–" without
    rows."""
    if cell is None:
        return "–"
    return f"{cell['mean_error_of_stroke']:+.2%} / {cell['interval95_of_stroke']:.2%}".replace("%", "\u00a0%")


def _floor_cell(case: dict | None, part: str) -> str:
    """``"– / 1.10 %"``: a width as % of the part's pooled stroke, with no mean (the laser's own
    95 % interval at rest, or a pooled interval net of it: :func:`beyond_laser`)."""
    if not case or case.get(part) is None:
        return "–"
    return f"– / {case[part]:.2%}".replace("%", "\u00a0%")


def _part_label(entry: dict) -> str:
    """Where a run's heating-only part ends, short: ``to 23.4 s (load_N)``, ``whole run``."""
    until = entry["heating_only_until_s"]
    if until is None:
        return "whole run"
    return f"to {until:.1f} s ({'load_N' if entry['logs_load'] else 'first pulse'})"


def without_help_table(info: dict) -> Table:
    """The EKF with the load logged and withheld, whole run and heating-only, per run and pooled."""
    rows = []
    for name, entry in info["runs"].items():
        logged = entry["load_logged"]
        cells = [_pair(logged[p]) if logged else "not logged" for p in PARTS]
        rows.append([name, *cells, *(_pair(entry["load_withheld"][p]) for p in PARTS), _part_label(entry)])
    pooled = info["pooled"]
    rows.append(
        [
            "pooled",
            *(_pair(pooled["load_logged"][p]) if pooled["load_logged"] else "not logged" for p in PARTS),
            *(_pair(pooled["load_withheld"][p]) for p in PARTS),
            "",
        ]
    )
    floor = info.get("laser_at_rest")
    if floor and floor["interval95_width_mm"] is not None:
        rows.append(
            [
                "laser alone at rest",
                *(_floor_cell(floor["load_logged"], p) for p in PARTS),
                *(_floor_cell(floor["load_withheld"], p) for p in PARTS),
                f"{floor['interval95_width_mm'] * 1e3:.1f}\u00a0um over {floor['n']} rest rows",
            ]
        )
        net = info.get("beyond_laser") or {}
        rows.append(
            [
                "pooled, beyond the laser's noise",
                *(_floor_cell(net.get("load_logged"), p) for p in PARTS),
                *(_floor_cell(net.get("load_withheld"), p) for p in PARTS),
                "sqrt(interval^2 - laser's^2)",
            ]
        )
    parts = ("whole run", "heating only", "heating only, own stroke")
    head = [
        "run",
        *(f"load logged: {p}" for p in parts),
        *(f"load withheld: {p}" for p in parts),
        "heating-only part",
    ]
    return Table(
        head,
        rows,
        caption="Causal EKF, mean error / 95 % interval of the error, both as % of the run's stroke "
        "(last of each three: of the heating-only part's own stroke)",
    )


WITHOUT_HELP_TEXT = (
    "What the estimator does without help: the causal EKF run twice on each run that logs "
    "load_N, with the load as a measurement (load logged) and as if the column were not logged "
    "(load withheld; the load is then a random walk with a jump detector). Each cell is the mean "
    "error / the 95 % interval (2.5 % to 97.5 % percentile) of the error, both as % of the run's "
    "stroke (the range of its laser displacement; pooled: the runs' errors together over the mean "
    "of their strokes), and for the heating-only part once more as % of that part's own stroke "
    "(the thermal stroke, which a rider's step does not inflate). Heating only: the rows before the first load change, found from the logged "
    "load_N (a change of more than 2 % of the load at rest, at least 1 mN); without a logged load, "
    "the rest and the first heating pulse (to the first row back at the probe), on which the load is "
    "assumed not to change. A run that does not log load_N (or with --ignore load_N) has no load-"
    "logged case. The row of the laser alone is its 95 % interval over the runs' rest rows, where "
    "the muscle is still, as % of each column's pooled stroke. No estimator's interval against this "
    "laser can be narrower; where a cell is close to it, the laser's noise, not the estimator, sets "
    "that cell. The row under it takes the laser's noise out of the pooled interval, "
    "sqrt(interval^2 - laser's^2) (widths of independent, near-normal errors add in quadrature): "
    "the estimator's own interval, the figure to hold against a target where the laser row is close "
    "to the target itself."
)
"""The paragraph over the report's table of the EKF with the load logged and withheld."""


def extras_section(result) -> Section | None:
    """The EKF with the load logged and withheld (:func:`without_help_table`), then the
    published-format table of every estimator (per run and pooled)."""
    info = result.extras.get("published_format")
    if not info:
        return None
    keys = (
        "stroke_mm",
        "mean_error_mm",
        "interval95_lo_mm",
        "interval95_hi_mm",
        "interval95_width_mm",
        "mean_error_of_stroke",
        "interval95_of_stroke",
        "n",
    )
    by_estimator = result.extras.get("published_format_by_estimator") or {KIND.primary: info}
    rows = [
        [f"{name} ({v})", *(m[k] for k in keys)]
        for v, block in by_estimator.items()
        for name, m in {**block["runs"], "pooled": block["pooled"]}.items()
    ]
    head = [
        "run",
        "stroke [mm]",
        "mean error [mm]",
        "2.5 % [mm]",
        "97.5 % [mm]",
        "95 % interval [mm]",
        "mean / stroke",
        "interval / stroke",
        "rows",
    ]
    help_info = result.extras.get("ekf_with_and_without_load")
    return Section(
        "Self-sensing error in the published format",
        paragraphs=([WITHOUT_HELP_TEXT] if help_info else [])
        + [
            "Error = self-sensed - laser displacement (after the run's zero). The 95 % interval is "
            "from the 2.5 % to the 97.5 % percentile of the error; the stroke is each run's range of the "
            "laser displacement as logged (pooled: the mean of the runs' ranges). Published inductive self-sensing (van der Weijde et al., Soft "
            "Robotics 2017): mean -0.27 mm, 95 % interval 2.14 mm over 10-30 mm. Three estimators: "
            "the open-loop inversion (the primary model) and the causal EKF with the load logged and "
            "withheld; the EKF also lags after an unannounced load change (it is counted, not hidden)."
        ],
        tables=([without_help_table(help_info)] if help_info else [])
        + [Table(head, rows, caption="Self-sensing error per run and pooled")],
    )


# --- virtual rig ---------------------------------------------------------------------------


def exact_inputs(
    sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS, *, law=None
) -> pd.DataFrame:
    """The exact logged inputs and the true displacement of a powered run.

    :func:`tcamlab.rig.selfsensing.powered_run` with the rig's true R0, S and TCR
    and the effects in ``mods`` (they act on the true R); ``law``, a
    :class:`tcamlab.rig.selfsensing.ResistanceLaw`, makes the true R a law other than
    tcamlab's (SYNTHETIC: leads, a quadratic TCR, another stretch sensitivity).

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``voltage`` [V], ``current`` [A], ``load`` [N] (the
        hanging weight), and ``true_displacement`` [m] from the first row, which
        the laser of :func:`measure` reads (never an input of the model).
    """
    t = proto["time"].to_numpy(float)
    v = proto["voltage"].to_numpy(float)
    mass = proto["load_mass"].to_numpy(float)
    from tcamlab.rig.selfsensing import TCAMLAB_LAW, powered_run  # the rig package imports the registry

    run = powered_run(sample, rig, t, v, mass, mods, law=law or TCAMLAB_LAW)
    return pd.DataFrame(
        {
            "time": t,
            "voltage": v,
            "current": run.current,
            "load": mass * G_ACCEL,
            "true_displacement": run.extension - run.rest_extension,
        }
    )


def instrument_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of each logged column's chain [SI]: ADC noise and quantisation, the laser; time and load exact."""
    qv = VOLTAGE_SPAN_V / (2**VOLTAGE_BITS - 1)
    qi = CURRENT_SPAN_A / (2**CURRENT_BITS - 1)
    return {
        "time": 0.0,
        "voltage": float(np.hypot(VOLTAGE_SD_V * noise_scale, qv / np.sqrt(12))),
        "current": float(np.hypot(CURRENT_SD_A * noise_scale, qi / np.sqrt(12))),
        "load": 0.0,
        "displacement": instruments.laser_sd(noise_scale),
    }


def measure(
    inputs: pd.DataFrame, outputs: dict, rng: np.random.Generator, noise_scale: float, *, noisy_zero=False
) -> pd.DataFrame:
    """Logged ``time``, ``voltage`` and ``current`` (ADCs), ``load`` (exact), ``displacement`` (laser).

    The laser reads the true displacement of :func:`exact_inputs` (the model's
    ``outputs`` are self-sensed, not measured); ``noisy_zero`` as the dynamic kind.
    """
    v = inputs["voltage"].to_numpy(float)
    i = inputs["current"].to_numpy(float)
    v_log = _quantise(v + rng.normal(0.0, VOLTAGE_SD_V * noise_scale, v.size), VOLTAGE_SPAN_V, VOLTAGE_BITS)
    i_log = _quantise(i + rng.normal(0.0, CURRENT_SD_A * noise_scale, i.size), CURRENT_SPAN_A, CURRENT_BITS)
    truth = inputs["true_displacement"] if "true_displacement" in inputs else outputs["displacement"]
    disp, zero = instruments.laser_zeroed(np.asarray(truth, float), rng, noise_scale, noisy_zero=noisy_zero)
    out = pd.DataFrame(
        {
            "time": inputs["time"].to_numpy(float),
            "voltage": v_log,
            "current": i_log,
            "load": inputs["load"].to_numpy(float),
            "displacement": disp,
        }
    )
    out.attrs["zero_error"] = {"displacement": zero}
    return out


RIG_FIELDS = (
    "load",
    "ambient",
    "thermal_mass",
    "heat_loss",
    "damping",
    "initial_resistance",
    "spring_constant",
    "tcr",
)
"""Rig fields of the powered run: shown in the report and written by the virtual rig."""

REPORT_RIG_FIELDS = (*RIG_FIELDS, "lead_resistance", "stretch_factor")
"""Rig fields shown in the report: :data:`RIG_FIELDS` and the resistance law's two nuisances
(the virtual rig writes neither: its law is tcamlab's unless a ``law`` is given)."""

LEAD_ZERO_SD = 0.3
"""Prior sd of R_lead [ohm] where the file states 0 (tcamlab's law) and no sd: real rigs'
leads and contacts are 0.2-0.5 ohm, so 0.3 ohm reaches them within two sd. For a linear
coordinate (value / prior sd, as rho in the static kind): 0 is a legitimate statement and a
logarithm is undefined there. The calibration's box is six prior sds about the stated value,
so R_lead can be fitted below 0, which loading refuses (:data:`LAW_CALIBRATION`)."""
STRETCH_DEFAULT_SD = 0.2
"""Relative prior sd of k_s without a stated sd [-]: 0.2 about the stated value (1:
chapter 3's map), fitted as its logarithm (k_s > 0: R rises with stretch); a muscle whose
stretch sensitivity differs from chapter 3's by 20 % is typical of the sensing fits."""

FIT_BLOCK = 16
"""Rows (0.16 s at 100 Hz, against a thermal time constant of seconds) averaged into one
residual by the fits of ``calibrate`` and ``diagnose`` (:attr:`tcamlab.kinds.Kind.fit_block`).
The displacement is read from V / I, whose noise is almost all of the residual's, through a gain
that R0, the TCR and the thermal constants all move: fitted row by row on three runs of
tcamlab's own law with every parameter at its true value, R0 came out 23.80 ohm (95 % 23.77 to
23.83) against 24.0, a smaller gain buying a smaller noise, and the diagnosis named a
resistance drift that was not there."""

TCR2_ZERO_SD = 2e-6
"""Prior sd of the coating's quadratic TCR [1/K^2] where the file states none: a silver
coating's R(T) bends by a few 1e-7 to 1e-6 /K^2, and a law that is not exactly tcamlab's linear
one is the normal case (a 3.6e-6 /K^2 bend left out put the EKF's mean 2.2 % of the stroke
off; fitted about 0 +- 2e-6 it was 0.1 %). Fitted by both stages of ``calibrate``."""

CALIBRATION = (
    CalibrationParam("initial_resistance", "rig", "R0", "ohm", 0.05, "R of the unloaded muscle at ambient"),
    CalibrationParam("tcr", "rig", "TCR", "1/K", 0.1, "an oven test of R against temperature, unloaded"),
    CalibrationParam(
        "tcr2",
        "rig",
        "TCR2",
        "1/K^2",
        1.0,
        "an oven test of R against temperature over the whole working range, unloaded (the bend of R(T))",
        positive=False,
        zero_sd=TCR2_ZERO_SD,
    ),
    CalibrationParam(
        "thermal_mass",
        "rig",
        "C_th",
        "J/K",
        0.5,
        "a logged temperature during a pulse (heating rate P / C_th)",
    ),
    CalibrationParam(
        "heat_loss",
        "rig",
        "lambda",
        "W/K",
        0.5,
        "a logged temperature at steady state (T - T_a = P / lambda)",
    ),
    CalibrationParam(
        "damping",
        "rig",
        "b",
        "N s/m",
        0.3,
        "a load step logged faster than b/k; the open-loop inversion does not use b, the estimator does",
    ),
)
"""Calibratable parameters of the powered run (R0, the TCR and the thermal constants set the
open-loop inversion, with the coating's quadratic TCR about 0 +- :data:`TCR2_ZERO_SD` unless the
file states it; b enters once the estimator models the mechanics). R_lead and k_s are
used as stated: see :data:`LAW_CALIBRATION`)."""

LAW_CALIBRATION = (
    CalibrationParam(
        "lead_resistance",
        "rig",
        "R_lead",
        "ohm",
        1.0,
        "a four-wire reading across the muscle alone, or R of the leads shorted at the muscle's ends",
        positive=False,
        zero_sd=LEAD_ZERO_SD,
    ),
    CalibrationParam(
        "stretch_factor",
        "rig",
        "k_s",
        "-",
        STRETCH_DEFAULT_SD,
        "a pull test of the unheated muscle with R logged (R against extension at ambient)",
    ),
)
"""The resistance law's nuisances as calibration parameters, kept out of :data:`CALIBRATION`.

On synthetic runs of the virtual rig's law (bench/bench_observer.py's draw) the fit took
R_lead to the box's edge below 0 (a calibrated file that loading refuses) and k_s to 0.4-1.7
against a truth of 0.85 (k_s is fixed only together with R0, r = -1.00); on a run with a
true resistance drift the verdict went from attributed to aliased. Neither stopped the
diagnosis from naming an effect on law runs without drift. ``calibrate``'s second stage fits
them through the EKF instead, bounded and held where not identified
(:mod:`tcamlab.calibration.estimator`)."""


KIND = Kind(
    name="selfsensing",
    description="self-sensing powered run (thesis sec. 5.2): displacement from voltage and "
    "current through the combined model R(T, delta) (chapter 3 x silver TCR x swelling (2.8)) and the "
    "electro-thermal model (2.18), against a reference laser",
    required_columns=("time_s", "voltage_V", "current_A", "displacement_mm"),
    optional_columns=("load_N", "resistance_ohm", "temperature_C"),
    min_rows=10,
    inputs=("time", "voltage", "current"),
    outputs=("displacement",),
    tension_outputs=(),
    variants={
        "open-loop inversion": {},
        "EKF (causal)": {"estimator": "ekf"},
        WITHHELD: {"estimator": "ekf", "use_load": False},
    },
    predict=predict,
    run_options=run_options,
    needs_training=False,
    validation_extras=validation_extras,
    x_column="time",
    regimes=regimes,
    shared_inputs=("voltage",),
    report_rig_fields=REPORT_RIG_FIELDS,
    figures=figures,
    extras_section=extras_section,
    preset=THESIS_TCA,
    logged_columns=("time", "voltage", "current", "load", "displacement"),
    decimals={"time_s": 3, "voltage_V": 4, "current_A": 6, "load_N": 6, "displacement_mm": 3},
    written_rig_fields=RIG_FIELDS,
    hidden_rig_fields=(),
    default_runs=3,
    default_scatter={"twists": 2e-3, "coil_length": 2e-3},
    noisy_inputs=("voltage", "current"),
    strength_quantities=("displacement",),
    protocol=protocol,
    benchmark_program={},
    benchmark_uncertainty={},
    benchmark_pairs=(("inter-coil-contact", "coating-tcr"),),
    program_options=PROGRAM_OPTIONS,
    exact_inputs=exact_inputs,
    instrument_sd=instrument_sd,
    measure=measure,
    simulation_rig_defaults={"initial_resistance": 24.0, "spring_constant": 2.5},
    segment_rig_fields=(),
    coil_length_rig_fields=(),
    calibration=CALIBRATION,
    nuisance_zeros=("displacement",),
    fit_block=FIT_BLOCK,
)
