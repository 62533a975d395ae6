"""Static model of a twisted-and-coiled actuator (thesis section 2.3).

Heating a twisted fiber swells it radially; by (2.1) the twist angle drops in
the ratio d0/d and the untwist makes a torque (2.6)-(2.9). The coil turns
that torque and the external force into a length change through the
Castigliano compliances f11, f12 of (2.11) and the helix geometry (2.10).

Conventions (see README, "Models"):

* ``delta`` is the extension of the coil from its unloaded length at the
  reference temperature, positive when longer [m].
* ``radial_cte`` (rho) is positive for a fiber that swells radially on
  heating. The thesis quotes rho = -8.1e-5 /K, but with (2.7)-(2.9) a
  negative rho shrinks the fiber, reverses the torque and makes the thesis
  TCA *extend* on heating, against its own figure 2.7 and its own words
  ("the diameter of the twisted fiber increases"). We take |rho| with the
  swelling sign; a positive torque then shortens the coil (2.11).
* The twist enters twice: as the twist *angle* phi0 = 2 pi N [rad] in the
  torque (2.6), and as twist *per unit length* N / l [turns/m] in the bias
  angle alpha_f = atan(pi d N / l) of (2.12). Chapter 3 calls N "phi0"
  (a count); chapter 2 calls the angle phi0. Both are derived from N here.
* (2.13) prints "0.00111 x 10^6 dT"; the text says 0.00111 GPa per degC, i.e.
  1.11e6 Pa/K, which is what ``shear_modulus_slope`` holds. Following the
  thesis, G_t' replaces G_t in the torque only; f11 and f12 keep G_t.
* f11, f12 use the current fiber diameter d = d0 (1 + rho dT), the
  "radially expanded" d in which (2.11) is written. The bias angle, and so
  G_t, are fixed at fabrication (d0, N / l).
* f11 is the four-term form of section 2.3.2; the fifth term of section 3.2
  has units 1/(N m), not m/N, and is left out.

All functions are pure and vectorised: array arguments broadcast.
"""

from __future__ import annotations

import math

import numpy as np

from tcamlab.errors import ConvergenceError, ModelDomainError
from tcamlab.models._roots import MAXITER, RTOL, XTOL, RootResult, bracketed_newton
from tcamlab.models.coil import compliance_coefficients, compliance_terms, restoring_force

METHOD = "jit"
"""Default static solver: compiled per-point safeguarded Newton (see ``displacement``)."""

__all__ = [
    "volume_fraction",
    "bias_angle",
    "transverse_shear_modulus",
    "shear_modulus_at",
    "softened_modulus",
    "youngs_modulus_at",
    "max_temperature_rise",
    "torque",
    "torque_from_strain",
    "pitch_residual",
    "n_coils",
    "compliances",
    "displacement",
    "internal_force",
    "sample_shear_modulus",
    "shear_modulus_of",
]


def volume_fraction(thread_plies=2, max_volume_fraction=0.887):
    """Fiber volume fraction V_f = (r_f / r)^2 V_fmax (section 2.5.1).

    The filament radius is taken as r_f = r / plies, as the thesis does for
    its 2-ply thread.

    Parameters
    ----------
    thread_plies : int or array_like
        Number of plies [-].
    max_volume_fraction : float or array_like
        V_fmax [-].

    Returns
    -------
    ndarray
        V_f [-].
    """
    return np.asarray(max_volume_fraction, float) / np.asarray(thread_plies, float) ** 2


def bias_angle(fiber_diameter, twists, fiber_length):
    """Fiber bias angle alpha_f = atan(pi d phi) (section 2.3.3, after [13]).

    Parameters
    ----------
    fiber_diameter : array_like
        d [m].
    twists : array_like
        Turns inserted over the fiber length [turns].
    fiber_length : array_like
        l [m]; ``twists / fiber_length`` is the twist density phi [turns/m].

    Returns
    -------
    ndarray
        alpha_f [rad].
    """
    d = np.asarray(fiber_diameter, float)
    return np.arctan(np.pi * d * np.asarray(twists, float) / np.asarray(fiber_length, float))


