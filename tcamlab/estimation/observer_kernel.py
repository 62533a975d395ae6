"""Numba kernels of the self-sensing estimator and the closed-loop plant (SI throughout).

State s = (T, x, v, F, theta): actuator temperature [degC], extension from the
unloaded length [m], its rate [m/s], the external (load) force [N] and the
filter's correction to the thermal part of R [1/K].

  C_th dT/dt = P - lambda (T - T_a)          (2.18), P the measured V I - I^2 R_lead
  m dv/dt    = F - b v - F_i(x, T)           (2.19), F_i of (2.15)
  dF/dt      = w                             (random walk: the load is unknown; its
                                              variance widened when jump_detector alarms)

The resistance R(T, x) enters through a table on a regular (T, x) grid,
interpolated bilinearly, so any combined resistance model (a Python function)
can be used at compiled speed; its slopes come from the same table.

Every physical equation is compiled from the one Python function the rest of
tcamlab uses (coil.compliance_terms, static.torque_from_strain, ...), through
tcamlab.models.compiled, which the dynamic solver shares.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tcamlab.models import compiled

# Parameter vector layout.
P_TA, P_CTH, P_LAM, P_MASS, P_DAMP, P_L, P_D0, P_RHO = 0, 1, 2, 3, 4, 5, 6, 7
P_GT, P_SLOPE, P_E, P_PHI0, P_NCOIL, P_S0 = 8, 9, 10, 11, 12, 13
P_LEAD = 14
"""Lead resistance [ohm]: in series with the muscle, unheated; it takes I^2 R_lead of the power."""
N_PARAMS = 15
# Noise vector layout (ObserverConfig.noise_vector).
N_SDV, N_SDI, N_QT, N_QV, N_QF, N_SDLOAD, N_QTHETA, N_JUMP_K, N_JUMP_H, N_JUMP_SD, N_JUMP_HOLD = range(11)
# Grid layout of the resistance table: T_first, dT_step, x_first, x_step.
G_T0, G_DT, G_X0, G_DX = 0, 1, 2, 3
NX = 5
"""State dimension: (T, x, v, F, theta)."""
EPS = (1e-4, 1e-7, 1e-6, 1e-5, 1e-6)
"""Forward-difference steps of (T [K], x [m], v [m/s], F [N], theta [1/K]) for the transition Jacobian."""


@njit(cache=True)
def internal_force(x, temp, p):
    """F_i(x, T) of (2.15) [N]; the state is clamped into the model's domain."""
    dT = temp - p[P_TA]
    g_tau = compiled.softened_modulus(dT, p[P_GT], p[P_SLOPE])
    floor = 0.05 * p[P_GT]
    if g_tau < floor:
        g_tau = floor
    r = p[P_RHO] * dT
    tau = compiled.torque_from_strain(g_tau, p[P_PHI0], p[P_D0], p[P_L], r)
    s = p[P_S0] + x / p[P_L]
    s = min(max(s, 1e-3), 0.999)
    a, b, c = compiled.compliance_coefficients(p[P_D0] * (1.0 + r), p[P_L], p[P_NCOIL])
    f11, _, f12, _ = compiled.compliance_terms(s, a, b, c, p[P_GT], p[P_E])
    return compiled.restoring_force(x, f11, f12, tau)


@njit(cache=True)
def equilibrium(temp, force, p, x_guess):
    """Static extension x with F_i(x, T) = F (2.11), by a secant iteration [m]."""
    x0 = x_guess
    x1 = x_guess + 1e-4
    f0 = internal_force(x0, temp, p) - force
    for _ in range(60):
        f1 = internal_force(x1, temp, p) - force
        if f1 == f0:
            break
        x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
        x0, f0, x1 = x1, f1, x2
        if abs(x1 - x0) < 1e-13:
            break
    return x1


