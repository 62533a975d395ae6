"""Expected separation of hypotheses under a protocol.

Criterion: for each pair of hypotheses (i, j),

    D_ij = sum over predicted rows and quantities of (m_i - m_j)^2 / (s^2 + v_i + v_j)

with m and v the mean and variance of a hypothesis's predictions over draws of its fitted
parameters, and s the diagnosis's noise floor of that quantity. It is the T-optimality
criterion of Atkinson & Fedorov (1975) for discriminating between rival models (the squared
distance of one model's predictions from the other's), with each model's predictive variance
added to the noise in the denominator so that a difference the current fits cannot pin down
counts for less. For two Gaussian predictive distributions that differ mainly in the mean,
D_ij / 2 is the expected log Bayes factor in favour of the true one after the new runs. A
protocol separates as well as its hardest pair: min over pairs of D_ij.

D_ij treats the rows as independent. :func:`refit_separation` keeps the draws' correlation
between rows: with S_i the covariance over rows of hypothesis i's draws,

    R_ij = r^T (sigma^2 I + S_i + S_j)^-1 r,    r = mean_i - mean_j,

which, for predictions linear in the parameters near the fits, is the least over shifts of
both hypotheses' parameters (each penalised by its posterior from the runs so far) of the
squared normalised distance between them: the T-criterion with each rival refitted to the new
runs under what the old runs say. R_ij <= D_ij is not guaranteed row by row, but a smooth
shift of one hypothesis's curve towards the other's counts against R and not against D.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["pair_separation", "separation", "refit_separation", "information_gain"]


def pair_separation(mean_i, var_i, mean_j, var_j, noise_var) -> float:
    """D_ij of two hypotheses' predictions [-].

    Parameters
    ----------
    mean_i, mean_j : array_like
        Predicted means per row [SI].
    var_i, var_j : array_like
        Predictive variances per row from the parameter draws [SI^2].
    noise_var : array_like or float
        Noise floor variance per row [SI^2].
    """
    d2 = (np.asarray(mean_i, float) - np.asarray(mean_j, float)) ** 2
    den = np.asarray(noise_var, float) + np.asarray(var_i, float) + np.asarray(var_j, float)
    return float(np.sum(d2 / den))


def separation(means: list, variances: list, noise_var) -> tuple[float, np.ndarray]:
    """(min over pairs of D_ij, the matrix D) of several hypotheses' predictions [-].

    ``means`` and ``variances``: one array per hypothesis, the same rows in each (noise
    normalisation by ``noise_var`` [SI^2], per row). One hypothesis alone: (inf, [[0]]).
    """
    k = len(means)
    D = np.zeros((k, k))
    for i, j in itertools.combinations(range(k), 2):
        D[i, j] = D[j, i] = pair_separation(means[i], variances[i], means[j], variances[j], noise_var)
    if k < 2:
        return float("inf"), D
    return float(min(D[i, j] for i, j in itertools.combinations(range(k), 2))), D


def refit_separation(draws_i: np.ndarray, draws_j: np.ndarray, noise_sd) -> float:
    """R_ij of two hypotheses from their draws [-] (the module's docstring).

    Parameters
    ----------
    draws_i, draws_j : ndarray
        Predictions of each draw [SI], shape (draws, rows).
    noise_sd : array_like or float
        Noise floor per row [SI].

    Notes
    -----
    Computed with the Woodbury identity in the draws' space: with A the centred draws of both
    hypotheses over sqrt(n - 1), normalised by the noise, (I + A A^T)^-1 = I - A (I + A^T A)^-1 A^T.
    """
    s = np.asarray(noise_sd, float)
    parts, means = [], []
    for d in (np.atleast_2d(draws_i), np.atleast_2d(draws_j)):
        m = d.mean(axis=0)
        means.append(m)
        if d.shape[0] > 1:
            parts.append(((d - m) / s).T / np.sqrt(d.shape[0] - 1))
    z = (means[0] - means[1]) / s
    if not parts:
        return float(z @ z)
    A = np.hstack(parts)
    b = A.T @ z
    inner = np.eye(A.shape[1]) + A.T @ A
    return float(z @ z - b @ np.linalg.solve(inner, b))


def information_gain(B: np.ndarray) -> tuple[float, np.ndarray]:
    """Expected information gain of new runs about one hypothesis's parameters [nats], and the
    posterior covariance of its standardised parameters after them.

    ``B`` (rows x parameters, rows normalised by the noise) is the predictions' sensitivity to
    one current posterior sd of each standardised parameter (the current posterior is then
    the identity). Linearised, the new runs update it to (I + B^T B)^-1, and the gain is
    0.5 log det(I + B^T B) (D-optimality, Bayesian form).
    """
    B = np.atleast_2d(np.asarray(B, float))
    info = np.eye(B.shape[1]) + B.T @ B
    return 0.5 * float(np.linalg.slogdet(info)[1]), np.linalg.inv(info)
