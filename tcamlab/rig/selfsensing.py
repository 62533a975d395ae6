"""Virtual rig of the self-sensing kind: a powered TCA under a hanging load that may change.

The truth of a powered run is the thesis's dynamic model (2.14)-(2.19) with two
changes the self-sensing run needs:

* the Joule power is V^2 / R(T, x), with R the combined model of
  :mod:`tcamlab.models.selfsensing` (the thesis holds R constant in (2.18)), and
  the current is I = V / R;
* the hanging mass m(t) may change during the run (a rider put on the hanger):
  m x'' + b x' + F_i(x, T) = m g.

Effects of the library act on the true R (:func:`effect_factor`):
inter-coil contact, R0 drift and a TCR other than the stated one.

A :class:`ResistanceLaw` makes the true R differ from tcamlab's model as a real rig's
does (SYNTHETIC, an option of :func:`powered_run`): a lead resistance in series, a
quadratic TCR term and a different stretch sensitivity.

The ODE is integrated by :func:`scipy.integrate.solve_ivp` (RK45) piece by piece
between changes of the held voltage and load, as the dynamic model's reference path.
g(x) = R / R0 of chapter 3 is tabulated once per run on a fine grid (cubic spline,
relative error below 1e-9), so the right-hand side needs no root solve.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from tcamlab.effects import NO_MODS, Mods
from tcamlab.errors import ModelDomainError
from tcamlab.models import selfsensing as ssm
from tcamlab.models import static
from tcamlab.models.coil import compliance_coefficients, compliance_terms, restoring_force
from tcamlab.models.dynamic import acceleration
from tcamlab.params import G_ACCEL, Rig, Sample

__all__ = [
    "PoweredRun",
    "ResistanceLaw",
    "TCAMLAB_LAW",
    "powered_run",
    "rest_state",
    "internal_force",
    "law_resistance",
    "GRID_HALF_WIDTH_M",
]

GRID_HALF_WIDTH_M = 15e-3
"""Half-width of the tabulated g(x) around the rest extension [m] (strokes are a few mm)."""


@dataclass(frozen=True)
class ResistanceLaw:
    """A true resistance law other than tcamlab's (SYNTHETIC; the virtual rig's option).

    R = R_lead + R0 (1 + k_s u + c3 u^3) (1 + tcr dT + tcr2 dT^2) / (1 + rho dT)^2,
    u = g(x) - 1, dT = T - T_a; the voltage is read across leads and muscle, so only
    I^2 R_muscle heats. The cubic stretch term and a law without the swelling divisor are forms
    tcamlab's estimator does not fit: a rig made with them tests what it does with a law it
    cannot represent.

    Attributes
    ----------
    lead_ohm : float
        R_lead, leads and contacts in series, unheated [ohm] (a real rig: 0.2-0.5).
    tcr2_per_K2 : float
        Quadratic temperature coefficient of the coating [1/K^2].
    stretch_factor : float
        k_s, the stretch sensitivity relative to chapter 3's map [-].
    stretch_cubic : float
        c3, a cubic stretch term on u = g(x) - 1 [-] (u, counted from the unloaded coil, is
        about 0.76 at the template's rest under 50 g and moves 0.01 per mm; there c3 = 0.06
        steepens R(x) by 10 %).
    swelling : bool
        Whether R falls with the wire's radial swelling, (1 + rho dT)^-2 (chapter 3); False: a
        law without that term.
    """

    lead_ohm: float = 0.0
    tcr2_per_K2: float = 0.0
    stretch_factor: float = 1.0
    stretch_cubic: float = 0.0
    swelling: bool = True

    def stretch(self, g):
        """1 + k_s u + c3 u^3 with u = g - 1 [-]; plain floats stay floats (the ODE's path)."""
        u = g - 1.0
        return 1.0 + self.stretch_factor * u + self.stretch_cubic * u * u * u

    def heat(self, dT, tcr: float, rho: float):
        """(1 + tcr dT + tcr2 dT^2), over (1 + rho dT)^2 where the law swells [-]."""
        coat = 1.0 + tcr * dT + self.tcr2_per_K2 * dT * dT
        return coat / (1.0 + rho * dT) ** 2 if self.swelling else coat


TCAMLAB_LAW = ResistanceLaw()
"""tcamlab's own law: no lead, linear TCR, chapter 3's stretch sensitivity."""


def law_resistance(g, dT, r0, tcr, rho, law: ResistanceLaw = TCAMLAB_LAW):
    """(R_total, R_muscle) of :class:`ResistanceLaw` [ohm] from g(x) [-] and dT [K]; vectorised."""
    muscle = r0 * law.stretch(g) * law.heat(dT, tcr, rho)
    return law.lead_ohm + muscle, muscle


@dataclass(frozen=True)
class PoweredRun:
    """The true state of a powered run at the sample times (SI).

    Attributes
    ----------
    temperature : ndarray
        T [degC].
    extension : ndarray
        x, extension from the unloaded length at ambient [m].
    resistance : ndarray
        True R [ohm] (effects included), leads included: what V / I reads.
    current : ndarray
        I = V / R [A].
    rest_extension : float
        x at the first sample [m].
    """

    temperature: np.ndarray
    extension: np.ndarray
    resistance: np.ndarray
    current: np.ndarray
    rest_extension: float


def _mechanics(sample: Sample):
    """Constants of F_i(x, T) (2.15) as the dynamic model's reference right-hand side."""
    kw = sample.model_kwargs()
    gt = static.shear_modulus_of(sample)
    n = float(static.n_coils(kw["fiber_length"], kw["coil_length"], kw["coil_diameter"]))
    return kw, gt, n


def internal_force(x, dT, sample: Sample, gt: float, n: float):
    """F_i of (2.15) [N] at extension x [m] and temperature rise dT [K]."""
    l, d0 = sample.fiber_length, sample.fiber_diameter
    g_tau = static.softened_modulus(dT, gt, sample.shear_modulus_slope)
    if g_tau <= 0:
        limit = gt / sample.shear_modulus_slope  # a non-positive G_t' needs a positive slope
        raise ModelDomainError(
            f"self-sensing rig: the temperature rise {float(dT):.1f} K passed the G_t' = 0 limit "
            f"of (2.13) at {limit:.1f} K above ambient"
        )
    r = sample.radial_cte * dT
    tau = static.torque_from_strain(g_tau, 2.0 * np.pi * sample.twists, d0, l, r)
    a, b, c = compliance_coefficients(d0 * (1.0 + r), l, n)
    f11, _, f12, _ = compliance_terms(sample.coil_length / l + x / l, a, b, c, gt, sample.youngs_modulus)
    return restoring_force(x, f11, f12, tau)


def _g_table(sample: Sample, spring_constant: float, x_rest: float) -> CubicSpline:
    grid = np.linspace(x_rest - GRID_HALF_WIDTH_M, x_rest + GRID_HALF_WIDTH_M, 601)
    return CubicSpline(
        grid, ssm.geometric_ratio(grid, spring_constant=spring_constant, **sample.sensor_kwargs())
    )


def rest_state(
    sample: Sample, rig: Rig, voltage: float, mass: float, tcr: float, law: ResistanceLaw = TCAMLAB_LAW
) -> tuple[float, float]:
    """Temperature [degC] and extension [m] at rest under a held probe voltage and mass.

    (2.18) at steady state with P = V^2 R_muscle / R^2 and the statics at that T, solved
    together by fixed-point passes (the probe heats by a few kelvin, so they converge fast).
    """
    ta, r0 = rig.ambient, float(rig.initial_resistance)
    t0, x0 = ta, float(static.displacement(0.0, mass * G_ACCEL, **sample.model_kwargs()))
    for _ in range(20):
        g0 = float(ssm.geometric_ratio(x0, spring_constant=rig.spring_constant, **sample.sensor_kwargs()))
        total, muscle = law_resistance(g0, t0 - ta, r0, tcr, sample.radial_cte, law)
        t0 = ssm.rest_temperature(voltage**2 * muscle / total**2, rig.heat_loss, ta)
        x0 = float(static.displacement(t0 - ta, mass * G_ACCEL, **sample.model_kwargs()))
    return float(t0), x0


def _scalar_resistance(g: CubicSpline, r0, tcr, ta, rho, x0, t0, mods: Mods, law: ResistanceLaw):
    """(R_total, R_muscle)(t, T, x) in float arithmetic for the ODE's right-hand side (the terms
    of :func:`law_resistance` and ``effect_factor``; numpy scalar calls cost ten times more)."""
    xs = g.x.tolist()
    c3, c2, c1, c0 = (row.tolist() for row in g.c)
    last = len(xs) - 2

    def r(tt, temp, x):
        i = min(max(bisect_right(xs, x) - 1, 0), last)
        dx = x - xs[i]
        gx = ((c3[i] * dx + c2[i]) * dx + c1[i]) * dx + c0[i]
        dT = temp - ta
        heat = law.heat(dT, tcr, rho)
        contact = 1.0 - mods.contact_slope * max(0.0, x0 - x - mods.contact_onset)
        muscle = r0 * law.stretch(gx) * heat * (1.0 + mods.r0_drift * (tt - t0)) * contact
        return law.lead_ohm + muscle, muscle

    return r


def _integrate(rhs, t, v, m, y0, rtol) -> np.ndarray:
    """(T, x, v) at the sample times by RK45, piece by piece between changes of V and m."""
    out = np.empty((t.size, 3))
    out[0] = y0
    change = np.flatnonzero((np.diff(v[:-1]) != 0) | (np.diff(m[:-1]) != 0)) + 1
    bounds = np.concatenate(([0], change, [t.size - 1]))
    for i0, i1 in zip(bounds[:-1], bounds[1:]):
        if i1 <= i0:
            continue
        sol = solve_ivp(
            rhs,
            (t[i0], t[i1]),
            out[i0],
            method="RK45",
            t_eval=t[i0 : i1 + 1],
            args=(v[i0], m[i0]),
            rtol=rtol,
            atol=(1e-6, 1e-10, 1e-9),
        )
        if not sol.success:
            raise ModelDomainError(
                f"self-sensing rig: integration failed at t = {t[i0]:.4g} s: {sol.message}"
            )
        out[i0 : i1 + 1] = sol.y.T
    return out


def powered_run(
    sample: Sample,
    rig: Rig,
    time,
    voltage,
    load_mass,
    mods: Mods = NO_MODS,
    *,
    rtol: float = 1e-8,
    law: ResistanceLaw = TCAMLAB_LAW,
) -> PoweredRun:
    """Integrate a powered run: T, x, R and I at the sample times.

    Parameters
    ----------
    sample, rig : Sample, Rig
        True parameters [SI]; the rig's ``initial_resistance`` (R0, unloaded, at
        ambient), ``spring_constant`` (S of chapter 3), ``tcr``, ``thermal_mass``,
        ``heat_loss``, ``damping`` and ``ambient`` are used.
    time : array_like, shape (n,)
        Strictly increasing [s].
    voltage : array_like, shape (n,)
        Held from each sample to the next [V].
    load_mass : array_like, shape (n,)
        Hanging mass, held likewise [kg].
    mods : Mods
        contact_slope, contact_onset, r0_drift, tcr_extra.
    rtol : float
        Relative tolerance of the integrator.
    law : ResistanceLaw
        The true resistance law (SYNTHETIC option; default tcamlab's own).

    Returns
    -------
    PoweredRun
    """
    t = np.asarray(time, float)
    v = np.asarray(voltage, float)
    m = np.asarray(load_mass, float)
    if rig.initial_resistance is None or rig.spring_constant is None:
        raise ModelDomainError("self-sensing rig needs initial_resistance and spring_constant in [rig]")
    _, gt, n = _mechanics(sample)
    r0, tcr, ta = float(rig.initial_resistance), rig.tcr + mods.tcr_extra, rig.ambient
    cth, lam, b = rig.thermal_mass, rig.heat_loss, rig.damping
    t0, x0 = rest_state(sample, rig, float(v[0]), float(m[0]), tcr, law)
    g = _g_table(sample, rig.spring_constant, x0)

    def r_of(tt, temp, x):
        bare = law_resistance(g(x), temp - ta, r0, tcr, sample.radial_cte, law)[1]
        return law.lead_ohm + bare * ssm.effect_factor(tt - t[0], x0 - x, mods)

    r_scalar = _scalar_resistance(g, r0, tcr, ta, sample.radial_cte, x0, float(t[0]), mods, law)

    def rhs(tt, y, volt, mass):
        temp, x, vel = y
        if abs(x - x0) > GRID_HALF_WIDTH_M:
            raise ModelDomainError("self-sensing rig: the stroke left the tabulated range")
        dT = temp - ta
        total, muscle = r_scalar(tt, temp, x)
        tdot = (volt * volt * muscle / (total * total) - lam * dT) / cth
        acc = acceleration(vel, internal_force(x, dT, sample, gt, n), mass, b, mass * G_ACCEL)
        return [tdot, vel, acc]

    out = _integrate(rhs, t, v, m, (t0, x0, 0.0), rtol)
    temp, x = out[:, 0], out[:, 1]
    res = r_of(t, temp, x)
    return PoweredRun(temp, x, res, v / res, x0)
