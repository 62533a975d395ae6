"""Expected separation of hypotheses under a protocol.

Criterion (Box & Hill 1967, in its multivariate form): the symmetric Kullback-Leibler
divergence between two hypotheses' predictive distributions of the new runs,

    J_ij = KL(i || j) + KL(j || i),

with each hypothesis's predictive distribution Gaussian: centred on its fit's prediction m_i,
with covariance C_i = s^2 I + S_i (the noise floor s of each quantity plus S_i, the second
moment over rows of its parameter draws' predictions about m_i). KL(i || j) is the expected log Bayes factor
for i over j when i is true, so J_ij / 2 is the expected log Bayes factor for the true one of
the pair when either is equally likely a priori. Written out,

    J_ij = 1/2 [tr(C_j^-1 C_i) + tr(C_i^-1 C_j) - 2 n] + 1/2 r^T (C_i^-1 + C_j^-1) r,   r = m_i - m_j.

The second term is the T-criterion of Atkinson & Fedorov (1975) with each rival's predictive
covariance (for predictions linear in the parameters, the least squared normalised distance
between the two after refitting both to the new runs under what the old runs say). The first
term is what the mean misses when one hypothesis nests the other: a drift fitted at about zero
on a heating-only run predicts the same mean as recalibration under a heat-cool program, but
a spread of hundreds of micrometres where recalibration predicts a few; the new runs settle
which, and only the variance term sees it. :func:`refit_separation` is J_ij with the draws'
correlation between rows kept (the criterion the design decides on); :func:`pair_separation`
the same with every row independent (an upper bound when rows are correlated, kept as D).

A protocol separates as well as its hardest pair: min over pairs.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["pair_separation", "separation", "refit_separation", "information_gain", "wald_after"]


def pair_separation(mean_i, var_i, mean_j, var_j, noise_var) -> float:
    """J_ij of two hypotheses' predictions with every row independent [-] (the module's
    docstring): per row, with a = s^2 + v_i and b = s^2 + v_j,
    1/2 [(a - b)^2 / (a b) + r^2 (1/a + 1/b)].

    Parameters
    ----------
    mean_i, mean_j : array_like
        Predicted means per row [SI].
    var_i, var_j : array_like
        Predictive variances per row from the parameter draws [SI^2].
    noise_var : array_like or float
        Noise floor variance per row [SI^2].
    """
    r2 = (np.asarray(mean_i, float) - np.asarray(mean_j, float)) ** 2
    a = np.asarray(noise_var, float) + np.asarray(var_i, float)
    b = np.asarray(noise_var, float) + np.asarray(var_j, float)
    return float(np.sum(0.5 * ((a - b) ** 2 / (a * b) + r2 * (1.0 / a + 1.0 / b))))


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


def _spread(draws: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centre, A) of draws normalised by the noise, C / s^2 = I + A A^T (A rows x draws): the
    centre is the first draw (the hypothesis's fit), A the other draws' deviations from it
    over sqrt(draws - 1), their second moment about the fit."""
    d = np.atleast_2d(np.asarray(draws, float))
    m = d[0]
    if d.shape[0] < 2:
        return m / s, np.zeros((d.shape[1], 0))
    return m / s, ((d[1:] - m) / s).T / np.sqrt(d.shape[0] - 1)


def refit_separation(draws_i: np.ndarray, draws_j: np.ndarray, noise_sd) -> float:
    """J_ij of two hypotheses from their draws, rows correlated [-] (the module's docstring).

    Parameters
    ----------
    draws_i, draws_j : ndarray
        Predictions of each draw [SI], shape (draws, rows); the first is the fit itself, the
        centre of the hypothesis's predictive distribution. (Not the draws' mean: where the
        model bends, the mean of 30 draws drifts from the fit; on a curvature sensor near the
        edge of its map it sat 4 noise sds from the fit, which both fit within the noise.)
    noise_sd : array_like or float
        Noise floor per row [SI].

    Notes
    -----
    Computed in the draws' space (k draws, n rows, O(n k^2)): with M = I + A A^T and
    W = (I + A^T A)^-1, M^-1 = I - A W A^T (Woodbury), so
    tr(M_j^-1 M_i) - n = |A_i|^2 - tr(W_j A_j^T A_j) - tr(W_j A_j^T A_i A_i^T A_j) and
    z^T M^-1 z = z^T z - (A^T z)^T W (A^T z).
    """
    s = np.asarray(noise_sd, float)
    (mi, Ai), (mj, Aj) = _spread(draws_i, s), _spread(draws_j, s)
    z = mi - mj
    Wi = np.linalg.inv(np.eye(Ai.shape[1]) + Ai.T @ Ai)
    Wj = np.linalg.inv(np.eye(Aj.shape[1]) + Aj.T @ Aj)
    Gij = Ai.T @ Aj
    tr_ji = np.sum(Ai * Ai) - np.trace(Wj @ (Aj.T @ Aj)) - np.trace(Wj @ Gij.T @ Gij)
    tr_ij = np.sum(Aj * Aj) - np.trace(Wi @ (Ai.T @ Ai)) - np.trace(Wi @ Gij @ Gij.T)
    bi, bj = Ai.T @ z, Aj.T @ z
    quad = 2.0 * float(z @ z) - float(bi @ Wi @ bi) - float(bj @ Wj @ bj)
    return float(0.5 * (tr_ji + tr_ij) + 0.5 * quad)


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


def wald_after(B: np.ndarray, root_effect: np.ndarray, theta: np.ndarray) -> tuple[float, np.ndarray]:
    """(Wald statistic of an effect's parameters at their fit after new runs [-], their sds
    then [SI]).

    The J criterion averages over the effect's current posterior, which on a protocol that
    cannot pin the effect is wide: a G(T) slope fitted at 4.4e3 Pa/K (95 % -2.7e4 to 3.6e4) on
    one load spreads its draws' predictions at a second load and J reads the spread as
    separation, yet at the fitted slope recalibration absorbs the effect at any load (0.04-0.08
    um left over four loads, against 6 um of noise). This asks the question at the fit: with
    the runs so far and the new ones, would an effect as large as fitted stand out from zero?

    Parameters
    ----------
    B : ndarray
        Sensitivity of the new runs' rows (over their noise) to one current posterior sd of each
        standardised parameter (recalibrated and effect), rows x parameters, as in
        :func:`information_gain`.
    root_effect : ndarray
        The effect parameters' rows of the joint covariance's square root (theta = theta_fit +
        root_effect z, z standard normal) [SI].
    theta : ndarray
        The effect's fitted parameters [SI].

    Notes
    -----
    Linearised, Sigma_after = R (I + B^T B)^-1 R^T with R = ``root_effect`` (the recalibrated
    parameters refitted alongside, as nuisances), and the statistic is
    theta^T Sigma_after^+ theta: the chi^2 of the effect against zero if the new runs come out
    as the fit predicts; half of it is the log likelihood ratio, so it decides (a Bayes factor
    of 100) from 2 ln 100, as J does.
    """
    _, post = information_gain(B)
    R = np.atleast_2d(np.asarray(root_effect, float))
    cov = R @ post @ R.T
    t = np.asarray(theta, float)
    return float(t @ np.linalg.pinv(cov) @ t), np.sqrt(np.clip(np.diag(cov), 0.0, None))
