"""Self-sensing estimator: displacement and temperature from voltage and current alone.

An extended Kalman filter (EKF) on the state (T, x, v, F):

* time update: the electro-thermal model (2.18) driven by the *measured* power
  P = V I - I^2 R_lead held over the sample interval, and the dynamic model
  (2.14)-(2.19) with the load force F as a random walk and a load-jump detector
  (:data:`UNKNOWN_LOAD_NOISE`), unless a ``load_N`` column is logged: then it is a
  second measurement, and the stated load only the first row's prior;
* measurement update: the measured current I against V / R(T, x), the combined
  resistance model (temperature coefficient of the silver, fiber swelling and
  the coil's geometry), tabulated on a (T, x) grid (:class:`ResistanceTable`), with a
  lead resistance and a stretch factor as calibrated nuisances
  (:func:`calibrate_resistance_law`).

Why an EKF: the model is smooth, the state is small (4), and the per-sample
cost must stay in microseconds for a 1 kHz loop; an unscented filter costs
2n + 1 = 9 propagations a sample against 5 here and gains little on a model
this close to linear over one millisecond.

Noise, from the instruments (:data:`DEFAULT_NOISE`, documented there): the
voltage and current channels' sds enter both the measurement (I) and the
process (the power's error, sd_P^2 = (I sd_V)^2 + (V sd_I)^2, integrated over
the interval by 1/C_th). The model-error densities q_T, q_v and q_F say how
far the calibrated thermal model, the mechanics and the load may wander per
second.

Parameters (C_th, lambda, b, m, R0, the sample's geometry, ...) come from an
experiment file or its ``NAME.calibrated.toml`` (:func:`observer_config`), never
from constants here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from tcamlab.params import G_ACCEL, SILVER_TCR, Rig, Sample

__all__ = [
    "ObserverConfig",
    "ResistanceTable",
    "SelfSensingObserver",
    "EstimateResult",
    "estimate",
    "observer_config",
    "config_from",
    "combined_resistance",
    "spring_constant",
    "unloaded_resistance",
    "predict_displacement",
    "filter_run",
    "TCS_STIFFNESS_RATIO",
    "parameter_vector",
    "initial_state",
    "rest_extension",
    "DEFAULT_NOISE",
    "THETA_NOISE",
    "UNKNOWN_LOAD_NOISE",
    "LOAD_PRIOR_REL",
    "LOAD_PRIOR_SD",
    "LAW_PRIORS",
    "calibrate_resistance_law",
    "best_least_squares",
    "STRETCH_STARTS",
    "law_fit_weights",
    "rest_rows_count",
    "chain_sd",
    "VOLTAGE_NOISE_SD",
    "VOLTAGE_QUANTUM",
    "CURRENT_NOISE_SD",
    "CURRENT_QUANTUM",
    "MAX_STEP_S",
]

MAX_STEP_S = 1e-3
"""Largest integration sub-step of the filter's time update [s] (RK4; the
mechanics' natural frequency is about 14 rad/s, the thermal time constant 3 s)."""

VOLTAGE_NOISE_SD = 5e-3
"""Analogue noise on the driver-voltage reading [V]."""
VOLTAGE_QUANTUM = 15.0 / 1023
"""One code of a 10-bit ADC over a 15 V divider [V] (14.7 mV)."""
CURRENT_NOISE_SD = 0.5e-3
"""Amplifier noise of the current sense (0.1 ohm, gain 50) [A]."""
CURRENT_QUANTUM = 1.0 / 1023
"""One code of a 10-bit ADC over the sense's 1 A span [A] (0.98 mA)."""


def chain_sd(noise_sd: float, quantum: float) -> float:
    """sd of a reading: noise and uniform quantisation, sqrt(sd^2 + q^2 / 12)."""
    return float(np.hypot(noise_sd, quantum / np.sqrt(12.0)))


DEFAULT_NOISE = {
    "sd_voltage": chain_sd(VOLTAGE_NOISE_SD, VOLTAGE_QUANTUM),
    "sd_current": chain_sd(CURRENT_NOISE_SD, CURRENT_QUANTUM),
    "q_temperature": 0.5,
    "q_velocity": 1e-8,
    "q_force": 1e-6,
    "sd_load": 2e-3,
    "q_theta": 0.0,
    "sd_theta": 0.0,
    "jump_drift": 0.0,
    "jump_threshold": 0.0,
    "jump_sd": 0.0,
    "jump_hold": 1.0,
}
"""Noise of the filter, SI.

* ``sd_voltage`` [V]: the driver voltage read by a 10-bit ADC over a 15 V divider
  (one code 14.7 mV, sd 4.2 mV) with 5 mV analogue noise: 6.5 mV.
* ``sd_current`` [A]: a 0.1 ohm sense resistor, gain 50, 10-bit ADC over 5 V
  (one code 0.98 mA, sd 0.28 mA) with 0.5 mA amplifier noise: 0.58 mA.
* ``q_temperature`` [K^2/s]: model error of (2.18) beyond the power noise: a
  lambda 5% off at 60 K above ambient errs by 0.16 K/s; 0.5 K^2/s lets the
  estimate move 0.7 K in a second on the resistance's word. Much looser makes T
  and the load unobservable apart (the estimate drifts: README).
* ``q_velocity`` [m^2/s^3]: unmodelled forces on the mechanics.
* ``q_force`` [N^2/s]: the load's random walk (sd 1 mN after 1 s): looser lets the
  resistance noise into x through the load (dx = f11 dF, f11 = 0.09 m/N for the
  thesis TCA), tighter follows a load change more slowly (measured: README).
* ``sd_load`` [N]: a logged load cell (LSP-5 with amplifier, 2 mN).
* ``sd_theta`` [1/K], ``q_theta`` [1/K^2/s]: prior sd and random walk of theta, the
  filter's correction to the thermal part of R, R = R(T, x) (1 + theta (T - T_a)).
  Off (0) by default; :data:`THETA_NOISE` when the load is logged (README: with the load
  unknown, theta and the load trade off and the estimate gets worse, not better).
* ``jump_drift`` [-], ``jump_threshold`` [-], ``jump_sd`` [N], ``jump_hold`` [s]: the
  load-jump detector (a two-sided CUSUM of the normalised current innovation,
  :func:`tcamlab.estimation.observer_kernel.jump_detector`); on an alarm the load's
  variance grows by ``jump_sd^2`` and, for ``jump_hold``, its random walk by
  ``jump_sd^2 / jump_hold`` [N^2/s] (the mechanics settle in about 0.5 s). Off (threshold 0)
  by default; :data:`UNKNOWN_LOAD_NOISE` when no load is logged.
"""