def transverse_shear_modulus(youngs_modulus, volume_fraction, bias_angle):
    """Transverse shear modulus G_t of a twisted fiber, eq. (2.12) / (3.4).

    Parameters
    ----------
    youngs_modulus : array_like
        E [Pa].
    volume_fraction : array_like
        V_f [-].
    bias_angle : array_like
        alpha_f [rad].

    Returns
    -------
    ndarray
        G_t [Pa].
    """
    a = np.asarray(bias_angle, float)
    c = np.cos(a)
    num = (
        4.0
        * np.asarray(volume_fraction, float)
        * np.asarray(youngs_modulus, float)
        * (a / 2.0 - np.sin(2.0 * a) / 4.0) ** 2
    )
    den = np.pi * (2.0 + np.pi) * (2.0 / 3.0 - c + c**3 / 3.0) * (1.0 - c)
    return num / den


def sample_shear_modulus(
    fiber_diameter, fiber_length, twists, youngs_modulus, thread_plies=2, max_volume_fraction=0.887
):
    """G_t of a sample from its fabrication geometry, (2.12) with V_f and alpha_f.

    Parameters
    ----------
    fiber_diameter : array_like
        d0 [m].
    fiber_length : array_like
        l [m].
    twists : array_like
        Turns inserted [turns].
    youngs_modulus : array_like
        E [Pa].
    thread_plies : array_like
        Plies [-].
    max_volume_fraction : array_like
        V_fmax [-].

    Returns
    -------
    ndarray
        G_t [Pa].

    Raises
    ------
    ModelDomainError
        Where G_t is not a positive finite number: a bias angle of about 0 (a fiber of 1e12 mm
        with 150 twists) makes (2.12) 0 / 0.
    """
    alpha = bias_angle(fiber_diameter, twists, fiber_length)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        g = transverse_shear_modulus(
            youngs_modulus, volume_fraction(thread_plies, max_volume_fraction), alpha
        )
    if not np.all(np.isfinite(g) & (g > 0)):
        raise ModelDomainError(
            f"the shear modulus G_t of (2.12) is not a positive number for this fiber (bias angle alpha_f "
            f"as low as {float(np.min(alpha)):.3g} rad): check fiber_diameter_mm, fiber_length_mm and twists",
            hint="the thesis TCA: fiber_diameter_mm = 0.17, fiber_length_mm = 95, twists = 150",
        )
    return g


def shear_modulus_of(sample) -> float:
    """G_t of a sample object [Pa]: :func:`sample_shear_modulus` of its fields of the same names
    (:class:`tcamlab.params.Sample`, or any object with them)."""
    return float(
        sample_shear_modulus(
            sample.fiber_diameter,
            sample.fiber_length,
            sample.twists,
            sample.youngs_modulus,
            sample.thread_plies,
            sample.max_volume_fraction,
        )
    )


def max_temperature_rise(shear_modulus, shear_modulus_slope):
    """Temperature rise at which G_t' of (2.13) reaches zero [K].

    Parameters
    ----------
    shear_modulus : array_like
        G_t at the reference temperature [Pa].
    shear_modulus_slope : array_like
        Drop of G_t per kelvin [Pa/K]; zero means no limit.

    Returns
    -------
    ndarray
        G_t / slope [K] (inf for a zero slope).
    """
    g = np.asarray(shear_modulus, float)
    k = np.asarray(shear_modulus_slope, float)
    with np.errstate(divide="ignore"):
        return np.where(k > 0, g / np.where(k > 0, k, 1.0), np.inf)


def shear_modulus_at(delta_T, shear_modulus, shear_modulus_slope):
    """Temperature-dependent transverse shear modulus G_t', eq. (2.13).

    G_t' = G_t - k dT with k = 1.11e6 Pa/K for nylon (the text's 0.00111 GPa
    per degC; the printed equation's "x 10^6" is a unit slip).

    Parameters
    ----------
    delta_T : array_like
        Temperature rise above the reference [K].
    shear_modulus : array_like
        G_t at the reference temperature [Pa].
    shear_modulus_slope : array_like
        k [Pa/K].

    Returns
    -------
    ndarray
        G_t' [Pa].

    Raises
    ------
    ModelDomainError
        Where G_t' <= 0: the linear softening law has left its range.
    """
    g = softened_modulus(
        np.asarray(delta_T, float), np.asarray(shear_modulus, float), np.asarray(shear_modulus_slope, float)
    )
    if np.any(g <= 0):
        dt_max = float(np.min(max_temperature_rise(shear_modulus, shear_modulus_slope)))
        worst = float(np.max(delta_T))
        raise ModelDomainError(
            f"temperature rise {worst:.1f} K makes the shear modulus G_t' of eq. (2.13) "
            f"non-positive (valid below {dt_max:.1f} K above the reference)",
            hint="check the temperature or voltage column's unit in [columns] (a log in degF read as "
            "degC, mV read as V) and [rig] ambient_C, the reference the rise counts from; or use the "
            "constant-G model: shear_modulus_slope_MPa_per_K = 0",
        )
    return g