@njit(cache=True)
def _deriv(temp, x, v, force, power, p):
    """(dT/dt, dx/dt, dv/dt) of (2.18) and (2.19)."""
    d_temp = compiled.heating_rate(temp - p[P_TA], 0.0, 1.0, p[P_CTH], p[P_LAM], 0.0, 0.0) + power / p[P_CTH]
    return d_temp, v, compiled.acceleration(v, internal_force(x, temp, p), p[P_MASS], p[P_DAMP], force)


@njit(cache=True)
def propagate(s, power, dt, p, nsub, out):
    """RK4 over dt in ``nsub`` sub-steps with the power held; F is held too."""
    h = dt / nsub
    y0, y1, y2, f = s[0], s[1], s[2], s[3]
    for _ in range(nsub):
        a0, a1, a2 = _deriv(y0, y1, y2, f, power, p)
        b0, b1, b2 = _deriv(y0 + 0.5 * h * a0, y1 + 0.5 * h * a1, y2 + 0.5 * h * a2, f, power, p)
        c0, c1, c2 = _deriv(y0 + 0.5 * h * b0, y1 + 0.5 * h * b1, y2 + 0.5 * h * b2, f, power, p)
        d0, d1, d2 = _deriv(y0 + h * c0, y1 + h * c1, y2 + h * c2, f, power, p)
        y0 += h * (a0 + 2.0 * b0 + 2.0 * c0 + d0) / 6.0
        y1 += h * (a1 + 2.0 * b1 + 2.0 * c1 + d1) / 6.0
        y2 += h * (a2 + 2.0 * b2 + 2.0 * c2 + d2) / 6.0
    out[0], out[1], out[2], out[3] = y0, y1, y2, f
    for i in range(4, out.size):  # theta (the filter's) is constant in the model
        out[i] = s[i]


@njit(cache=True)
def table_resistance(temp, x, table, grid):
    """Bilinear R(T, x) from the table and its slopes (R [ohm], dR/dT [ohm/K], dR/dx [ohm/m])."""
    nt, nx = table.shape
    ft = (temp - grid[G_T0]) / grid[G_DT]
    fx = (x - grid[G_X0]) / grid[G_DX]
    i = min(max(int(math.floor(ft)), 0), nt - 2)
    j = min(max(int(math.floor(fx)), 0), nx - 2)
    u = ft - i
    w = fx - j
    r00, r01, r10, r11 = table[i, j], table[i, j + 1], table[i + 1, j], table[i + 1, j + 1]
    r = (1 - u) * ((1 - w) * r00 + w * r01) + u * ((1 - w) * r10 + w * r11)
    drdt = ((1 - w) * (r10 - r00) + w * (r11 - r01)) / grid[G_DT]
    drdx = ((1 - u) * (r01 - r00) + u * (r11 - r10)) / grid[G_DX]
    return r, drdt, drdx


@njit(cache=True)
def _predict(s, c, power, dt, p, nsub, q, s_new, work):
    """EKF time update in place: s <- f(s), c <- A c A' + Q, A by forward differences.

    ``work`` is scratch of shape (3, NX, NX) (no allocation per sample).
    """
    propagate(s, power, dt, p, nsub, s_new)
    a = work[0]
    ac = work[1]
    pert = work[2, 0]
    moved = work[2, 1]
    for j in range(NX):
        for i in range(NX):
            pert[i] = s[i]
        eps = EPS[j]
        pert[j] += eps
        propagate(pert, power, dt, p, nsub, moved)
        for i in range(NX):
            a[i, j] = (moved[i] - s_new[i]) / eps
    for i in range(NX):  # 4x4 products by hand: a BLAS call costs more than the arithmetic
        for j in range(NX):
            acc = 0.0
            for k in range(NX):
                acc += a[i, k] * c[k, j]
            ac[i, j] = acc
    for i in range(NX):
        for j in range(NX):
            acc = 0.0
            for k in range(NX):
                acc += ac[i, k] * a[j, k]
            c[i, j] = acc
        c[i, i] += q[i]
    for i in range(NX):
        s[i] = s_new[i]


