"""Error metrics between measured and predicted series, and acceptance checks.

:func:`error_metrics` compares one measured series with one prediction;
:func:`pooled_metrics` does the same over several runs concatenated;
:func:`check_thresholds` compares metrics against the acceptance limits of an
experiment file (see :data:`METRIC_UNITS_NOTE` for units and
:data:`THRESHOLD_FORMS` for the key grammar).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import stats

from tcamlab.errors import ConfigError, InputError

__all__ = [
    "MIN_REST_ROWS",
    "ZERO_METHOD_NOTE",
    "ZeroEstimate",
    "estimate_zero",
    "logged_zero",
    "ZERO_RULES",
    "ZERO_REST",
    "ZERO_WHOLE_RUN",
    "LOGGED_ZERO",
    "METRIC_NAMES",
    "METRIC_LABELS",
    "METRIC_UNITS_NOTE",
    "THRESHOLD_FORMS",
    "UNIT_SUFFIXES",
    "ThresholdCheck",
    "check_thresholds",
    "STATUS_PASSED",
    "STATUS_FAILED",
    "STATUS_NO_LIMITS",
    "STATUSES",
    "threshold_status",
    "error_metrics",
    "pooled_metrics",
    "quantity_unit",
    "SANITY_CHECKS",
    "SanityWarning",
    "FLAT_FRACTION",
    "ZERO_SE_LIMIT",
    "ZERO_NOISE_LIMIT",
    "REFERENCE_TOLERANCE",
    "r2_warnings",
    "flat_prediction_warning",
    "dead_channel_warning",
    "opposite_direction_warning",
    "OPPOSITE_CORRELATION",
    "zero_offset_warning",
    "reference_warning",
    "domain_warning",
    "unused_threshold_warnings",
    "stated_shift_warning",
    "opposite_sign_warning",
    "STATED_SD_LIMIT",
    "PLAUSIBLE_MAX",
    "PLAUSIBLE_MIN_C",
    "PLAUSIBLE_RESISTANCE_OHM",
    "implausible_value_warnings",
]

METRIC_NAMES = ("rmse", "mae", "max_abs", "bias", "nrmse", "r2")

METRIC_LABELS = {
    "rmse": "RMSE",
    "mae": "MAE",
    "max_abs": "max |err|",
    "bias": "bias",
    "nrmse": "NRMSE",
    "r2": "R²",
}
"""Column heading of each metric in reports (a new metric needs its name, its label and
its formula in :func:`error_metrics`; reports and metrics.json follow)."""
"""Keys of :func:`error_metrics` that are metrics (``n`` and ``n_nan`` are counts)."""

UNIT_SUFFIXES = ("per_mm", "mm", "N", "ohm")
"""Unit suffixes a quantity name or threshold key may end in (``_<suffix>``)."""

METRIC_UNITS_NOTE = """\
Units of the error metrics follow the quantity they are computed on.

``rmse``, ``mae``, ``max_abs`` and ``bias`` carry the unit of the series
passed in: metrics of a displacement in mm are in mm, of a force in N are in
N, of a resistance in ohm are in ohm. Convert the series to the display unit
*before* calling :func:`error_metrics` (tcamlab works in SI internally, the
reports and the thresholds in lab units). ``nrmse`` (rmse divided by the
range of the measured series) and ``r2`` are dimensionless, and ``n`` /
``n_nan`` are counts.

