"""Typed sample and rig parameters, in SI, and the thesis presets with provenance.

Everything inside tcamlab is SI (m, kg, s, N, Pa, K or degC for absolute
temperatures, ohm, V, W, J). The experiment files use lab units with the
unit in the key name (``fiber_diameter_mm``); :data:`SAMPLE_KEYS` and
:data:`RIG_KEYS` are the one place that maps those keys to the SI fields and
their conversion factors.

Each preset value carries its provenance: the thesis section or equation it
comes from, or ``"assumed: <reason>"`` where the thesis gives no value.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from tcamlab.errors import ConfigError

G_ACCEL = 9.80665
"""Standard gravity [m/s^2]."""

SILVER_TCR = 3.8e-3
"""Temperature coefficient of resistance of silver [1/K] (CRC Handbook)."""


@dataclass(frozen=True)
class Sample:
    """Geometry and material of one twisted-and-coiled fiber sample (SI).

    Attributes
    ----------
    fiber_diameter : float
        Diameter of the twisted fiber, d0 [m].
    fiber_length : float
        Length of the twisted fiber that forms the coil, l [m].
    coil_length : float
        Length of the coiled actuator or sensor, L [m]; sin(alpha0) = L / l.
    coil_diameter : float
        Outside diameter of the coil, D [m].
    twists : float
        Number of turns inserted into the fiber over its length l [turns].
        The twist angle of section 2.3.1 is ``2 pi twists`` [rad]; the twist
        per unit length in the bias angle is ``twists / l`` [turns/m].
    youngs_modulus : float
        Young's modulus of the fiber, E [Pa].
    thread_plies : int
        Number of plies in the thread; the filament radius is r / plies.
    max_volume_fraction : float
        Maximum fiber volume fraction V_fmax [-].
    radial_cte : float
        Transverse (radial) thermal expansion coefficient rho [1/K], positive
        when the fiber swells on heating (see README, "sign of rho").
    shear_modulus_slope : float
        Drop of the transverse shear modulus per kelvin, eq. (2.13) [Pa/K].
    """

    fiber_diameter: float
    fiber_length: float
    coil_length: float
    coil_diameter: float
    twists: float
    youngs_modulus: float
    thread_plies: int = 2
    max_volume_fraction: float = 0.887
    radial_cte: float = 8.1e-5
    shear_modulus_slope: float = 1.11e6

    def __post_init__(self) -> None:
        validate_sample(self)

    @property
    def sin_alpha0(self) -> float:
        """Sine of the initial pitch angle, L / l [-]."""
        return self.coil_length / self.fiber_length

    @property
    def alpha0(self) -> float:
        """Initial pitch angle [rad]."""
        return math.asin(self.sin_alpha0)

    @property
    def n_coils(self) -> float:
        """Number of coils n = l cos(alpha0) / (pi D) [-] (section 2.3.2)."""
        return self.fiber_length * math.cos(self.alpha0) / (math.pi * self.coil_diameter)

    def replace(self, **changes: float) -> Sample:
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def model_kwargs(self) -> dict[str, float]:
        """The fields as keyword arguments for the model functions."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def sensor_kwargs(self) -> dict[str, float]:
        """Keyword arguments of the sensing and curvature models (no thermal fields)."""
        kw = self.model_kwargs()
        del kw["radial_cte"], kw["shear_modulus_slope"]
        return kw


def _key(name: str, value) -> str:
    """``coil_length_mm = 95``: an SI field as its experiment-file key and value."""
    key, factor = next((k, f) for k, (si, f) in SAMPLE_KEYS.items() if si == name)
    if isinstance(value, (int, float)) and math.isfinite(value):
        return f"{key} = {value / factor:g}"
    return f"{key} = {value!r}"


