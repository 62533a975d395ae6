"""Logging quantisation: the step of a logged column and the part of its error that
second differences cannot see.

A reading r = Q(x + n) of a slowly varying quantity x with white instrument noise n
(sd sigma) through a quantiser of step q has, averaged over where x sits in the step,
error variance sigma^2 + q^2 / 12 (the error of Q is uniform and independent of x + n
when x is). That error splits into a white part and the noise-averaged sawtooth
e(x) = E_n[Q(x + n)] - x, whose Fourier series

    e(x) = sum_k (-1)^k (q / (pi k)) exp(-2 pi^2 k^2 sigma^2 / q^2) sin(2 pi k x / q)

has variance :func:`hidden_variance`. While x moves by less than a step between rows,
e(x) moves with it: a smooth error that second differences of the residuals remove as
they remove a model's smooth misfit. With sigma >= q / 2 it is gone (exp(-pi^2)); a
quiet sensor on a coarse converter (the 10-bit laser ADC of the voltage-step rig, step
9.8 um, at a fifth of its noise: 1 um) keeps most of q^2 / 12. Its residuals then miss
a perfect model by sqrt(sigma^2 + q^2 / 12) = 3.0 um where second differences see
2.4 um, and a null experiment looked like a gap.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

__all__ = [
    "logging_step",
    "hidden_variance",
    "white_sigma",
    "slow_rows",
    "phase_concentration",
    "unseen_variance",
]

LATTICE_TOLERANCE = 0.15
"""A change counts as a whole number of steps when within this share of a step of one."""

LATTICE_SHARE = 0.95
"""Share of the nonzero row-to-row changes that must be whole numbers of steps."""

MIN_CHANGES = 20
"""Fewest nonzero row-to-row changes from which a step is inferred."""

MIN_STEP_QUANTILE = 0.05
"""The first guess of the step is this quantile of the nonzero row-to-row changes."""

MAX_HIDDEN_TO_SEEN = 3.0
"""Largest hidden quantisation sd believed, in multiples of the sd second differences see.
A reading that coarse and that quiet would show its staircase plainly; beyond it the lattice
is the protocol's (the pull test's encoder under a parameter error: predictions off the
lattice by an elongation-dependent amount pass the phase test, and a 1 mm "step" made the
displacement floor 0.29 mm against 0.06 mm seen). The laser at a fifth of its noise: 1.2."""

MAX_PHASE_CONCENTRATION = 0.5
"""Largest phase concentration of the predictions on a quantiser's step (:func:`unseen_variance`)."""

SERIES_TERMS = 64
"""Terms of the sawtooth's Fourier series in :func:`hidden_variance`."""


def logging_step(x) -> float | None:
    """The quantisation step of a logged column [its unit], or None if it has none.

    The smallest row-to-row change is a first guess q0; the step is refined as the mean
    change per step over the changes of at most five steps, which recovers an ADC code
    written with fewer decimals (9.775 um codes written as 9 or 10 um). A column is
    quantised when :data:`LATTICE_SHARE` of its changes are whole numbers of the step.

    Parameters
    ----------
    x : array_like
        The logged values.
    """
    d = np.abs(np.diff(np.asarray(x, float)))
    d = d[np.isfinite(d)]
    scale = float(np.max(np.abs(x))) if np.size(x) else 0.0
    d = d[d > 1e-12 * max(scale, 1e-300)]
    if d.size < MIN_CHANGES:
        return None
    q0 = float(np.quantile(d, MIN_STEP_QUANTILE))  # a rare smaller change is no step
    small = d[d <= 5.5 * q0]
    step = float(np.sum(small) / np.sum(np.maximum(np.round(small / q0), 1.0)))
    k = d / step
    on_lattice = np.abs(k - np.round(k)) <= LATTICE_TOLERANCE
    return step if np.mean(on_lattice) >= LATTICE_SHARE else None


