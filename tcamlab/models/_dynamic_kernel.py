"""Numba kernels for the dynamic model (imported lazily: JIT cost stays out of ``--help``).

State y = (T, x, v): actuator temperature [degC], extension [m], velocity [m/s].

  C_th dT/dt = V^2 / (R (1 + beta dT)) - lambda (1 + gamma dT) dT      (2.18)
  m dv/dt    = m g - b v - F_i(x, T)                                    (2.19)
  F_i        = (x + f12 tau) / f11                                      (2.15)

Each equation is compiled from the Python function the rest of the package
uses (thermal.heating_rate, static.torque_from_strain, coil.compliance_terms,
...), once, in tcamlab.models.compiled (shared with the self-sensing observer),
so there is one implementation of each. Numba's disk cache does not notice
edits to those modules: touch compiled.py and this file after changing them.

beta and gamma are zero in the thesis model; the effect library uses them
for a temperature-dependent resistance and convective heat loss.

Integration: Dormand-Prince 5(4) on each sample interval, where the voltage
is held. An interval is split into 1, 2, 4, ... equal sub-steps until the
embedded error estimate meets the tolerances; a failure to get there, a
non-finite state, or a state outside the model's domain returns a status
code that the Python side turns into an exception.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from tcamlab.models import compiled

# Parameter vector layout (shared with dynamic.py).
P_MASS, P_DAMP, P_CTH, P_LAM, P_RES, P_TA, P_BETA, P_GAMMA = 0, 1, 2, 3, 4, 5, 6, 7
P_S0, P_L, P_D0, P_RHO, P_GT, P_SLOPE, P_E, P_PHI0 = 8, 9, 10, 11, 12, 13, 14, 15
P_NCOIL, P_FEXT, P_CSLOPE = 16, 17, 18
N_PARAMS = 19

OK, ERR_SHEAR, ERR_PITCH, ERR_NONFINITE, ERR_STEPS = 0, 1, 2, 3, 4
MAX_HALVINGS = 16

# Dormand-Prince 5(4) tableau.
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = (71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)


@njit(cache=True, fastmath=False)
def rhs(T, x, v, volt, p, out):
    """Right-hand side; writes (dT/dt, dx/dt, dv/dt) into ``out``; returns a status."""
    dT = T - p[P_TA]
    out[0] = compiled.heating_rate(dT, volt, p[P_RES], p[P_CTH], p[P_LAM], p[P_BETA], p[P_GAMMA])
    out[1] = v
    g_tau = compiled.softened_modulus(dT, p[P_GT], p[P_SLOPE])
    if g_tau <= 0.0:
        return ERR_SHEAR
    r = p[P_RHO] * dT
    tau = compiled.torque_from_strain(g_tau, p[P_PHI0], p[P_D0], p[P_L], r)
    s = p[P_S0] + x / p[P_L]
    if s <= 0.0 or s >= 1.0:
        return ERR_PITCH
    # f11, f12 at the swollen diameter; E at its fabrication value, G_t too unless the
    # coil slope (effect library's G(T)) softens it.
    g_c = compiled.softened_modulus(dT, p[P_GT], p[P_CSLOPE])
    if g_c <= 0.0:
        return ERR_SHEAR
    a, b, c = compiled.compliance_coefficients(p[P_D0] * (1.0 + r), p[P_L], p[P_NCOIL])
    f11, _, f12, _ = compiled.compliance_terms(s, a, b, c, g_c, p[P_E])
    out[2] = compiled.acceleration(
        v, compiled.restoring_force(x, f11, f12, tau), p[P_MASS], p[P_DAMP], p[P_FEXT]
    )
    return OK


@njit(cache=True)
def _dp5_step(y, h, volt, p, k, ytmp, ynew, atol, rtol):
    """One DP5 step of size h from y; returns (status, error norm)."""
    st = rhs(y[0], y[1], y[2], volt, p, k[0])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ytmp[i] = y[i] + h * _A21 * k[0, i]
    st = rhs(ytmp[0], ytmp[1], ytmp[2], volt, p, k[1])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ytmp[i] = y[i] + h * (_A31 * k[0, i] + _A32 * k[1, i])
    st = rhs(ytmp[0], ytmp[1], ytmp[2], volt, p, k[2])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ytmp[i] = y[i] + h * (_A41 * k[0, i] + _A42 * k[1, i] + _A43 * k[2, i])
    st = rhs(ytmp[0], ytmp[1], ytmp[2], volt, p, k[3])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ytmp[i] = y[i] + h * (_A51 * k[0, i] + _A52 * k[1, i] + _A53 * k[2, i] + _A54 * k[3, i])
    st = rhs(ytmp[0], ytmp[1], ytmp[2], volt, p, k[4])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ytmp[i] = y[i] + h * (
            _A61 * k[0, i] + _A62 * k[1, i] + _A63 * k[2, i] + _A64 * k[3, i] + _A65 * k[4, i]
        )
    st = rhs(ytmp[0], ytmp[1], ytmp[2], volt, p, k[5])
    if st != OK:
        return st, 0.0
    for i in range(3):
        ynew[i] = y[i] + h * (_B1 * k[0, i] + _B3 * k[2, i] + _B4 * k[3, i] + _B5 * k[4, i] + _B6 * k[5, i])
    st = rhs(ynew[0], ynew[1], ynew[2], volt, p, k[6])
    if st != OK:
        return st, 0.0
    err = 0.0
    for i in range(3):
        e = h * (
            _E1 * k[0, i] + _E3 * k[2, i] + _E4 * k[3, i] + _E5 * k[4, i] + _E6 * k[5, i] + _E7 * k[6, i]
        )
        sc = atol[i] + rtol * max(abs(y[i]), abs(ynew[i]))
        q = abs(e) / sc
        if q > err:
            err = q
        if not np.isfinite(ynew[i]):
            return ERR_NONFINITE, 0.0
    return OK, err


@njit(cache=True)
def integrate(t, volt, y0, p, atol, rtol, store_every, out_T, out_x):
    """Integrate over the sample grid ``t``; store every ``store_every``-th sample.

    Returns (status, index of failure or -1, total sub-steps).
    """
    k = np.empty((7, 3))
    ytmp = np.empty(3)
    ynew = np.empty(3)
    y = y0.copy()
    ysub = np.empty(3)
    nsub = 1
    steps = 0
    out_T[0] = y[0]
    out_x[0] = y[1]
    for j in range(t.size - 1):
        dt = t[j + 1] - t[j]
        halvings = 0
        while True:
            h = dt / nsub
            ysub[:] = y
            worst = 0.0
            status = OK
            for _ in range(nsub):
                status, err = _dp5_step(ysub, h, volt[j], p, k, ytmp, ynew, atol, rtol)
                if status != OK:
                    break
                if err > worst:
                    worst = err
                ysub[:] = ynew
            if status == ERR_SHEAR or status == ERR_PITCH:
                return status, j, steps
            if status == OK and worst <= 1.0:
                break
            nsub *= 2
            halvings += 1
            if halvings > MAX_HALVINGS:
                return ERR_STEPS, j, steps
        steps += nsub
        y[:] = ysub
        if worst < 0.01 and nsub > 1:
            nsub //= 2
        if (j + 1) % store_every == 0:
            out_T[(j + 1) // store_every] = y[0]
            out_x[(j + 1) // store_every] = y[1]
    return OK, -1, steps


@njit(cache=True, parallel=True)
def integrate_many(t, volt, y0s, ps, atol, rtol, store_every, out_T, out_x, status, fail_at):
    """Integrate one trajectory per row of ``ps`` in parallel (Monte Carlo)."""
    n = ps.shape[0]
    for i in prange(n):
        st, at, _ = integrate(t, volt, y0s[i], ps[i], atol, rtol, store_every, out_T[i], out_x[i])
        status[i] = st
        fail_at[i] = at