@njit(cache=True)
def ekf_step(s, c, volt, cur, load_force, dt, p, nsub, noise, table, grid, out):
    """One causal EKF step from the previous sample's (V, I) to this sample's (V, I).

    ``noise`` = (sd_V [V], sd_I [A], q_T [K^2/s], q_v [m^2/s^3], q_F [N^2/s],
    sd_load [N], q_theta [1/K^2/s]), optionally followed by (jump_k [-], jump_h [-], jump_sd [N],
    jump_hold [s]).
    The power held over the last interval is the previous sample's V I less I^2 R_lead
    (``out[0]``, ``out[1]`` carry V and I between calls; ``out[2]``, ``out[3]`` the
    load-jump detector's sums and ``out[4]`` the time left of its hold when ``out`` has
    them, :func:`jump_detector`: on an alarm the load's variance grows by jump_sd^2 and,
    for jump_hold, its random walk by jump_sd^2 / jump_hold per second, so the load
    follows the mechanics' transient instead of the temperature taking it).
    Updates ``s`` and ``c`` in place; returns the normalised innovation
    squared of the current measurement (NaN when it carried no information).
    """
    v_prev, i_prev = out[0], out[1]
    power = max(v_prev * i_prev - p[P_LEAD] * i_prev * i_prev, 0.0)
    sd_v, sd_i = noise[0], noise[1]
    sd_p = math.sqrt((i_prev * sd_v) ** 2 + (v_prev * sd_i) ** 2)
    jumps = noise.size > N_JUMP_HOLD and out.size > 4 and noise[N_JUMP_H] > 0.0
    q_f = noise[4]
    if jumps and out[4] > 0.0:
        q_f += noise[N_JUMP_SD] ** 2 / noise[N_JUMP_HOLD]
        out[4] -= dt
    q = (
        (sd_p * dt / p[P_CTH]) ** 2 + noise[2] * dt,
        0.0,
        noise[3] * dt,
        q_f * dt,
        noise[6] * dt,
    )
    s_new = np.empty(NX)
    work = np.empty((3, NX, NX))
    _predict(s, c, power, dt, p, nsub, q, s_new, work)
    out[0], out[1] = volt, cur
    z = _update_current(s, c, volt, cur, sd_v, sd_i, table, grid, p[P_TA], out)
    if load_force == load_force:  # a logged load is a second measurement
        update_load(s, c, load_force, noise[5])
    elif jumps and z == z:
        if jump_detector(out, z, noise[N_JUMP_K], noise[N_JUMP_H]):
            c[3, 3] += noise[N_JUMP_SD] ** 2
            out[4] = noise[N_JUMP_HOLD]
    return z * z


@njit(cache=True)
def jump_detector(sums, z, drift, threshold):
    """Two-sided CUSUM of the normalised current innovation ``z``; True when it alarms.

    A load step moves R within the mechanics' settling time, which the held power cannot
    (T changes at most at P / C_th): a run of same-sign innovations is the load's, and on
    an alarm the caller widens the load's variance. ``sums[2]``, ``sums[3]`` hold the
    upper and lower sums; both restart after an alarm.
    """
    sums[2] = max(0.0, sums[2] + z - drift)
    sums[3] = max(0.0, sums[3] - z - drift)
    if sums[2] > threshold or sums[3] > threshold:
        sums[2] = 0.0
        sums[3] = 0.0
        return True
    return False