def _coil_problems(s: Sample) -> list[str]:
    """What makes a sample no coil: no twist, a coil as long as its fiber, or no wider than it."""
    out = []
    if isinstance(s.twists, (int, float)) and s.twists == 0:
        out.append(_key("twists", s.twists))
    if (
        _finite_positive(s.coil_length)
        and _finite_positive(s.fiber_length)
        and s.coil_length >= s.fiber_length
    ):
        out.append(
            f"{_key('coil_length', s.coil_length)} not shorter than {_key('fiber_length', s.fiber_length)}"
        )
    if (
        _finite_positive(s.coil_diameter)
        and _finite_positive(s.fiber_diameter)
        and s.coil_diameter <= s.fiber_diameter
    ):
        out.append(
            f"{_key('coil_diameter', s.coil_diameter)} does not exceed {_key('fiber_diameter', s.fiber_diameter)}"
        )
    return out


def _finite_positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def validate_sample(s: Sample, where: str = "[sample]") -> None:
    """Raise :class:`ConfigError` when a sample is physically impossible, or no coil (outside the
    models' scope), naming every key at fault in one message."""
    coil = _coil_problems(s)
    positive = (
        "fiber_diameter", "fiber_length", "coil_length", "coil_diameter",
        "twists", "youngs_modulus", "thread_plies", "max_volume_fraction",
    )  # fmt: skip
    bad = [
        f"{_key(n, getattr(s, n))} must be a positive finite number"
        for n in positive
        if not _finite_positive(getattr(s, n)) and not (n == "twists" and coil and s.twists == 0)
    ]
    if _finite_positive(s.max_volume_fraction) and s.max_volume_fraction > 1:
        bad.append(f"{_key('max_volume_fraction', s.max_volume_fraction)} exceeds 1 (a volume fraction)")
    if not math.isfinite(s.radial_cte) or not math.isfinite(s.shear_modulus_slope):
        bad.append("radial_cte_per_K and shear_modulus_slope_MPa_per_K must be finite")
    if len(coil) >= 2 or (coil and s.twists == 0):
        rest = f"; also {'; '.join(bad)}" if bad else ""
        raise ConfigError(
            f"{where}: not a coiled sample ({'; '.join(coil)}){rest}: tcamlab's models describe "
            "twisted-and-coiled samples only, so a straight fiber is outside their scope",
            hint="a coiled sample has twists > 0, coil_length_mm < fiber_length_mm and "
            "coil_diameter_mm > fiber_diameter_mm",
        )
    problems = bad + [
        p.replace("does not exceed", "must exceed")
        + (", so sin(alpha0) = L/l >= 1" if "shorter" in p else "")
        for p in coil
    ]
    if problems:
        raise ConfigError(
            f"{where}: " + "; ".join(problems),
            hint="give each key in the unit its name ends in (mm, GPa), e.g. coil_length_mm = 20; "
            "a coil is made from a longer twisted fiber and is wider than it",
        )