UNKNOWN_LOAD_NOISE = {
    "q_force": 1e-9,
    "jump_drift": 0.5,
    "jump_threshold": 8.0,
    "jump_sd": 0.05,
    "jump_hold": 4.0,
}
"""The load unknown: a random walk of 1e-9 N^2/s (sd 1 mN after 1000 s: a hanging load held) between steps, and a
step of the load found by the jump detector (drift 0.5, alarm at 8 sds of summed innovation:
by Siegmund's approximation a false alarm about once in 10^4 noise-only samples, 100 s at
100 Hz) with a 50 mN sd, the 5 g rider of the virtual rig's protocol, and a 4 s hold (on the
kind's rider run: threshold 12 and a 1 s hold left 76 um of the 1.5 mm step after 2 s, a 2 s
hold 54 um; 6 gave 47 um with a false alarm every 13 s at 100 Hz). The walk is slow because
between steps it lets the current noise into x (dx = f11 dF): on the bench's withheld runs
(six seeds) the heating-only part's 95 % interval was up to 24 % of its own 0.3 mm stroke at
1e-6 N^2/s, up to 16 % at 1e-7. The hold is 4 s because with that slow walk the filter finishes
splitting a step between load and temperature only through the hold: on two rider runs
(protocol seeds 7 and 8) a 2 s hold left -30 and -7 um 10 s after the rider, a 4 s hold -17 and
-2 um, as the 1e-6 walk with a 2 s hold did (-16 and -3 um). Measured: docs, self-sensing.

The walk went from 1e-7 to 1e-9 N^2/s (with :data:`LOAD_PRIOR_SD` from 1 mN to 0.1 mN) because
between steps a walk lets an error of the resistance law into x through the load: on an
independent generator's heating-only run (0.18 mm stroke, a lead 0.1 ohm from the calibrated
one) the load drifted 3 mN and x -30 % of the stroke (95 % interval 48 %); held, +1.0 % / 12.9 %,
with the riders of the other runs still found by the detector (docs, self-sensing)."""

LOAD_PRIOR_SD = 1e-4
"""Prior sd of the stated load (load_g) at the first row when no load is logged [N]. Not the
weighing's accuracy (0.1 g is 1 mN): the run's R0 comes from its rest rows at the stated load,
and the rest-row zero takes out a constant offset, so a wrong load_g moves R0, not the zeroed
displacement. What this sd sets is how far the resistance may later pull the load; 1 mN let a
resistance-law error pull it 3 mN on a heating-only run (:data:`UNKNOWN_LOAD_NOISE`)."""

LOAD_PRIOR_REL = 0.1
"""Prior sd of the stated load at the first row when a load IS logged, as a fraction of it [-]:
the file's load_g is then a nominal value and the first logged row (sd ``sd_load``) decides."""


THETA_NOISE = {"sd_theta": 1e-4, "q_theta": 1e-12}
"""theta on: 1e-4 /K covers a TCR 2 % off (7.6e-5 /K) or lambda 1-2 % off at 60 K."""


@dataclass(frozen=True)
class ResistanceTable:
    """R(T, x) on a regular grid, for the compiled filter.

    Attributes
    ----------
    values : ndarray, shape (nT, nx)
        R [ohm].
    grid : ndarray, shape (4,)
        (first T [degC], T step [K], first x [m], x step [m]).
    """

    values: np.ndarray
    grid: np.ndarray

    @classmethod
    def build(cls, resistance, t_range, x_range, n_t=121, n_x=161):
        """Tabulate a vectorised ``resistance(temperature [degC], extension [m])`` [ohm]."""
        t = np.linspace(t_range[0], t_range[1], n_t)
        x = np.linspace(x_range[0], x_range[1], n_x)
        tt, xx = np.meshgrid(t, x, indexing="ij")
        values = np.ascontiguousarray(np.asarray(resistance(tt, xx), float))
        grid = np.array([t[0], t[1] - t[0], x[0], x[1] - x[0]])
        return cls(values, grid)


