"""Every statistical constant and weighting of the calibration against a hand-computed value.

Each test feeds a small hand-made input to the function that uses the constant and compares
its output with a value computed here from the documented formula (closed form, or scipy's
quantiles of the documented level), so that a small change of the constant or of the formula
fails. The problems are tiny linear-Gaussian stand-ins of :class:`CalibrationProblem` (its
own residual stacking, Jacobian, box, fit and intervals on a linear data part) whose posterior
is known exactly; the parameters are described here (positive: fitted in log), so the tests
do not depend on which coordinate a kind's own parameters use.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from tcamlab.calibration.fit import (
    CHI2_95,
    Z95,
    laplace_covariance,
    map_fit,
    profile_interval,
)
from tcamlab.calibration.identify import (
    COMPONENT_SHARE,
    CONSTRAINED_RATIO,
    PINNED_PROMISE,
    PINNED_RATIO,
    PINNED_REL_SD,
    closer_probability,
    directions,
    tier,
)
from tcamlab.calibration.problem import (
    FAIL_RESIDUAL,
    FD_STEP,
    MAX_LOG_SPAN,
    ROW_SIGMA_FLOOR,
    CalibrationProblem,
    Spec,
    profile_random_effects,
    random_effect_basis,
)
from tcamlab.kinds import CalibrationParam

# the documented values, typed in from the docstrings (not imported)
Z_975 = stats.norm.ppf(0.975)  # "95 %" two-sided
DOC_FD_STEP = 1e-5
DOC_FLOOR = 0.5
DOC_PRIOR_BOX_SDS = 6.0
DOC_MAX_FACTOR = 1e3


def _param(field="thermal_mass", positive=True):
    return CalibrationParam(field, "sample", "C_th", "J/K", 0.1, "a logged temperature", positive)


def _spec(name="a", stated=2.0, prior_sd=0.2, positive=True, reading=None):
    return Spec(
        name=name,
        param=_param(name, positive),
        experiments=(0,),
        stated=stated,
        stated_in_file=True,
        prior_sd=prior_sd,
        sd_stated=True,
        key=f"{name}_J_per_K",
        factor=1.0,
        reading=reading,
    )


class LinearProblem(CalibrationProblem):
    """A calibration problem whose data residuals are ``A u - y`` (already normalised): the
    prior rows, Jacobian, box, fit and profile are :class:`CalibrationProblem`'s own."""

    def __init__(self, a, y, specs):
        self.a, self.y = np.asarray(a, float), np.asarray(y, float)
        self.specs = list(specs)
        self.u0 = np.array([s.u0 for s in self.specs])
        self.sd_u = np.array([s.sd_u for s in self.specs])
        self.stated_u0 = np.array([s.stated_u0 for s in self.specs])
        self.stated_sd_u = np.array([s.stated_sd_u for s in self.specs])
        self.size = self.y.size

    def data_residuals(self, u):
        return self.a @ np.asarray(u, float) - self.y


def _bare(size=3):
    """A problem with nothing but its size (for the Jacobian of a given function)."""
    p = CalibrationProblem.__new__(CalibrationProblem)
    p.size = size
    return p


@pytest.fixture(scope="module")
def linear():
    """Two positive parameters (log coordinates) seen by four data rows; the exact posterior."""
    specs = [_spec("a", 2.0, 0.2), _spec("b", 5.0, 1.0)]
    a = np.array([[3.0, 1.0], [1.0, -2.0], [0.5, 0.5], [2.0, 1.0]])
    p = LinearProblem(a, np.zeros(4), specs)
    u_true = p.u0 + np.array([0.05, -0.1])
    p.y = a @ u_true + np.array([0.3, -0.2, 0.1, -0.4])
    prec = np.diag(p.sd_u**-2.0)
    cov = np.linalg.inv(a.T @ a + prec)
    u_map = cov @ (a.T @ p.y + prec @ p.u0)
    fit = map_fit(p)
    return p, fit, cov, u_map


# ---------------------------------------------------------------------------- fit.py
def test_chi2_95_and_z95_are_the_95_percent_quantiles():
    assert CHI2_95 == pytest.approx(stats.chi2.ppf(0.95, 1), rel=1e-12)
    assert Z95 == pytest.approx(Z_975, rel=1e-12)
    assert Z95**2 == pytest.approx(CHI2_95, rel=1e-12)