The quantity names passed to :func:`check_thresholds` carry the unit as a
suffix (``displacement_mm``, ``force_N``, ``gauge_factor_per_mm``,
``resistance_ohm``); a threshold with the same suffix (``rmse_mm``) applies
to those quantities only, so its limit is read in that unit.
"""
"""How the units of the metrics are decided (also shown in reports)."""

_THRESHOLD_METRICS = ("max_abs", "r2_min", "rmse", "mae", "bias", "nrmse")

THRESHOLD_FORMS = (
    "<metric> or <metric>_<unit> with <metric> one of "
    + ", ".join(sorted(_THRESHOLD_METRICS))
    + " and <unit> one of "
    + ", ".join(UNIT_SUFFIXES)
    + " (e.g. rmse_mm, max_abs_N, nrmse, r2_min)"
)
"""Human-readable grammar of threshold keys, used in error hints."""


# --------------------------------------------------------------------------
# metrics
# --------------------------------------------------------------------------


def _as_pair(measured, predicted) -> tuple[np.ndarray, np.ndarray]:
    try:
        m = np.asarray(measured, dtype=float)
        p = np.asarray(predicted, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"metrics: measured/predicted are not numeric ({exc})",
            "pass numeric arrays of the same shape",
        ) from None
    if m.shape != p.shape:
        raise InputError(
            f"metrics: measured has shape {m.shape} but predicted has shape {p.shape}",
            "evaluate the prediction at the measured samples",
        )
    return m.ravel(), p.ravel()


def error_metrics(measured, predicted) -> dict[str, float]:
    """Error metrics of a prediction against a measurement.

    Pairs where either value is NaN are left out and counted in ``n_nan``.
    Units follow the quantity (see :data:`METRIC_UNITS_NOTE`).

    Parameters
    ----------
    measured, predicted : array_like
        Same shape; any shape is flattened.

    Returns
    -------
    dict
        ``rmse`` sqrt(mean(e^2)), ``mae`` mean(|e|), ``max_abs`` max(|e|),
        ``bias`` mean(e), with e = predicted - measured; ``nrmse`` rmse /
        (max(measured) - min(measured)), NaN if that range is 0; ``r2`` 1 -
        SS_res / SS_tot (centred), NaN if SS_tot is 0; ``n`` number of pairs
        used and ``n_nan`` number left out (both int). With no valid pair all
        metrics are NaN.

    Raises
    ------
    InputError
        Shapes differ, values are not numeric, or a value is +-inf.
    """
    m, p = _as_pair(measured, predicted)
    nan = np.isnan(m) | np.isnan(p)
    m, p = m[~nan], p[~nan]
    n_nan = int(np.count_nonzero(nan))
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(p))):
        raise InputError(
            "metrics: measured or predicted contains +-inf",
            "replace missing samples by NaN, they are then left out",
        )
    n = int(m.size)
    if n == 0:
        out = {k: float("nan") for k in METRIC_NAMES}
        out.update(n=0, n_nan=n_nan)
        return out
    e = p - m
    abs_e = np.abs(e)
    with np.errstate(over="ignore"):  # errors beyond 1e154 give an infinite RMSE, as they should
        ss_res = float(np.dot(e, e))
    rmse = float(np.sqrt(ss_res / n))
    span = float(np.ptp(m))
    if span > 0.0:
        nrmse = rmse / span
        dm = m - m.mean()
        ss_tot = float(np.dot(dm, dm))
        r2 = 1.0 - ss_res / ss_tot if ss_tot > 0.0 else float("nan")
    else:
        nrmse = float("nan")
        r2 = float("nan")
    return {
        "rmse": rmse,
        "mae": float(abs_e.mean()),
        "max_abs": float(abs_e.max()),
        "bias": float(e.mean()),
        "nrmse": float(nrmse),
        "r2": float(r2),
        "n": n,
        "n_nan": n_nan,
    }


def pooled_metrics(pairs: Iterable[tuple[object, object]]) -> dict[str, float]:
    """:func:`error_metrics` over several (measured, predicted) pairs concatenated.

    Each pair may have its own length; within a pair the shapes must match.

    Raises
    ------
    InputError
        No pair given, or a pair fails :func:`error_metrics` validation.
    """
    pairs = list(pairs)
    if not pairs:
        raise InputError(
            "pooled_metrics: no (measured, predicted) pairs given",
            "pass at least one run",
        )
    checked = [_as_pair(m, p) for m, p in pairs]
    measured = np.concatenate([m for m, _ in checked])
    predicted = np.concatenate([p for _, p in checked])
    return error_metrics(measured, predicted)


# --------------------------------------------------------------------------
# nuisance zeros
# --------------------------------------------------------------------------

MIN_REST_ROWS = 10
"""Fewest leading rest rows a zero is estimated from; with fewer, the logged zero stands."""

ZERO_REST = "rest"
"""Zero rule (default): each run's zero from its rows at rest only, else the logged zero."""
ZERO_WHOLE_RUN = "whole-run"
"""Zero rule on request: each run's zero fitted over the whole run (each model's mean error)."""
ZERO_RULES = (ZERO_REST, ZERO_WHOLE_RUN)
"""The values of ``[validation] zero`` in an experiment file."""

ZERO_METHOD_NOTE = """\
Each run's zero (tare) of a zero-referenced channel is a nuisance parameter:
logged = true + zero + noise on every row, the first included. It is estimated
from the run's leading rows at rest only (tcamlab.kinds.rest_rows): the mean of
measured - predicted over them when there are at least MIN_REST_ROWS, its
standard error the sd of those residuals over sqrt(rows), its 95 % interval
Student-t with rows - 1 degrees of freedom. With fewer rows at rest (the static
oven test has one) the logged zero stands: a displacement logged from its first
row is referenced to that row (the model's displacement is 0 there), a load cell
is taken as logged; its uncertainty is the noise sd of the run (second
differences of the residuals) over sqrt(rows used, at least 1), reported beside
the bias, which then keeps the model's mean error. Every model of a kind is
scored after its own zero under the same rule. With [validation] zero =
"whole-run" each model's zero is instead fitted over the whole run: its bias is
0 by construction and R^2 excludes its mean error, so the unadjusted metrics
(under the rest rule) are shown beside. The RMSE is sqrt(mean(e^2)) over all n
rows (not divided by n - zeros)."""
"""How validation treats the zeros (shown in reports)."""

LOGGED_ZERO = "logged zero"
"""``ZeroEstimate.source`` of a zero that stands as logged (too few rows at rest)."""


