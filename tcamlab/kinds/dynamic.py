"""Dynamic voltage-step test (thesis section 2.5.2): displacement against time.

The model is (2.14)-(2.19): the electro-thermal balance (2.18) heats the
actuator, whose mass-spring-damper follows the static force (2.15). Effect
terms of :class:`tcamlab.effects.Mods` that act here: shear_slope_extra, coil_shear_slope,
resistance_tc, heat_loss_tc, delay. Validation adds a band for the measured
points (:mod:`tcamlab.band`): a prediction band from a calibrated file's joint
posterior (``[calibration]``), else a stated-uncertainty band from the stated sds.

The virtual rig's voltage step (:func:`protocol`, :func:`measure`): a pulse
from the template's rig after a quiet baseline, logged at 100 Hz by the
Arduino with the laser chain of :mod:`tcamlab.instruments`.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from tcamlab import band, instruments
from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ConfigError, ModelDomainError
from tcamlab.kinds import CalibrationParam, Kind, RunOptions, require_hanging_load
from tcamlab.kinds import protocol_values as pv
from tcamlab.kinds.static import RHO_ZERO_SD, SLOPE_ZERO_SD
from tcamlab.models import dynamic as _dyn
from tcamlab.params import G_ACCEL, THESIS_TCA, Rig, Sample
from tcamlab.report.document import Figure, Section, Table
from tcamlab.report.figures import draw_band, legend_label, new_figure
from tcamlab.signals import second_difference_sigma

COOLING_WINDOW_S = 3.0
"""Rows up to this long after a pulse ends are labelled "cooling" by the diagnosis [s]."""

PULSE_START_S = 0.5
"""Quiet baseline before the pulse [s]; voltage and duration come from the rig
(10 V for 1 s in the thesis)."""
DYNAMIC_RATE_HZ = 100
"""Arduino logging rate [Hz]."""
DYNAMIC_DURATION_S = 10.0
"""Length of a run [s], long enough to see most of the cooling."""
TIMING_JITTER_PROB = 0.03
"""Chance that the loop runs 1 ms early or late; the logged ``millis()`` is of the
actual sample, so the logged time is exact."""


def predict(
    sample: Sample,
    rig: Rig,
    data: pd.DataFrame,
    mods: Mods = NO_MODS,
    *,
    constant_g: bool = False,
    method: str = _dyn.METHOD,
) -> dict[str, np.ndarray]:
    """Voltage-step test: displacement (and temperature) against time.

    Parameters
    ----------
    data : DataFrame
        ``time`` [s], ``voltage`` [V].
    mods : Mods
        shear_slope_extra, coil_shear_slope, resistance_tc, heat_loss_tc, delay.

    Returns
    -------
    dict
        ``displacement`` [m] (zero at the first row), ``temperature`` [degC], ``current``
        [A] (V / R(T)) and ``resistance`` [ohm] (R(T)); calibration compares the last three
        with the logs where logged.
    """
    t = data["time"].to_numpy(float)
    v = data["voltage"].to_numpy(float)
    kw = sample.model_kwargs()
    kw["shear_modulus_slope"] = (0.0 if constant_g else kw["shear_modulus_slope"]) + mods.shear_slope_extra
    res = _dyn.response(
        t,
        v,
        load=run_load(rig, data),
        damping=rig.damping,
        thermal_mass=rig.thermal_mass,
        heat_loss=rig.heat_loss,
        resistance=rig.resistance,
        ambient=rig.ambient,
        # the rig's stated (or calibrated) beta plus the effect library's, if any
        resistance_tc=rig.heater_tcr + mods.resistance_tc,
        heat_loss_tc=mods.heat_loss_tc,
        coil_shear_slope=mods.coil_shear_slope,
        method=method,
        **kw,
    )
    disp, temp = res.displacement, res.temperature
    if mods.delay:
        # The laser's record lags the logged voltage (its response time and the logger's
        # sampling, thesis 2.5.2: one Arduino drives the MC33926 and samples the laser; the
        # driver switches in microseconds). The heating is not delayed, so neither are the
        # temperature and the current. Shift the output, not the held input: continuous in the
        # delay, so fits work.
        disp = np.interp(t - mods.delay, t, disp, left=0.0)
    # R(T) = R (1 + beta (T - T_a)) as in (2.18), beta the rig's plus the effect's; I = V / R(T)
    resistance = rig.resistance * (1.0 + (rig.heater_tcr + mods.resistance_tc) * (temp - rig.ambient))
    return {"displacement": disp, "temperature": temp, "current": v / resistance, "resistance": resistance}


def run_load(rig: Rig, data: pd.DataFrame) -> float:
    """The hanging mass of a run [kg]: the mean of its logged ``load`` [N] over g (a run made at
    another load than the stated one, a designed protocol's ``loads_g``), else the rig's. The
    model takes one load per run: the weight hangs still through the pulse."""
    if "load" not in data:
        return float(rig.load)
    force = data["load"].to_numpy(float)
    mean = float(np.mean(force[np.isfinite(force)]))
    if not mean > 0:
        # said in the logged column's words, not as the model's mass in kg
        raise ModelDomainError(
            f"dynamic model: the logged load_N averages {mean:g} N; a hanging load pulls, so it must be positive",
            "log the hanging weight in newtons (m g), or leave load_N out to use the rig's load_g",
        )
    return mean / G_ACCEL


def run_options(sample: Sample, rig: Rig, data: pd.DataFrame, *, where="", **_) -> RunOptions:
    """The dynamic model needs no per-run constant beyond the sample and the rig; its moving
    mass is the hanging load, so a load of 0 is refused naming the key (``where``, the
    experiment file, prefixes the error)."""
    require_hanging_load(sample, rig, "dynamic", where, logged="load" in data.columns)
    return RunOptions()


def regimes(data: pd.DataFrame, quantity: str, frames=()) -> dict[str, np.ndarray]:
    """Phase of every row: heating (voltage on), cooling (3 s after a pulse) or steady."""
    n = len(data)
    t = data["time"].to_numpy(float)
    v = data["voltage"].to_numpy(float)
    on = np.abs(v) > 0.01 * max(np.abs(v).max(), 1e-12)
    lab = np.full(n, "steady", dtype=object)
    lab[on] = "heating"
    if on.any():
        ends = np.flatnonzero(on[:-1] & ~on[1:]) + 1
        for e in ends:
            m = (~on) & (t >= t[e - 1]) & (t <= t[e - 1] + COOLING_WINDOW_S)
            m[:e] = False
            lab[m] = "cooling"
    return {"phase": lab}


def parameter_distribution(experiment):
    """The distribution the band draws from, or None without any uncertainty.

    A calibrated file's ``[calibration]`` (joint, :func:`tcamlab.band.from_calibration`);
    otherwise the stated sds of ``[rig.uncertainty]`` (fields of
    :data:`tcamlab.models.dynamic.MC_PARAMS`) and ``[sample.uncertainty]``, independent.
    """
    sample, rig = experiment.sample, experiment.rig
    joint = experiment.calibration
    if joint is not None:
        values = {f: getattr(sample if f[0] == "sample" else rig, f[1]) for f in joint.fields}
        return band.from_calibration(joint, values)
    stated = {
        ("rig", k): (float(getattr(rig, k)), float(sd))
        for k, sd in rig.uncertainty.items()
        if k in _dyn.MC_PARAMS
    }
    stated |= {
        ("sample", k): (float(getattr(sample, k)), float(sd))
        for k, sd in experiment.sample_uncertainty.items()
        if k in _DRAWN_SAMPLE
    }
    return band.from_stated(stated)


_DRAWN_SAMPLE = tuple(k for k in Sample.__dataclass_fields__ if k != "thread_plies")
"""Sample fields the band can draw (the kernel takes every one but the ply count)."""


def _drawable(field: tuple[str, str]) -> bool:
    where, name = field
    return name in _dyn.MC_PARAMS if where == "rig" else name in _DRAWN_SAMPLE


def _rest_rows(t: np.ndarray, v: np.ndarray, zeroing_row: bool) -> np.ndarray:
    """Rows before the voltage first comes on, without the zeroing row."""
    on = np.abs(v) > 0.01 * max(np.abs(v).max(), 1e-12)
    first = int(np.argmax(on)) if on.any() else t.size
    rest = np.arange(t.size) < first
    rest[0] &= not zeroing_row
    return rest


def _run_zero(prediction, meas, pred, t, v, sigma: float, zero_sd: float | None):
    """The band's zero shift, the run's zero shown, its sd, its rows and whether row 0 is the
    zeroing row [m]. Where validation already estimated and subtracted the zero
    (``prediction.zeros``), the shift is 0 and its standard error is the sd; else the
    zero is the mean residual of the rest rows (:func:`tcamlab.band.rest_zero`)."""
    est = (getattr(prediction, "zeros", None) or {}).get("displacement")
    if est is None:
        zeroing_row = bool(meas[0] == 0.0)
        zero, sd, n = band.rest_zero(meas - pred, _rest_rows(t, v, zeroing_row), sigma, zero_sd)
        return zero, zero, sd, n, zeroing_row
    # the logged row 0 is data + zero: exactly 0 when the log was zeroed on it
    zeroing_row = bool(meas[0] + est.value == 0.0)
    if zero_sd is None:
        zero_sd = float(est.stderr) if math.isfinite(est.stderr) else sigma
    return 0.0, float(est.value), float(zero_sd), int(est.rows), zeroing_row


def run_band(experiment, prediction, dist, *, draws: int, seed: int, call, zero_sd: float | None = None):
    """The band of one run on its rows, and its summary (lengths [m] in the band, mm in the summary).

    ``call(fn, *args, **kwargs)`` runs a model and names the run in its errors.
    ``zero_sd`` [m]: sd of the run's zero when estimated elsewhere (default: the standard
    error of the zero validation subtracted, ``prediction.zeros["displacement"]``, else
    from the rest rows, :func:`tcamlab.band.rest_zero`). Returns (None, summary) when
    every draw left the model's domain.
    """
    data = prediction.data
    t, v = data["time"].to_numpy(float), data["voltage"].to_numpy(float)
    meas = data["displacement"].to_numpy(float)
    pred = prediction.predicted[KIND.primary]["displacement"]
    idx, decimated = band.band_grid(t, v, band.MAX_GRID_POINTS)
    draws = band.draws_for(float(t[-1] - t[0]), draws)
    values = dist.draw(draws, np.random.default_rng(seed))
    kernel = {f[1]: x for f, x in values.items() if _drawable(f)}
    mc = call(_dyn.monte_carlo, t[idx], v[idx], experiment.sample, experiment.rig, draws=kernel)
    sigma = second_difference_sigma(meas - pred)
    zero, shown, zero_sd, n_rest, zeroing_row = _run_zero(prediction, meas, pred, t, v, sigma, zero_sd)
    spread = math.hypot(sigma, zero_sd)
    summary = {
        "draws": draws,
        "out_of_range": mc.n_invalid,
        "noise_sd_mm": sigma * 1e3,
        "zero_mm": shown * 1e3,
        "zero_sd_mm": zero_sd * 1e3,
        "rest_rows": n_rest,
        "grid_points": int(idx.size),
        "decimated": decimated,
    }
    if mc.displacement.shape[0] == 0:
        return None, summary
    lo, hi = (np.interp(t, t[idx], q) for q in band.mixture_interval(mc.displacement + zero, spread))
    plo, phi = band.parameter_interval(mc.displacement)
    counted = np.ones(t.size, bool)
    counted[0] = not zeroing_row
    informative = band.informative_rows(np.interp(t, t[idx], (phi - plo) / 2), spread) & counted
    summary |= {
        "rows": int(counted.sum()),
        "coverage": band.coverage(meas, lo, hi, counted),
        "informative_rows": int(informative.sum()),
        "coverage_informative": band.coverage(meas, lo, hi, informative),
    }
    centre = np.interp(t, t[idx], np.median(mc.displacement, axis=0)) + zero
    return {"lower": lo, "median": centre, "upper": hi}, summary


def _band_note(name: str, label: str, s: dict, requested: int) -> str:
    inf = (
        f"{s['coverage_informative']:.3f} over {s['informative_rows']} informative rows"
        if s["informative_rows"]
        else "no informative rows (the parameter part stays below half the noise part)"
    )
    grid = (
        f"; computed on a decimated grid of {s['grid_points']} rows and interpolated"
        if s["decimated"]
        else ""
    )
    if s["draws"] < requested:
        grid += f"; {s['draws']} draws instead of {requested} on this long log (integration budget)"
    return f"{name}: {label} covers {s['coverage']:.3f} of {s['rows']} measured points; {inf}{grid}"


def validation_extras(experiment, predictions, *, mc_draws: int, seed: int, call) -> tuple[list, dict]:
    """Attach the band to every run; notes and the ``prediction_band`` extras."""
    dist = parameter_distribution(experiment) if mc_draws else None
    if dist is None:
        why = (
            "--mc-draws 0" if not mc_draws else "no [rig.uncertainty], [sample.uncertainty] or [calibration]"
        )
        return [f"{why}: no band drawn"], {}
    label = band.band_label(dist.calibrated)
    notes, summary = [], {}
    for p in predictions:
        b, info = run_band(
            experiment,
            p,
            dist,
            draws=mc_draws,
            seed=seed,
            call=lambda fn, *a, _n=p.name, **k: call(_n, fn, *a, **k),
        )
        summary[p.name] = info
        if info["out_of_range"]:
            notes.append(
                f"{p.name}: {info['out_of_range']} of {info['draws']} draws left the model's domain "
                f"(e.g. past the G_t' > 0 limit of eq. (2.13)) and were left out of the band"
            )
        if b is None:
            continue
        p.band = b
        notes.append(_band_note(p.name, label, info, mc_draws))
    held = [".".join(f) for f in dist.fields if not _drawable(f)]
    return notes, {
        "prediction_band": {
            "label": label,
            "calibrated": dist.calibrated,
            "nominal": band.NOMINAL,
            "distribution": dist.description,
            "parameters": [".".join(f) for f in dist.fields if _drawable(f)],
            "held_at_value": held,
            "noise": "noise floor (second differences of the residuals) and the run's zero "
            "(the mean residual of the rest rows before the pulse, or validation's estimate)",
            "informative_rows": f"rows where the parameter part's half-width is at least "
            f"{band.INFORMATIVE_RATIO:g} x the noise part's",
            "runs": summary,
        }
    }


def figures(result) -> list[Figure]:
    """Displacement against time with the band (labelled as what it is), as thesis figure 2.9."""
    fig, ax = new_figure()
    info = result.extras.get("prediction_band") or {}
    label = info.get("label")
    for p in result.predictions:
        if p.band is not None:
            # one grey band per run under the points; one legend entry for all of them
            t = p.data["time"].to_numpy()
            draw_band(
                ax, t, p.band["lower"] * 1e3, p.band["upper"] * 1e3, label=label, color="0.55", alpha=0.3
            )
            label = None
    for p in result.predictions:
        t = p.data["time"].to_numpy()
        name = legend_label(p.name)
        (line,) = ax.plot(t, p.data["displacement"] * 1e3, ".", ms=1.5, label=f"{name} measured")
        ax.plot(
            t,
            p.predicted["G(T)"]["displacement"] * 1e3,
            "-",
            color=line.get_color(),
            lw=1,
            label=f"{name} model",
        )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement [mm]")
    ax.legend(fontsize=6, ncol=2)
    return [Figure(fig, _figure_caption(info), alt="dynamic plot")]


def _figure_caption(info: dict) -> str:
    text = "Displacement against time under the voltage pulse: measured (points), model (line)"
    if not info:
        return text + ", as in thesis figure 2.9."
    what = (
        "for measured points: calibrated parameters drawn jointly, noise and the run's zero"
        if info["calibrated"]
        else "drawn from the stated sds independently, plus noise and the run's zero; the "
        "parameters are not calibrated, so this is not a prediction band"
    )
    grid = (
        " Computed on a decimated grid and interpolated."
        if any(r.get("decimated") for r in info["runs"].values())
        else ""
    )
    return f"{text} and {info['label']} (grey, one per run; {what}), as in thesis figure 2.9.{grid}"


def extras_section(result) -> Section | None:
    """The band's label, distribution and coverage per run, as a report section."""
    info = result.extras.get("prediction_band")
    if not info:
        return None
    rows = [
        [
            name,
            s["draws"],
            s["out_of_range"],
            f"{s['noise_sd_mm']:.4g}",
            f"{s['zero_mm']:.4g} ± {s['zero_sd_mm']:.2g}",
            s.get("rows", "-"),
            _fmt_cov(s.get("coverage")),
            s.get("informative_rows", "-"),
            _fmt_cov(s.get("coverage_informative")),
            f"{s['grid_points']} (decimated)" if s["decimated"] else f"{s['grid_points']} (every row)",
        ]
        for name, s in info["runs"].items()
    ]
    paragraphs = [
        f"{info['label'][0].upper()}{info['label'][1:]}, nominal {info['nominal']:.0%}. Parameters drawn: "
        f"{', '.join(info['parameters']) or 'none'} ({info['distribution']}); plus {info['noise']}.",
        f"Coverage counts every measured row but the zeroing row (logged as exactly 0); informative "
        f"rows are the {info['informative_rows']}. Elsewhere the band is the noise band and covers "
        f"about {info['nominal']:.0%} whatever the parameters.",
    ]
    if info["held_at_value"]:
        paragraphs.append(
            "Held at their values (the model cannot draw them): " + ", ".join(info["held_at_value"])
        )
    if not info["calibrated"]:
        paragraphs.append(
            "The parameters are not calibrated: the band draws the stated sds independently, so it is "
            "a stated-uncertainty band, not a prediction band, and its coverage is no test of the "
            "model. Run tcamlab calibrate and validate the NAME.calibrated.toml it writes."
        )
    head = [
        "run",
        "draws",
        "out of range",
        "noise sd [mm]",
        "zero [mm]",
        "rows",
        "coverage",
        "informative rows",
        "coverage (informative)",
        "grid rows",
    ]
    return Section(
        info["label"][0].upper() + info["label"][1:],
        paragraphs=paragraphs,
        tables=[Table(head, rows, caption=f"{info['label']} per run")],
    )