@dataclass(frozen=True)
class ObserverConfig:
    """Everything the filter needs, SI.

    Attributes
    ----------
    sample : Sample
    rig : Rig
        C_th, lambda, b, the hanging mass m (inertia and the load's prior) and
        T_a are read from here.
    initial_resistance : float
        Chapter 3's R0: unloaded, at ambient [ohm].
    resistance_tc : float
        Temperature coefficient of R [1/K].
    table : ResistanceTable
    noise : dict
        As :data:`DEFAULT_NOISE`.
    initial_temperature_sd : float
        Prior sd of T at the start [K].
    initial_load_sd : float, optional
        Prior sd of the load force at the first row [N]; default :meth:`load_prior_sd`.
    lead_resistance : float
        R_lead of the leads and contacts in series, unheated [ohm] (in ``table`` too).
    stretch_factor : float
        k_s, the stretch sensitivity relative to chapter 3's map [-] (in ``table`` too).
    tcr2 : float
        The coating's quadratic TCR [1/K^2] (in ``table`` too; 0: linear).
    """

    sample: Sample
    rig: Rig
    initial_resistance: float
    resistance_tc: float
    table: ResistanceTable
    noise: dict = field(default_factory=lambda: dict(DEFAULT_NOISE))
    initial_temperature_sd: float = 2.0
    initial_load_sd: float | None = None
    lead_resistance: float = 0.0
    stretch_factor: float = 1.0
    tcr2: float = 0.0

    def load_prior_sd(self) -> float:
        """Prior sd of the load force at the first row [N] (:data:`LOAD_PRIOR_SD` unless set)."""
        return LOAD_PRIOR_SD if self.initial_load_sd is None else float(self.initial_load_sd)

    def noise_vector(self) -> np.ndarray:
        n = {**DEFAULT_NOISE, **self.noise}
        keys = (
            "sd_voltage", "sd_current", "q_temperature", "q_velocity", "q_force", "sd_load", "q_theta",
            "jump_drift", "jump_threshold", "jump_sd", "jump_hold",
        )  # fmt: skip
        return np.array([float(n[k]) for k in keys])

    def with_noise(self, **changes) -> ObserverConfig:
        return replace(self, noise={**self.noise, **changes})


def parameter_vector(sample: Sample, rig: Rig, lead_resistance: float = 0.0) -> np.ndarray:
    """Parameter vector of :mod:`tcamlab.estimation.observer_kernel` [SI]; R_lead [ohm]."""
    from tcamlab.estimation import observer_kernel as K
    from tcamlab.models import static

    p = np.zeros(K.N_PARAMS)
    p[K.P_TA], p[K.P_CTH], p[K.P_LAM] = rig.ambient, rig.thermal_mass, rig.heat_loss
    # a mechanical time constant m/b below the RK4 sub-step is unstable there (|h b/m| > 2.8: a
    # 1 ug load put the estimate at 1e215 mm); the inertia is raised to one sub-step's, which
    # leaves out only motion faster than MAX_STEP_S
    p[K.P_MASS], p[K.P_DAMP] = max(rig.load, rig.damping * MAX_STEP_S), rig.damping
    p[K.P_L], p[K.P_D0], p[K.P_RHO] = sample.fiber_length, sample.fiber_diameter, sample.radial_cte
    p[K.P_GT] = static.shear_modulus_of(sample)
    p[K.P_SLOPE], p[K.P_E] = sample.shear_modulus_slope, sample.youngs_modulus
    p[K.P_PHI0] = 2.0 * np.pi * sample.twists
    p[K.P_NCOIL] = float(static.n_coils(sample.fiber_length, sample.coil_length, sample.coil_diameter))
    p[K.P_S0] = sample.coil_length / sample.fiber_length
    p[K.P_LEAD] = float(lead_resistance)
    return p


def rest_extension(sample: Sample, rig: Rig, temperature=None, force=None) -> float:
    """Static extension x under the rig's load at ambient (or the given T [degC], F [N]) [m]."""
    from tcamlab.estimation import observer_kernel as K

    p = parameter_vector(sample, rig)
    t = rig.ambient if temperature is None else temperature
    f = rig.force if force is None else force
    return float(K.equilibrium(float(t), float(f), p, 0.5 * sample.coil_length))


TCS_STIFFNESS_RATIO = 0.6
"""S f11(alpha0) assumed for chapter 3's map when the rig states no spring constant
(the ratio of the sensing template, README "Presets and assumed values")."""


def combined_resistance(
    sample: Sample,
    rig: Rig,
    initial_resistance: float,
    resistance_tc: float,
    lead_resistance: float = 0.0,
    stretch_factor: float = 1.0,
    tcr2: float = 0.0,
):
    """R(T, x) of :mod:`tcamlab.models.selfsensing` as a function of (T [degC], x [m]) -> R [ohm].

    ``initial_resistance`` is chapter 3's R0: unloaded, at ambient. S is
    ``rig.spring_constant``, else :data:`TCS_STIFFNESS_RATIO` / f11(alpha0). The two
    nuisances of a real rig: R = R_lead + R0 (1 + k_s (g(x) - 1)) heat(T), with
    ``lead_resistance`` R_lead [ohm] (unheated, in series) and ``stretch_factor`` k_s [-]
    (1: chapter 3's map). ``tcr2`` [1/K^2] is the coating's quadratic TCR: the coating factor
    1 + TCR dT + tcr2 dT^2 (0: tcamlab's linear law, the same table to the bit).
    """
    from tcamlab.models import selfsensing

    kw = sample.sensor_kwargs()
    s_c = spring_constant(sample, rig)

    def resistance(temperature, extension):
        # g depends on the extension alone: chapter 3's implicit map is solved once per distinct
        # extension, not once per cell of a (T, x) table (121 times fewer roots; each root is
        # solved element by element, so the values are the same to the bit)
        ext = np.asarray(extension, float)
        distinct, where = np.unique(ext, return_inverse=True)
        g = selfsensing.geometric_ratio(distinct, spring_constant=s_c, **kw)[where].reshape(ext.shape)
        coating = selfsensing.coating_factor(temperature, rig.ambient, resistance_tc)
        if tcr2:
            coating = coating + tcr2 * (np.asarray(temperature, float) - rig.ambient) ** 2
        heat = coating * selfsensing.swelling_factor(temperature, rig.ambient, sample.radial_cte)
        return lead_resistance + initial_resistance * (1.0 + stretch_factor * (g - 1.0)) * heat

    return resistance