def test_map_and_laplace_covariance_are_the_exact_linear_gaussian_posterior(linear):
    p, fit, cov, u_map = linear
    assert fit.u == pytest.approx(u_map, abs=1e-7)
    got, jac = laplace_covariance(p, fit.u)
    assert got == pytest.approx(cov, rel=1e-6, abs=1e-12)
    # the prior rows weigh 1 / sd_u each: the last rows of the Jacobian are diag(1 / sd_u)
    assert jac[-2:] == pytest.approx(np.diag(1.0 / p.sd_u), rel=1e-6)
    r = p.residuals(fit.u)
    assert fit.chi2 == pytest.approx(float(r @ r), rel=1e-9)


@pytest.mark.parametrize("k", [0, 1])
@pytest.mark.parametrize("side", [-1, 1])
def test_profile_bound_of_a_quadratic_chi2_is_z_975_posterior_sds_out(linear, k, side):
    p, fit, cov, u_map = linear
    cov_fit, jac = laplace_covariance(p, fit.u)
    prof = profile_interval(p, fit, cov_fit, k, side, jac)
    assert not prof.open
    expected = u_map[k] + side * Z_975 * math.sqrt(cov[k, k])
    assert prof.bound == pytest.approx(expected, abs=2e-3 * math.sqrt(cov[k, k]))


# ---------------------------------------------------------------------------- core.py
def test_estimate_posterior_sd_laplace_interval_and_tier(linear):
    from tcamlab.calibration.core import _estimate  # only calibrate() reaches it otherwise

    p, fit, cov, u_map = linear
    cov_fit, jac = laplace_covariance(p, fit.u)
    for k, s in enumerate(p.specs):
        sides = [profile_interval(p, fit, cov_fit, k, side, jac) for side in (-1, 1)]
        est = _estimate(p, k, fit.u, cov_fit, sides)
        sd_u = math.sqrt(cov[k, k])
        value = math.exp(u_map[k])
        assert est.value == pytest.approx(value, rel=1e-7)
        # log coordinates: sd = value * sd of log(value), relative sd = sd of log(value)
        assert est.posterior_sd == pytest.approx(value * sd_u, rel=1e-5)
        assert est.posterior_sd_rel == pytest.approx(sd_u, rel=1e-5)
        assert est.prior_sd_rel == pytest.approx(s.prior_sd / s.stated, rel=1e-12)
        lo, hi = math.exp(u_map[k] - Z_975 * sd_u), math.exp(u_map[k] + Z_975 * sd_u)
        assert est.laplace_95 == pytest.approx((lo, hi), rel=1e-5)
        assert est.profile_95 == pytest.approx((lo, hi), rel=2e-3 * sd_u)
        assert est.shift_in_stated_sds == pytest.approx((value - s.stated) / s.prior_sd, rel=1e-6)
        assert est.identification == tier(sd_u, s.prior_sd / s.stated)


# ---------------------------------------------------------------------------- problem.py
def test_fd_step_is_1e_5_forward_and_central():
    p = _bare(1)
    u = np.zeros(1)
    # forward: (f(h) - f(0)) / h of u^2 is h exactly
    fwd = p.jacobian(u, fn=lambda v: np.array([v[0] ** 2]), central=False)
    assert fwd[0, 0] == pytest.approx(DOC_FD_STEP, rel=1e-9)
    # central: (f(h) - f(-h)) / 2h of u^3 is h^2 exactly
    cen = p.jacobian(u, fn=lambda v: np.array([v[0] ** 3]))
    assert cen[0, 0] == pytest.approx(DOC_FD_STEP**2, rel=1e-6)
    assert FD_STEP == DOC_FD_STEP


def test_jacobian_takes_the_inner_side_when_one_side_fails():
    p = _bare(1)

    def fn(v):
        return np.array([FAIL_RESIDUAL]) if v[0] > 0 else np.array([v[0] ** 2 + v[0]])

    # up fails: (f(0) - f(-h)) / h = 1 - h
    col = p.jacobian(np.zeros(1), fn=fn)
    assert col[0, 0] == pytest.approx(1.0 - DOC_FD_STEP, rel=1e-9)