def _fmt_cov(x) -> str:
    return "-" if x is None else f"{x:.3f}"


# --- virtual rig ---------------------------------------------------------------------------


SECOND_VOLTAGE_FACTOR = 0.8
"""The second condition of a two-condition experiment (:data:`tcamlab.kinds.CONDITIONS`): the
step at 0.8 x the stated voltage (0.64 x the power). A temperature rise that scales with V^2
tells a resistance or heat loss that changes with temperature, or a coil that softens with
it, from a constant C_th, lambda or G_t slope set wrong."""


def protocol(
    rig: Rig,
    rng: np.random.Generator,
    *,
    condition: int | None = None,
    voltage_V: float | None = None,
    pulse_s: float | None = None,
    pulses: int = 1,
    period_s: float | None = None,
    duration_s: float | None = None,
    load_N: float | None = None,
) -> pd.DataFrame:
    """The exact voltage step of one run.

    Parameters
    ----------
    rig : Rig
        ``voltage`` [V] and ``pulse`` [s] of the step.
    rng : numpy.random.Generator
        Draws the timing jitter of each sample (:data:`TIMING_JITTER_PROB`).
    condition : {None, 0, 1}
        1: the step at :data:`SECOND_VOLTAGE_FACTOR` times the stated voltage.
    voltage_V, pulse_s : float, optional
        This run's step voltage [V] and pulse length [s] (a designed protocol's); default the rig's.
    pulses : int
        Pulses in a train, each ``period_s`` [s] after the last (default 2 x the pulse + 2 s).
    duration_s : float, optional
        Logged duration [s] (default :data:`DYNAMIC_DURATION_S`, longer for a train).
    load_N : float, optional
        This run's hanging weight [N], logged as ``load`` (a designed protocol's ``loads_g``);
        default the rig's, not logged.

    Returns
    -------
    pandas.DataFrame
        ``time`` [s] (integer ms of the actual samples), ``voltage`` [V] (as commanded), and
        ``load`` [N] with ``load_N``.
    """
    pulse = float(rig.pulse if pulse_s is None else pulse_s)
    period = 2.0 * pulse + 2.0 if period_s is None else float(period_s)
    train_end = PULSE_START_S + (int(pulses) - 1) * period + pulse
    duration = duration_s or max(DYNAMIC_DURATION_S, train_end + DYNAMIC_DURATION_S - PULSE_START_S - 1.0)
    n = int(round(duration * DYNAMIC_RATE_HZ))
    period_ms = int(round(1000 / DYNAMIC_RATE_HZ))
    u = rng.random(n)
    jitter = np.where(u < TIMING_JITTER_PROB / 2, -1, np.where(u > 1 - TIMING_JITTER_PROB / 2, 1, 0))
    jitter[0] = 0
    ms = np.arange(n) * period_ms + jitter
    nominal = np.arange(n) / DYNAMIC_RATE_HZ
    # The pulse is on the nominal grid; the 1e-9 s keeps float steps off its edges.
    on = np.zeros(n, bool)
    for j in range(int(pulses)):
        t0 = PULSE_START_S + j * period
        on |= (nominal >= t0 - 1e-9) & (nominal < t0 + pulse - 1e-9)
    level = float(rig.voltage) * (SECOND_VOLTAGE_FACTOR if condition else 1.0)
    level = level if voltage_V is None else float(voltage_V)
    volt = np.where(on, round(level, 3), 0.0)
    out = pd.DataFrame({"time": ms / 1000.0, "voltage": volt})
    if load_N is not None:
        out["load"] = float(load_N)
    return out