def spring_constant(sample: Sample, rig: Rig) -> float:
    """S of chapter 3's map: the rig's, else :data:`TCS_STIFFNESS_RATIO` / f11(alpha0) [N/m]."""
    from tcamlab.models import sensing

    if rig.spring_constant is not None:
        return float(rig.spring_constant)
    return TCS_STIFFNESS_RATIO * sensing.conditioning(1.0, **sample.sensor_kwargs()).spring_stiffness_model


def unloaded_resistance(sample: Sample, rig: Rig) -> float:
    """Chapter 3's R0 (unloaded, at ambient) [ohm]: ``initial_resistance`` when stated, else the
    rig's ``resistance`` (the loaded actuator's, as the dynamic kind states it) over g(x0)."""
    from tcamlab.models import selfsensing

    if rig.initial_resistance is not None:
        return float(rig.initial_resistance)
    g = selfsensing.geometric_ratio(
        rest_extension(sample, rig), spring_constant=spring_constant(sample, rig), **sample.sensor_kwargs()
    )
    return float(rig.resistance / g)


def observer_config(experiment, *, resistance=None, noise=None, temperature_span=160.0) -> ObserverConfig:
    """The filter's configuration from an experiment (or calibrated) file.

    Parameters
    ----------
    experiment : tcamlab.config.Experiment
        Its ``sample`` and ``rig`` (C_th, lambda, b, load, ambient, R0 by
        :func:`unloaded_resistance`, the TCR ``tcr``, S by :func:`spring_constant`).
    resistance : callable, optional
        R(T [degC], x [m]) [ohm], vectorised; default :func:`combined_resistance`.
    noise : dict, optional
        Overrides of :data:`DEFAULT_NOISE`.
    temperature_span : float
        Tabulated range above ambient [K].
    """
    return config_from(
        experiment.sample,
        experiment.rig,
        resistance=resistance,
        noise=noise,
        temperature_span=temperature_span,
    )


DOMAIN_BISECTIONS = 30
"""Halvings of the search for the edge of chapter 3's domain (2^-30 of the table's span)."""


def defined_extensions(resistance, rig: Rig, x0: float, span: tuple[float, float]) -> tuple[float, float]:
    """The part of ``span`` [m] around ``x0`` where ``resistance(T_a, x)`` is defined.

    Chapter 3's map (3.1)-(3.7) has no physical coil diameter beyond an extension that
    depends on the sample and S; a heavy stated load puts the table's upper edge there.
    The geometric factor does not depend on T, so the edge is searched at ambient.

    Raises
    ------
    ModelDomainError
        Where the rest extension ``x0`` itself lies outside (names the stated load).
    """
    from tcamlab.errors import ModelDomainError, TcamlabError

    def ok(x: float) -> bool:
        try:
            return bool(np.isfinite(resistance(np.array([rig.ambient]), np.array([x]))).all())
        except TcamlabError:
            return False

    if not ok(x0):
        raise ModelDomainError(
            f"self-sensing EKF: the stated load (load_g = {rig.load * 1e3:g} g) stretches the muscle "
            f"by {x0 * 1e3:.4g} mm at rest, beyond chapter 3's sensing model for this sample and "
            f"spring_constant_N_per_m = {rig.spring_constant:g}",
            "check load_g and spring_constant_N_per_m in [rig]",
        )
    edges = []
    for far in span:
        good, bad = x0, far
        if ok(far):
            edges.append(far)
            continue
        for _ in range(DOMAIN_BISECTIONS):
            mid = 0.5 * (good + bad)
            good, bad = (mid, bad) if ok(mid) else (good, mid)
        edges.append(good)
    return edges[0], edges[1]


def config_from(
    sample: Sample,
    rig: Rig,
    *,
    initial_resistance=None,
    resistance=None,
    noise=None,
    temperature_span=160.0,
    lead_resistance=0.0,
    stretch_factor=1.0,
    tcr2=0.0,
) -> ObserverConfig:
    """As :func:`observer_config`, from a sample and a rig; ``initial_resistance`` overrides R0 [ohm].

    ``lead_resistance`` [ohm], ``stretch_factor`` [-] and ``tcr2`` [1/K^2] are the resistance
    law's nuisances (:func:`combined_resistance`); a given ``resistance`` must include them itself.
    """
    r0 = unloaded_resistance(sample, rig) if initial_resistance is None else float(initial_resistance)
    tcr = float(getattr(rig, "tcr", SILVER_TCR))
    fn = resistance or combined_resistance(sample, rig, r0, tcr, lead_resistance, stretch_factor, tcr2)
    x0 = rest_extension(sample, rig)
    half = 0.3 * x0 + 2e-3  # loads from about 70% to 130% of the stated one
    x_range = defined_extensions(fn, rig, x0, (x0 - half, x0 + half))
    table = ResistanceTable.build(fn, (rig.ambient - 20.0, rig.ambient + temperature_span), x_range)
    return ObserverConfig(
        sample, rig, float(r0), tcr, table, {**DEFAULT_NOISE, **(noise or {})},
        lead_resistance=float(lead_resistance), stretch_factor=float(stretch_factor), tcr2=float(tcr2),
    )  # fmt: skip