def youngs_modulus_at(delta_T, youngs_modulus, relative_slope):
    """Young's modulus E' = E (1 - c dT) of the f11 terms (effect library).

    The thesis keeps E constant (section 2.3.3, c = 0). Plain arithmetic,
    compiled by the static kernel as well.

    Parameters
    ----------
    delta_T : float or ndarray
        Temperature rise [K].
    youngs_modulus : float or ndarray
        E at fabrication [Pa].
    relative_slope : float or ndarray
        c [1/K].

    Returns
    -------
    float or ndarray
        E' [Pa].
    """
    return youngs_modulus * (1.0 - relative_slope * delta_T)


def torque(delta_T, shear_modulus, fiber_diameter, twists, fiber_length, radial_cte):
    """Temperature-induced untwisting torque, eqs. (2.6)-(2.9).

    tau = G J phi0 (1 - d0/d) / l with J = pi d^4 / 32, d = d0 (1 + rho dT),
    phi0 = 2 pi N. Equivalently (2.9):
    tau = G phi0 pi d0^4 (1 + rho dT)^3 rho dT / (32 l).

    Parameters
    ----------
    delta_T : array_like
        Temperature rise [K].
    shear_modulus : array_like
        G (G_t or G_t') [Pa].
    fiber_diameter : array_like
        d0 [m].
    twists : array_like
        Turns inserted N [turns] (phi0 = 2 pi N [rad]).
    fiber_length : array_like
        l [m].
    radial_cte : array_like
        rho [1/K], positive for radial swelling.

    Returns
    -------
    ndarray
        tau [N m], positive for the untwisting torque of a swelling fiber.
    """
    x = np.asarray(radial_cte, float) * np.asarray(delta_T, float)
    phi0 = 2.0 * np.pi * np.asarray(twists, float)
    return torque_from_strain(
        np.asarray(shear_modulus, float),
        phi0,
        np.asarray(fiber_diameter, float),
        np.asarray(fiber_length, float),
        x,
    )


def torque_from_strain(shear_modulus, twist_angle, fiber_diameter, fiber_length, radial_strain):
    """Untwisting torque in the form of eq. (2.9), plain arithmetic.

    tau = G phi0 pi d0^4 (1 + x)^3 x / (32 l) with the radial strain
    x = rho dT. The one implementation of (2.9): :func:`torque` calls it on
    arrays and the numba kernels compile it (so: floats or float ndarrays).

    Parameters
    ----------
    shear_modulus : float or ndarray
        G (G_t or G_t') [Pa].
    twist_angle : float or ndarray
        phi0 = 2 pi N [rad].
    fiber_diameter : float or ndarray
        d0 [m].
    fiber_length : float or ndarray
        l [m].
    radial_strain : float or ndarray
        x = rho dT [-].

    Returns
    -------
    float or ndarray
        tau [N m].
    """
    x = radial_strain
    return (
        shear_modulus * twist_angle * math.pi * fiber_diameter**4 * (1.0 + x) ** 3 * x / (32.0 * fiber_length)
    )


def softened_modulus(delta_T, modulus, slope):
    """Linear softening of a modulus with temperature, eq. (2.13): M' = M - k dT.

    Plain arithmetic (compiled by the numba kernels as well); no domain check
    (see :func:`shear_modulus_at`).

    Parameters
    ----------
    delta_T : float or ndarray
        Temperature rise [K].
    modulus : float or ndarray
        M at the reference temperature [Pa].
    slope : float or ndarray
        k [Pa/K].

    Returns
    -------
    float or ndarray
        M' [Pa].
    """
    return modulus - slope * delta_T


def n_coils(fiber_length, coil_length, coil_diameter):
    """Number of coils n = l cos(alpha0) / (pi D) (section 2.3.2).

    Parameters
    ----------
    fiber_length : array_like
        l [m].
    coil_length : array_like
        L [m]; sin(alpha0) = L / l.
    coil_diameter : array_like
        D [m].

    Returns
    -------
    ndarray
        n [-].
    """
    s0 = np.asarray(coil_length, float) / np.asarray(fiber_length, float)
    return np.asarray(fiber_length, float) * np.sqrt(1.0 - s0**2) / (np.pi * np.asarray(coil_diameter, float))