@dataclass(frozen=True)
class ZeroEstimate:
    """One run's estimated zero of one channel, in the unit of the series.

    Attributes
    ----------
    value : float
        The zero: mean of measured - predicted over ``rows`` rows, or the logged zero.
    stderr : float
        Its standard error (sd of those residuals / sqrt(rows); for a logged zero,
        the run's noise sd / sqrt(rows)).
    ci95 : tuple of float
        95 % interval: Student-t with rows - 1 degrees of freedom, or normal for a
        logged zero.
    rows : int
        Rows it was estimated from (a logged zero: the rest rows it stands on, at least 1).
    source : str
        ``"rest rows"``, ``"logged zero"`` or ``"whole run"``.
    """

    value: float
    stderr: float
    ci95: tuple[float, float]
    rows: int
    source: str

    def scaled(self, factor: float) -> ZeroEstimate:
        """The same estimate in another unit (``factor`` units per unit)."""
        lo, hi = self.ci95
        return ZeroEstimate(
            self.value * factor, self.stderr * factor, (lo * factor, hi * factor), self.rows, self.source
        )

    def to_dict(self) -> dict:
        """JSON-safe dict: value, stderr, ci95, rows, source (NaN becomes None)."""

        def num(x):
            return float(x) if np.isfinite(x) else None

        return {
            "value": num(self.value),
            "stderr": num(self.stderr),
            "ci95": [num(self.ci95[0]), num(self.ci95[1])],
            "rows": int(self.rows),
            "source": self.source,
        }


def _mean_zero(sel: np.ndarray, source: str) -> ZeroEstimate:
    """Mean of the residuals ``sel`` with its standard error and Student-t interval."""
    k = int(sel.size)
    if k == 0:
        return ZeroEstimate(float("nan"), float("nan"), (float("nan"), float("nan")), 0, source)
    value = float(sel.mean())
    if k < 2:
        return ZeroEstimate(value, float("nan"), (float("nan"), float("nan")), k, source)
    se = float(sel.std(ddof=1)) / np.sqrt(k)
    half = float(stats.t.ppf(0.975, k - 1)) * se
    return ZeroEstimate(value, se, (value - half, value + half), k, source)


def logged_zero(residual, rest, *, first_row: bool = True) -> ZeroEstimate:
    """The zero that stands as logged, with the noise sd over sqrt(rest rows) as its sd.

    Parameters
    ----------
    residual : array_like
        One run's measured - predicted [any unit].
    rest : array_like of int
        Indices of the run's leading rows at rest (at least the first row).
    first_row : bool
        The channel is referenced to its first row (a displacement log whose model
        reads 0 there): the zero is that row's residual. Else (a load cell) the log
        is taken as it is: the zero is 0.

    Returns
    -------
    ZeroEstimate
        ``source`` "logged zero", ``rows`` the rest rows used (at least 1); the
        standard error is the noise sd of the residuals
        (:func:`tcamlab.signals.second_difference_sigma`) over sqrt(rows), NaN for
        fewer than 3 finite residuals.
    """
    from tcamlab.signals import second_difference_sigma

    r = np.asarray(residual, float)
    if not np.any(np.isfinite(r)):
        return ZeroEstimate(float("nan"), float("nan"), (float("nan"), float("nan")), 0, LOGGED_ZERO)
    value = float(r[0]) if first_row else 0.0
    rows = max(1, int(np.size(rest))) if not first_row else 1
    sd = second_difference_sigma(r[np.isfinite(r)]) / np.sqrt(rows)
    half = 1.959963984540054 * sd
    return ZeroEstimate(value, float(sd), (value - half, value + half), rows, LOGGED_ZERO)


def estimate_zero(
    measured,
    predicted,
    rest=None,
    *,
    min_rest: int = MIN_REST_ROWS,
    rule: str = ZERO_REST,
    first_row: bool = True,
) -> ZeroEstimate:
    """A run's zero: the mean of measured - predicted at rest, else the logged zero.

    See :data:`ZERO_METHOD_NOTE`. Pairs with a NaN are left out.

    Parameters
    ----------
    measured, predicted : array_like
        One run's series [any unit, the same for both].
    rest : array_like of int, optional
        Indices of the run's leading rows at rest (:func:`tcamlab.kinds.rest_rows`);
        default the first row.
    min_rest : int
        Fewest usable rest rows for a rest-row estimate.
    rule : {"rest", "whole-run"}
        :data:`ZERO_REST` (default) or :data:`ZERO_WHOLE_RUN` (the mean residual of
        every row: the model's mean error is taken away).
    first_row : bool
        With too few rest rows, the channel's logged zero is its first row
        (:func:`logged_zero`).

    Returns
    -------
    ZeroEstimate
        In the unit of the series; all NaN when no pair is usable.
    """
    m, p = _as_pair(measured, predicted)
    r = m - p
    if rule == ZERO_WHOLE_RUN:
        return _mean_zero(r[np.isfinite(r)], "whole run")
    if rule != ZERO_REST:
        raise ValueError(f"unknown zero rule {rule!r}; use one of {', '.join(ZERO_RULES)}")
    rest = np.arange(min(1, r.size)) if rest is None else np.asarray(rest, dtype=int)
    at_rest = r[rest]
    at_rest = at_rest[np.isfinite(at_rest)]
    if at_rest.size >= min_rest:
        return _mean_zero(at_rest, "rest rows")
    return logged_zero(r, rest, first_row=first_row)