def test_failed_is_half_the_size_times_fail_residual_squared():
    p = _bare(4)
    edge = 0.5 * 4 * FAIL_RESIDUAL**2
    assert p.failed(edge)
    assert not p.failed(edge * (1 - 1e-9))
    assert FAIL_RESIDUAL == 1.0e3


def _d2_over_6(r):
    return np.array([(r[i + 1] - 2 * r[i] + r[i - 1]) ** 2 / 6.0 for i in range(1, len(r) - 1)])


def test_row_noise_without_inputs_is_the_second_difference_estimator():
    r1 = np.array([0.0, 1.0, -1.0, 2.0, 0.5, 0.0])
    r2 = np.array([1.0, 0.0, 0.0, 3.0])
    rows = CalibrationProblem.row_noise([r1, r2, np.array([1.0, 2.0])], [{}, {}, {}])
    # pooled over both runs' second differences (a 2-row run has none), one sd everywhere
    d = np.concatenate([_d2_over_6(r1), _d2_over_6(r2)])
    sd = math.sqrt(d.mean())
    assert [len(v) for v in rows] == [6, 4, 2]
    for v in rows:
        assert v == pytest.approx(np.full(v.size, sd), rel=1e-12)


def test_row_noise_follows_the_slopes_with_its_floor_at_half_the_single_sd():
    # second differences d_i; the local G_i = d_i^2 / (6 c) makes a = 0, b = c exact
    c = 2.5
    d = np.array([0.0, 1.0, 3.0, 0.2, 2.0, 4.0, 0.0, 1.5])
    n = d.size + 2
    r = np.zeros(n)
    r[1] = 0.3
    for i in range(1, n - 1):
        r[i + 1] = d[i - 1] + 2 * r[i] - r[i - 1]
    g = np.zeros(n)
    g[1:-1] = d**2 / (6 * c)
    rows = CalibrationProblem.row_noise([r], [{"R1": np.sqrt(g)}])[0]
    total = float(np.mean(d**2 / 6))
    expected = np.sqrt(np.maximum(c * g, DOC_FLOOR**2 * total))
    assert rows == pytest.approx(expected, rel=1e-7)
    # the floor (0.25 x 0.673 = 0.168 in variance) is what the ends, the d = 0 rows and the
    # d = 0.2 and d = 1 rows (c G = 0.0067 and 0.167) get
    floored = np.isclose(rows, DOC_FLOOR * math.sqrt(total), rtol=1e-9)
    assert floored.sum() == 6
    assert ROW_SIGMA_FLOOR == DOC_FLOOR


def test_row_noise_splits_output_and_input_noise():
    # squared second differences / 6 = 1 + 2 G on every row: a = 1, b = 2
    rng = np.random.default_rng(3)
    n = 12
    g = np.zeros(n)
    g[1:-1] = rng.uniform(0.0, 4.0, n - 2)
    d = np.sqrt(6.0 * (1.0 + 2.0 * g[1:-1]))
    r = np.zeros(n)
    for i in range(1, n - 1):
        r[i + 1] = d[i - 1] + 2 * r[i] - r[i - 1]
    rows = CalibrationProblem.row_noise([r], [{"R1": np.sqrt(g / 2), "R2": np.sqrt(g / 2)}])[0]
    total = float(np.mean(d**2 / 6))
    assert rows == pytest.approx(np.sqrt(np.maximum(1.0 + 2.0 * g, 0.25 * total)), rel=1e-7)


def test_zero_is_the_mean_weighted_by_inverse_row_variance():
    p = _bare(3)
    p.row_sigma = {(0, 0, "q"): np.array([1.0, 2.0, 0.5])}
    r = np.array([3.0, -1.0, 2.0])
    w = np.array([1.0, 0.25, 4.0])
    assert p.zero_of(0, 0, "q", r) == pytest.approx(float(np.sum(w * r) / np.sum(w)), rel=1e-12)