def _contact_resistance(sample: Sample, rig: Rig, initial_resistance, mods, law=(0.0, 1.0, 0.0)):
    """R(T, x) with the inter-coil contact term of ``mods``, or None when there is none.

    The filter then reads R through the same contact factor the effect library puts on
    the true R (:func:`tcamlab.models.selfsensing.effect_factor`, contraction from the
    rest extension at ambient).
    """
    if mods is None or not getattr(mods, "contact_slope", 0.0):
        return None
    from tcamlab.models import selfsensing

    r0 = unloaded_resistance(sample, rig) if initial_resistance is None else float(initial_resistance)
    base = combined_resistance(sample, rig, r0, float(getattr(rig, "tcr", SILVER_TCR)), *law)
    contact = replace(mods, r0_drift=0.0)
    x0 = rest_extension(sample, rig)

    def resistance(temperature, extension):
        return base(temperature, extension) * selfsensing.effect_factor(0.0, x0 - extension, contact)

    return resistance


def filter_run(
    sample: Sample,
    rig: Rig,
    data,
    mods=None,
    *,
    initial_resistance=None,
    use_load=True,
    lead_resistance=0.0,
    stretch_factor=1.0,
    noise=None,
    tcr2=0.0,
) -> tuple[EstimateResult, float]:
    """The EKF over a logged run and its rest reference: (EstimateResult, x_rest [m]).

    Parameters as :func:`predict_displacement`, which is this plus the displacement from
    x_rest, the static rest extension at the rest rows' steady temperature under the first
    row's load (logged, else stated).
    """
    t = data["time"].to_numpy(float)
    v = data["voltage"].to_numpy(float)
    i = data["current"].to_numpy(float)
    if mods is not None and getattr(mods, "tcr_extra", 0.0):
        rig = replace(rig, tcr=rig.tcr + mods.tcr_extra)
    if mods is not None and getattr(mods, "r0_drift", 0.0):
        i = i * (1.0 + mods.r0_drift * (t - t[0]))
    # "load" is the selfsensing kind's logged load_N column; "load_force" the simulations'
    column = next((c for c in ("load_force", "load") if c in data), None)
    load = data[column].to_numpy(float) if use_load and column else None
    law = (float(lead_resistance), float(stretch_factor), float(tcr2))
    rest = slice(0, rest_rows_count(data))
    rig = _logged_mass(rig, load, rest)
    config = config_from(
        sample,
        rig,
        initial_resistance=initial_resistance,
        resistance=_contact_resistance(sample, rig, initial_resistance, mods, law),
        noise=noise if noise is not None else (THETA_NOISE if load is not None else UNKNOWN_LOAD_NOISE),
        lead_resistance=law[0],
        stretch_factor=law[1],
        tcr2=law[2],
    )
    if load is not None:
        config = replace(config, initial_load_sd=max(LOAD_PRIOR_SD, LOAD_PRIOR_REL * abs(rig.force)))
    p_rest = float(np.mean(v[rest] * i[rest] - law[0] * i[rest] ** 2))
    t0 = rig.ambient + p_rest / rig.heat_loss  # steady at the probe power
    est = estimate(t, v, i, config, load=load, initial_temperature=t0)
    # from the statics' rest extension at the rest temperature under the first row's load, as
    # the kind does: the rest rows' mean of the estimate would cancel a common error and hide it
    f_rest = float(load[0]) if load is not None and np.isfinite(load[0]) else rig.force
    x_rest = rest_extension(sample, rig, t0, f_rest)
    return est, x_rest


def _logged_mass(rig: Rig, load, rest: slice) -> Rig:
    """The rig with its hanging mass read from the logged load at rest [N] when there is one:
    the stated load_g is then only a nominal value, and a wrong one (1 ug beside a logged 50 g)
    had set the filter's inertia and load prior and put the estimate 294 % of the stroke off."""
    if load is None:
        return rig
    at_rest = np.asarray(load[rest], float)
    at_rest = at_rest[np.isfinite(at_rest)]
    if at_rest.size == 0 or not float(np.mean(at_rest)) > 0:
        return rig
    return replace(rig, load=float(np.mean(at_rest)) / G_ACCEL)


def predict_displacement(
    sample: Sample,
    rig: Rig,
    data,
    mods=None,
    *,
    initial_resistance=None,
    use_load=True,
    lead_resistance=0.0,
    stretch_factor=1.0,
    noise=None,
    tcr2=0.0,
):
    """The self-sensed displacement and temperature of a logged run, by the EKF (causal).

    The selfsensing kind's prediction: same signature and return as
    ``tcamlab.kinds.selfsensing.predict_displacement``.

    Parameters
    ----------
    sample, rig :
        Calibrated or stated parameters [SI].
    data : DataFrame
        ``time`` [s], ``voltage`` [V], ``current`` [A]; ``load_force`` or ``load`` [N] is used as a
        measurement when present and ``use_load`` (else the load is unknown).
    mods : Mods, optional
        ``r0_drift`` and ``tcr_extra`` are undone (the drift by scaling I back).
    initial_resistance : float, optional
        Chapter 3's R0 [ohm]; default :func:`unloaded_resistance`.
    use_load : bool
        Read a logged load as a measurement (sd ``sd_load``); the stated ``rig.load`` is
        then only the prior at the first row.
    lead_resistance, stretch_factor : float
        R_lead [ohm] and k_s [-] of :func:`combined_resistance` (calibrated nuisances).
    noise : dict, optional
        Overrides of the filter's noise; default :data:`THETA_NOISE` with a logged load,
        :data:`UNKNOWN_LOAD_NOISE` without.
    tcr2 : float
        The coating's quadratic TCR of :func:`combined_resistance` [1/K^2] (0: linear).

    Returns
    -------
    dict
        ``displacement`` [m] from the static rest extension at the rest rows' steady
        temperature (leading rows at the first voltage) under the first row's load
        (logged, else stated), ``temperature`` [degC], ``load_force`` [N].
    """
    est, x_rest = filter_run(
        sample, rig, data, mods, initial_resistance=initial_resistance, use_load=use_load,
        lead_resistance=lead_resistance, stretch_factor=stretch_factor, noise=noise, tcr2=tcr2,
    )  # fmt: skip
    return {
        "displacement": est.displacement + est.extension0 - x_rest,
        "temperature": est.temperature,
        "load_force": est.load_force,
    }


