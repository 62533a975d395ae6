"""The virtual rig's measurement chains: what each lab instrument does to a true value.

Each chain takes the exact quantity [SI] and returns what the logger writes
[SI]: instrument noise (times ``noise_scale``), ADC codes, tare and display
resolution. Each has a matching ``*_sd`` giving the standard deviation of
that chain (noise and quantisation together, :func:`chain_sd`). The kind
modules (:mod:`tcamlab.kinds`) build their rig's ``measure`` and
``instrument_sd`` from these; the constants are documented in the table of
:mod:`tcamlab.rig`.

The random draws are taken in a fixed order inside each chain, so a run's
bytes depend only on the seed and the order the kind calls the chains in.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "THERMOMETER_SD_C",
    "THERMOMETER_RESOLUTION_C",
    "LASER_NOISE_SD_M",
    "LASER_SPAN_M",
    "ADC_BITS",
    "LASER_QUANTUM_M",
    "LASER_TARE_SAMPLES",
    "LASER_LOG_RESOLUTION_M",
    "ENCODER_RESOLUTION_M",
    "LOADCELL_SD_N",
    "LOADCELL_OFFSET_N",
    "LOADCELL_SPAN_N",
    "LOADCELL_BITS",
    "LOADCELL_QUANTUM_N",
    "OHMMETER_SD_OHM",
    "OHMMETER_RESOLUTION_OHM",
    "CAMERA_SD_PER_M",
    "CAMERA_RESOLUTION_PER_M",
    "CURRENT_SENSE_SD_A",
    "CURRENT_SENSE_SPAN_A",
    "CURRENT_SENSE_BITS",
    "quantise",
    "chain_sd",
    "thermometer",
    "thermometer_sd",
    "laser",
    "laser_zeroed",
    "laser_sd",
    "encoder",
    "encoder_sd",
    "load_cell",
    "load_cell_tare",
    "load_cell_sd",
    "ohmmeter",
    "ohmmeter_sd",
    "camera",
    "camera_sd",
    "current_sense",
    "current_sense_sd",
]

# --- constants (see the table of tcamlab.rig) -----------------------------------------

THERMOMETER_SD_C = 0.2
"""Thermocouple reader noise in the oven's vent hole [degC]."""
THERMOMETER_RESOLUTION_C = 0.1
"""Display resolution of the thermocouple reader [degC]."""

LASER_NOISE_SD_M = 5e-6
"""Analog noise of the laser displacement sensor [m]."""
LASER_SPAN_M = 10e-3
"""Range of the laser output read by the ADC [m]."""
ADC_BITS = 10
"""Bits of the Arduino ADC reading the laser."""
LASER_QUANTUM_M = LASER_SPAN_M / (2**ADC_BITS - 1)
"""One ADC code of the laser [m] (10 mm / 1023 = 9.78 um)."""
LASER_TARE_SAMPLES = 64
"""Readings at rest the sketch averages to zero the laser."""
LASER_LOG_RESOLUTION_M = 1e-6
"""Displacement written with 3 decimals in mm [m]."""

ENCODER_RESOLUTION_M = 1e-5
"""Linear-actuator encoder grid [m]."""
LOADCELL_SD_N = 2e-3
"""LSP-5 load cell with its amplifier [N]."""
LOADCELL_OFFSET_N = -0.4e-3
"""Residual zero offset of the load cell after taring [N]."""
LOADCELL_SPAN_N = (-0.5, 0.5)
"""Amplifier span read by the load cell's ADC [N]."""
LOADCELL_BITS = 12
"""Bits of the load cell's ADC."""
LOADCELL_QUANTUM_N = (LOADCELL_SPAN_N[1] - LOADCELL_SPAN_N[0]) / (2**LOADCELL_BITS - 1)
"""One ADC code of the load cell [N] (1 N / 4095 = 0.244 mN)."""

OHMMETER_SD_OHM = 2e-3
"""Bench multimeter noise on a 10-30 ohm sensor [ohm]."""
OHMMETER_RESOLUTION_OHM = 1e-3
"""Display resolution of the multimeter [ohm]."""

CURRENT_SENSE_SD_A = 0.05e-3
"""Noise of a current-sense chain (0.1 ohm shunt into an INA219-class monitor) [A]."""
CURRENT_SENSE_SPAN_A, CURRENT_SENSE_BITS = 0.4, 12
"""Span and resolution of the current ADC: quantum 0.4 A / 4095 = 98 uA."""
CAMERA_SD_PER_M = 0.2
"""Curvature noise of the camera images [1/m]."""
CAMERA_RESOLUTION_PER_M = 1e-3
"""Curvature written with 6 decimals in 1/mm [1/m]."""


