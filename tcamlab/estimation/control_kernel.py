"""Compiled closed loop on the virtual rig: plant, instruments, estimator and PI controller.

One loop per sample k (period dt), in the order a real controller runs:

1. the controller picks V_k from the feedback of sample k-1 (one sample delay);
2. the driver applies V_k; the ADCs read V and I (noise, quantisation), the
   laser reads the displacement (noise, quantisation);
3. the self-sensing estimator takes (V, I) (:func:`kernel.ekf_step`), with the load-jump
   detector's sums and hold carried between samples, so a configured detector runs here
   as it does over a log;
4. the plant (the dynamic model with the TRUE parameters and the TRUE
   resistance R(T, x)) integrates over [t_k, t_k+1] with V_k held, heated by
   V_k^2 / R, under the TRUE load force of the interval.

Numba's disk cache does not notice edits to :mod:`tcamlab.estimation.observer_kernel`
(whose functions and constants, NX among them, are compiled in here): touch this file
after changing that one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tcamlab.estimation import observer_kernel as K

MODE_OPEN, MODE_LASER, MODE_SELF, MODE_VOLTAGE = 0, 1, 2, 3
"""Feedback: none (feedforward only), laser, self-sensing estimate; or a given voltage profile."""

# Controller vector layout.
C_KP, C_KI, C_VMIN, C_VMAX, C_LAM, C_TA, C_XM0 = 0, 1, 2, 3, 4, 5, 6
# Instrument vector layout: sd V, sd I, V quantum, I quantum, laser sd, laser quantum.
I_SDV, I_SDI, I_QV, I_QI, I_SDL, I_QL = 0, 1, 2, 3, 4, 5


@njit(cache=True)
def _quantise(x, q):
    if q <= 0.0:
        return x
    return q * math.floor(x / q + 0.5)


@njit(cache=True)
def control_law(y, r, dt, integ, ctrl, ff_r, ff_t, table_m, grid_m):
    """PI on the displacement error plus the static feedforward; returns (V, new integral).

    P = lambda (T_ff(r) - T_a) + kp e + ki z,  e = y - r (too long -> more heat),
    V = sqrt(P R(T_ff, x_ref)) within [V_min, V_max]; the integral is held
    while the output saturates in the error's direction (anti-windup).
    """
    t_ff = np.interp(r, ff_r, ff_t)
    p_ff = ctrl[C_LAM] * (t_ff - ctrl[C_TA])
    r_hat, _, _ = K.table_resistance(t_ff, ctrl[C_XM0] + r, table_m, grid_m)
    e = y - r
    p = p_ff + ctrl[C_KP] * e + ctrl[C_KI] * integ
    p_min = ctrl[C_VMIN] ** 2 / r_hat
    p_max = ctrl[C_VMAX] ** 2 / r_hat
    saturated = (p >= p_max and e > 0.0) or (p <= p_min and e < 0.0)
    if not saturated:
        integ += e * dt
    p = min(max(p, p_min), p_max)
    return math.sqrt(p * r_hat), integ


@njit(cache=True)
def _measure(s, volt, table_t, grid_t, x0_true, inst, draws):
    """(V read, I read, laser displacement read) of the true state under V."""
    r_true, _, _ = K.table_resistance(s[0], s[1], table_t, grid_t)
    v_read = _quantise(volt + inst[I_SDV] * draws[0], inst[I_QV])
    i_read = _quantise(volt / r_true + inst[I_SDI] * draws[1], inst[I_QI])
    laser = _quantise(s[1] - x0_true + inst[I_SDL] * draws[2], inst[I_QL])
    return v_read, i_read, laser, r_true


@njit(cache=True)
def run_loop(mode, time, ref, force, load_meas, v_given, s_true, p_true, table_t, grid_t, s_est, c_est, p_m, noise, table_m,
             grid_m, ctrl, ff_r, ff_t, inst, draws, out):  # fmt: skip
    """Run the loop; ``out`` columns: true displacement, estimate, V, true T, estimated T, laser reading."""
    n = time.size
    x0_true = s_true[1]
    carry = np.zeros(6)  # V, I, the jump detector's two sums, its hold [s], the innovation's variance
    plant = np.empty(K.NX)
    integ = 0.0
    y = 0.0
    x0_m = ctrl[C_XM0]
    for k in range(n):
        dt = time[k + 1] - time[k] if k + 1 < n else time[k] - time[k - 1]
        nsub = max(1, int(math.ceil(dt / 1e-3)))
        if mode == MODE_VOLTAGE:
            volt = v_given[k]
        else:
            volt, integ = control_law(y, ref[k], dt, integ, ctrl, ff_r, ff_t, table_m, grid_m)
            if mode == MODE_OPEN:
                integ = 0.0
        v_read, i_read, laser, _ = _measure(s_true, volt, table_t, grid_t, x0_true, inst, draws[k])
        if k == 0:
            carry[0], carry[1] = v_read, i_read
        else:
            K.ekf_step(s_est, c_est, v_read, i_read, load_meas[k], time[k] - time[k - 1], p_m, nsub, noise, table_m,
                       grid_m, carry)  # fmt: skip
        y = laser if mode == MODE_LASER else s_est[1] - x0_m
        out[k, 0] = s_true[1] - x0_true
        out[k, 1] = s_est[1] - x0_m
        out[k, 2] = volt
        out[k, 3] = s_true[0]
        out[k, 4] = s_est[0]
        out[k, 5] = laser
        r_now, _, _ = K.table_resistance(s_true[0], s_true[1], table_t, grid_t)
        s_true[3] = force[k]
        K.propagate(s_true, volt * volt / r_now, dt, p_true, nsub, plant)
        s_true[:] = plant