# --------------------------------------------------------------------------
# thresholds
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class ThresholdCheck:
    """Outcome of one threshold applied to one quantity.

    Attributes
    ----------
    key : str
        Threshold key as written in the experiment file (``rmse_mm``).
    quantity : str
        Quantity the metric belongs to (``displacement_mm``).
    value : float
        Metric value (for ``bias`` the signed bias; the check uses |bias|).
    limit : float
        Acceptance limit.
    passed : bool
        ``value >= limit`` for ``r2_min``, ``value <= limit`` otherwise;
        False when the value is NaN or missing.
    """

    key: str
    quantity: str
    value: float
    limit: float
    passed: bool

    @property
    def metric(self) -> str:
        """Metric name of the key (``rmse``, ``r2``...)."""
        return _parse_threshold_key(self.key)[0]

    @property
    def comparison(self) -> str:
        """``">="`` for a minimum (``r2_min``), ``"<="`` otherwise."""
        return ">=" if _parse_threshold_key(self.key)[2] else "<="

    def describe(self) -> str:
        """One line such as ``displacement_mm rmse 0.42 <= 0.5: pass``."""
        from tcamlab.numbers import fmt, fmt_r2, unit_label

        metric = self.metric
        value = fmt_r2(self.value) if metric == "r2" else fmt(self.value)
        shown = f"|{value}|" if metric == "bias" else value
        unit = "" if metric in ("r2", "nrmse") else unit_label(self.quantity)
        limit = fmt(self.limit) + (f" {unit}" if unit else "")
        shown += f" {unit}" if unit else ""
        verdict = "pass" if self.passed else "FAIL"
        return f"{self.quantity} {metric} {shown} {self.comparison} {limit}: {verdict}"

    def to_dict(self) -> dict:
        """JSON-safe dict (NaN value becomes None)."""
        d = asdict(self)
        d["value"] = d["value"] if np.isfinite(d["value"]) else None
        d["passed"] = bool(d["passed"])
        return d


def quantity_unit(quantity: str) -> str | None:
    """Unit suffix of a quantity name, or None.

    ``"stroke_per_mm"`` is ``"per_mm"`` (not ``"mm"``), ``"force_N"`` is
    ``"N"``; the longest matching suffix of :data:`UNIT_SUFFIXES` wins.
    """
    for suffix in sorted(UNIT_SUFFIXES, key=len, reverse=True):
        if quantity.endswith("_" + suffix):
            return suffix
    return None


def _parse_threshold_key(key: str) -> tuple[str, str | None, bool]:
    """Split a threshold key into (metric, unit suffix or None, is_minimum)."""
    if isinstance(key, str):
        for metric in sorted(_THRESHOLD_METRICS, key=len, reverse=True):
            if key == metric:
                return _metric_of(metric), None, metric == "r2_min"
            if key.startswith(metric + "_"):
                unit = key[len(metric) + 1 :]
                if unit in UNIT_SUFFIXES:
                    return _metric_of(metric), unit, metric == "r2_min"
    hint = THRESHOLD_FORMS
    if key == "r2" or (isinstance(key, str) and key.startswith("r2_") and not key.startswith("r2_min")):
        hint = "r2 is a minimum: write r2_min; valid forms: " + THRESHOLD_FORMS
    raise ConfigError(f"unknown threshold key {key!r}", hint)


def _metric_of(threshold_metric: str) -> str:
    return "r2" if threshold_metric == "r2_min" else threshold_metric


STATUS_PASSED = "passed"
STATUS_FAILED = "failed"
STATUS_NO_LIMITS = "no limits set"
STATUSES = (STATUS_PASSED, STATUS_FAILED, STATUS_NO_LIMITS)
"""The three outcomes of a validation: every threshold met, one or more failed, or none
checked (no ``[thresholds]``, or none matching a quantity): neutral, never a pass."""


def threshold_status(checks: Iterable[ThresholdCheck]) -> str:
    """:data:`STATUS_NO_LIMITS` without checks, else passed or failed.

    A validation that checked nothing has not passed: it says so instead.
    """
    checks = list(checks)
    if not checks:
        return STATUS_NO_LIMITS
    return STATUS_PASSED if all(c.passed for c in checks) else STATUS_FAILED


