"""Which states of the self-sensing filter voltage and current can tell apart, over which protocol.

The filter's state is s = (T, x, v, F, theta) (:mod:`tcamlab.estimation.observer_kernel`); its
one measurement is the current I = V / R(T, x) (1 + theta (T - T_a)). Linearised about a
trajectory, sample k maps a change ds_0 of the state at the window's start to a change of
the k-th current reading by H_k Phi_k ds_0, with Phi_k = A_(k-1) ... A_0 the product of the
transition Jacobians. The observability Gramian of the window

    W = sum_k Phi_k' H_k' H_k Phi_k / sd_k^2            [1 / (state unit)^2]

is the Fisher information the readings carry about the window's initial state (the process
noise left out: what the model's own dynamics make separable). Its rank and condition
number, in states scaled by :data:`STATE_SCALES`, say which combinations the readings pin
and which rest on the priors (README "Self-sensing": the figures per protocol).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "STATE_NAMES",
    "STATE_SCALES",
    "Observability",
    "gramian",
    "linear_gramian",
    "marginal",
    "summarise",
    "trajectory_gramian",
]

STATE_NAMES = ("T", "x", "v", "F", "theta")
"""The filter's states, in the kernel's order."""
STATE_SCALES = np.array([1.0, 10e-6, 1e-4, 1e-3, 1e-4])
"""Units the Gramian is expressed in: 1 K, 10 um, 0.1 mm/s, 1 mN, 1e-4 /K (a size that matters
for each state: 1 K reads as about 150 um, 10 um is the sensing goal's scale, 1 mN moves x
by about 0.05 mm, theta 1e-4 /K is a TCR 2.6 % off)."""


@dataclass(frozen=True)
class Observability:
    """The Gramian's verdict.

    Attributes
    ----------
    singular_values : ndarray
        Of the scaled Gramian, descending [1 / scale^2].
    rank : int
        Singular values above ``tol`` times the largest.
    condition : float
        Largest over smallest singular value [-] (inf when singular).
    weakest : dict
        The least-informed direction: {state name: component} (unit vector in scaled states).
    sd : dict
        {state name: sd [scale units]} if the readings alone had to pin every state, the
        square roots of the diagonal of the pseudo-inverse.
    """

    singular_values: np.ndarray
    rank: int
    condition: float
    weakest: dict
    sd: dict


def linear_gramian(a_seq, h_seq, sd_seq) -> np.ndarray:
    """W = sum_k Phi_k' H_k' H_k Phi_k / sd_k^2 of a linear(ised) system.

    Parameters
    ----------
    a_seq : sequence of ndarray, shape (n, n)
        A_k, the transition from sample k to k + 1 (the last one is not used).
    h_seq : sequence of ndarray, shape (m, n) or (n,)
        H_k, the measurement Jacobian at sample k.
    sd_seq : sequence of float
        sd of the reading at sample k [its unit].

    Returns
    -------
    ndarray, shape (n, n)
    """
    n = np.asarray(a_seq[0]).shape[0]
    phi = np.eye(n)
    w = np.zeros((n, n))
    for k, (h, sd) in enumerate(zip(h_seq, sd_seq)):
        hp = np.atleast_2d(h) @ phi
        w += hp.T @ hp / float(sd) ** 2
        if k < len(a_seq):
            phi = np.asarray(a_seq[k]) @ phi
    return w


def marginal(w, keep) -> np.ndarray:
    """The information on the states ``keep`` (indices) with the others unknown: the Schur
    complement W_kk - W_ko W_oo^+ W_ok [1 / unit^2] (x and v are slaved to T and F within the
    mechanics' settling, so their initial values are forgotten; this asks about the rest)."""
    w = np.asarray(w, float)
    keep = list(keep)
    other = [i for i in range(w.shape[0]) if i not in keep]
    if not other:
        return w[np.ix_(keep, keep)]
    w_ko = w[np.ix_(keep, other)]
    return w[np.ix_(keep, keep)] - w_ko @ np.linalg.pinv(w[np.ix_(other, other)]) @ w_ko.T


def summarise(w, scales=None, names=STATE_NAMES, tol=1e-9) -> Observability:
    """Rank, condition and weakest direction of a Gramian in scaled states.

    Parameters
    ----------
    w : ndarray, shape (n, n)
        Gramian in SI state units [1 / unit^2].
    scales : ndarray, optional
        Unit of each state [SI]; W is expressed in them (default ones).
    names : sequence of str
    tol : float
        Relative threshold of the rank.
    """
    w = np.asarray(w, float)
    s = np.ones(w.shape[0]) if scales is None else np.asarray(scales, float)
    ws = w * np.outer(s, s)
    u, sv, _ = np.linalg.svd(0.5 * (ws + ws.T))
    rank = int(np.sum(sv > tol * sv[0])) if sv[0] > 0 else 0
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    weakest = {nm: float(c) for nm, c in zip(names, u[:, -1])}
    pinv = np.linalg.pinv(ws, rcond=tol)
    sd = {nm: float(np.sqrt(max(pinv[i, i], 0.0))) for i, nm in enumerate(names)}
    return Observability(sv, rank, cond, weakest, sd)


def trajectory_gramian(config, time, voltage, current, states, start=0, stop=None) -> np.ndarray:
    """The filter's linearised Gramian over rows [start, stop) of a run, about ``states``.

    Parameters
    ----------
    config : tcamlab.estimation.observer.ObserverConfig
    time, voltage, current : ndarray, shape (n,)
        [s], [V], [A]: the power V I - I^2 R_lead of row k is held to row k + 1.
    states : ndarray, shape (n, 5)
        The trajectory (the filter's estimate, or the truth) [T degC, x m, v m/s, F N, theta 1/K].

    Returns
    -------
    ndarray, shape (5, 5)
        W in SI state units [1 / unit^2].
    """
    from tcamlab.estimation import observer as so
    from tcamlab.estimation import observer_kernel as K

    stop = len(time) if stop is None else stop
    p = so.parameter_vector(config.sample, config.rig, config.lead_resistance)
    sd_v, sd_i = config.noise["sd_voltage"], config.noise["sd_current"]
    a_seq, h_seq, sd_seq = [], [], []
    for k in range(start, stop):
        s = np.asarray(states[k], float)
        r_tab, drdt, drdx = K.table_resistance(s[0], s[1], config.table.values, config.table.grid)
        dT = s[0] - config.rig.ambient
        r = r_tab * (1.0 + s[4] * dT)
        g = -voltage[k] / r**2
        h_seq.append(np.array([g * (drdt * (1 + s[4] * dT) + r_tab * s[4]), g * drdx * (1 + s[4] * dT), 0.0, 0.0,
                               g * r_tab * dT]))  # fmt: skip
        sd_seq.append(float(np.hypot(sd_i, sd_v / r)))
        if k + 1 < stop:
            a_seq.append(_transition(s, voltage[k], current[k], time[k + 1] - time[k], p))
    return linear_gramian(a_seq, h_seq, sd_seq)


def _transition(s, volt, cur, dt, p):
    """A = d f / d s of the filter's time update by forward differences (its own steps)."""
    from tcamlab.estimation import observer_kernel as K

    power = max(volt * cur - p[K.P_LEAD] * cur * cur, 0.0)
    nsub = max(1, int(np.ceil(dt / 1e-3)))
    base = np.empty(K.NX)
    K.propagate(s, power, dt, p, nsub, base)
    a = np.empty((K.NX, K.NX))
    moved = np.empty(K.NX)
    for j, eps in enumerate(K.EPS):
        pert = s.copy()
        pert[j] += eps
        K.propagate(pert, power, dt, p, nsub, moved)
        a[:, j] = (moved - base) / eps
    return a


def gramian(config, data, states, rows=None, keep=(0, 3, 4)) -> Observability:
    """:func:`summarise` of :func:`trajectory_gramian` over ``rows`` (a slice) of a logged run.

    ``data`` has ``time`` [s], ``voltage`` [V] and ``current`` [A]; ``states`` as
    :func:`trajectory_gramian`. The states ``keep`` (default T, F, theta: :func:`marginal`
    of the others), in :data:`STATE_SCALES`.
    """
    sel = rows or slice(0, len(data))
    t, v, i = (data[c].to_numpy(float) for c in ("time", "voltage", "current"))
    w = trajectory_gramian(config, t, v, i, states, sel.start or 0, sel.stop)
    keep = list(keep)
    names = [STATE_NAMES[k] for k in keep]
    return summarise(marginal(w, keep), STATE_SCALES[keep], names)
