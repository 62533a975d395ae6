"""Dynamic model of a TCA under a hanging load, eqs. (2.14)-(2.19).

  m x'' + b x' + F_i(x, T) = m g,   F_i = (x + f12 tau(T)) / f11      (2.19), (2.15)
  C_th T' = V(t)^2 / R - lambda (T - T_a)                             (2.18)

x is the extension from the unloaded length at ambient temperature
[m], positive when longer (downwards for a hanging load, so gravity is +m g:
the thesis writes (2.16) for an upward axis). The run starts at rest at the
static equilibrium under the load at ambient temperature, so the returned
``displacement`` (x - x(0)) is zero at t = 0, as in the rig logs.

Two integrators:

* ``method="dp5"`` (default): a JIT-compiled Dormand-Prince 5(4) that steps
  sample interval by sample interval with the voltage held, splitting an
  interval until the embedded error estimate meets ``rtol``/``atol``.
* ``method`` one of scipy's ``"RK45"``, ``"DOP853"``, ``"LSODA"``, ``"Radau"``,
  ``"BDF"``: ``scipy.integrate.solve_ivp`` with a Python right-hand side, the
  reference the fast path is checked and benchmarked against.

Both raise :class:`~tcamlab.errors.IntegrationError` on solver failure and
:class:`~tcamlab.errors.ModelDomainError` when the temperature makes
G_t' <= 0 (2.13) or the coil closes or straightens completely.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from tcamlab.errors import IntegrationError, ModelDomainError
from tcamlab.models import static as _static
from tcamlab.models import thermal
from tcamlab.models.coil import compliance_coefficients, compliance_terms, restoring_force
from tcamlab.params import G_ACCEL

RTOL = 1e-8
"""Default relative tolerance of the integrators [-]."""
ATOL = (1e-6, 1e-10, 1e-9)
"""Default absolute tolerances of (T [K], x [m], v [m/s])."""
METHOD = "dp5"
SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")

__all__ = [
    "response",
    "DynamicResult",
    "monte_carlo",
    "MonteCarloResult",
    "lognormal_draws",
    "acceleration",
    "RTOL",
    "ATOL",
    "METHOD",
]


@dataclass
class DynamicResult:
    """Simulated voltage-step response.

    Attributes
    ----------
    time : ndarray
        [s].
    voltage : ndarray
        [V].
    temperature : ndarray
        Actuator temperature [degC].
    displacement : ndarray
        Length change from t = 0, positive when longer [m].
    extension0 : float
        Static extension under the load at ambient, x(0) [m].
    method : str
        Integrator used.
    steps : int
        Integrator steps taken (sub-steps for dp5, RHS-evaluation count / 6 for scipy).
    raw : object
        The scipy ``OdeResult`` list for scipy methods, else None.
    """

    time: np.ndarray
    voltage: np.ndarray
    temperature: np.ndarray
    displacement: np.ndarray
    extension0: float
    method: str
    steps: int = 0
    raw: object = None

    def to_pandas(self) -> pd.DataFrame:
        """Frame with SI columns time, voltage, temperature, displacement."""
        return pd.DataFrame(
            {
                "time": self.time,
                "voltage": self.voltage,
                "temperature": self.temperature,
                "displacement": self.displacement,
            }
        )

    def plot(self, ax=None):
        """Displacement [mm] against time [s] on ``ax`` (a new figure if None)."""
        if ax is None:
            from matplotlib.figure import Figure

            ax = Figure().add_subplot()
        ax.plot(self.time, self.displacement * 1e3, label=f"model ({self.method})")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("displacement [mm]")
        return ax


def _pack(
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies,
    max_volume_fraction,
    radial_cte,
    shear_modulus_slope,
    load,
    damping,
    thermal_mass,
    heat_loss,
    resistance,
    ambient,
    resistance_tc,
    heat_loss_tc,
    coil_shear_slope=0.0,
):
    """Parameter vector of the kernel (layout in _dynamic_kernel)."""
    from tcamlab.models import _dynamic_kernel as K

    p = np.zeros(K.N_PARAMS)
    g_t = float(
        _static.sample_shear_modulus(
            fiber_diameter, fiber_length, twists, youngs_modulus, thread_plies, max_volume_fraction
        )
    )
    n = float(_static.n_coils(fiber_length, coil_length, coil_diameter))
    p[K.P_MASS], p[K.P_DAMP] = load, damping
    p[K.P_CTH], p[K.P_LAM], p[K.P_RES], p[K.P_TA] = thermal_mass, heat_loss, resistance, ambient
    p[K.P_BETA], p[K.P_GAMMA] = resistance_tc, heat_loss_tc
    p[K.P_S0], p[K.P_L], p[K.P_D0] = coil_length / fiber_length, fiber_length, fiber_diameter
    p[K.P_RHO], p[K.P_GT], p[K.P_SLOPE] = radial_cte, g_t, shear_modulus_slope
    p[K.P_E], p[K.P_PHI0] = youngs_modulus, 2.0 * np.pi * twists
    p[K.P_NCOIL] = n
    p[K.P_FEXT] = load * G_ACCEL
    p[K.P_CSLOPE] = coil_shear_slope
    for name, value, unit in (
        ("load", load, "kg"),
        ("damping", damping, "N s/m"),
        ("thermal_mass", thermal_mass, "J/K"),
        ("heat_loss", heat_loss, "W/K"),
        ("resistance", resistance, "ohm"),
    ):
        if not value > 0:
            raise ModelDomainError(f"dynamic model: {name} = {value:g} {unit} must be positive")
    return p


def _check_grid(time, voltage):
    t = np.ascontiguousarray(time, dtype=float)
    v = np.ascontiguousarray(np.broadcast_to(np.asarray(voltage, float), t.shape))
    if t.ndim != 1 or t.size < 2:
        raise ModelDomainError("dynamic model: time needs at least two samples")
    if not np.all(np.diff(t) > 0):
        raise ModelDomainError("dynamic model: time must be strictly increasing")
    return t, v


OVERHEAT_HINT = (
    "check the voltage column's unit (mV read as V heats a million times too much) and [rig] "
    "resistance_ohm, heat_loss_W_per_K and heater_tcr_per_K (a heater whose R falls as it heats "
    "runs away); or use the constant-G model: shear_modulus_slope_MPa_per_K = 0"
)
"""What to look at when the modelled temperature leaves G_t''s range: the voltage is logged,
so lowering a stated voltage would change nothing."""


def _raise_status(status, where, t, p):
    from tcamlab.models import _dynamic_kernel as K

    at = f"t = {t[where]:.4g} s" if where >= 0 else "start"
    if status == K.ERR_SHEAR:
        dt_max = p[K.P_GT] / max(p[K.P_SLOPE], p[K.P_CSLOPE], 1e-300)
        raise ModelDomainError(
            f"dynamic model: at {at} the temperature exceeds T_a + {dt_max:.1f} K, where "
            f"G_t' of eq. (2.13) reaches zero",
            hint=OVERHEAT_HINT,
        )
    if status == K.ERR_PITCH:
        raise ModelDomainError(f"dynamic model: at {at} the coil closed or straightened fully")
    if status == K.ERR_NONFINITE:
        raise IntegrationError(f"dynamic model: non-finite state at {at}")
    raise IntegrationError(
        f"dynamic model: step size collapsed at {at} (tolerances not met after 2^{K.MAX_HALVINGS} sub-steps)",
        hint="loosen rtol/atol or check the parameters",
    )


def response(
    time,
    voltage,
    fiber_diameter,
    fiber_length,
    coil_length,
    coil_diameter,
    twists,
    youngs_modulus,
    thread_plies=2,
    max_volume_fraction=0.887,
    radial_cte=8.1e-5,
    shear_modulus_slope=1.11e6,
    load=0.05,
    damping=0.84,
    thermal_mass=0.0266,
    heat_loss=0.00893,
    resistance=40.0,
    ambient=20.0,
    resistance_tc=0.0,
    heat_loss_tc=0.0,
    coil_shear_slope=0.0,
    *,
    method=METHOD,
    rtol=RTOL,
    atol=ATOL,
):
    """Displacement response to a sampled voltage profile, eqs. (2.14)-(2.19).

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times, strictly increasing [s]; the voltage is held between them.
    voltage : array_like, shape (n,) or scalar
        Applied voltage [V].
    fiber_diameter, fiber_length, coil_length, coil_diameter : float
        d0, l, L, D [m].
    twists : float
        Turns inserted [turns].
    youngs_modulus : float
        E [Pa].
    thread_plies : int
        Plies [-].
    max_volume_fraction : float
        V_fmax [-].
    radial_cte : float
        rho [1/K] (positive: swelling).
    shear_modulus_slope : float
        k of (2.13) [Pa/K]; 0 for the constant-G model.
    load : float
        Hanging mass m [kg].
    damping : float
        b [N s/m].
    thermal_mass : float
        C_th [J/K].
    heat_loss : float
        lambda [W/K].
    resistance : float
        R at ambient [ohm].
    ambient : float
        T_a [degC].
    resistance_tc : float
        beta in R(T) = R (1 + beta dT) [1/K]; 0 in the thesis (effect library).
    heat_loss_tc : float
        gamma in lambda(T) = lambda (1 + gamma dT) [1/K]; 0 in the thesis.
    coil_shear_slope : float
        k_c in G_c = G_t - k_c dT of the f11, f12 terms [Pa/K]; 0 in the thesis, which
        softens G only in the torque (effect library's G(T)).
    method : str
        ``"dp5"`` (JIT) or a :func:`scipy.integrate.solve_ivp` method name.
    rtol : float
        Relative tolerance.
    atol : tuple of 3 floats
        Absolute tolerances of (T [K], x [m], v [m/s]).

    Returns
    -------
    DynamicResult

    Raises
    ------
    ModelDomainError
        Temperature beyond the G_t' > 0 range, or the coil fully closed/open.
    IntegrationError
        The integrator failed.
    """
    t, v = _check_grid(time, voltage)
    p = _pack(
        fiber_diameter,
        fiber_length,
        coil_length,
        coil_diameter,
        twists,
        youngs_modulus,
        thread_plies,
        max_volume_fraction,
        radial_cte,
        shear_modulus_slope,
        load,
        damping,
        thermal_mass,
        heat_loss,
        resistance,
        ambient,
        resistance_tc,
        heat_loss_tc,
        coil_shear_slope,
    )
    x0 = float(
        _static.displacement(
            0.0,
            load * G_ACCEL,
            fiber_diameter,
            fiber_length,
            coil_length,
            coil_diameter,
            twists,
            youngs_modulus,
            thread_plies,
            max_volume_fraction,
            radial_cte,
            shear_modulus_slope,
        )
    )
    y0 = np.array([float(ambient), x0, 0.0])
    atol_arr = np.asarray(atol, float)
    if method == "dp5":
        from tcamlab.models import _dynamic_kernel as K

        out_T = np.empty(t.size)
        out_x = np.empty(t.size)
        status, where, steps = K.integrate(t, v, y0, p, atol_arr, float(rtol), 1, out_T, out_x)
        if status != K.OK:
            _raise_status(status, where, t, p)
        return DynamicResult(t, v, out_T, out_x - x0, x0, "dp5", int(steps))
    if method in SCIPY_METHODS:
        out_T, out_x, steps, raw = _solve_ivp(t, v, y0, p, method, rtol, atol_arr)
        return DynamicResult(t, v, out_T, out_x - x0, x0, method, steps, raw)
    raise ValueError(f"unknown method {method!r}; use 'dp5' or one of {SCIPY_METHODS}")


def acceleration(velocity, internal_force, mass, damping, force):
    """Acceleration of the hanging load, eq. (2.19): (F - b v - F_i) / m.

    Plain arithmetic (the numba kernel compiles this same function).

    Parameters
    ----------
    velocity : float or ndarray
        v [m/s], positive downwards (extension).
    internal_force : float or ndarray
        F_i of (2.15) [N].
    mass : float or ndarray
        m [kg].
    damping : float or ndarray
        b [N s/m].
    force : float or ndarray
        External force m g [N].

    Returns
    -------
    float or ndarray
        dv/dt [m/s^2].
    """
    return (force - damping * velocity - internal_force) / mass


def _python_rhs(p):
    """The right-hand side in plain Python (reference path for solve_ivp).

    Built from the same equation functions as the kernel's ``rhs``; only the
    integrator differs.
    """
    from tcamlab.models import _dynamic_kernel as K

    m, b, cth, lam, res, ta = (p[K.P_MASS], p[K.P_DAMP], p[K.P_CTH], p[K.P_LAM], p[K.P_RES], p[K.P_TA])
    beta, gamma, s0, l, d0 = p[K.P_BETA], p[K.P_GAMMA], p[K.P_S0], p[K.P_L], p[K.P_D0]
    rho, gt, slope, e, phi0 = p[K.P_RHO], p[K.P_GT], p[K.P_SLOPE], p[K.P_E], p[K.P_PHI0]
    n, fext, cslope = p[K.P_NCOIL], p[K.P_FEXT], p[K.P_CSLOPE]

    def f(_t, y, volt):
        temp, x, vel = y
        dT = temp - ta
        tdot = thermal.heating_rate(dT, volt, res, cth, lam, beta, gamma)
        g_tau = _static.softened_modulus(dT, gt, slope)
        if g_tau <= 0:
            raise ModelDomainError(
                f"dynamic model: temperature exceeds T_a + {gt / slope:.1f} K, where G_t' "
                "of eq. (2.13) reaches zero",
                hint=OVERHEAT_HINT,
            )
        r = rho * dT
        tau = _static.torque_from_strain(g_tau, phi0, d0, l, r)
        a, b_, c = compliance_coefficients(d0 * (1 + r), l, n)
        g_c = _static.softened_modulus(dT, gt, cslope)
        if g_c <= 0:
            raise ModelDomainError("dynamic model: the coil's G_t - k_c dT reaches zero")
        f11, _, f12, _ = compliance_terms(s0 + x / l, a, b_, c, g_c, e)
        return [tdot, vel, acceleration(vel, restoring_force(x, f11, f12, tau), m, b, fext)]

    return f


def _solve_ivp(t, v, y0, p, method, rtol, atol):
    from scipy.integrate import solve_ivp

    f = _python_rhs(p)
    # Integrate piece by piece between voltage changes: the RHS is smooth there.
    change = np.flatnonzero(np.diff(v[:-1]) != 0) + 1
    bounds = np.concatenate(([0], change, [t.size - 1]))
    out_T = np.empty(t.size)
    out_x = np.empty(t.size)
    out_T[0], out_x[0] = y0[0], y0[1]
    y = y0.copy()
    nfev = 0
    raws = []
    for i0, i1 in zip(bounds[:-1], bounds[1:]):
        sol = solve_ivp(
            f,
            (t[i0], t[i1]),
            y,
            method=method,
            t_eval=t[i0 : i1 + 1],
            rtol=rtol,
            atol=atol,
            args=(float(v[i0]),),
        )
        if not sol.success:
            raise IntegrationError(
                f"dynamic model: solve_ivp ({method}) failed between t = {t[i0]:.4g} s and "
                f"{t[i1]:.4g} s: {sol.message}"
            )
        out_T[i0 : i1 + 1] = sol.y[0]
        out_x[i0 : i1 + 1] = sol.y[1]
        y = sol.y[:, -1].copy()
        nfev += sol.nfev
        raws.append(sol)
    return out_T, out_x, nfev, raws


def lognormal_draws(mean, sd, size, rng):
    """Positive draws with the given mean and standard deviation.

    A log-normal with sigma^2 = ln(1 + (sd/mean)^2) and
    mu = ln(mean) - sigma^2 / 2 has exactly that mean and sd, and is
    positive however large sd is relative to the mean (lambda's stated sd,
    0.01615 W/K, exceeds its value, 0.00893 W/K).

    Parameters
    ----------
    mean, sd : float
        Mean and standard deviation (same unit).
    size : int
        Number of draws.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray
    """
    if sd <= 0:
        return np.full(size, float(mean))
    sigma2 = np.log1p((sd / mean) ** 2)
    return rng.lognormal(np.log(mean) - sigma2 / 2, np.sqrt(sigma2), size)


MC_PARAMS = ("load", "damping", "thermal_mass", "heat_loss", "resistance")


@dataclass
class MonteCarloResult:
    """Monte Carlo prediction band of the dynamic model.

    Attributes
    ----------
    time : ndarray
        Stored sample times [s].
    displacement : ndarray, shape (n_valid, n_time)
        Displacement of the draws that stayed in the model's domain [m].
    draws : dict of ndarray
        The parameter draws (all of them) [SI].
    valid : ndarray of bool
        Draws that stayed in the valid range (G_t' > 0, coil neither closed nor open).
    distribution : str
        How the draws were made.
    """

    time: np.ndarray
    displacement: np.ndarray
    draws: dict
    valid: np.ndarray
    distribution: str = "log-normal, moment-matched to the stated mean and sd"
    quantile_levels: tuple = field(default=(0.025, 0.5, 0.975))

    @property
    def n_invalid(self) -> int:
        return int((~self.valid).sum())

    def band(self, levels=None):
        """Quantiles of the displacement over the valid draws, shape (len(levels), n_time)."""
        levels = self.quantile_levels if levels is None else levels
        if self.displacement.shape[0] == 0:
            return np.full((len(levels), self.time.size), np.nan)
        return np.quantile(self.displacement, levels, axis=0)

    def to_pandas(self) -> pd.DataFrame:
        q = self.band()
        return pd.DataFrame({"time": self.time, "lower": q[0], "median": q[1], "upper": q[-1]})

    def plot(self, ax=None):
        if ax is None:
            from matplotlib.figure import Figure

            ax = Figure().add_subplot()
        q = self.band()
        ax.fill_between(self.time, q[0] * 1e3, q[-1] * 1e3, alpha=0.3, label="95% Monte Carlo band")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("displacement [mm]")
        return ax


def monte_carlo(
    time,
    voltage,
    sample,
    rig,
    *,
    n_draws=1000,
    seed=0,
    uncertainty=None,
    shear_modulus_slope=None,
    store_every=1,
    rtol=1e-6,
    atol=(1e-4, 1e-8, 1e-7),
    draws=None,
):
    """Prediction band from parameter uncertainty, by Monte Carlo (parallel, JIT).

    Parameters
    ----------
    time, voltage : array_like
        Sample grid [s] and held voltage [V].
    sample : tcamlab.params.Sample
    rig : tcamlab.params.Rig
        Means of the uncertain parameters.
    n_draws : int
        Number of draws.
    seed : int
        Seed of the numpy Generator.
    uncertainty : mapping, optional
        Rig field -> standard deviation (SI); default ``rig.uncertainty``. Fields
        outside ``MC_PARAMS`` are ignored.
    shear_modulus_slope : float, optional
        Override of the sample's slope (0 for constant G).
    store_every : int
        Keep every k-th sample of the grid (memory: n_draws x n_time doubles).
    rtol, atol :
        Integrator tolerances (looser defaults than :func:`response`: the band
        is a statistical quantity).
    draws : mapping, optional
        {field: ndarray of n_draws} [SI]: parameter draws to use instead of the
        independent log-normal ones (e.g. from a calibrated joint distribution,
        :mod:`tcamlab.band`); rig fields of ``MC_PARAMS`` and sample fields. A
        field not given keeps its value; ``uncertainty`` is then ignored.

    Returns
    -------
    MonteCarloResult
        Draws that leave the valid range are counted, not hidden: ``valid``.
    """
    from tcamlab.models import _dynamic_kernel as K

    t, v = _check_grid(time, voltage)
    base = {name: float(getattr(rig, name)) for name in MC_PARAMS}
    skw = sample.model_kwargs()
    if shear_modulus_slope is not None:
        skw["shear_modulus_slope"] = shear_modulus_slope
    if draws is None:
        rng = np.random.default_rng(seed)
        unc = dict(rig.uncertainty if uncertainty is None else uncertainty)
        draws = {n: lognormal_draws(base[n], float(unc.get(n, 0.0)), n_draws, rng) for n in MC_PARAMS}
    else:
        draws = {n: np.asarray(x, float) for n, x in draws.items()}
        n_draws = len(next(iter(draws.values()))) if draws else n_draws
    full = {n: draws.get(n, np.full(n_draws, base[n])) for n in MC_PARAMS}
    ps, x0, ok = _draw_rows(skw, full, draws, n_draws, rig.ambient)
    y0s = np.column_stack([np.full(n_draws, rig.ambient), x0, np.zeros(n_draws)])
    n_store = (t.size - 1) // store_every + 1
    out_T = np.empty((n_draws, n_store))
    out_x = np.empty((n_draws, n_store))
    status = np.zeros(n_draws, dtype=np.int64)
    fail_at = np.zeros(n_draws, dtype=np.int64)
    K.integrate_many(
        t, v, y0s, ps, np.asarray(atol, float), float(rtol), int(store_every), out_T, out_x, status, fail_at
    )
    status[~ok] = K.ERR_PITCH
    if np.any((status == K.ERR_NONFINITE) | (status == K.ERR_STEPS)):
        k = int(np.flatnonzero((status == K.ERR_NONFINITE) | (status == K.ERR_STEPS))[0])
        _raise_status(int(status[k]), int(fail_at[k]), t, ps[k])
    valid = status == K.OK
    disp = out_x[valid] - x0[valid, None]
    return MonteCarloResult(t[::store_every][:n_store], disp, dict(draws), valid)


def _draw_rows(skw, rig_draws, draws, n_draws, ambient):
    """Kernel parameter rows and start extensions of the draws; ``ok`` is False where a
    draw of sample fields has no static equilibrium (those rows are left at the first row)."""
    from tcamlab.models import _dynamic_kernel as K

    rig0 = {n: float(x[0]) for n, x in rig_draws.items()}
    p0 = _pack(**skw, **rig0, ambient=ambient, resistance_tc=0.0, heat_loss_tc=0.0)
    ps = np.tile(p0, (n_draws, 1))
    ok = np.ones(n_draws, bool)
    sample_fields = [n for n in draws if n in skw]
    if sample_fields:
        x0 = np.empty(n_draws)
        for k in range(n_draws):
            kw = {**skw, **{n: float(draws[n][k]) for n in sample_fields}}
            rk = {n: float(x[k]) for n, x in rig_draws.items()}
            try:
                ps[k] = _pack(**kw, **rk, ambient=ambient, resistance_tc=0.0, heat_loss_tc=0.0)
                x0[k] = float(_static.displacement(0.0, rk["load"] * G_ACCEL, **kw))
            except ModelDomainError:
                ok[k], x0[k] = False, 0.0
        return ps, x0, ok
    ps[:, K.P_MASS] = rig_draws["load"]
    ps[:, K.P_DAMP] = rig_draws["damping"]
    ps[:, K.P_CTH] = rig_draws["thermal_mass"]
    ps[:, K.P_LAM] = rig_draws["heat_loss"]
    ps[:, K.P_RES] = rig_draws["resistance"]
    ps[:, K.P_FEXT] = rig_draws["load"] * G_ACCEL
    return ps, _static.displacement(0.0, rig_draws["load"] * G_ACCEL, **skw), ok