def _take(arr, idx):
    """``arr[idx]`` for per-point arrays; scalars pass through unchanged."""
    return arr if arr.ndim == 0 else arr[idx]


def compliances(sin_alpha, fiber_diameter, fiber_length, n_coils, shear_modulus, youngs_modulus):
    """Castigliano compliances f11 and f12 of eq. (2.11) (four-term f11).

    Parameters
    ----------
    sin_alpha : array_like
        Sine of the current pitch angle [-].
    fiber_diameter : array_like
        Current fiber diameter d [m].
    fiber_length : array_like
        l [m].
    n_coils : array_like
        n [-].
    shear_modulus : array_like
        G [Pa].
    youngs_modulus : array_like
        E [Pa].

    Returns
    -------
    f11 : ndarray
        Force compliance [m/N].
    f12 : ndarray
        Torque compliance [m/(N m)] = [1/N].
    """
    a, b, c = compliance_coefficients(
        np.asarray(fiber_diameter, float), np.asarray(fiber_length, float), np.asarray(n_coils, float)
    )
    f11, _, f12, _ = compliance_terms(
        np.asarray(sin_alpha, float),
        a,
        b,
        c,
        np.asarray(shear_modulus, float),
        np.asarray(youngs_modulus, float),
    )
    return f11, f12


def displacement(
    delta_T,
    force,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
    radial_cte=8.1e-5,
    shear_modulus_slope=0.0,
    youngs_modulus_slope=0.0,
    coil_shear_slope=0.0,
    *,
    method=METHOD,
    xtol=XTOL,
    rtol=RTOL,
    maxiter=MAXITER,
    full_output=False,
):
    """Static extension of a TCA under a force and a temperature rise, (2.9)-(2.13).

    Solves l (sin(alpha) - sin(alpha0)) = f11(alpha) F - f12(alpha) tau(dT)
    for sin(alpha) by a bracketed Newton iteration on [0, 1], then returns
    delta = l (sin(alpha) - sin(alpha0)) (2.10).

    With ``shear_modulus_slope = 0`` this is the constant-G model of (2.12);
    with the nylon slope 1.11e6 Pa/K it is the G(T) model of (2.13).

    Parameters
    ----------
    delta_T : array_like
        Temperature rise above the reference temperature [K].
    force : array_like
        External tensile force F [N] (a hanging mass m: F = m g).
    fiber_diameter : array_like
        d0 [m].
    fiber_length : array_like
        l [m].
    coil_length : array_like
        L [m].
    coil_diameter : array_like
        D [m].
    twists : array_like
        Turns inserted N [turns].
    youngs_modulus : array_like
        E [Pa].
    thread_plies : array_like, default 2
        Plies of the thread [-].
    max_volume_fraction : array_like, default 0.887
        V_fmax [-].
    radial_cte : array_like, default 8.1e-5
        rho [1/K], positive for swelling.
    shear_modulus_slope : array_like, default 0.0
        k in G_t' = G_t - k dT [Pa/K]; 0 gives the constant-G model.
    youngs_modulus_slope : array_like, default 0.0
        c in E' = E (1 - c dT) for the E terms of f11 [1/K]. The thesis keeps E
        constant (section 2.3.3); the effect library uses this. G_t stays at
        its fabrication value.
    coil_shear_slope : array_like, default 0.0
        k_c in G_c = G_t - k_c dT, the shear modulus of the f11, f12 terms [Pa/K].
        The thesis keeps G_t there (0); a physical G(T) softens the coil too
        (the effect library's G(T) uses this).
    method : {"jit", "numpy"}
        ``"jit"`` (default): a compiled per-point safeguarded Newton, run in
        parallel; ``"numpy"``: the same iteration vectorised over arrays in
        numpy (no compiler; the reference the JIT path is tested against).
    xtol, rtol : float
        Tolerances on sin(alpha) [-].
    maxiter : int
        Iteration limit.
    full_output : bool
        Also return the raw :class:`RootResult` (on sin(alpha)).

    Returns
    -------
    delta : ndarray
        Extension [m], broadcast shape of the inputs.
    result : RootResult
        Only with ``full_output=True``.

    Raises
    ------
    ModelDomainError
        If G_t' <= 0 at some temperature, or no equilibrium exists in
        0 <= alpha <= 90 deg (the coil would close or straighten fully).
    ConvergenceError
        If the iteration limit is reached.
    """
    given = (
        delta_T, force, fiber_diameter, fiber_length, coil_length, coil_diameter, twists,
        youngs_modulus, thread_plies, max_volume_fraction, radial_cte, shear_modulus_slope,
        youngs_modulus_slope, coil_shear_slope,
    )  # fmt: skip
    raw = [np.asarray(v, float) for v in given]
    shape = np.broadcast_shapes(*(a.shape for a in raw))
    # Scalars stay scalars (the common case: one sample, arrays of dT and F),
    # so the iteration indexes only what varies.
    flat = [a.reshape(()) if a.size == 1 else np.broadcast_to(a, shape).ravel() for a in raw]
    dT, F, d0, l, L, D, N, E_fab, plies, vfmax, rho, slope, e_slope, c_slope = flat
    size = int(np.prod(shape))
    g_t = sample_shear_modulus(d0, l, N, E_fab, plies, vfmax)
    E = youngs_modulus_at(dT, E_fab, e_slope)
    if np.any(E <= 0):
        raise ModelDomainError(
            "static model: Young's modulus E (1 - c dT) is not positive",
            hint="the E(T) slope is too large for this temperature range",
        )
    g_tau = shear_modulus_at(dT, g_t, slope)
    tau = torque(dT, g_tau, d0, N, l, rho)
    # the coil's compliance terms see G_t unless a coil slope is given (thesis: G_t there)
    g_t = shear_modulus_at(dT, g_t, c_slope) if np.any(c_slope != 0) else g_t
    s0 = L / l
    n = n_coils(l, L, D)
    if method == "jit":
        return _displacement_jit(
            shape, size, dT, F, g_t, g_tau, d0, l, s0, n, N, rho, E_fab, e_slope,
            xtol, rtol, maxiter, full_output,
        )  # fmt: skip
    if method != "numpy":
        raise ValueError(f"unknown method {method!r}; use 'jit' or 'numpy'")
    return _displacement_numpy(
        shape, size, dT, F, g_t, E, tau, d0, l, s0, n, rho, (xtol, rtol, maxiter), full_output
    )