def check_thresholds(
    metrics_by_quantity: Mapping[str, Mapping[str, float]],
    thresholds: Mapping[str, float],
) -> list[ThresholdCheck]:
    """Apply acceptance thresholds to metrics of several quantities.

    Convention
    ----------
    A threshold key is ``<metric>`` or ``<metric>_<unit>`` with ``<metric>``
    one of ``rmse``, ``mae``, ``max_abs``, ``bias``, ``nrmse``, ``r2_min``
    and ``<unit>`` one of ``mm``, ``N``, ``per_mm``, ``ohm``.

    * A key with a unit applies to every quantity whose name ends in that
      unit (``rmse_mm`` to ``displacement_mm``; ``mm`` does not match
      ``..._per_mm``). Its limit is in that unit, so the caller passes
      metrics already converted to the display unit of each quantity.
    * A key without a unit applies to every quantity (meant for the
      dimensionless ``nrmse`` and ``r2_min``).
    * ``r2_min`` passes when ``r2 >= limit``; every other key passes when
      ``value <= limit``, with ``|bias|`` for ``bias``.
    * A NaN or missing metric fails its check. A key that matches no
      quantity yields no check.

    Parameters
    ----------
    metrics_by_quantity : mapping
        ``{"displacement_mm": error_metrics(...), "force_N": ...}``.
    thresholds : mapping
        ``{"rmse_mm": 0.5, "r2_min": 0.9}``.

    Returns
    -------
    list of ThresholdCheck
        In threshold order, then quantity order.

    Raises
    ------
    ConfigError
        Unknown threshold key, or a limit that is not a finite number.
    """
    parsed = []
    for key, limit in thresholds.items():
        metric, unit, is_min = _parse_threshold_key(key)
        try:
            limit_f = float(limit)
        except (TypeError, ValueError):
            limit_f = float("nan")
        if not np.isfinite(limit_f) or isinstance(limit, bool):
            raise ConfigError(
                f"threshold {key!r} has limit {limit!r}, not a finite number",
                "write a number in the unit of the key suffix",
            )
        parsed.append((key, metric, unit, is_min, limit_f))

    checks: list[ThresholdCheck] = []
    for key, metric, unit, is_min, limit_f in parsed:
        for quantity, metrics in metrics_by_quantity.items():
            if unit is not None and quantity_unit(quantity) != unit:
                continue
            raw = metrics.get(metric, float("nan"))
            value = float("nan") if raw is None else float(raw)
            compared = abs(value) if metric == "bias" else value
            if not np.isfinite(compared):
                passed = False
            elif is_min:
                passed = compared >= limit_f
            else:
                passed = compared <= limit_f
            checks.append(ThresholdCheck(key, quantity, value, limit_f, bool(passed)))
    return checks


# --------------------------------------------------------------------------
# sanity checks
# --------------------------------------------------------------------------

FLAT_FRACTION = 0.01
"""A prediction is flat when its range is below this fraction of the measured range."""

ZERO_SE_LIMIT = 3.0
ZERO_NOISE_LIMIT = 3.0
"""A zero is a warning when it is beyond ZERO_SE_LIMIT standard errors (it is real) AND beyond
ZERO_NOISE_LIMIT noise sds (the sd of the residuals it was estimated from): a log re-zeroed on
one noisy row carries a zero of about one noise sd, so only a larger one points at a tare, a
reference (R0) or a model error."""

REFERENCE_TOLERANCE = 0.01
"""A resistance reference (R0) is a warning when it differs from the logged rest value by more
than this fraction of it (and by more than 3 standard errors of the rest mean)."""

STATED_SD_LIMIT = 3.0
"""A calibrated or identified parameter further than this many stated sds from its stated
value is a warning: beyond 3 sds (p < 0.003 for a Gaussian) the stated value, its stated
uncertainty, or the model is wrong."""

SANITY_CHECKS = {
    "reference-far-from-rest": f"R0 within {REFERENCE_TOLERANCE:.0%} of the logged rest value",
    "r2-below-zero": "R² ≥ 0 (the model beats the measured mean)",
    "flat-prediction": f"prediction and measurement both vary (predicted range ≥ {FLAT_FRACTION:.0%} "
    "of the measured range; a constant measurement is a dead channel)",
    "opposite-direction": "the measurement moves with the prediction (correlation >= -0.5; "
    "below, the column is likely logged with the opposite sign)",
    "zero-offset": f"each zero within {ZERO_SE_LIMIT:g} standard errors or {ZERO_NOISE_LIMIT:g} noise sds",
    "outside-domain": "every row inside the model's domain (a finite prediction)",
    "estimator-off-target": "each self-sensing estimator within its targets on every run (mean "
    "error and 95 % interval at most 2 % and 10 % of the run's stroke with the load logged, 3 % "
    "and 15 % withheld)",
    "threshold-unused": "every [thresholds] key applies to a quantity of the kind",
    "parameter-far-from-stated": "every calibrated or identified parameter within 3 stated sds "
    "of its stated value, and of the stated value's sign",
    "implausible-value": "every logged channel within what a thread muscle or sensor plausibly "
    "sees (|voltage| <= 100 V, |current| <= 5 A, |load| <= 20 N, |force| <= 100 N, "
    "temperature >= -60 degC, resistance 0.1 to 1e5 ohm; beyond, the column's unit is likely wrong)",
}
"""The sanity checks every validation runs, and what each requires (in the order warnings are
listed: a wrong reference first, as it explains the others)."""


