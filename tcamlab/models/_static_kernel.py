"""Numba kernel of the static solve (imported lazily; compiled once, cached on disk).

Per point: a safeguarded Newton iteration (Newton inside the bracket, bisection
when a step leaves it) for h(s) = l (s - s0) - F f11(s) + tau f12(s) = 0 on
s = sin(alpha) in [0, 1], the same equation as the vectorised numpy path of
:func:`tcamlab.models.static.displacement`.
Arrays are either per-point (length n) or length 1 (shared by every point).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from tcamlab.models import compiled

OK, NO_BRACKET, NO_CONVERGENCE = 0, 1, 2

# The equations come compiled from tcamlab.models.compiled, which wraps the same
# Python functions the numpy path calls, so there is one implementation of each.
# Numba's disk cache does not notice edits to those modules: touch compiled.py
# and this file after changing them.


@njit(cache=True, inline="always")
def _at(a, i):
    return a[i] if a.size > 1 else a[0]


@njit(cache=True)
def _h(s, l, s0, F, tau, A, B, C, g, e):
    f11, df11, f12, df12 = compiled.compliance_terms(s, A, B, C, g, e)
    h, dh = compiled.pitch_residual(s, l, s0, F, tau, f11, df11, f12, df12)
    return h, dh, f11, f12


@njit(cache=True, parallel=True)
def solve(
    n, dT, F, g_t, g_tau, d0, l, s0, ncoil, twists, rho, e_fab, e_slope, xtol, rtol, maxiter, out_s, status
):
    for i in prange(n):
        dti = _at(dT, i)
        x = _at(rho, i) * dti
        d0i = _at(d0, i)
        li = _at(l, i)
        ni = _at(ncoil, i)
        gi = _at(g_t, i)
        tau = compiled.torque_from_strain(_at(g_tau, i), 2.0 * np.pi * _at(twists, i), d0i, li, x)
        A, B, C = compiled.compliance_coefficients(d0i * (1.0 + x), li, ni)
        e = compiled.youngs_modulus_at(dti, _at(e_fab, i), _at(e_slope, i))
        Fi = _at(F, i)
        s0i = _at(s0, i)
        h_lo = _h(0.0, li, s0i, Fi, tau, A, B, C, gi, e)[0]
        h_hi = _h(1.0, li, s0i, Fi, tau, A, B, C, gi, e)[0]
        if h_lo * h_hi > 0.0:
            status[i] = NO_BRACKET
            out_s[i] = np.nan
            continue
        lo, hi = (0.0, 1.0) if h_lo <= 0.0 else (1.0, 0.0)
        _, _, f11, f12 = _h(s0i, li, s0i, Fi, tau, A, B, C, gi, e)
        s = s0i + (f11 * Fi - f12 * tau) / li
        s = min(max(s, 0.0), 1.0)
        status[i] = NO_CONVERGENCE
        for _ in range(maxiter):
            h, dh, _, _ = _h(s, li, s0i, Fi, tau, A, B, C, gi, e)
            if h == 0.0:
                status[i] = OK
                break
            if h < 0.0:
                lo = s
            else:
                hi = s
            a, b = min(lo, hi), max(lo, hi)
            tol = xtol + rtol * abs(s)
            sn = s - h / dh if dh != 0.0 else 0.5 * (a + b)
            if sn < a - tol or sn > b + tol or not np.isfinite(sn):
                sn = 0.5 * (a + b)
            else:
                sn = min(max(sn, a), b)
            step = abs(sn - s)
            s = sn
            if step <= tol or b - a <= tol:
                status[i] = OK
                break
        out_s[i] = s
