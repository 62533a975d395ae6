"""The self-sensing rig's program: the commanded voltage and hanging mass of one powered run.

One run holds every protocol of the bench in order (:data:`SEGMENTS`): a quiet start at the
probe voltage, voltage steps, PWM, a sine and a chirp, with a rider put on the hanger at a
random time (the load changes, so the thermal model alone cannot predict the displacement).
:mod:`tcamlab.kinds.selfsensing` runs it through the virtual rig.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from tcamlab.params import Rig

RATE_HZ = 100
"""Logging rate of the powered run [Hz]."""
PROBE_V = 1.5
"""Probe voltage between heating phases [V]: keeps a current to read R (about 35 mA, 6 K of self-heating)."""
SEGMENTS = (
    ("rest", 2.0),
    ("steps", 12.0),
    ("pwm", 12.0),
    ("sine", 12.0),
    ("chirp", 12.0),
)
"""Protocol segments and their durations [s], in order."""
STEP_LEVELS_V = (4.0, 6.0)
"""Voltage steps, each 3 s on then 3 s at the probe [V] (6 V on 40 ohm: about 100 K at steady state)."""
PWM_V, PWM_HZ, PWM_DUTY = 6.0, 1.0, 0.5
"""PWM amplitude [V], frequency [Hz] and duty cycle [-]."""
SINE_MEAN_V, SINE_AMP_V, SINE_HZ = 3.5, 2.5, 0.25
"""Sine voltage: mean [V], amplitude [V], frequency [Hz]."""
CHIRP_F0_HZ, CHIRP_F1_HZ = 0.05, 1.0
"""Chirp of the same mean and amplitude, linear from f0 to f1 over its segment [Hz]."""
RIDER_KG = 5e-3
"""Mass of the rider put on the hanger during the run [kg] (5 g, a tenth of the load)."""
RIDER_WINDOW_S = (15.0, 35.0)
"""The rider goes on at a uniform random time in this window [s]."""


def _segment_voltage(name: str, tau: np.ndarray, duration: float) -> np.ndarray:
    """Commanded voltage of one protocol segment at local times ``tau`` [s] from its start [V]."""
    if name == "steps":
        half = duration / (2 * len(STEP_LEVELS_V))
        k = np.minimum((tau // (2 * half)).astype(int), len(STEP_LEVELS_V) - 1)
        on = (tau % (2 * half)) < half
        return np.where(on, np.asarray(STEP_LEVELS_V)[k], PROBE_V)
    if name == "pwm":
        return np.where((tau * PWM_HZ) % 1.0 < PWM_DUTY, PWM_V, PROBE_V)
    if name == "sine":
        return SINE_MEAN_V + SINE_AMP_V * np.sin(2 * np.pi * SINE_HZ * tau)
    if name == "chirp":
        phase = 2 * np.pi * (CHIRP_F0_HZ * tau + 0.5 * (CHIRP_F1_HZ - CHIRP_F0_HZ) / duration * tau**2)
        return SINE_MEAN_V + SINE_AMP_V * np.sin(phase)
    return np.full(tau.shape, PROBE_V)


def protocol(rig: Rig, rng: np.random.Generator) -> pd.DataFrame:
    """The commanded voltage and hanging mass of one run.

    Parameters
    ----------
    rig : Rig
        ``load`` [kg] before the rider goes on.
    rng : numpy.random.Generator
        Draws the time the rider goes on (uniform in :data:`RIDER_WINDOW_S`).

    Returns
    -------
    pandas.DataFrame
        ``time`` [s], ``voltage`` [V] (held, 1 mV steps of the driver), ``load_mass`` [kg].
    """
    total = sum(d for _, d in SEGMENTS)
    t = np.arange(int(round(total * RATE_HZ))) / RATE_HZ
    v = np.empty(t.size)
    start = 0.0
    for name, duration in SEGMENTS:
        m = (t >= start - 1e-9) & (t < start + duration - 1e-9)
        v[m] = _segment_voltage(name, t[m] - start, duration)
        start += duration
    on = float(rng.uniform(*RIDER_WINDOW_S))
    mass = np.where(t >= on, rig.load + RIDER_KG, rig.load)
    return pd.DataFrame({"time": t, "voltage": np.round(v, 3), "load_mass": mass})