LAW_PRIORS = {"lead_resistance": (0.35, 0.15), "stretch_factor": (1.0, 0.2)}
"""Stated priors (mean, sd) of the resistance law's nuisances: R_lead [ohm], leads and contacts
of a bench rig (0.2-0.5 ohm); k_s [-], chapter 3's stretch sensitivity within 20 %."""

LAW_FIT_ERROR_SD = 50e-6
"""sd of one thinned row's displacement error in :func:`calibrate_resistance_law` [m]."""
LAW_FIT_THIN = 10
"""Every LAW_FIT_THIN-th row enters the fit: neighbouring errors are correlated (the filter's
memory), so the thinned rows weigh the priors about right."""


def law_fit_weights(displacement_variance, rest: int, error_sd: float = LAW_FIT_ERROR_SD) -> np.ndarray:
    """Weight of each row's displacement error in :func:`calibrate_resistance_law` [-].

    error_sd / sqrt(error_sd^2 + excess), with excess the filter's own displacement variance
    above its mean over the ``rest`` leading rows [m^2]: a row's expected error is the fit's
    sd plus the filter's own uncertainty there. After a load change nobody logged, the filter
    says for seconds that it does not know the load (the jump detector widens it), and its
    error then is the load's lag, not the law's; weighted as a row at rest, that lag (-100 to
    -270 um a second after a 5 g rider, still -20 to -50 um 10 s later, at the true law) bent
    R0, the TCR and tcr2 to cancel it on the training runs, and the heating rows of withheld
    runs paid (bench_observer.py seed 4, load unknown: -6.3 % of the heating part's stroke,
    -2.7 % weighted; docs, self-sensing). The variance at rest is the load prior's, a common
    offset that the rest-row zero takes out, hence the excess.

    Parameters
    ----------
    displacement_variance : array_like, shape (n,)
        The filter's posterior variance of x per row [m^2] (:attr:`EstimateResult.variance`).
    rest : int
        Number of leading rest rows (:func:`rest_rows_count`).
    error_sd : float
        sd of one row's error where the filter is as sure as at rest [m].

    Returns
    -------
    ndarray, shape (n,)
        In (0, 1]; 1 where the variance is at or below its rest level.
    """
    var = np.asarray(displacement_variance, float)
    excess = np.clip(var - np.mean(var[: max(int(rest), 1)]), 0.0, None)
    return error_sd / np.sqrt(error_sd**2 + excess)


def calibrate_resistance_law(
    sample: Sample, rig: Rig, runs, *, use_load=True, priors=None, reference="laser"
) -> dict:
    """R0, TCR, R_lead, k_s and tcr2 of the resistance law from training runs (MAP).

    The calibrated nuisances of the resistance law (:func:`combined_resistance`). With
    ``reference="laser"`` the EKF (:func:`predict_displacement`) is fitted to the laser of
    the training runs, each run after its rest-row zero (least squares on every
    :data:`LAW_FIT_THIN`-th row, sd :data:`LAW_FIT_ERROR_SD`, each row weighted down where the
    filter's own displacement variance grows past its rest level, :func:`law_fit_weights`).
    With ``"innovations"`` no laser is used: the EKF's own innovation likelihood
    (:meth:`EstimateResult.negative_log_likelihood`) is minimised (Powell). R0 and the TCR
    start from the rig (a calibrated file's) with its stated sds, when given, else 1 % and
    5 %; R_lead and k_s from :data:`LAW_PRIORS`; the quadratic TCR from the rig's ``tcr2``
    (0 for the linear law) with its stated sd, else
    :data:`tcamlab.kinds.selfsensing.TCR2_ZERO_SD`. R_lead is bounded at 0.

    Parameters
    ----------
    sample, rig :
        Calibrated parameters [SI]; C_th, lambda and b are held.
    runs : sequence of DataFrame
        ``time`` [s], ``voltage`` [V], ``current`` [A], ``displacement`` [m] (laser, zeroed at
        the first row; not read with ``"innovations"``), optional ``load`` [N].
    use_load : bool
        Read a logged load as the EKF would in use.
    priors : dict, optional
        Overrides of :data:`LAW_PRIORS`.
    reference : {"laser", "innovations"}

    Returns
    -------
    dict
        ``initial_resistance`` [ohm], ``tcr`` [1/K], ``lead_resistance`` [ohm],
        ``stretch_factor`` [-], ``tcr2`` [1/K^2] (pass it to :func:`predict_displacement`'s
        ``tcr2`` with the others), and ``cost`` (the objective at the optimum [-]).
    """
    from tcamlab.kinds.selfsensing import TCR2_ZERO_SD  # lazy: the kinds pull in pandas

    pri = {**LAW_PRIORS, **(priors or {})}
    unc = getattr(rig, "uncertainty", None) or {}
    r0, tcr, tcr2 = float(rig.initial_resistance), float(rig.tcr), float(getattr(rig, "tcr2", 0.0))
    mu = np.array([r0, tcr, pri["lead_resistance"][0], pri["stretch_factor"][0], tcr2])
    sd = np.array([unc.get("initial_resistance", 0.01 * r0), unc.get("tcr", 0.05 * tcr),
                   pri["lead_resistance"][1], pri["stretch_factor"][1],
                   unc.get("tcr2", TCR2_ZERO_SD)])  # fmt: skip

    def runs_of(u):
        theta = mu + sd * u
        fitted = replace(rig, initial_resistance=theta[0], tcr=theta[1], tcr2=theta[4])
        for data in runs:
            yield data, filter_run(
                sample, fitted, data, initial_resistance=theta[0], use_load=use_load,
                lead_resistance=theta[2], stretch_factor=theta[3], tcr2=theta[4],
            )  # fmt: skip

    def residuals(u):
        out = [u]
        for data, (est, x_rest) in runs_of(u):
            e = est.displacement + est.extension0 - x_rest - data["displacement"].to_numpy(float)
            rest = rest_rows_count(data)
            e = (e - e[:rest].mean()) * law_fit_weights(est.variance[:, 1], rest)
            out.append(e[::LAW_FIT_THIN] / LAW_FIT_ERROR_SD)
        return np.concatenate(out)

    def nll(u):
        return 0.5 * float(u @ u) + sum(est.negative_log_likelihood() for _, (est, _) in runs_of(u))

    # R_lead >= 0: a negative lead is no wire; it would trade with R0 and the TCR unbounded
    lo = np.array([-np.inf, -np.inf, -mu[2] / sd[2], -np.inf, -np.inf])
    if reference not in ("laser", "innovations"):
        raise ValueError(f"reference {reference!r}: 'laser' or 'innovations'")
    u, cost = _law_optimum(residuals if reference == "laser" else nll, lo, least=reference == "laser")
    theta = mu + sd * u
    keys = ("initial_resistance", "tcr", "lead_resistance", "stretch_factor", "tcr2")
    return {**dict(zip(keys, map(float, theta))), "cost": float(cost)}