@dataclass(frozen=True)
class SanityWarning:
    """One failed sanity check, with the numbers behind it.

    Attributes
    ----------
    check : str
        A key of :data:`SANITY_CHECKS`.
    message : str
        One line with the numbers (lab units).
    quantity, run : str or None
        What it concerns (None: pooled, or not tied to a quantity).
    values : dict
        The numbers, JSON-safe.
    """

    check: str
    message: str
    quantity: str | None = None
    run: str | None = None
    values: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-safe dict (NaN values become None)."""

        def num(x):
            if isinstance(x, (float, np.floating)):
                return float(x) if np.isfinite(x) else None
            return x

        d = asdict(self)
        d["values"] = {k: num(v) for k, v in self.values.items()}
        return d


def r2_warnings(quantity: str, block: Mapping) -> list[SanityWarning]:
    """R² below 0 pooled or in any run (``block``: {"runs": {run: metrics}, "pooled": metrics})."""
    from tcamlab.numbers import fmt_r2

    runs = {r: m["r2"] for r, m in block["runs"].items() if m["r2"] is not None and m["r2"] < 0}
    pooled = block["pooled"]["r2"]
    if not runs and not (pooled is not None and pooled < 0):
        return []
    listed = ", ".join(f"{r} {fmt_r2(v)}" for r, v in runs.items())
    msg = (
        f"{quantity}: R² below 0 (pooled {fmt_r2(pooled)}"
        + (f"; runs {listed}" if listed else "")
        + "): the model predicts worse than the measured mean"
    )
    return [SanityWarning("r2-below-zero", msg, quantity, None, {"r2_pooled": pooled, **runs})]


def dead_channel_warning(run: str, quantity: str, unit: str, measured, predicted) -> SanityWarning | None:
    """One run's constant measurement against a varying prediction (a dead or unplugged
    channel), which the pooled :func:`flat_prediction_warning` misses beside runs that vary."""
    w = flat_prediction_warning(quantity, unit, measured, predicted)
    if w is None or w.values["measured_range"] > 0:
        return None
    return SanityWarning("flat-prediction", f"{run} {w.message}", quantity, run, w.values)


def flat_prediction_warning(quantity: str, unit: str, measured, predicted) -> SanityWarning | None:
    """A prediction whose range is below :data:`FLAT_FRACTION` of a varying measurement's, or
    a constant measurement against a varying prediction (a dead channel)."""
    from tcamlab.numbers import with_unit

    m, p = _as_pair(measured, predicted)
    ok = np.isfinite(m) & np.isfinite(p)
    if not ok.any():
        return None
    span_m, span_p = float(np.ptp(m[ok])), float(np.ptp(p[ok]))
    values = {"predicted_range": span_p, "measured_range": span_m}
    if span_m <= 0.0 and span_p > 0.0:
        msg = (
            f"{quantity}: the measurement is constant ({with_unit(float(m[ok][0]), unit)} on every row) "
            f"while the prediction spans {with_unit(span_p, unit)}: a dead or unplugged channel?"
        )
        return SanityWarning("flat-prediction", msg, quantity, None, values)
    if span_m <= 0.0 or span_p >= FLAT_FRACTION * span_m:
        return None
    msg = (
        f"{quantity}: the prediction is flat: its range {with_unit(span_p, unit)} is "
        f"{span_p / span_m:.2g} of the measured range {with_unit(span_m, unit)} (below {FLAT_FRACTION:.0%})"
    )
    return SanityWarning("flat-prediction", msg, quantity, None, values)


OPPOSITE_CORRELATION = -0.5
"""A measurement whose correlation with the prediction is below this moves against the model:
a model in the right direction, however poor, correlates positively."""


def opposite_direction_warning(quantity: str, measured, predicted) -> SanityWarning | None:
    """A measurement that moves against the prediction (pooled correlation below
    :data:`OPPOSITE_CORRELATION`): a column logged with the opposite sign (a contraction
    counted positive), which calibration would otherwise absorb by flipping a parameter."""
    m, p = _as_pair(measured, predicted)
    ok = np.isfinite(m) & np.isfinite(p)
    if ok.sum() < 3 or np.ptp(m[ok]) <= 0 or np.ptp(p[ok]) <= 0:
        return None
    r = float(np.corrcoef(m[ok], p[ok])[0, 1])
    if not r < OPPOSITE_CORRELATION:
        return None
    msg = (
        f"{quantity}: the measurement moves against the model (correlation {r:+.2f}): is the column "
        "logged with the opposite sign? (a negative scale in its [columns] entry flips it)"
    )
    return SanityWarning("opposite-direction", msg, quantity, None, {"correlation": r})


def zero_offset_warning(run: str, quantity: str, unit: str, zero: ZeroEstimate) -> SanityWarning | None:
    """A zero beyond :data:`ZERO_SE_LIMIT` standard errors and :data:`ZERO_NOISE_LIMIT` noise sds."""
    from tcamlab.numbers import fmt, with_unit

    if not (np.isfinite(zero.value) and np.isfinite(zero.stderr)) or zero.stderr <= 0:
        return None
    noise = zero.stderr * np.sqrt(zero.rows)
    if abs(zero.value) <= ZERO_SE_LIMIT * zero.stderr or abs(zero.value) <= ZERO_NOISE_LIMIT * noise:
        return None
    msg = (
        f"{run} {quantity}: zero offset {with_unit(zero.value, unit)} ({fmt(abs(zero.value) / zero.stderr, 3)} "
        f"standard errors, {fmt(abs(zero.value) / noise, 3)} noise sds of {with_unit(noise, unit)}; "
        f"{zero.source}): a tare, a reference (R0) or the model is off"
    )
    values = {"zero": zero.value, "stderr": zero.stderr, "noise_sd": noise, "rows": zero.rows}
    return SanityWarning("zero-offset", msg, quantity, run, values)


def reference_warning(run: str, name: str, used: float, source: str, rest) -> SanityWarning | None:
    """A resistance reference ``used`` [ohm] far from the mean of the logged ``rest`` values [ohm]."""
    from tcamlab.numbers import fmt

    rest = np.asarray(rest, dtype=float)
    rest = rest[np.isfinite(rest)]
    if rest.size == 0 or not np.isfinite(used):
        return None
    mean = float(rest.mean())
    se = float(rest.std(ddof=1) / np.sqrt(rest.size)) if rest.size > 1 else 0.0
    diff = used - mean
    if abs(diff) <= REFERENCE_TOLERANCE * abs(mean) or abs(diff) <= 3.0 * se:
        return None
    msg = (
        f"{run}: {name} = {fmt(used)} ohm ({source}) is {diff / mean:+.1%} from the logged rest value "
        f"{fmt(mean)} ohm (mean of {rest.size} rows at rest)"
    )
    values = {"used_ohm": used, "rest_ohm": mean, "rest_rows": int(rest.size), "relative": diff / mean}
    return SanityWarning("reference-far-from-rest", msg, name, run, values)


def unused_threshold_warnings(thresholds: Mapping[str, float], checks, quantities) -> list[SanityWarning]:
    """A ``[thresholds]`` key that matched no quantity checked nothing (``rmse_N`` on a static test)."""
    used = {c.key for c in checks}
    return [
        SanityWarning(
            "threshold-unused",
            f"threshold {key} = {limit} applies to no quantity of this experiment "
            f"({', '.join(quantities)}): nothing was checked against it",
            None,
            None,
            {"key": key},
        )
        for key, limit in thresholds.items()
        if key not in used
    ]


def domain_warning(
    run: str, quantity: str, outside: int, rows: int, model: str | None = None
) -> SanityWarning | None:
    """Rows of a run where the model (the primary one, or ``model``) gives no finite prediction
    (outside its domain, or an estimator that diverged)."""
    if outside <= 0:
        return None
    who = f"{model}: " if model else ""
    msg = (
        f"{who}{run} {quantity}: {outside} of {rows} rows outside the model's domain (no finite "
        "prediction); left out of the metrics"
    )
    values = {"rows_outside": outside, "rows": rows, **({"model": model} if model else {})}
    return SanityWarning("outside-domain", msg, quantity, run, values)


PLAUSIBLE_MAX = {
    "voltage": (100.0, "V", "mV"),
    "current": (5.0, "A", "mA"),
    "load": (20.0, "N", "gf"),
    "force": (100.0, "N", "mN"),
}
"""Largest |value| [SI] a channel of a thread muscle or sensor plausibly logs, its unit, and the
unit a log that far above it is most likely in: a muscle driven at 1496 V or loaded with 50 N
is a log in mV or grams read as V or N, and the model then fails far downstream, or fits
a wrong parameter, with no word about the unit."""

PLAUSIBLE_RESISTANCE_OHM = (0.1, 1e5)
"""Range of a logged resistance [ohm] a thread muscle or sensor plausibly shows (the thesis's
are 24-30 ohm; silver-coated threads run from about 1 to some thousand ohm): a 30 ohm sensor
logged in kohm and read as ohm reads 0.03, one in mohm reads 30,000."""

RESISTANCE_COLUMNS = ("resistance", "r1", "r2")
"""The channels :data:`PLAUSIBLE_RESISTANCE_OHM` applies to (curvature's two sensors too)."""

PLAUSIBLE_MIN_C = -60.0
"""Lowest temperature [degC] a muscle or sensor test plausibly logs: a column in degF read as K
starts near -200 degC."""


def _implausible_resistances(run: str, data: Mapping) -> list[SanityWarning]:
    """A resistance channel whose median is outside :data:`PLAUSIBLE_RESISTANCE_OHM`."""
    lo, hi = PLAUSIBLE_RESISTANCE_OHM
    out = []
    for name in RESISTANCE_COLUMNS:
        if name not in data:
            continue
        typical = float(np.nanmedian(np.asarray(data[name], float)))
        if lo <= typical <= hi or not np.isfinite(typical):
            continue
        likely = "kohm" if typical < lo else "mohm"
        msg = (
            f"{run}: {name} is typically {typical:.4g} ohm, outside the {lo:g} to {hi:g} ohm a thread "
            f'muscle or sensor plausibly shows: is the column in {likely}? (unit = "{likely}" in its '
            "[columns] entry)"
        )
        out.append(
            SanityWarning("implausible-value", msg, name, run, {"median": typical, "low": lo, "high": hi})
        )
    return out


def implausible_value_warnings(run: str, data: Mapping) -> list[SanityWarning]:
    """A warning per channel of a run's ``data`` [SI] beyond :data:`PLAUSIBLE_MAX` or below
    :data:`PLAUSIBLE_MIN_C` (the column's unit is likely wrong)."""
    out = []
    for name, (limit, unit, likely) in PLAUSIBLE_MAX.items():
        if name not in data:
            continue
        peak = float(np.nanmax(np.abs(np.asarray(data[name], float)), initial=0.0))
        if peak > limit:
            msg = (
                f"{run}: {name} reaches {peak:.4g} {unit}, beyond the {limit:g} {unit} a thread "
                f'muscle or sensor plausibly sees: is the column in {likely}? (unit = "{likely}" in its '
                "[columns] entry)"
            )
            out.append(SanityWarning("implausible-value", msg, name, run, {"peak": peak, "limit": limit}))
    out += _implausible_resistances(run, data)
    if "temperature" in data:
        low = float(np.nanmin(np.asarray(data["temperature"], float), initial=np.inf))
        if low < PLAUSIBLE_MIN_C:
            msg = (
                f"{run}: temperature falls to {low:.4g} degC, below the {PLAUSIBLE_MIN_C:g} degC "
                'a muscle test plausibly sees: is the column in another unit? (unit = "degF" or "K" '
                "in its [columns] entry, as the log is)"
            )
            values = {"lowest": low, "limit": PLAUSIBLE_MIN_C}
            out.append(SanityWarning("implausible-value", msg, "temperature", run, values))
    return out


def opposite_sign_warning(
    name: str, value: float, stated: float, unit: str, source: str
) -> SanityWarning | None:
    """A calibrated or identified parameter of the opposite sign to its (non-zero) stated value,
    whatever its stated sd: the model's response to it is then reversed (a swelling fiber made
    to shrink, a modulus made to grow with temperature), which fits a log whose sign is
    flipped as well as the right one fits the right log; None otherwise.

    Parameters
    ----------
    name : str
        The parameter, e.g. ``"sample.radial_cte_per_K (rho)"``.
    value, stated : float
        Calibrated or identified value and stated value [``unit``].
    unit, source : str
        The lab unit; where ``value`` came from.
    """
    from tcamlab.numbers import fmt

    if not (np.isfinite(value) and np.isfinite(stated)) or stated == 0 or value * stated >= 0:
        return None
    u = f" {unit}" if unit and unit != "-" else ""
    msg = (
        f"{name} = {fmt(value)}{u} ({source}) has the opposite sign to the stated {fmt(stated)}{u}: "
        "the model's response to it is reversed; is a logged column's sign flipped? (a negative "
        "scale in its [columns] entry flips it back)"
    )
    return SanityWarning("parameter-far-from-stated", msg, name, None, {"value": value, "stated": stated})


def stated_shift_warning(
    name: str, value: float, stated: float, stated_sd: float | None, unit: str, source: str
) -> SanityWarning | None:
    """A calibrated or identified parameter more than :data:`STATED_SD_LIMIT` stated sds from
    its stated value (all in the lab ``unit``); None without a stated sd.

    Parameters
    ----------
    name : str
        The parameter, e.g. ``"rig.thermal_mass_J_per_K (C_th)"``.
    value, stated, stated_sd : float
        Calibrated or identified value, stated value and stated sd [``unit``].
    source : str
        Where ``value`` came from (``"calibrated, NAME.calibrated.toml"``).
    """
    from tcamlab.numbers import fmt

    flipped = opposite_sign_warning(name, value, stated, unit, source)
    if flipped is not None:
        return flipped
    if stated_sd is None or not (np.isfinite(stated_sd) and stated_sd > 0) or not np.isfinite(value):
        return None
    shift = (value - stated) / stated_sd
    if abs(shift) <= STATED_SD_LIMIT:
        return None
    u = f" {unit}" if unit and unit != "-" else ""
    msg = (
        f"{name} = {fmt(value)}{u} ({source}) is {shift:+.1f} stated sds from the stated "
        f"{fmt(stated)}{u} (sd {fmt(stated_sd)}{u}; limit {STATED_SD_LIMIT:g}): the stated value, "
        "its uncertainty or the model is off"
    )
    values = {"value": value, "stated": stated, "stated_sd": stated_sd, "shift_in_stated_sds": shift}
    return SanityWarning("parameter-far-from-stated", msg, name, None, values)