# --- helpers -------------------------------------------------------------------------------


def quantise(x, q: float) -> np.ndarray:
    """``x`` rounded to the nearest multiple of ``q`` (same units as ``x``)."""
    return np.round(np.asarray(x, float) / q) * q


def chain_sd(sd: float, *quanta: float, noise_scale: float = 1.0) -> float:
    """Standard deviation of a chain: noise ``noise_scale * sd`` and uniform quantisation steps.

    Parameters
    ----------
    sd : float
        Instrument noise sd [units of the quantity].
    *quanta : float
        Quantisation steps of the chain [same units]; each adds ``q**2 / 12``.
    noise_scale : float
        Multiplies ``sd`` (not the quantisation).

    Returns
    -------
    float
        sqrt((noise_scale sd)^2 + sum q^2 / 12) [same units].
    """
    return math.sqrt((float(noise_scale) * sd) ** 2 + sum(q * q / 12.0 for q in quanta))


# --- chains --------------------------------------------------------------------------------


def thermometer(temperature: np.ndarray, rng: np.random.Generator, noise_scale: float) -> np.ndarray:
    """Logged temperature [degC]: reader noise, then the display resolution."""
    temp = np.asarray(temperature, float)
    noisy = temp + float(noise_scale) * rng.normal(0.0, THERMOMETER_SD_C, temp.size)
    return quantise(noisy, THERMOMETER_RESOLUTION_C)


def thermometer_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`thermometer` [degC]."""
    return chain_sd(THERMOMETER_SD_C, THERMOMETER_RESOLUTION_C, noise_scale=noise_scale)


def current_sense(current: np.ndarray, rng: np.random.Generator, noise_scale: float) -> np.ndarray:
    """Logged current [A]: the monitor's noise, then its ADC (codes 0 to 2^bits - 1 over the span)."""
    cur = np.asarray(current, float)
    noisy = cur + float(noise_scale) * rng.normal(0.0, CURRENT_SENSE_SD_A, cur.size)
    q = CURRENT_SENSE_SPAN_A / (2**CURRENT_SENSE_BITS - 1)
    return np.clip(np.round(noisy / q), 0, 2**CURRENT_SENSE_BITS - 1) * q


def current_sense_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`current_sense` [A]."""
    q = CURRENT_SENSE_SPAN_A / (2**CURRENT_SENSE_BITS - 1)
    return chain_sd(CURRENT_SENSE_SD_A, q, noise_scale=noise_scale)


def laser(
    displacement: np.ndarray, rng: np.random.Generator, noise_scale: float, *, noisy_zero: bool = False
) -> np.ndarray:
    """Logged displacement [m] through the laser, its 10-bit ADC and the zero (:func:`laser_zeroed`)."""
    return laser_zeroed(displacement, rng, noise_scale, noisy_zero=noisy_zero)[0]


def laser_zeroed(
    displacement: np.ndarray, rng: np.random.Generator, noise_scale: float, *, noisy_zero: bool = False
) -> tuple[np.ndarray, float]:
    """Logged displacement [m] through the laser, its 10-bit ADC and the zero, and the zero error [m].

    The sensor rests near mid-span (a random mount within +-0.5 mm). By
    default the sketch zeroes on the mean code of :data:`LASER_TARE_SAMPLES`
    readings at rest and logs that as row 0 (exactly 0), so later rows carry
    the tare error (about sd / 8) as an offset. With ``noisy_zero`` the zero
    is the run's first reading itself (a lab that zeroes on one reading, or
    re-zeroes its log on the first row): row 0 is still 0, and every later
    row carries that reading's noise and quantisation (about one noise sd)
    as an offset. Written to :data:`LASER_LOG_RESOLUTION_M`.

    Parameters
    ----------
    displacement : ndarray
        True displacement from the first row [m].
    rng : numpy.random.Generator
        Draws the mount, the tare readings (not with ``noisy_zero``) and the
        readings, in that order.
    noise_scale : float
        Multiplies :data:`LASER_NOISE_SD_M`.
    noisy_zero : bool
        Zero on the first reading instead of the averaged tare.

    Returns
    -------
    (ndarray, float)
        The logged displacement [m] and the zero error [m]: the constant the
        rows after the first carry, logged = true + zero error + noise.
    """
    ns = float(noise_scale)
    disp = np.asarray(displacement, float)
    rest = 0.5 * LASER_SPAN_M + rng.uniform(-0.5e-3, 0.5e-3)
    top = 2**ADC_BITS - 1

    def codes(x):
        return np.clip(np.round((rest + x) / LASER_QUANTUM_M), 0, top)

    if noisy_zero:
        reading = codes(disp + ns * rng.normal(0.0, LASER_NOISE_SD_M, disp.size))
        zero, zero_at = reading[0], disp[0]
    else:
        zero = codes(
            np.full(LASER_TARE_SAMPLES, 0.0) + ns * rng.normal(0.0, LASER_NOISE_SD_M, LASER_TARE_SAMPLES)
        ).mean()
        zero_at = 0.0
        reading = codes(disp + ns * rng.normal(0.0, LASER_NOISE_SD_M, disp.size))
    out = (reading - zero) * LASER_QUANTUM_M
    out[0] = 0.0
    return quantise(out, LASER_LOG_RESOLUTION_M), float(rest + zero_at - zero * LASER_QUANTUM_M)


def laser_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`laser` [m] (noise, ADC code and log resolution)."""
    return chain_sd(LASER_NOISE_SD_M, LASER_QUANTUM_M, LASER_LOG_RESOLUTION_M, noise_scale=noise_scale)