@dataclass(frozen=True)
class Rig:
    """Rig and operating parameters of a test (SI).

    Attributes
    ----------
    load : float
        Hanging mass [kg].
    ambient : float
        Ambient (reference) temperature T_a [degC].
    voltage : float
        Step voltage [V].
    pulse : float
        Duration of the voltage pulse [s].
    resistance : float
        Electrical resistance of the actuator R [ohm].
    thermal_mass : float
        Thermal mass C_th [J/K].
    heat_loss : float
        Heat loss coefficient lambda [W/K].
    damping : float
        Damping coefficient b [N s/m].
    initial_resistance : float or None
        Unloaded sensor resistance R0 [ohm]; None means "the run's first row".
    spring_constant : float or None
        Sensor spring constant S in F = S delta [N/m]; None means "identified".
    sensor_offset : float
        Sensor-to-cable distance d1 of the curvature robot [m].
    segment_lengths : tuple of float
        Rest lengths of the robot's sensor segments, tip first [m].
    tcr : float
        Temperature coefficient of the heater/sensor coating's resistance [1/K]
        (self-sensing; silver's by default).
    heater_tcr : float
        Temperature coefficient beta of the actuator's resistance in the voltage-step test,
        R(T) = R (1 + beta (T - T_a)) [1/K]; 0 is the thesis's constant R (sec. 2.5.2).
        Calibrated where the runs log ``current_A`` or ``resistance_ohm``.
    lead_resistance : float
        R_lead of the leads and contacts in series with a self-sensing muscle, unheated
        [ohm]: the voltage is read across leads and muscle, so only I^2 (R - R_lead) heats.
        0 is tcamlab's law.
    stretch_factor : float
        k_s, the self-sensing muscle's stretch sensitivity relative to chapter 3's map,
        R = R_lead + R0 (1 + k_s (g(x) - 1)) heat(T) [-]; 1 is tcamlab's law.
    tcr2 : float
        Quadratic temperature coefficient of a self-sensing muscle's coating,
        heat(T) = (1 + tcr dT + tcr2 dT^2) / (1 + rho dT)^2 [1/K^2]; 0 is tcamlab's (linear) law.
    uncertainty : mapping
        Standard deviations of any of the fields above, same units.
    """

    load: float = 0.05
    ambient: float = 20.0
    voltage: float = 10.0
    pulse: float = 1.0
    resistance: float = 40.0
    thermal_mass: float = 0.0266
    heat_loss: float = 0.00893
    damping: float = 0.84
    initial_resistance: float | None = None
    spring_constant: float | None = None
    sensor_offset: float = 9e-3
    segment_lengths: tuple[float, ...] = (30e-3, 30e-3)
    tcr: float = SILVER_TCR
    heater_tcr: float = 0.0
    lead_resistance: float = 0.0
    stretch_factor: float = 1.0
    tcr2: float = 0.0
    uncertainty: Mapping[str, float] = field(default_factory=dict)

    @property
    def force(self) -> float:
        """Weight of the hanging load, m g [N]."""
        return self.load * G_ACCEL

    def replace(self, **changes) -> Rig:
        return dataclasses.replace(self, **changes)


# --- key map between experiment files (lab units) and SI fields -------------
# key in TOML -> (SI field, factor to SI). The single place that knows units
# of experiment-file keys.
SAMPLE_KEYS: dict[str, tuple[str, float]] = {
    "fiber_diameter_mm": ("fiber_diameter", 1e-3),
    "fiber_length_mm": ("fiber_length", 1e-3),
    "coil_length_mm": ("coil_length", 1e-3),
    "coil_diameter_mm": ("coil_diameter", 1e-3),
    "twists": ("twists", 1.0),
    "youngs_modulus_GPa": ("youngs_modulus", 1e9),
    "thread_plies": ("thread_plies", 1.0),
    "max_volume_fraction": ("max_volume_fraction", 1.0),
    "radial_cte_per_K": ("radial_cte", 1.0),
    "shear_modulus_slope_MPa_per_K": ("shear_modulus_slope", 1e6),
}

RIG_KEYS: dict[str, tuple[str, float]] = {
    "load_g": ("load", 1e-3),
    "ambient_C": ("ambient", 1.0),
    "voltage_V": ("voltage", 1.0),
    "pulse_s": ("pulse", 1.0),
    "resistance_ohm": ("resistance", 1.0),
    "thermal_mass_J_per_K": ("thermal_mass", 1.0),
    "heat_loss_W_per_K": ("heat_loss", 1.0),
    "damping_N_s_per_m": ("damping", 1.0),
    "initial_resistance_ohm": ("initial_resistance", 1.0),
    "spring_constant_N_per_m": ("spring_constant", 1.0),
    "sensor_offset_mm": ("sensor_offset", 1e-3),
    "segment_lengths_mm": ("segment_lengths", 1e-3),
    "tcr_per_K": ("tcr", 1.0),
    "heater_tcr_per_K": ("heater_tcr", 1.0),
    "lead_resistance_ohm": ("lead_resistance", 1.0),
    "stretch_factor": ("stretch_factor", 1.0),
    "tcr2_per_K2": ("tcr2", 1.0),
}


@dataclass(frozen=True)
class PresetValue:
    """One preset value in SI with where it comes from."""

    value: object
    provenance: str