def _displacement_numpy(shape, size, dT, F, g_t, E, tau, d0, l, s0, n, rho, tolerances, full_output):
    """The numpy solve of (2.10) = (2.11) for s = sin(alpha), bracketed in [0, 1] (SI)."""
    xtol, rtol, maxiter = tolerances
    d = d0 * (1.0 + rho * dT)
    a, b, c = compliance_coefficients(d, l, n)

    def h(s, i):
        terms = compliance_terms(s, _take(a, i), _take(b, i), _take(c, i), _take(g_t, i), _take(E, i))
        return pitch_residual(s, _take(l, i), _take(s0, i), _take(F, i), _take(tau, i), *terms)

    # Linearised first guess: delta ~ f11(s0) F - f12(s0) tau.
    f11_0, _, f12_0, _ = compliance_terms(s0, a, b, c, g_t, E)
    guess = np.broadcast_to(np.clip(s0 + (f11_0 * F - f12_0 * tau) / l, 0.0, 1.0), (size,))
    try:
        res = bracketed_newton(
            h, np.zeros(size), np.ones(size), guess, xtol=xtol, rtol=rtol, maxiter=maxiter, what="sin(alpha)"
        )
    except ConvergenceError as exc:
        if "no sign change" in exc.message:
            raise ModelDomainError(
                "static model: no equilibrium pitch angle in [0, 90] deg for some "
                "(temperature, force) points: " + exc.message,
                hint="the coil would close or straighten completely; check load and sample",
            ) from None
        raise
    delta = (l * (res.root - s0)).reshape(shape)
    if full_output:
        return delta, res
    return delta


def pitch_residual(sin_alpha, fiber_length, sin_alpha0, force, torque, f11, df11, f12, df12):
    """Residual of (2.10) = (2.11) in s = sin(alpha) and its derivative.

    h(s) = l (s - s0) - F f11(s) + tau f12(s); plain arithmetic, shared by the
    numpy solve and the compiled kernel.

    Parameters
    ----------
    sin_alpha, sin_alpha0 : float or ndarray
        Current and unloaded s [-].
    fiber_length : float or ndarray
        l [m].
    force : float or ndarray
        F [N].
    torque : float or ndarray
        tau [N m].
    f11, df11, f12, df12 : float or ndarray
        From :func:`tcamlab.models.coil.compliance_terms` [m/N], [1/N].

    Returns
    -------
    h : float or ndarray
        [m].
    dh : float or ndarray
        dh/ds [m].
    """
    h = fiber_length * (sin_alpha - sin_alpha0) - force * f11 + torque * f12
    return h, fiber_length - force * df11 + torque * df12


