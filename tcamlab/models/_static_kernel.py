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

OK, NO_BRACKET, NO_CONVERGENCE = 0, 1, 2


@njit(cache=True, inline="always")
def _at(a, i):
    return a[i] if a.size > 1 else a[0]


@njit(cache=True)
def _h(s, l, s0, F, tau, A, B, C, g, e):
    s2 = s * s
    c2 = 1.0 - s2
    f11 = A * c2 * c2 / g + B * c2 / (2.0 * g) + 2.0 * A * s2 * c2 / e + B * s2 / (2.0 * e)
    df11 = -4.0 * A * s * c2 / g - B * s / g + 4.0 * A * s * (c2 - s2) / e + B * s / e
    f12 = C * c2 / g
    df12 = -2.0 * C * s / g
    return l * (s - s0) - F * f11 + tau * f12, l - F * df11 + tau * df12, f11, f12


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
        tau = _at(g_tau, i) * 2.0 * np.pi * _at(twists, i) * np.pi * d0i**4 * (1.0 + x) ** 3 * x / (32.0 * li)
        d = d0i * (1.0 + x)
        A = 8.0 * ni / (np.pi**3 * d**4) * (li / ni) ** 3
        B = 8.0 * ni / (np.pi * d**2) * (li / ni)
        C = 8.0 * ni / (np.pi**2 * d**4) * (li / ni) ** 2
        e = _at(e_fab, i) * (1.0 - _at(e_slope, i) * dti)
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