def test_prior_in_fitted_coordinates_and_the_reading_multiplied_in():
    s = _spec(stated=2.0, prior_sd=0.2)
    assert s.stated_sd_u == pytest.approx(0.1, rel=1e-12)
    assert s.u0 == pytest.approx(math.log(2.0), rel=1e-12)
    # a reading at rest 2.2 +- 0.11, i.e. log(2.2) +- 0.05: precisions 100 and 400 add
    s = _spec(stated=2.0, prior_sd=0.2, reading=(2.2, 0.11))
    assert s.sd_u == pytest.approx(500**-0.5, rel=1e-12)
    assert s.u0 == pytest.approx((100 * math.log(2.0) + 400 * math.log(2.2)) / 500, rel=1e-12)
    # a parameter that may be 0: value / prior sd, prior sd 1 in those units
    s = _spec(stated=3.0, prior_sd=0.5, positive=False, reading=(3.5, 0.25))
    assert s.stated_u0 == pytest.approx(6.0) and s.stated_sd_u == 1.0
    assert s.sd_u == pytest.approx((1 + 4) ** -0.5, rel=1e-12)
    assert s.u0 == pytest.approx((6.0 + 4 * 7.0) / 5, rel=1e-12)


def test_box_is_six_prior_sds_at_most_a_factor_1000():
    specs = [_spec("a", 2.0, 0.2), _spec("b", 1.0, 3.0), _spec("c", 3.0, 0.5, positive=False)]
    p = LinearProblem(np.zeros((1, 3)), np.zeros(1), specs)
    lo, hi = p.bounds()
    span = np.array([DOC_PRIOR_BOX_SDS * 0.1, math.log(DOC_MAX_FACTOR), DOC_PRIOR_BOX_SDS * 1.0])
    assert lo == pytest.approx(p.u0 - span, rel=1e-12)
    assert hi == pytest.approx(p.u0 + span, rel=1e-12)
    assert MAX_LOG_SPAN == pytest.approx(math.log(DOC_MAX_FACTOR))


def test_profiled_random_effects_are_the_whitened_marginal_residuals():
    rng = np.random.default_rng(11)
    g = rng.normal(0.0, 1.5, (7, 2))
    r = rng.normal(0.0, 1.0, 7)
    m = np.eye(7) + g @ g.T
    lam, vec = np.linalg.eigh(m)
    expected = vec @ np.diag(lam**-0.5) @ vec.T @ r  # (I + G G^T)^-1/2 r
    u_mat, shrink = random_effect_basis(g)
    sv = np.linalg.svd(g, compute_uv=False)
    assert shrink == pytest.approx(1.0 - 1.0 / np.sqrt(1.0 + sv**2), rel=1e-12)
    out = profile_random_effects(r, u_mat, shrink)
    assert out == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert float(out @ out) == pytest.approx(float(r @ np.linalg.solve(m, r)), rel=1e-9)


# ---------------------------------------------------------------------------- identify.py
def test_pinned_ratio_is_the_90_percent_promise():
    r = math.tan(0.5 * math.pi * (1 - 0.90))
    assert PINNED_PROMISE == 0.90
    assert PINNED_RATIO == pytest.approx(r, rel=1e-12)
    assert closer_probability(r) == pytest.approx(0.90, rel=1e-12)
    assert closer_probability(0.5) == pytest.approx(2 / math.pi * math.atan(2.0), rel=1e-12)
    assert closer_probability(0.0) == 1.0


def test_tier_at_and_beside_each_threshold():
    r = math.tan(0.5 * math.pi * (1 - 0.90))
    # relative sd at most 10 % (ratio 0.1 well inside)
    assert tier(0.10, 1.0) == "pinned"
    assert tier(0.10 * (1 + 1e-9), 1.0) == "constrained"
    # ratio at most tan(pi/2 * 0.1) (both powers of two apart: the ratio is exact)
    assert tier(r / 8, 1 / 8) == "pinned"
    assert tier(r * (1 + 1e-9) / 8, 1 / 8) == "constrained"
    assert tier(r * (1 - 1e-9) / 8, 1 / 8) == "pinned"
    # constrained when the logs at least halve the prior sd
    assert tier(0.5, 1.0) == "constrained"
    assert tier(0.5 * (1 + 1e-9), 1.0) == "prior"
    assert tier(0.2, 0.0) == "prior"
    assert (PINNED_REL_SD, CONSTRAINED_RATIO) == (0.10, 0.5)