def _at(a, k: int) -> float:
    """Element ``k`` of a flattened argument that may be a scalar."""
    a = np.asarray(a, float)
    return float(a) if a.ndim == 0 or a.size == 1 else float(a.ravel()[k])


def _displacement_jit(
    shape, size, dT, F, g_t, g_tau, d0, l, s0, n, N, rho, E_fab, e_slope, xtol, rtol, maxiter, full_output
):
    from tcamlab.models import _static_kernel as K

    def vec(a):
        return np.ascontiguousarray(np.atleast_1d(np.asarray(a, float)))

    out = np.empty(size)
    status = np.zeros(size, dtype=np.int64)
    K.solve(
        size,
        vec(dT),
        vec(F),
        vec(g_t),
        vec(g_tau),
        vec(d0),
        vec(l),
        vec(s0),
        vec(n),
        vec(N),
        vec(rho),
        vec(E_fab),
        vec(e_slope),
        float(xtol),
        float(rtol),
        int(maxiter),
        out,
        status,
    )
    if np.any(status == K.NO_BRACKET):
        k = int(np.flatnonzero(status == K.NO_BRACKET)[0])
        raise ModelDomainError(
            "static model (2.10)-(2.11): no equilibrium pitch angle in [0, 90] deg at "
            f"dT = {_at(dT, k):.4g} K, F = {_at(F, k):.4g} N (point {k}; "
            f"{int((status == K.NO_BRACKET).sum())} of {size} points) for G_t = {_at(g_tau, k):.4g} Pa "
            f"and rho = {_at(rho, k):.4g} /K",
            hint="the coil would close or straighten completely; check load_g and the sample",
        )
    if np.any(status == K.NO_CONVERGENCE):
        raise ConvergenceError(
            f"static model: {int((status != K.OK).sum())} of {size} points did not converge "
            f"in {maxiter} iterations",
            hint="loosen xtol/rtol",
        )
    l_arr = np.asarray(l, float)
    delta = (l_arr * (out - np.asarray(s0, float))).reshape(shape)
    if full_output:
        return delta, RootResult(
            root=out, iterations=int(maxiter), converged=status == K.OK, residual=np.full(size, np.nan)
        )
    return delta


def internal_force(
    delta,
    delta_T,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
    radial_cte=8.1e-5,
    shear_modulus_slope=0.0,
):
    """Internal (restoring) force of the coil, eq. (2.15).

    F_i = (delta + f12 tau) / f11 with sin(alpha) = sin(alpha0) + delta / l.
    At static equilibrium F_i equals the external force of (2.11).

    Parameters
    ----------
    delta : array_like
        Extension from the unloaded reference length [m].
    delta_T : array_like
        Temperature rise [K].
    fiber_diameter, fiber_length, coil_length, coil_diameter, twists,
    youngs_modulus, thread_plies, max_volume_fraction, radial_cte,
    shear_modulus_slope :
        As in :func:`displacement`.

    Returns
    -------
    ndarray
        F_i [N], positive when the coil pulls back (tension).
    """
    delta = np.asarray(delta, float)
    dT = np.asarray(delta_T, float)
    g_t = sample_shear_modulus(
        fiber_diameter, fiber_length, twists, youngs_modulus, thread_plies, max_volume_fraction
    )
    tau = torque(
        dT, shear_modulus_at(dT, g_t, shear_modulus_slope), fiber_diameter, twists, fiber_length, radial_cte
    )
    l = np.asarray(fiber_length, float)
    s = np.asarray(coil_length, float) / l + delta / l
    if np.any((s < 0) | (s > 1)):
        raise ModelDomainError(
            "internal_force: extension puts the pitch angle outside [0, 90] deg",
            hint="the extension must satisfy -L <= delta <= l - L",
        )
    n = n_coils(fiber_length, coil_length, coil_diameter)
    d = np.asarray(fiber_diameter, float) * (1.0 + np.asarray(radial_cte, float) * dT)
    f11, f12 = compliances(s, d, l, n, g_t, youngs_modulus)
    return restoring_force(delta, f11, f12, tau)