@dataclass(frozen=True)
class Preset:
    """A named parameter set from the thesis.

    ``sample`` and ``rig`` map SI field names of :class:`Sample` and
    :class:`Rig` to :class:`PresetValue`; ``uncertainty`` maps rig fields to
    their stated standard deviations.
    """

    name: str
    description: str
    sample: Mapping[str, PresetValue]
    rig: Mapping[str, PresetValue]
    uncertainty: Mapping[str, PresetValue] = field(default_factory=dict)

    def build_sample(self, **overrides: float) -> Sample:
        values = {k: v.value for k, v in self.sample.items()}
        values.update(overrides)
        return Sample(**values)

    def build_rig(self, **overrides) -> Rig:
        values = {k: v.value for k, v in self.rig.items()}
        unc = {k: v.value for k, v in self.uncertainty.items()}
        unc.update(overrides.pop("uncertainty", {}) or {})
        values.update(overrides)
        return Rig(uncertainty=unc, **values)

    def provenance(self) -> dict[str, str]:
        """Field name -> provenance text, sample and rig together."""
        out = {k: v.provenance for k, v in self.sample.items()}
        out.update({k: v.provenance for k, v in self.rig.items()})
        out.update({f"sd({k})": v.provenance for k, v in self.uncertainty.items()})
        return out


P = PresetValue

_NYLON_E = P(
    3.45e9, "sec. 3.3 (Young's modulus of nylon 6,6, used for chapter 2 too: assumed, chapter 2 gives no E)"
)
_RHO = P(
    8.1e-5, "sec. 2.5.1 |rho| = 8.1e-5 /K; sign taken positive (radial swelling), see README 'sign of rho'"
)
_SLOPE = P(1.11e6, "sec. 2.3.3 text: 0.00111 GPa per degC (eq. 2.13 misprints the factor)")
_VFMAX = P(0.887, "sec. 2.5.1, V_fmax = 0.887 [43]")
_PLIES = P(2, "sec. 2.5.1: 2-ply thread, r_f = r/2")

THESIS_TCA = Preset(
    name="thesis-tca",
    description="Silver-coated nylon TCA of chapter 2 (static oven and voltage-step tests)",
    sample={
        "fiber_diameter": P(0.17e-3, "sec. 2.5: thread diameter 0.17 mm"),
        "fiber_length": P(95e-3, "sec. 2.5.1: l = 95 mm"),
        "coil_length": P(
            20e-3,
            "assumed: thesis omits it; 20 mm gives sin(alpha0) = 0.21, a coil "
            "slightly opened by annealing under load (closed coils of this "
            "wire would give about 14 mm)",
        ),
        "coil_diameter": P(0.36e-3, "sec. 2.5: actuator diameter 0.36 mm"),
        "twists": P(
            150.0,
            "assumed: thesis omits it; 150 turns over 95 mm give a fiber bias "
            "angle of 40 deg, typical of coiled nylon [13]; G_t = 170 MPa keeps "
            "G_t' > 0 up to 153 K above ambient",
        ),
        "youngs_modulus": _NYLON_E,
        "thread_plies": _PLIES,
        "max_volume_fraction": _VFMAX,
        "radial_cte": _RHO,
        "shear_modulus_slope": _SLOPE,
    },
    rig={
        "load": P(0.05, "sec. 2.5.1/2.5.2: 50 g hanging weight"),
        "ambient": P(20.0, "sec. 2.5.2: T_a = 20 degC"),
        "voltage": P(10.0, "sec. 2.5.2: 10 V"),
        "pulse": P(1.0, "sec. 2.5.2: applied for one second"),
        "resistance": P(40.0, "sec. 2.5.2: R = 40 ohm"),
        "thermal_mass": P(0.0266, "sec. 2.5.2: C_th = 0.0266 J/K [22]"),
        "heat_loss": P(0.00893, "sec. 2.5.2: lambda = 0.00893 W/K [22]"),
        "damping": P(0.84, "sec. 2.5.2: b = 0.84 N s/m [22]"),
    },
    uncertainty={
        "thermal_mass": P(0.00845, "sec. 2.5.2: +- 0.00845 J/K"),
        "heat_loss": P(0.01615, "sec. 2.5.2: +- 0.01615 W/K"),
        "damping": P(0.12, "sec. 2.5.2: +- 0.12 N s/m"),
    },
)