STRETCH_STARTS = (0.0, -1.5, 1.5)
"""Starts of the stretch factor in the law's least-squares fits, in its prior sds [-].

The law's cost has two basins where a stretch law is not chapter 3's: in one the fitted k_s
takes up the real slope of R(x) at rest, in the other k_s stays near 1 and the TCR pays for it.
On the virtual rig with a cubic stretch term (``bench_observer.py --off-form``, seed 6, load
logged: true k_s 0.85, c3 -0.07, so a slope at rest of 0.73), a start at the prior's centre
ended at k_s 0.997 and TCR 0.00273 (true 0.0036; cost 1067), a start 1.5 sd lower at k_s 0.69
and TCR 0.00377 (cost 1014). 1.5 sd covers k_s +-0.15 with a cubic term up to 0.09."""


def best_least_squares(fn, u0: np.ndarray, lo: np.ndarray, max_nfev: int, stretch_index: int | None = None):
    """The lowest-cost bounded least-squares fit of ``fn`` (scipy's result) over starts ``u0``
    and, when ``stretch_index`` is given, ``u0`` with that coordinate at each of
    :data:`STRETCH_STARTS` (kept within the bounds ``lo``) [-, prior-sd units]."""
    from scipy.optimize import least_squares

    starts = [np.asarray(u0, float)]
    if stretch_index is not None:
        for k in STRETCH_STARTS[1:]:
            u = starts[0].copy()
            u[stretch_index] = max(k, lo[stretch_index] + 0.1)
            starts.append(u)
    fits = [
        least_squares(fn, u, bounds=(lo, np.inf), diff_step=1e-3, x_scale=1.0, max_nfev=max_nfev)
        for u in starts
    ]
    return min(fits, key=lambda f: f.cost)


def _law_optimum(objective, lo: np.ndarray, *, least: bool) -> tuple[np.ndarray, float]:
    """(u, cost) at the optimum of the law's objective in prior-sd units, from a start off the
    lower bounds ``lo`` (differences at a bound are one-sided): least squares of the residuals
    (``least``, from each of :data:`STRETCH_STARTS`), else Powell on a scalar."""
    from scipy.optimize import minimize

    u0 = np.maximum(0.0, lo + 0.1)
    if least:
        fit = best_least_squares(objective, u0, lo, 40, stretch_index=3)
        return fit.x, float(fit.cost)
    bounds = [(b, None) if np.isfinite(b) else (None, None) for b in lo]
    fit = minimize(
        objective, u0, method="Powell", bounds=bounds, options={"xtol": 1e-2, "ftol": 1e-3, "maxfev": 300}
    )
    return fit.x, float(fit.fun)


def rest_rows_count(data) -> int:
    """Number of leading rows at the first voltage (the rest rows)."""
    v = data["voltage"].to_numpy(float)
    moved = np.flatnonzero(np.abs(v - v[0]) > 0.02 * max(float(np.ptp(v)), 1e-12))
    return max(int(moved[0]) if moved.size else v.size, 1)


@dataclass
class EstimateResult:
    """The filter's estimates over a log, SI.

    Attributes
    ----------
    time : ndarray [s]
    displacement : ndarray
        Estimated x - x(0), the logs' convention (positive longer) [m].
    temperature : ndarray [degC]
    load_force : ndarray [N]
    variance : ndarray, shape (n, 4)
        Posterior variances of (T, x, v, F) [K^2, m^2, m^2/s^2, N^2].
    nis : ndarray
        Normalised innovation squared per sample (NaN where V carried no information).
    extension0 : float
        x at the start [m].
    innovation_variance : ndarray
        Variance of each row's current innovation [A^2] (NaN where V carried no information).
    """

    time: np.ndarray
    displacement: np.ndarray
    temperature: np.ndarray
    load_force: np.ndarray
    variance: np.ndarray
    nis: np.ndarray
    extension0: float
    innovation_variance: np.ndarray | None = None

    def negative_log_likelihood(self) -> float:
        """0.5 sum(nis + ln(2 pi S)) over the informative rows: the innovations' Gaussian
        negative log-likelihood [-] (S in A^2; the prediction-error decomposition)."""
        ok = np.isfinite(self.nis) & np.isfinite(self.innovation_variance)
        return float(0.5 * np.sum(self.nis[ok] + np.log(2.0 * np.pi * self.innovation_variance[ok])))

    @property
    def displacement_sd(self) -> np.ndarray:
        return np.sqrt(self.variance[:, 1])