PROTOCOL_KEYS = (
    "kind",
    "voltages_V",
    "loads_g",
    "pulse_s",
    "pulses",
    "period_s",
    "duration_s",
    "runs",
    "channels",
)
"""Keys of a dynamic ``[protocol]`` table (docs/design.md)."""

MAX_PULSES = 100
"""Most pulses in one run's train."""

DESIGN_LOAD_FACTOR = 2.0
"""The design menu's second hanging load, times the stated one: the coil's own compliance
scales with the load and the untwisting torque does not, so a G(T) that softens the coil
(``shear-modulus-temperature``) parts from a recalibrated G_t slope there."""

RUN_OVERHEAD_S = 120.0
"""Rig time per run beyond its logged duration [s]: the coil cools back to ambient."""


def protocol_runs(table: dict, rig: Rig) -> list[dict]:
    """Each run's :func:`protocol` options from a ``[protocol]`` table (docs/design.md): runs
    cycle through ``voltages_V`` (the rig's voltage when absent), each with the table's
    pulse, train and duration."""
    unknown = sorted(set(table) - set(PROTOCOL_KEYS))
    if unknown:
        raise ConfigError(
            f"[protocol]: unknown key {unknown[0]!r}", "allowed keys: " + ", ".join(PROTOCOL_KEYS)
        )
    volts = pv.positive_list(table, "voltages_V", [rig.voltage], "e.g. voltages_V = [10.0, 8.0]")
    grams = (
        pv.positive_list(table, "loads_g", [], "e.g. loads_g = [50.0, 100.0]") if "loads_g" in table else []
    )
    loads = [g * 1e-3 * G_ACCEL for g in grams]
    n = pv.runs(table, max(len(volts), len(loads)))
    common = {
        "pulse_s": pv.bounded(
            table, "pulse_s", rig.pulse, 2.0 / DYNAMIC_RATE_HZ, MAX_DURATION_S, "e.g. pulse_s = 1.0"
        ),
        "pulses": pv.whole(table, "pulses", 1, MAX_PULSES, "e.g. pulses = 3"),
    }
    _train_timing(table, common)
    pv.channels(table, LOGGED, KIND.required_columns, list(KIND.required_columns), "the voltage-step rig")
    out = [{"voltage_V": volts[k % len(volts)], **common} for k in range(n)]
    for k, run in enumerate(out if loads else ()):
        run["load_N"] = loads[k % len(loads)]
    return out