def test_directions_ratio_relative_sd_and_the_component_share():
    sd_u = np.array([0.5, 2.0, 1.0])
    # whitened eigenvectors; the first one's exponents a = v / sd_u come out 1, 0.31, 0.29
    a1 = np.array([1.0, 0.31, 0.29])
    v1 = a1 * sd_u
    v1 /= np.linalg.norm(v1)
    q, _ = np.linalg.qr(np.column_stack([v1, [0, 1.0, 0], [0, 0, 1.0]]))
    lam = np.array([0.0004, 0.25, 0.81])
    cw = q @ np.diag(lam) @ q.T
    cov = cw * np.outer(sd_u, sd_u)
    dirs = directions(["x", "y", "z"], sd_u, cov)
    best = dirs[0]
    assert best.ratio == pytest.approx(0.02, rel=1e-9)
    # exponents below 0.3 of the largest are left out of the name
    assert set(best.exponents) == {"x", "y"}
    assert best.exponents["y"] == pytest.approx(0.31, rel=1e-9)
    rel = math.sqrt(a1 @ cov @ a1)
    assert best.relative_sd == pytest.approx(rel, rel=1e-9)
    assert best.pinned == (rel <= 0.10 and 0.02 <= math.tan(0.05 * math.pi))
    assert [d.ratio for d in dirs] == pytest.approx(np.sqrt(lam), rel=1e-9)
    assert COMPONENT_SHARE == 0.3


def _restart_problem(target):
    """20 data rows, 2 parameters stated at 1 (log 0): the minimum chi-square is quadratic in
    the data, scaled here to ``target``."""
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 1.0, (20, 2))
    p = LinearProblem(a, rng.normal(0.0, 1.0, 20), [_spec("a", 1.0, 0.5), _spec("b", 1.0, 0.5)])
    h = a @ np.linalg.inv(a.T @ a + np.diag(p.sd_u**-2.0)) @ a.T
    chi2_min = float(p.y @ (np.eye(20) - h) @ p.y)
    p.y = p.y * math.sqrt(target / chi2_min)
    return p


@pytest.mark.parametrize("scale, restarted", [(1 - 1e-4, False), (1 + 1e-4, True)])
def test_map_fit_restarts_beyond_3_sds_of_chi2_above_its_expectation(monkeypatch, scale, restarted):
    import tcamlab.calibration.fit as fit_module

    n = 20 + 2  # data rows and prior rows
    p = _restart_problem((n + 3.0 * math.sqrt(2.0 * n)) * scale)
    calls = []
    solve = fit_module.solve

    def counted(*args, **kw):
        calls.append(1)
        return solve(*args, **kw)

    monkeypatch.setattr(fit_module, "solve", counted)
    map_fit(p)
    # one fit from the stated values; with restarts two along the lead and two per axis
    assert len(calls) == (1 + 2 + 2 * 2 if restarted else 1)


def test_zero_interval_is_z_975_sds_of_the_noise_and_the_parameters():
    from tcamlab.calibration.core import _zeros  # only calibrate() reaches it otherwise

    class Run:
        def __init__(self, n, path):
            self.data, self.path = np.zeros(n), path

    cov = np.array([[0.04, 0.01], [0.01, 0.09]])
    g = np.array([[1.0, 2.0], [0.5, -1.0]])
    p = _bare(0)
    p.zero_labels = lambda: [(0, 0, "q"), (0, 1, "q")]
    p.zeros = lambda u: np.array([0.3, -0.2])
    p.jacobian = lambda u, fn=None: g
    p.runs = [[Run(16, "r1.csv"), Run(25, "r2.csv")]]
    p.sigma = {(0, "q"): 2.0}
    p.experiments = [SimpleNamespace(name="e")]
    out = _zeros(p, np.zeros(2), cov)
    for z, n, gk, value in zip(out, (16, 25), g, (0.3, -0.2)):
        sd = math.sqrt(4.0 / n + gk @ cov @ gk)  # the noise's sigma^2 / n plus the parameters'
        assert z.sd == pytest.approx(sd, rel=1e-12)
        assert z.interval_95 == pytest.approx((value - Z_975 * sd, value + Z_975 * sd), rel=1e-9)