THESIS_TCS = Preset(
    name="thesis-tcs",
    description="Silver-coated nylon twisted-and-coiled sensor of chapter 3 (pull test)",
    sample={
        "fiber_diameter": P(0.4e-3, "sec. 3.3: d0 = 0.4 mm"),
        "fiber_length": P(328e-3, "sec. 3.3: l = 328 mm"),
        "coil_length": P(90e-3, "sec. 3.3: L = 90 mm"),
        "coil_diameter": P(0.8e-3, "sec. 3.3: D = 0.8 mm"),
        "twists": P(750.0, "sec. 3.3: phi0 = 750 twists (a count, not an angle)"),
        "youngs_modulus": P(3.45e9, "sec. 3.3: E = 3.45 GPa (nylon 6,6)"),
        "thread_plies": P(2, "sec. 3.3 with sec. 2.5.1: 2-ply thread, r_f = r/2"),
        "max_volume_fraction": P(0.887, "sec. 2.5.1, V_fmax = 0.887 [43]"),
        "radial_cte": _RHO,
        "shear_modulus_slope": _SLOPE,
    },
    rig={
        "ambient": P(20.0, "assumed: room temperature, as in sec. 2.5.2"),
        "initial_resistance": P(30.0, "assumed: thesis gives no R0; only R/R0 enters the model"),
    },
)

THESIS_TCS_SPRING_CONSTANT = P(
    4.7,
    "assumed: thesis identifies S from its pull tests but gives no value; 4.7 N/m is 60% "
    "of the model's own spring stiffness 1/f11(alpha0) = 7.9 N/m, which keeps the sensing "
    "solve well conditioned (S f11 = 0.6). Not part of the thesis-tcs preset: S is "
    "identified from pull tests (fit-spring); the simulation template sets it",
)
"""The spring constant the sensing simulation template uses as truth [N/m]."""

THESIS_ROBOT = Preset(
    name="thesis-robot",
    description="Two-segment EcoFlex robot with an embedded TCS of chapter 4",
    sample={
        # The embedded sensor is assumed to be the chapter-3 sensor cut to the
        # 60 mm robot: same fiber and coil, lengths and twists scaled by 60/90.
        "fiber_diameter": P(0.4e-3, "assumed: chapter-3 sensor fiber, d0 = 0.4 mm"),
        "fiber_length": P(328e-3 * 60 / 90, "assumed: chapter-3 sensor scaled to 60 mm"),
        "coil_length": P(60e-3, "sec. 4.3: sensor spans the 60 mm robot"),
        "coil_diameter": P(0.8e-3, "assumed: chapter-3 sensor, D = 0.8 mm"),
        "twists": P(750.0 * 60 / 90, "assumed: chapter-3 twist density"),
        "youngs_modulus": P(3.45e9, "sec. 3.3: E = 3.45 GPa"),
        "thread_plies": P(2, "sec. 3.3: 2-ply thread"),
        "max_volume_fraction": P(0.887, "sec. 2.5.1"),
        "radial_cte": _RHO,
        "shear_modulus_slope": _SLOPE,
    },
    rig={
        "ambient": P(20.0, "assumed: room temperature"),
        "sensor_offset": P(9e-3, "sec. 4.3: d1 = 9 mm"),
        "segment_lengths": P(
            (30e-3, 30e-3),
            "sec. 4.3: 60 mm robot in two halves (tip EcoFlex 00-10, base 00-30)",
        ),
        "initial_resistance": P(10.0, "assumed: resistance of one 30 mm segment at rest; only R/R0 enters"),
        "spring_constant": P(
            14.1, "assumed: the chapter-3 value scaled to a 30 mm segment (4.7 N/m x 90/30)"
        ),
    },
)

PRESETS: dict[str, Preset] = {p.name: p for p in (THESIS_TCA, THESIS_TCS, THESIS_ROBOT)}


def get_preset(name: str) -> Preset:
    """Return the named preset or raise :class:`ConfigError` listing the names."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ConfigError(
            f"[sample] preset: unknown preset {name!r}",
            hint="one of " + ", ".join(sorted(PRESETS)),
        ) from None