def encoder(position: np.ndarray) -> np.ndarray:
    """Logged actuator position [m]: the encoder grid, no noise."""
    return quantise(position, ENCODER_RESOLUTION_M)


def encoder_sd() -> float:
    """Standard deviation of :func:`encoder` [m] (its grid only)."""
    return chain_sd(0.0, ENCODER_RESOLUTION_M)


def load_cell(
    force: np.ndarray, rng: np.random.Generator, noise_scale: float, *, offset: float = LOADCELL_OFFSET_N
) -> np.ndarray:
    """Logged force [N]: zero offset and noise, then the amplifier's 12-bit ADC (clipped to its span).

    ``offset`` [N] is the zero offset after taring (default the rig's fixed
    :data:`LOADCELL_OFFSET_N`; :func:`load_cell_tare` draws a run's own).
    """
    f = np.asarray(force, float)
    reading = f + offset + float(noise_scale) * rng.normal(0.0, LOADCELL_SD_N, f.size)
    code = np.clip(np.round((reading - LOADCELL_SPAN_N[0]) / LOADCELL_QUANTUM_N), 0, 2**LOADCELL_BITS - 1)
    return code * LOADCELL_QUANTUM_N + LOADCELL_SPAN_N[0]


def load_cell_tare(rng: np.random.Generator, noise_scale: float) -> float:
    """A run's zero offset [N] when the load cell is tared on one noisy reading.

    The fixed residual :data:`LOADCELL_OFFSET_N` minus the noise of the one
    tare reading, N(0, noise_scale :data:`LOADCELL_SD_N`): redrawn per run.
    """
    return LOADCELL_OFFSET_N - float(noise_scale) * rng.normal(0.0, LOADCELL_SD_N)


def load_cell_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`load_cell` [N] (the offset is a bias, not counted)."""
    return chain_sd(LOADCELL_SD_N, LOADCELL_QUANTUM_N, noise_scale=noise_scale)


def ohmmeter(resistance: np.ndarray, rng: np.random.Generator, noise_scale: float) -> np.ndarray:
    """Logged resistance [ohm]: multimeter noise, then its display resolution."""
    r = np.asarray(resistance, float)
    return quantise(
        r + float(noise_scale) * rng.normal(0.0, OHMMETER_SD_OHM, r.size), OHMMETER_RESOLUTION_OHM
    )


def ohmmeter_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`ohmmeter` [ohm]."""
    return chain_sd(OHMMETER_SD_OHM, OHMMETER_RESOLUTION_OHM, noise_scale=noise_scale)


def camera(curvature: np.ndarray, rng: np.random.Generator, noise_scale: float) -> np.ndarray:
    """Logged curvature [1/m]: image noise, then the written resolution."""
    k = np.asarray(curvature, float)
    return quantise(
        k + float(noise_scale) * rng.normal(0.0, CAMERA_SD_PER_M, k.size), CAMERA_RESOLUTION_PER_M
    )


def camera_sd(noise_scale: float = 1.0) -> float:
    """Standard deviation of :func:`camera` [1/m]."""
    return chain_sd(CAMERA_SD_PER_M, CAMERA_RESOLUTION_PER_M, noise_scale=noise_scale)