def hidden_variance(sigma: float, step: float) -> float:
    """Variance of the noise-averaged quantisation error e(x) [unit^2] (module docstring).

    q^2 / 12 at sigma = 0, falling as exp(-4 pi^2 sigma^2 / q^2) once sigma nears q / 2.
    """
    if not step > 0:
        return 0.0
    k = np.arange(1, SERIES_TERMS + 1, dtype=float)
    a = 4.0 * math.pi**2 * (sigma / step) ** 2
    # the tail past K terms is about exp(-a K^2) / K (exact as sigma -> 0 to 1 / (2 K^2))
    tail = math.exp(-a * SERIES_TERMS**2) / SERIES_TERMS
    return float(step**2 / (2.0 * math.pi**2) * (np.sum(np.exp(-a * k * k) / (k * k)) + tail))


def white_sigma(seen_var: float, step: float) -> float:
    """Instrument noise sd sigma whose white error variance sigma^2 + q^2/12 - hidden is
    ``seen_var`` (what second differences measure), for quantiser step ``step``."""
    if not seen_var > 0:
        return 0.0

    def g(s):
        return s * s + step * step / 12.0 - hidden_variance(s, step) - seen_var

    hi = math.sqrt(seen_var)  # g(hi) >= 0 since hidden <= q^2 / 12
    if g(0.0) >= 0.0:  # less than the truncated series leaves at sigma = 0
        return 0.0
    if g(hi) <= 0:
        return hi
    return float(optimize.brentq(g, 0.0, hi, xtol=1e-12 * hi + 1e-300))


def slow_rows(x, step: float) -> np.ndarray:
    """Rows whose reading changes by at most one step to the next: where e(x) moves smoothly.

    Where the quantity jumps by many steps between rows (one reading per oven step),
    e(x) is as good as white and second differences already count it."""
    d = np.abs(np.diff(np.asarray(x, float)))
    return np.append(d <= 1.5 * step, False)


def phase_concentration(values, step: float) -> float:
    """|mean exp(2 pi i v / step)| of ``values``: about 1/sqrt(n) where they sweep through
    the steps, 1 where they sit at one place in them."""
    v = np.asarray(values, float)
    return float(np.abs(np.mean(np.exp(2j * math.pi * v / step)))) if v.size else 1.0


def unseen_variance(x, predicted, seen_var: float) -> tuple[float, float | None]:
    """(variance [unit^2] that second differences of ``x``'s residuals miss, step or None).

    A lattice in the values is not always a quantiser: an encoder logging a 10 mm/s
    actuator at 10 Hz between 2 mm dwells reads whole millimetres only, and the true
    positions sit on that lattice. A quantiser reads a quantity that sweeps through its
    steps, so the model's ``predicted`` values on the slow rows must spread over the step
    (:func:`phase_concentration` at most :data:`MAX_PHASE_CONCENTRATION`; the voltage-step
    rig's laser: 0.07, the pull test's encoder: 0.79-0.995), and the hidden part may not
    exceed :data:`MAX_HIDDEN_TO_SEEN` times what second differences see (in sd).

    Parameters
    ----------
    x : array_like
        The logged column.
    predicted : array_like
        The model's values of it (a phase reference: they need not be right).
    seen_var : float
        The second-difference variance of its residuals [unit^2].
    """
    step = logging_step(x)
    if step is None:
        return 0.0, None
    slow = slow_rows(x, step)
    if np.count_nonzero(slow) < MIN_CHANGES:
        return 0.0, None
    if phase_concentration(np.asarray(predicted, float)[slow], step) > MAX_PHASE_CONCENTRATION:
        return 0.0, None
    sigma = white_sigma(seen_var, step)
    hidden = float(np.mean(slow)) * hidden_variance(sigma, step)
    if hidden > MAX_HIDDEN_TO_SEEN**2 * seen_var:
        return 0.0, None
    return hidden, step