def initial_state(config: ObserverConfig, temperature=None):
    """(s0, C0): the state at rest under the stated load and its prior covariance."""
    rig = config.rig
    t0 = rig.ambient if temperature is None else float(temperature)
    x0 = rest_extension(config.sample, rig, t0)
    s0 = np.array([t0, x0, 0.0, rig.force, 0.0])
    # The load's prior spreads x too: dx = f11 dF with f11 = dx/dF at rest.
    f11 = (rest_extension(config.sample, rig, t0, rig.force + 1e-3) - x0) / 1e-3
    sd_f = config.load_prior_sd()
    c0 = np.diag([config.initial_temperature_sd**2, (f11 * sd_f) ** 2, 1e-8, 0.0, 0.0])
    c0[4, 4] = config.noise["sd_theta"] ** 2
    c0[3, 3] = sd_f**2
    c0[1, 3] = c0[3, 1] = f11 * sd_f**2
    return s0, c0


def _as_load(load, n):
    if load is None:
        return np.full(n, np.nan)
    return np.ascontiguousarray(np.broadcast_to(np.asarray(load, float), (n,)))


def estimate(
    time, voltage, current, config: ObserverConfig, load=None, initial_temperature=None
) -> EstimateResult:
    """Estimate displacement and temperature over a whole log (compiled, causal).

    Parameters
    ----------
    time : array_like, shape (n,)
        [s], strictly increasing.
    voltage, current : array_like, shape (n,)
        Measured V [V] and I [A]; V is held from each sample to the next.
    config : ObserverConfig
    load : array_like, optional
        Logged load force [N] (NaN where not logged); default unknown.
    initial_temperature : float, optional
        The filter's initial guess [degC]; default ambient.

    Returns
    -------
    EstimateResult
    """
    from tcamlab.estimation import observer_kernel as K

    t = np.ascontiguousarray(time, float)
    v = np.ascontiguousarray(voltage, float)
    i = np.ascontiguousarray(current, float)
    n = t.size
    s0, c0 = initial_state(config, initial_temperature)
    out_s = np.empty((n, K.NX))
    out_var = np.empty((n, K.NX))
    out_nis = np.empty(n)
    out_sv = np.empty(n)
    p = parameter_vector(config.sample, config.rig, config.lead_resistance)
    K.ekf_batch(
        t, v, i, _as_load(load, n), s0, c0, p, config.noise_vector(), config.table.values,
        config.table.grid, MAX_STEP_S, out_s, out_var, out_nis, out_sv,
    )  # fmt: skip
    x_start = rest_extension(config.sample, config.rig)
    return EstimateResult(
        t, out_s[:, 1] - x_start, out_s[:, 0], out_s[:, 3], out_var, out_nis, x_start, out_sv
    )


class SelfSensingObserver:
    """The estimator on a live stream: one :meth:`step` per sample.

    Parameters
    ----------
    config : ObserverConfig
    dt : float
        Sample period [s] (a call may pass its own).
    initial_temperature : float, optional
        [degC]; default ambient.

    Examples
    --------
    >>> obs = SelfSensingObserver(config, dt=1e-3)          # doctest: +SKIP
    >>> delta, temperature, cov = obs.step(4.0, 0.1)        # doctest: +SKIP
    """

    def __init__(self, config: ObserverConfig, dt: float = 1e-3, initial_temperature=None):
        from tcamlab.estimation import observer_kernel as K

        self._k = K
        self.config = config
        self.dt = float(dt)
        self.state, self.covariance = initial_state(config, initial_temperature)
        self.extension0 = rest_extension(config.sample, config.rig)
        self._p = parameter_vector(config.sample, config.rig, config.lead_resistance)
        self._noise = config.noise_vector()
        self._carry = np.zeros(6)  # V, I of the last sample; the jump detector's sums and hold; S
        self._nsub = max(1, int(np.ceil(self.dt / MAX_STEP_S)))
        self._first = True
        self.nis = float("nan")

    def step(self, voltage: float, current: float, load: float | None = None, dt: float | None = None):
        """Take one sample (V [V], I [A], optional load force [N]).

        Returns
        -------
        delta : float
            Estimated displacement from the start, positive longer [m].
        temperature : float
            [degC].
        covariance : ndarray, shape (4, 4)
            Of (T, x, v, F), a copy.
        """
        lf = float("nan") if load is None else float(load)
        if self._first:  # the first sample only starts the power held over the next interval
            self._carry[0], self._carry[1] = voltage, current
            self._first = False
            if lf == lf:
                self._k.first_load_update(self.state, self.covariance, lf, self._noise[5], self._p)
        else:
            h = self.dt if dt is None else float(dt)
            nsub = self._nsub if dt is None else max(1, int(np.ceil(h / MAX_STEP_S)))
            self.nis = self._k.ekf_step(
                self.state, self.covariance, float(voltage), float(current), lf, h, self._p, nsub,
                self._noise, self.config.table.values, self.config.table.grid, self._carry,
            )  # fmt: skip
        return self.state[1] - self.extension0, self.state[0], self.covariance.copy()
