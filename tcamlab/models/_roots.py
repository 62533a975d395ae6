"""Vectorised, bracketed root finding shared by the models.

A safeguarded Newton iteration over whole arrays: every element keeps a
bracket [lo, hi] with a sign change; a Newton step that leaves the bracket,
or does not halve the residual, is replaced by bisection. This converges
quadratically near the root and can never leave the bracket, so the root it
returns is the one the caller bracketed (the physical branch), not whichever
root Newton happens to find.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tcamlab.errors import ConvergenceError

XTOL = 1e-15
"""Default absolute tolerance on the root (here sin(alpha) or d/d0) [-]."""
RTOL = 1e-12
"""Default relative tolerance on the root [-] (Newton then stops one step after
the error reaches about 1e-12, where the residual is at round-off)."""
MAXITER = 100
"""Default iteration limit (bisection alone halves the bracket 100 times)."""


@dataclass
class RootResult:
    """Raw result of :func:`bracketed_newton`.

    Attributes
    ----------
    root : ndarray
        The roots (NaN where ``valid`` is False).
    iterations : int
        Iterations used for the slowest element.
    converged : ndarray of bool
        Per-element convergence flag.
    residual : ndarray
        Function value at the last iterate (within one tolerance of the root).
    """

    root: np.ndarray
    iterations: int
    converged: np.ndarray
    residual: np.ndarray


def bracketed_newton(
    func: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    lo: np.ndarray,
    hi: np.ndarray,
    x0: np.ndarray | None = None,
    *,
    xtol: float = XTOL,
    rtol: float = RTOL,
    maxiter: int = MAXITER,
    what: str = "root",
) -> RootResult:
    """Find roots of ``func`` in the brackets ``[lo, hi]`` element-wise.

    Parameters
    ----------
    func : callable
        ``func(x, idx) -> (f, dfdx)``, where ``idx`` indexes (an index array
        or a slice) the elements of the flattened problem that ``x`` belongs
        to, so the callable can pick its per-element parameters.
    lo, hi : ndarray
        Brackets; ``f(lo)`` and ``f(hi)`` must differ in sign (or be zero).
    x0 : ndarray, optional
        Starting points inside the brackets (default: mid-points).
    xtol, rtol : float
        Converged when the bracket or the last step is below
        ``xtol + rtol * |x|``.
    maxiter : int
        Iteration limit; elements not converged then raise.
    what : str
        Name of the unknown, for error messages.

    Returns
    -------
    RootResult

    Raises
    ------
    ConvergenceError
        When a bracket has no sign change or the iteration limit is reached.
    """
    lo = np.array(lo, dtype=float, copy=True).ravel()
    hi = np.array(hi, dtype=float, copy=True).ravel()
    n = lo.size
    idx_all = np.arange(n)
    f_lo, _ = func(lo, idx_all)
    f_hi, _ = func(hi, idx_all)
    bad = (np.sign(f_lo) * np.sign(f_hi)) > 0
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise ConvergenceError(
            f"{what}: no sign change in bracket [{lo[k]:.6g}, {hi[k]:.6g}] for "
            f"{int(bad.sum())} of {n} points (first at index {k})",
            hint="the inputs may lie outside the model's physical range",
        )
    x = 0.5 * (lo + hi) if x0 is None else np.clip(np.array(x0, float).ravel(), lo, hi)
    # Orient brackets so that f(lo) <= 0 <= f(hi).
    swap = f_lo > 0
    lo[swap], hi[swap] = hi[swap], lo[swap].copy()
    converged = np.zeros(n, dtype=bool)
    residual = np.full(n, np.nan)
    active = idx_all
    it = 0
    for it in range(1, maxiter + 1):  # noqa: B007 (its last value is reported)
        # While every element is still iterating, a slice avoids fancy-index copies.
        sel = slice(None) if active.size == n else active
        xa = x[sel].copy()
        f, df = func(xa, sel)
        residual[sel] = f
        done_exact = f == 0
        neg = f < 0
        lo_a = np.where(neg, xa, lo[sel])
        hi_a = np.where(neg, hi[sel], xa)
        lo[sel], hi[sel] = lo_a, hi_a
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = xa - f / df
        mid = 0.5 * (lo_a + hi_a)
        a, b = np.minimum(lo_a, hi_a), np.maximum(lo_a, hi_a)
        tol = xtol + rtol * np.abs(xa)
        # A Newton point just outside the bracket (by less than the tolerance)
        # means an endpoint already is the root: take it rather than bisect.
        clipped = np.clip(xn, a, b)
        near = np.isfinite(xn) & (np.abs(xn - clipped) <= tol)
        xn = np.where(near, clipped, xn)
        out = ~np.isfinite(xn) | (xn < a) | (xn > b)
        xn = np.where(out, mid, xn)
        step = np.abs(xn - xa)
        conv = done_exact | (step <= tol) | (np.abs(b - a) <= tol)
        x[sel] = np.where(done_exact, xa, xn)
        converged[active[conv]] = True
        active = active[~conv]
        if active.size == 0:
            break
    if active.size:
        raise ConvergenceError(
            f"{what}: {active.size} of {n} points did not converge in {maxiter} iterations",
            hint="loosen xtol/rtol or check the inputs for extreme values",
        )
    return RootResult(root=x, iterations=it, converged=converged, residual=residual)