MAX_DURATION_S = 3600.0
"""Longest logged run of a ``[protocol]`` table [s]: an hour at 100 Hz, 360,000 rows."""


def _train_timing(table: dict, common: dict) -> None:
    """``period_s`` and ``duration_s`` of the table into ``common``, refused where the pulses
    of a train would overlap or the log would end before the last pulse does."""
    pulse, pulses = common["pulse_s"], common["pulses"]
    if "period_s" in table:
        common["period_s"] = pv.bounded(table, "period_s", 0.0, 0.0, MAX_DURATION_S, "e.g. period_s = 4.0")
        if pulses > 1 and not common["period_s"] > pulse:
            raise ConfigError(
                f"[protocol]: period_s = {common['period_s']:g} is not longer than pulse_s = {pulse:g}: "
                "the train's pulses would merge into one (the default period is twice the pulse plus 2 s)",
                f"e.g. period_s = {2.0 * pulse + 2.0:g}",
            )
    period = common.get("period_s", 2.0 * pulse + 2.0)
    end = PULSE_START_S + (pulses - 1) * period + pulse
    pv.run_length(end, "pulses and period_s", "e.g. pulses = 3 with period_s = 4.0")
    if "duration_s" in table:
        common["duration_s"] = pv.bounded(
            table, "duration_s", 0.0, 0.0, MAX_DURATION_S, "e.g. duration_s = 10.0"
        )
        if not common["duration_s"] >= end + 1.0 / DYNAMIC_RATE_HZ:
            raise ConfigError(
                f"[protocol]: duration_s = {common['duration_s']:g} ends before the last pulse does "
                f"({end:g} s after the log starts; without duration_s the log runs long enough)",
                f"e.g. duration_s = {np.ceil(end + DYNAMIC_DURATION_S - PULSE_START_S):g}",
            )