@njit(cache=True)
def _update_current(s, c, volt, cur, sd_v, sd_i, table, grid, ta, out):
    """Measurement update on the current I = V / (R(T, x) (1 + theta (T - T_a))).

    theta [1/K] absorbs a thermal part of R the calibrated model gets wrong (a TCR
    off, or a temperature off in proportion to the rise, as a lambda off makes it).
    Returns the normalised innovation (innovation / its sd; NaN without information);
    ``out[5]``, when ``out`` has it, gets the innovation's variance [A^2] (NaN without).
    """
    if out.size > 5:
        out[5] = np.nan
    r_tab, drdt, drdx = table_resistance(s[0], s[1], table, grid)
    dT = s[0] - ta
    scale = 1.0 + s[4] * dT
    r = r_tab * scale
    if not (abs(volt) > 3.0 * sd_v) or r <= 0.0:
        return np.nan
    pred = volt / r
    k = -volt / (r * r)
    h0 = k * (drdt * scale + r_tab * s[4])
    h1 = k * drdx * scale
    h4 = k * r_tab * dT
    var = sd_i * sd_i + (sd_v / r) ** 2
    ch = np.empty(NX)
    for i in range(NX):
        ch[i] = c[i, 0] * h0 + c[i, 1] * h1 + c[i, 4] * h4
    sv = h0 * ch[0] + h1 * ch[1] + h4 * ch[4] + var
    if out.size > 5:
        out[5] = sv
    innov = cur - pred
    for i in range(NX):
        s[i] += ch[i] * innov / sv
    for i in range(NX):
        for j in range(NX):
            c[i, j] -= ch[i] * ch[j] / sv
    return innov / math.sqrt(sv)


@njit(cache=True)
def first_load_update(s, c, load_force, sd, p):
    """:func:`update_load` at the first row, where the prior holds x in equilibrium with F: x is
    then re-solved at the updated F (the prior's linear x-F link is off by the curvature of
    x(F) over a load far from the stated one)."""
    update_load(s, c, load_force, sd)
    s[1] = equilibrium(s[0], s[3], p, s[1])


LOAD_JUMP_SDS = 5.0
"""A logged load this many sds of its innovation from the filter's load is a step the load's
random walk cannot make (a rider put on, a hand on the hanger): the load's variance is widened
by the innovation squared before the update, so the filter takes the step within a row, as the
muscle does, instead of over the walk's gain (about 5 % a row at 100 Hz: a 5 g rider was
followed over 0.2 s, 407 um off on average over the next half second; measured). A false alarm
of Gaussian load-cell noise at 5 sds is about 6e-7 a row."""


@njit(cache=True)
def update_load(s, c, load_force, sd):
    """Measurement update on a logged load force [N] of sd ``sd`` [N] (a measurement, not a
    reset; a step beyond :data:`LOAD_JUMP_SDS` is believed, its variance widened first)."""
    sv = c[3, 3] + sd * sd
    innov = load_force - s[3]
    if innov * innov > LOAD_JUMP_SDS**2 * sv:  # a step the walk cannot make: the log is believed
        c[3, 3] += innov * innov
        sv = c[3, 3] + sd * sd
    k = c[:, 3].copy() / sv
    for i in range(NX):
        s[i] += k[i] * innov
    for i in range(NX):
        for j in range(NX):
            c[i, j] -= k[i] * k[j] * sv


@njit(cache=True, nogil=True)  # filter runs of a calibration go on threads
def ekf_batch(
    time, volt, cur, load_force, s0, c0, p, noise, table, grid, max_step, out_s, out_var, out_nis, out_sv
):
    """The EKF over a whole log (sample by sample, exactly as :func:`ekf_step`); ``out_sv`` gets
    each row's innovation variance [A^2] (NaN where the row carried no information)."""
    s = s0.copy()
    c = c0.copy()
    carry = np.zeros(6)
    carry[0], carry[1] = volt[0], cur[0]
    if load_force[0] == load_force[0]:  # the stated load was the prior; the first logged row updates it
        first_load_update(s, c, load_force[0], noise[5], p)
    out_s[0, :] = s
    for i in range(NX):
        out_var[0, i] = c[i, i]
    out_nis[0] = np.nan
    out_sv[0] = np.nan
    for k in range(1, time.size):
        dt = time[k] - time[k - 1]
        nsub = max(1, int(math.ceil(dt / max_step)))
        out_nis[k] = ekf_step(s, c, volt[k], cur[k], load_force[k], dt, p, nsub, noise, table, grid, carry)
        out_sv[k] = carry[5]
        out_s[k, :] = s
        for i in range(NX):
            out_var[k, i] = c[i, i]
