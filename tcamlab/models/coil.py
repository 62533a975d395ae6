"""Coil compliances of a TCA or TCS, eq. (2.11) and the internal force (2.15).

Castigliano's theorem on a helical spring of n coils gives the extension

    delta = f11(alpha) F - f12(alpha) tau                                (2.11)

with the four-term force compliance of section 2.3.2 and the torque
compliance, written here as

    f11 = A c^4 / G + B c^2 / (2 G) + 2 A s^2 c^2 / E + B s^2 / (2 E),
    f12 = C c^2 / G,

s = sin(alpha), c^2 = 1 - s^2 (c^4 = (c^2)^2), and the geometry coefficients

    A = 8 n (l / n)^3 / (pi^3 d^4),  B = 8 n (l / n) / (pi d^2),
    C = 8 n (l / n)^2 / (pi^2 d^4).

This is the single implementation of (2.11): the numpy models call these
functions on arrays, and the numba kernels compile the very same functions
(``numba.njit(compliance_terms)``), so the functions here use plain
arithmetic only (no ``np.asarray``; pass floats or float ndarrays).
"""

from __future__ import annotations

import math

__all__ = ["compliance_coefficients", "compliance_terms", "fiber_mass", "restoring_force"]

NYLON_DENSITY = 1140.0
"""Density of nylon 6,6 [kg/m^3] (a handbook value; the thesis gives none). A silver coating
makes a sewing thread somewhat heavier; this is used only for an order-of-magnitude check."""


def fiber_mass(fiber_diameter, fiber_length, density=NYLON_DENSITY):
    """Mass of the precursor fiber, a solid cylinder [kg].

    Parameters
    ----------
    fiber_diameter : float or ndarray
        d0 [m].
    fiber_length : float or ndarray
        l, the fiber's length before coiling [m].
    density : float, optional
        [kg/m^3], nylon's by default.
    """
    return density * math.pi / 4.0 * fiber_diameter**2 * fiber_length


def compliance_coefficients(fiber_diameter, fiber_length, n_coils):
    """Geometry coefficients A, B, C of the compliances f11, f12 of eq. (2.11).

    Parameters
    ----------
    fiber_diameter : float or ndarray
        Current fiber diameter d [m].
    fiber_length : float or ndarray
        Fiber length l [m].
    n_coils : float or ndarray
        Number of coils n [-].

    Returns
    -------
    a : float or ndarray
        A = 8 n (l/n)^3 / (pi^3 d^4) [1/m], so that A c^4 / G is in [m/N].
    b : float or ndarray
        B = 8 n (l/n) / (pi d^2) [1/m].
    c : float or ndarray
        C = 8 n (l/n)^2 / (pi^2 d^4) [1/m^2], so that C c^2 / G is in [1/N].
    """
    d = fiber_diameter
    l = fiber_length
    n = n_coils
    a = 8.0 * n / (math.pi**3 * d**4) * (l / n) ** 3
    b = 8.0 * n / (math.pi * d**2) * (l / n)
    c = 8.0 * n / (math.pi**2 * d**4) * (l / n) ** 2
    return a, b, c


def compliance_terms(sin_alpha, a, b, c, shear_modulus, youngs_modulus):
    """Compliances f11, f12 of eq. (2.11) and their derivatives in sin(alpha).

    Parameters
    ----------
    sin_alpha : float or ndarray
        s = sin(alpha) of the current pitch angle [-].
    a, b, c : float or ndarray
        Coefficients of :func:`compliance_coefficients` [1/m], [1/m], [1/m^2].
    shear_modulus : float or ndarray
        G [Pa].
    youngs_modulus : float or ndarray
        E [Pa].

    Returns
    -------
    f11 : float or ndarray
        Force compliance [m/N].
    df11 : float or ndarray
        d f11 / d s [m/N].
    f12 : float or ndarray
        Torque compliance [1/N].
    df12 : float or ndarray
        d f12 / d s [1/N].
    """
    s = sin_alpha
    g = shear_modulus
    e = youngs_modulus
    s2 = s * s
    c2 = 1.0 - s2
    f11 = a * c2 * c2 / g + b * c2 / (2.0 * g) + 2.0 * a * s2 * c2 / e + b * s2 / (2.0 * e)
    df11 = -4.0 * a * s * c2 / g - b * s / g + 4.0 * a * s * (c2 - s2) / e + b * s / e
    f12 = c * c2 / g
    df12 = -2.0 * c * s / g
    return f11, df11, f12, df12


def restoring_force(delta, f11, f12, torque):
    """Internal force of the coil, eq. (2.15): F_i = (delta + f12 tau) / f11.

    Parameters
    ----------
    delta : float or ndarray
        Extension from the unloaded reference length [m].
    f11 : float or ndarray
        Force compliance [m/N].
    f12 : float or ndarray
        Torque compliance [1/N].
    torque : float or ndarray
        tau [N m].

    Returns
    -------
    float or ndarray
        F_i [N], positive when the coil pulls back.
    """
    return (delta + f12 * torque) / f11