def design_menu(sample: Sample, rig: Rig) -> list[tuple[str, dict]]:
    """Candidate protocols of a voltage-step test [(name, ``[protocol]`` table)]: the thesis's
    step repeated, a second voltage (0.8 x, 1.2 x), a shorter (0.5 x) or longer (2 x) pulse,
    a train of three pulses; then the step repeated logging the current (:data:`EXTRA_CHANNELS`:
    I = V / R(T) shows a resistance that changes with temperature, which the displacement
    confuses with a heat loss that does), the same at a second voltage 0.8 x, and the step
    repeated logging the temperature. Two runs per voltage; a channel adds no run."""
    v0, p0 = round(float(rig.voltage), 3), round(float(rig.pulse), 3)
    base = {
        "kind": "dynamic",
        "voltages_V": [v0],
        "pulse_s": p0,
        "pulses": 1,
        "runs": 2,
        "channels": ["time_s", "voltage_V", "displacement_mm"],
    }
    menu = [("repeat (same protocol)", base)]
    for f in (0.8, 1.2):
        menu.append((f"second voltage {f:g}x", {**base, "voltages_V": [v0, round(f * v0, 3)], "runs": 4}))
    menu.append(("shorter pulse 0.5x", {**base, "pulse_s": round(0.5 * p0, 3)}))
    menu.append(("longer pulse 2x", {**base, "pulse_s": round(2.0 * p0, 3)}))
    menu.append(("pulse train of 3", {**base, "pulses": 3, "period_s": round(2.0 * p0 + 2.0, 3)}))
    g0 = round(float(rig.load) * 1e3, 3)
    loads = {"loads_g": [g0, round(DESIGN_LOAD_FACTOR * g0, 3)], "runs": 4}
    menu.append(
        (f"second load {DESIGN_LOAD_FACTOR:g}x", {**base, **loads, "channels": [*base["channels"], "load_N"]})
    )
    return menu + _logging_menu(base, v0)


