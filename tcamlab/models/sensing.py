"""Twisted-and-coiled sensor (TCS): resistance to displacement and force (section 3.2).

Pulling a TCS twists its fiber tighter and thins it; the silver keeps its share
of the cross-section, so by (3.1)-(3.2) R0 / R = (d / d0)^2 and

    d = d0 sqrt(R0 / R).                                             (3.1)-(3.2)

The thinner fiber carries the torque (3.3), tau = G_t J phi0 (1 - d0/d) / l,
negative for d < d0. With F = S delta, (3.5)-(3.7) give

    delta (1 - S f11(alpha)) = -f12(alpha) tau,  delta = l (sin alpha - sin alpha0).

Conventions (README, "Models"):

* phi0 of (3.3) is the twist *angle* 2 pi N; chapter 3 calls the count N
  "phi0" (750 twists). The bias angle uses N / l [turns/m].
* f11 is the four-term form of section 2.3.2: the fifth term printed in
  section 3.2 has units 1/(N m), not m/N.
* f11 and f12 use the current diameter d (from R), as in chapter 2; G_t is
  fixed at fabrication.
* The equation in delta has several roots. The physical root is the one with
  delta = 0 at R = R0 and continuous in R. On the stretched side (R > R0) it
  exists and is unique exactly when the margin m0 = 1 - S f11(alpha0) is
  positive; as m0 -> 0 the inversion amplifies resistance noise by 1 / m0.
  :func:`conditioning` reports m0, and :func:`invert` refuses m0 <= 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tcamlab.errors import ModelDomainError
from tcamlab.models import static as _static
from tcamlab.models._roots import MAXITER, bracketed_newton
from tcamlab.models.coil import compliance_coefficients, compliance_terms

__all__ = [
    "diameter_from_resistance",
    "resistance_from_diameter",
    "torque",
    "invert",
    "forward",
    "conditioning",
    "Conditioning",
    "ILL_CONDITIONED_MARGIN",
]

ILL_CONDITIONED_MARGIN = 0.05
"""Margin 1 - S f11(alpha0) below which the inversion is flagged ill-conditioned:
resistance noise is amplified more than 20-fold into displacement."""

XTOL = 1e-18
"""Absolute tolerance on delta [m] of the sensing solves."""
RTOL = 1e-13
"""Relative tolerance on delta [-] (forward-then-inverse recovers 1e-9 easily)."""


def diameter_from_resistance(resistance, initial_resistance, fiber_diameter):
    """Fiber diameter from resistance, eqs. (3.1)-(3.2): d = d0 sqrt(R0 / R).

    Parameters
    ----------
    resistance : array_like
        R [ohm].
    initial_resistance : array_like
        R0 at d = d0 [ohm].
    fiber_diameter : array_like
        d0 [m].

    Returns
    -------
    ndarray
        d [m].
    """
    r = np.asarray(resistance, float)
    if np.any(~(r > 0)):
        raise ModelDomainError(
            "sensing model: resistance must be positive", hint="check the resistance column and its unit"
        )
    return np.asarray(fiber_diameter, float) * np.sqrt(np.asarray(initial_resistance, float) / r)


def resistance_from_diameter(diameter, initial_resistance, fiber_diameter):
    """Inverse of :func:`diameter_from_resistance`: R = R0 (d0 / d)^2 [ohm]."""
    return (
        np.asarray(initial_resistance, float)
        * (np.asarray(fiber_diameter, float) / np.asarray(diameter, float)) ** 2
    )


def torque(diameter, fiber_diameter, twists, fiber_length, shear_modulus):
    """Torque of the thinned fiber, eq. (3.3) (= (2.6)).

    Parameters
    ----------
    diameter : array_like
        Current fiber diameter d [m].
    fiber_diameter : array_like
        d0 [m].
    twists : array_like
        Turns inserted N [turns]; phi0 = 2 pi N [rad].
    fiber_length : array_like
        l [m].
    shear_modulus : array_like
        G_t [Pa].

    Returns
    -------
    ndarray
        tau [N m], negative when the fiber has thinned (d < d0).
    """
    d = np.asarray(diameter, float)
    j = np.pi * d**4 / 32.0
    return (
        np.asarray(shear_modulus, float)
        * j
        * 2.0
        * np.pi
        * np.asarray(twists, float)
        * (1.0 - np.asarray(fiber_diameter, float) / d)
        / np.asarray(fiber_length, float)
    )


@dataclass(frozen=True)
class Conditioning:
    """How well the sensing inversion is posed for a sample and spring constant.

    Attributes
    ----------
    margin : float
        m0 = 1 - S f11(alpha0) [-]; the physical root exists for m0 > 0.
    amplification : float
        1 / m0: factor between relative torque error and displacement error.
    status : str
        ``"ok"``, ``"ill-conditioned"`` (0 < m0 < ILL_CONDITIONED_MARGIN) or
        ``"no-physical-root"`` (m0 <= 0).
    spring_stiffness_model : float
        1 / f11(alpha0), the model's own spring stiffness [N/m].
    """

    margin: float
    amplification: float
    status: str
    spring_stiffness_model: float

    def describe(self) -> str:
        if self.status == "ok":
            return (
                f"well posed: S f11 = {1 - self.margin:.3f} "
                f"(margin {self.margin:.3f}, noise amplification {self.amplification:.2g}x)"
            )
        if self.status == "ill-conditioned":
            return (
                f"ill-conditioned: S f11 = {1 - self.margin:.4f} is within "
                f"{self.margin:.4f} of 1; resistance noise is amplified "
                f"{self.amplification:.3g}x into displacement"
            )
        return (
            f"no physical root: S f11 = {1 - self.margin:.4f} >= 1, so no displacement "
            f"continuous from R = R0 solves (3.6); S exceeds the model's spring stiffness "
            f"{self.spring_stiffness_model:.4g} N/m"
        )


def _geometry(
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies,
    max_volume_fraction,
):
    g_t = _static.sample_shear_modulus(
        fiber_diameter, fiber_length, twists, youngs_modulus, thread_plies, max_volume_fraction
    )
    n = _static.n_coils(fiber_length, coil_length, coil_diameter)
    return g_t, n


def conditioning(
    spring_constant,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
):
    """Margin of the sensing equation at rest, m0 = 1 - S f11(alpha0) (section 3.2).

    Parameters
    ----------
    spring_constant : float
        S [N/m].
    fiber_diameter, fiber_length, coil_length, coil_diameter : float
        d0, l, L, D [m].
    twists : float
        N [turns].
    youngs_modulus : float
        E [Pa].
    thread_plies : int
    max_volume_fraction : float

    Returns
    -------
    Conditioning
    """
    g_t, n = _geometry(
        fiber_diameter,
        fiber_length,
        coil_length,
        coil_diameter,
        twists,
        youngs_modulus,
        thread_plies,
        max_volume_fraction,
    )
    f11, _ = _static.compliances(
        coil_length / fiber_length, fiber_diameter, fiber_length, n, g_t, youngs_modulus
    )
    margin = float(1.0 - spring_constant * f11)
    if margin <= 0:
        status = "no-physical-root"
    elif margin < ILL_CONDITIONED_MARGIN:
        status = "ill-conditioned"
    else:
        status = "ok"
    return Conditioning(margin, float(1.0 / margin) if margin != 0 else np.inf, status, float(1.0 / f11))


def invert(
    resistance,
    initial_resistance,
    spring_constant,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
    *,
    xtol=XTOL,
    rtol=RTOL,
    maxiter=MAXITER,
    full_output=False,
):
    """Displacement and force from resistance, eqs. (3.1)-(3.7).

    Solves delta (1 - S f11) + f12 tau = 0 for the physical root (delta = 0 at
    R = R0, continuous in R) by a bracketed Newton iteration in delta.

    Parameters
    ----------
    resistance : array_like
        R [ohm].
    initial_resistance : float or array_like
        R0 [ohm].
    spring_constant : float
        S in F = S delta [N/m].
    fiber_diameter, fiber_length, coil_length, coil_diameter : float
        d0, l, L, D [m].
    twists : float
        N [turns].
    youngs_modulus : float
        E [Pa].
    thread_plies : int
    max_volume_fraction : float
    xtol, rtol : float
        Tolerances on delta [m], [-].
    maxiter : int
    full_output : bool
        Also return the :class:`RootResult` (None if no solve was needed).

    Returns
    -------
    delta : ndarray
        Elongation [m].
    force : ndarray
        F = S delta [N].

    Raises
    ------
    ModelDomainError
        If S f11(alpha0) >= 1 (no physical root: see :func:`conditioning`) or
        a resistance lies below what the coil can reach in compression.
    """
    geo = (
        fiber_diameter, fiber_length, coil_length, coil_diameter,
        twists, youngs_modulus, thread_plies, max_volume_fraction,
    )  # fmt: skip
    cond = conditioning(spring_constant, *geo)
    if cond.status == "no-physical-root":
        raise ModelDomainError(
            "sensing model: " + cond.describe(), hint="check the spring constant and the sample geometry"
        )
    r = np.asarray(resistance, float)
    shape = np.broadcast_shapes(r.shape, np.shape(initial_resistance))
    d = np.broadcast_to(diameter_from_resistance(r, initial_resistance, fiber_diameter), shape).ravel()
    g_t, n = _geometry(*geo)
    tau = torque(d, fiber_diameter, twists, fiber_length, g_t)
    l = float(fiber_length)
    s0 = float(coil_length) / l
    a, b, c = compliance_coefficients(d, l, n)
    S = float(spring_constant)
    E = float(youngs_modulus)

    def h(delta, i):
        s = s0 + delta / l
        f11, df11, f12, df12 = compliance_terms(s, a[i], b[i], c[i], g_t, E)
        return (
            delta * (1.0 - S * f11) + f12 * tau[i],
            1.0 - S * f11 - delta * S * df11 / l + tau[i] * df12 / l,
        )

    delta = np.zeros(d.size)
    stretched = tau < 0
    res = None
    if np.any(stretched):
        idx = np.flatnonzero(stretched)
        f11_0, _, f12_0, _ = compliance_terms(s0, a[idx], b[idx], c[idx], g_t, E)
        guess = -f12_0 * tau[idx] / (1.0 - S * f11_0)  # linearised: delta ~ -f12 tau / (1 - S f11)
        res = _invert_stretched(h, idx, guess, l, s0, (xtol, rtol, maxiter))
        delta[idx] = res.root
    compressed = tau > 0
    if np.any(compressed):
        delta[compressed] = _invert_compressed(h, np.flatnonzero(compressed), l, s0, xtol, rtol, maxiter)
    delta = delta.reshape(shape)
    if full_output:
        return delta, S * delta, res
    return delta, S * delta


def _invert_stretched(h, idx, guess, l, s0, tolerances):
    """Physical root for R > R0 (stretch): the :class:`RootResult` on (0, l (1 - s0)).

    h(0) = f12 tau < 0 and h(l (1 - s0)) > 0 while m0 > 0: the physical root is
    bracketed, and h increases on the bracket, so it is unique.
    """
    xtol, rtol, maxiter = tolerances
    hi = np.full(idx.size, l * (1.0 - s0) * (1.0 - 1e-12))
    return bracketed_newton(
        lambda x, j: h(x, idx[j]),
        np.zeros(idx.size),
        hi,
        np.clip(guess, 0.0, hi),
        xtol=xtol,
        rtol=rtol,
        maxiter=maxiter,
        what="sensing delta",
    )


def _invert_compressed(h, idx, l, s0, xtol, rtol, maxiter):
    """Physical root for R < R0 (compression): the sign change nearest delta = 0.

    Here the equation can have two roots or none; scanning down from
    delta = 0 finds the bracket of the root continuous from R = R0.
    """
    grid = -l * s0 * np.linspace(0.0, 1.0 - 1e-9, 257)[1:]
    lo = np.full(idx.size, np.nan)
    hi = np.zeros(idx.size)
    remaining = np.ones(idx.size, dtype=bool)
    for g in grid:
        f, _ = h(np.full(idx.size, g), idx)
        hit = remaining & (f <= 0)
        lo[hit] = g
        remaining &= ~hit
        hi[remaining] = g
        if not remaining.any():
            break
    if remaining.any():
        raise ModelDomainError(
            f"sensing model: {int(remaining.sum())} resistance samples lie below R0 by more "
            "than any compression of the coil explains (no physical root)",
            hint="check initial_resistance_ohm (R0) and the resistance column",
        )
    res = bracketed_newton(
        lambda x, j: h(x, idx[j]),
        lo,
        hi,
        0.5 * (lo + hi),
        xtol=xtol,
        rtol=rtol,
        maxiter=maxiter,
        what="sensing delta",
    )
    return res.root


def forward(
    displacement,
    initial_resistance,
    spring_constant,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
    *,
    xtol=1e-20,
    rtol=1e-14,
    maxiter=MAXITER,
):
    """Resistance of a TCS stretched by ``displacement`` (for simulation).

    Given delta, sin(alpha) follows from (3.7); the equation
    delta (1 - S f11(d)) + f12(d) tau(d) = 0 is then solved for the diameter d
    and R = R0 (d0 / d)^2. Writing f11 = P/d^4 + Q/d^2, f12 = U/d^4 and
    tau = K d^3 (d - d0) turns it into
    delta (1 - S P/d^4 - S Q/d^2) + U K (1 - d0/d) = 0,
    increasing in d for delta > 0, so the root is unique there.

    Parameters
    ----------
    displacement : array_like
        delta [m], -L < delta < l - L.
    initial_resistance, spring_constant, fiber_diameter, fiber_length, coil_length,
    coil_diameter, twists, youngs_modulus, thread_plies, max_volume_fraction :
        As in :func:`invert`.

    Returns
    -------
    ndarray
        R [ohm].
    """
    delta = np.asarray(displacement, float)
    shape = np.broadcast_shapes(delta.shape, np.shape(initial_resistance))
    dl = np.broadcast_to(delta, shape).ravel()
    l = float(fiber_length)
    d0 = float(fiber_diameter)
    s = float(coil_length) / l + dl / l
    if np.any((s <= 0) | (s >= 1)):
        raise ModelDomainError("sensing forward map: displacement puts the pitch angle outside (0, 90) deg")
    g_t, n = _geometry(
        fiber_diameter,
        fiber_length,
        coil_length,
        coil_diameter,
        twists,
        youngs_modulus,
        thread_plies,
        max_volume_fraction,
    )
    # Coefficients at unit diameter: f11 = P/d^4 + Q/d^2, f12 = U/d^4.
    # A and C scale as 1/d^4, B as 1/d^2 (2.11): split f11 by zeroing the others.
    a1, b1, c1 = compliance_coefficients(1.0, l, n)
    E = float(youngs_modulus)
    P, _, U, _ = compliance_terms(s, a1, 0.0, c1, g_t, E)
    Q = compliance_terms(s, 0.0, b1, 0.0, g_t, E)[0]
    K = g_t * np.pi / 32.0 * 2.0 * np.pi * float(twists) / l
    S = float(spring_constant)

    # Unknown u = d / d0 (order one), so the tolerances are relative.
    def q(u, i):
        dd = u * d0
        val = dl[i] * (1.0 - S * P[i] / dd**4 - S * Q[i] / dd**2) + U[i] * K * (1.0 - 1.0 / u)
        der = d0 * dl[i] * S * (4.0 * P[i] / dd**5 + 2.0 * Q[i] / dd**3) + U[i] * K / u**2
        return val, der

    u = _diameter_ratio(q, dl, S, xtol, rtol, maxiter)
    r0 = np.broadcast_to(np.asarray(initial_resistance, float), shape).ravel()
    return (r0 / u**2).reshape(shape)


def _diameter_ratio(q, dl, spring_constant, xtol, rtol, maxiter):
    """d / d0 solving ``q(u, i)`` per point: in [0.5, 1] when stretched, [1, 2] when compressed.

    Raises
    ------
    ModelDomainError
        Where a bracket holds no root: no physical coil diameter for that extension.
    """
    u = np.ones(dl.size)
    for idx, lo, hi in ((np.flatnonzero(dl > 0), 0.5, 1.0), (np.flatnonzero(dl < 0), 1.0, 2.0)):
        if not idx.size:
            continue
        ends = [q(np.full(idx.size, x), idx)[0] for x in (lo, hi)]
        bad = np.flatnonzero(np.sign(ends[0]) * np.sign(ends[1]) > 0)
        if bad.size:
            k = int(idx[bad[0]])
            raise ModelDomainError(
                f"sensing forward map (3.1)-(3.7): no physical coil diameter at delta = "
                f"{dl[k] * 1e3:.4g} mm (point {k}; {bad.size} of {dl.size} points) for "
                f"S = {spring_constant:.4g} N/m and the stated sample",
                hint="check spring_constant_N_per_m, the load and the sample's geometry",
            )
        res = bracketed_newton(
            lambda x, j, idx=idx: q(x, idx[j]),
            np.full(idx.size, lo),
            np.full(idx.size, hi),
            None,
            xtol=xtol,
            rtol=rtol,
            maxiter=maxiter,
            what="sensing diameter",
        )
        u[idx] = res.root
    return u