def _logging_menu(base: dict, v0: float) -> list[tuple[str, dict]]:
    """The protocols of :func:`design_menu` that log a channel beyond the displacement
    (:data:`EXTRA_CHANNELS`): the same runs, the same rig time."""
    current = {**base, "channels": [*base["channels"], "current_A"]}
    second = [v0, round(SECOND_VOLTAGE_FACTOR * v0, 3)]
    return [
        ("log the current", current),
        (
            f"log the current, second voltage {SECOND_VOLTAGE_FACTOR:g}x",
            {**current, "voltages_V": second, "runs": 4},
        ),
        ("log the temperature", {**base, "channels": [*base["channels"], "temperature_C"]}),
    ]


def exact_inputs(sample: Sample, rig: Rig, proto: pd.DataFrame, mods: Mods = NO_MODS) -> pd.DataFrame:
    """The model's exact inputs: the voltage step itself (``time`` [s], ``voltage`` [V])."""
    return proto.copy()


def instrument_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of each logged column's chain [SI]: time and commanded voltage exact, the hanging load
    of a run made at a second load exact (a known weight), laser."""
    return {"time": 0.0, "voltage": 0.0, "load": 0.0, "displacement": instruments.laser_sd(noise_scale)}


def channel_sd(noise_scale: float = 1.0) -> dict[str, float]:
    """Sd of the chains a protocol's ``channels`` add (:data:`EXTRA_CHANNELS`) [SI]: the current
    sense [A] and the thermometer [degC]."""
    return {
        "current": instruments.current_sense_sd(noise_scale),
        "temperature": instruments.thermometer_sd(noise_scale),
    }


EXTRA_CHANNELS = {"current_A": "current", "temperature_C": "temperature"}
"""Columns a ``[protocol]`` table's ``channels`` may add to a voltage-step run -> the model's
prediction each logs: the actuator's current (a sense resistor beside the supply) and its
temperature (a thermocouple on the coil)."""


def stated_voltage_warning(rig, runs) -> str | None:
    """A warning when the stated step voltage (``[rig] voltage_V``) is the peak |voltage| of no
    run that logs one (within 5 %): validate, calibrate and diagnose drive the model with the
    logged voltage, so the stated value then only sets the virtual rig's and the design's
    protocol, and a wrong value there would go unseen."""
    peaks = [
        float(np.nanmax(np.abs(r.data["voltage"].to_numpy(float)), initial=0.0))
        for r in runs
        if "voltage" in r.data
    ]
    if not peaks or any(abs(p - rig.voltage) <= 0.05 * max(p, 1e-12) for p in peaks):
        return None
    shown = ", ".join(f"{p:.4g}" for p in sorted(set(round(p, 6) for p in peaks)))
    return (
        f"rig voltage_V = {rig.voltage:g} V is the peak voltage of no run (logged peaks: {shown} V): "
        "validate, calibrate and diagnose use the logged voltage; the stated one sets only the "
        "virtual rig's and the design's protocol (state the step voltage the runs used)"
    )


REQUIRED_COLUMNS = ("time_s", "voltage_V", "displacement_mm")
"""The columns every voltage-step run logs."""

LOGGED = (*REQUIRED_COLUMNS, "load_N", *EXTRA_CHANNELS)
"""Every column a voltage-step run may log (a ``[protocol]``'s ``channels``)."""


def protocol_channels(channels) -> tuple[str, ...]:
    """The predictions the rig logs beyond time, voltage and displacement for a ``[protocol]``
    table's ``channels`` (:data:`EXTRA_CHANNELS`), in their order; a column this rig cannot log
    is refused naming it."""
    pv.channels({"channels": channels}, LOGGED, (), list(KIND.required_columns), "the voltage-step rig")
    return tuple(EXTRA_CHANNELS[c] for c in channels if c in EXTRA_CHANNELS)


def measure(
    inputs: pd.DataFrame,
    outputs: dict,
    rng: np.random.Generator,
    noise_scale: float,
    *,
    noisy_zero=False,
    channels=(),
) -> pd.DataFrame:
    """Logged ``time`` [s], ``voltage`` [V] (exact) and ``displacement`` [m] (laser); then each of
    ``channels`` (:func:`protocol_channels`): ``current`` [A] through
    :func:`tcamlab.instruments.current_sense`, ``temperature`` [degC] through the thermometer.

    ``noisy_zero``: the laser zeroes on the first reading
    (:func:`tcamlab.instruments.laser_zeroed`); its zero error [m] is in
    ``attrs["zero_error"]["displacement"]``. The extra channels draw after the laser, so a run
    without them is the same, draw for draw.
    """
    disp, zero = instruments.laser_zeroed(
        np.asarray(outputs["displacement"], float), rng, noise_scale, noisy_zero=noisy_zero
    )
    out = pd.DataFrame(
        {
            "time": inputs["time"].to_numpy(float),
            "voltage": inputs["voltage"].to_numpy(float),
            "displacement": disp,
        }
    )
    if "load" in inputs:  # a hanging weight, known as weighed
        out["load"] = inputs["load"].to_numpy(float)
    chains = {"current": instruments.current_sense, "temperature": instruments.thermometer}
    for q in channels:
        out[q] = chains[q](np.asarray(outputs[q], float), rng, noise_scale)
    out.attrs["zero_error"] = {"displacement": zero}
    return out


RIG_FIELDS = (
    "load",
    "ambient",
    "voltage",
    "pulse",
    "resistance",
    "thermal_mass",
    "heat_loss",
    "damping",
)
"""Rig fields of the voltage-step test: shown in the report and written by the virtual rig."""


HEATER_TCR_SD = 3.8e-3
"""Default prior sd of beta [1/K] when the file states none: silver's TCR (the coating of
the thesis's thread), so a coating anywhere from constant to twice silver's is within 2 sd."""

CALIBRATION = (
    CalibrationParam(
        "thermal_mass",
        "rig",
        "C_th",
        "J/K",
        0.5,
        "a logged temperature during the pulse (the initial heating rate is V^2/(R C_th)), or a "
        "static oven test of the same sample calibrated jointly (it fixes the displacement per "
        "kelvin: tcamlab calibrate static.toml dynamic.toml)",
    ),
    CalibrationParam(
        "heat_loss",
        "rig",
        "lambda",
        "W/K",
        1.0,
        "whatever pins C_th (the cooling tail fixes tau = C_th/lambda), or a pulse long enough "
        "to reach the steady temperature with a logged temperature (T - T_a = V^2/(R lambda))",
    ),
    CalibrationParam(
        "damping",
        "rig",
        "b",
        "N s/m",
        0.3,
        "log faster than the mechanical time constant b/k (e.g. 1 kHz), or a load step",
    ),
    CalibrationParam(
        "resistance",
        "rig",
        "R",
        "ohm",
        0.05,
        "log the current with the voltage (R = V/I during the pulse), or the resistance",
        needs=("current", "resistance"),
    ),
    CalibrationParam(
        "heater_tcr",
        "rig",
        "beta",
        "1/K",
        0.5,
        "a logged temperature during the pulse (R = V/I against T then gives beta directly), or "
        "whatever pins C_th: the current fixes only beta (T - T_a), and the rise rests on C_th",
        positive=False,
        needs=("current", "resistance"),
        zero_sd=HEATER_TCR_SD,
        effect="resistance-temperature",
    ),
    CalibrationParam(
        "radial_cte",
        "sample",
        "rho",
        "1/K",
        0.3,
        "a static oven test of the same sample, calibrated jointly "
        "(tcamlab calibrate static.toml dynamic.toml)",
        positive=False,
        zero_sd=RHO_ZERO_SD,
    ),
    CalibrationParam(
        "shear_modulus_slope",
        "sample",
        "G_t slope",
        "Pa/K",
        0.3,
        "a static oven test of the same sample, calibrated jointly "
        "(tcamlab calibrate static.toml dynamic.toml)",
        positive=False,
        zero_sd=SLOPE_ZERO_SD,
    ),
)
"""Calibratable parameters of the voltage-step test; the default prior sds are wide
(the thesis's own sds are 32 %, 181 % and 14 %). rho and the G_t slope are calibrated too:
the displacement sees the temperature only through them, so without them the pulse would
seem to fix C_th and lambda separately on the strength of the sample's stated rho alone.
R (at ambient) is calibrated only where some run logs ``current_A`` (R = V/I) or
``resistance_ohm`` (its default prior sd 5 %, an ohmmeter reading of the actuator): without
them the heating power V^2/R is one more factor along C_th's unpinned direction, and R stays
at its stated value. beta of R(T) (``heater_tcr_per_K``, 0 in the thesis) is calibrated under
the same condition: the current falls as the actuator heats, by beta (T - T_a), and the
model's T(t) ties that to C_th and lambda, so without a logged temperature beta is only as
certain as the temperature rise (constrained, about 17 % on the bundled pulse, not pinned). Its stated value is usually 0, so its default prior
sd is absolute, :data:`HEATER_TCR_SD`. It is the effect library's ``resistance-temperature``
effect as a parameter, so the diagnosis keeps it out of its recalibration: there the effect
stays a candidate."""


KIND = Kind(
    name="dynamic",
    description="voltage-step test (thesis section 2.5.2): displacement against time, "
    "model (2.14)-(2.19) with a band for the measured points (prediction band once calibrated)",
    required_columns=REQUIRED_COLUMNS,
    optional_columns=("temperature_C", "current_A", "resistance_ohm", "load_N"),
    min_rows=10,
    inputs=("time", "voltage"),
    outputs=("displacement",),
    tension_outputs=(),
    variants={"G(T)": {}},
    predict=predict,
    run_options=run_options,
    needs_training=False,
    validation_extras=validation_extras,
    x_column="time",
    regimes=regimes,
    shared_inputs=("voltage", "load"),
    report_rig_fields=(*RIG_FIELDS, "heater_tcr"),
    figures=figures,
    extras_section=extras_section,
    preset=THESIS_TCA,
    logged_columns=("time", "voltage", "load", "displacement", "current", "temperature"),
    decimals={
        "time_s": 3,
        "voltage_V": 3,
        "load_N": 6,
        "displacement_mm": 3,
        "current_A": 5,
        "temperature_C": 1,
    },
    written_rig_fields=RIG_FIELDS,
    hidden_rig_fields=(),
    default_runs=3,
    default_scatter={"twists": 2e-3, "coil_length": 2e-3},
    noisy_inputs=(),
    strength_quantities=("displacement",),
    protocol=protocol,
    benchmark_program={},
    # C_th, lambda and b: the template states the thesis's sds
    benchmark_uncertainty={},
    benchmark_pairs=(("response-delay", "convective-heat-loss"),),
    program_options=("condition", "voltage_V", "pulse_s", "pulses", "period_s", "duration_s", "load_N"),
    exact_inputs=exact_inputs,
    instrument_sd=instrument_sd,
    measure=measure,
    simulation_rig_defaults={},
    segment_rig_fields=(),
    coil_length_rig_fields=(),
    calibration=CALIBRATION,
    nuisance_zeros=("displacement",),
)
