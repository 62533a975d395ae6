"""The one number-format policy of tcamlab's text output, HTML and PDF reports.

- :func:`fmt`: 4 significant digits, trailing zeros dropped; positional between
  1e-3 and 1e6 (``0.00609``, ``133.5``, ``12350``), scientific outside
  (``8.614e-05``, ``8.1e-05``); never ``-0``.
- :func:`fmt_column`: a table column in one notation (never ``8.614e-05`` next
  to ``0.00609``).
- :func:`fmt_r2`: R² with 4 decimals (``0.9989``, ``-81.2065``); a value that
  4 decimals would round onto 1 (or 0) gets the decimals it needs to differ
  from it (``0.99998``), so a model short of perfect never prints as perfect.
- :func:`fmt_percent`: whole percent by default, never ``-0%``; :func:`fmt_percent_range`
  adds the decimals that keep an interval's two ends apart.
- :func:`fmt_interval`: a value and its interval with the digits that keep them apart
  (``10.1 (95 % 10.098 to 10.102)``, not ``10.1 to 10.1``).
- :func:`shift_text`: a recalibrated parameter's shift, ``+1.4 stated sds`` (or prior
  sds when the file states none); below 0.1 one significant digit (``+0.03``), not ``+0.0``.
- :func:`with_unit`: a value and its unit (``0.0123 mm``); every printed RMSE,
  MAE, max |err| and bias carries one (:func:`unit_label` of the quantity).

Missing values print as an en dash, NaN as ``NaN``.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "MISSING",
    "SIG_DIGITS",
    "R2_DECIMALS",
    "fmt",
    "fmt_r2",
    "fmt_percent",
    "fmt_percent_range",
    "percent_decimals",
    "with_unit",
    "unit_label",
    "bare_name",
    "rmse_unit",
    "lab_unit",
    "shift_text",
    "stated_label",
    "reading_text",
    "fmt_interval",
]

MISSING = "\u2013"
SIG_DIGITS = 4
R2_DECIMALS = 4
_MAX_DECIMALS = 8
_UNIT_LABELS = {"mm": "mm", "N": "N", "per_mm": "1/mm", "ohm": "ohm"}
_RMSE_UNITS = {"N": ("mN", 1e3), "1/mm": ("1/m", 1e3)}
"""Display unit -> (unit, factor) an RMSE or residual prints in: a load-cell residual is a few
mN and a curvature residual a few 1/m, so neither prints as 0.00123."""
_LAB_UNITS = {
    "m": ("mm", 1e3),
    "m/s": ("um/s", 1e6),
    "Pa": ("MPa", 1e-6),
    "Pa/K": ("MPa/K", 1e-6),
    "N": ("mN", 1e3),
    "-": ("", 1.0),
}
"""SI unit of a fitted parameter -> (lab unit, factor): slack in mm, drift in um/s."""


def _special(x) -> str | None:
    if x is None:
        return MISSING
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        return str(x)
    if math.isnan(float(x)):
        return "NaN"
    if math.isinf(float(x)):
        return "inf" if x > 0 else "-inf"
    return None


def _no_negative_zero(text: str) -> str:
    """``-0``, ``-0.000`` and ``-0%`` lose their sign (the value rounded to zero)."""
    if text.startswith("-") and not any(c in "123456789" for c in text.split("e")[0]):
        return text[1:]
    return text


def fmt(x, sig: int = SIG_DIGITS) -> str:
    """A number with ``sig`` significant digits (see the module docstring).

    Parameters
    ----------
    x : float, int or None
    sig : int
        Significant digits.
    """
    special = _special(x)
    if special is not None:
        return special
    if isinstance(x, numbers.Integral):
        return str(int(x))
    v = float(x)
    if v != 0.0 and not (1e-3 <= abs(v) < 1e6):
        mantissa, exponent = f"{v:.{sig - 1}e}".split("e")
        mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
        return _no_negative_zero(f"{mantissa}e{exponent}")
    text = np.format_float_positional(v, precision=sig, unique=False, fractional=False, trim="-")
    return _no_negative_zero(text)


def _is_float(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, numbers.Integral)) and math.isfinite(x)


def fmt_column(values, sig: int = SIG_DIGITS) -> list[str]:
    """:func:`fmt` of a table column, in one notation for the whole column: positional when
    the column mixes small and ordinary values that positional notation shows in full
    (``0.0001``, ``0.00094``, ``0.00108``, not ``1e-04`` next to ``0.00108``), else scientific
    for every value when any needs it. Non-float entries are formatted alone."""
    sizes = [abs(float(v)) for v in values if _is_float(v) and v != 0]
    if not sizes or all(1e-3 <= x < 1e6 for x in sizes):
        return [fmt(v, sig) for v in values]
    positional = min(sizes) >= 1e-5 and max(sizes) < 1e6
    out = []
    for v in values:
        if not _is_float(v) or v == 0:
            out.append(fmt(v, sig))
        elif positional:
            text = np.format_float_positional(
                float(v), precision=sig, unique=False, fractional=False, trim="-"
            )
            out.append(_no_negative_zero(text))
        else:
            mantissa, exponent = f"{float(v):.{sig - 1}e}".split("e")
            mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
            out.append(_no_negative_zero(f"{mantissa}e{exponent}"))
    return out


def fmt_r2(r2, decimals: int = R2_DECIMALS) -> str:
    """R² with ``decimals`` decimals, more where that would round a value onto 1 or 0."""
    special = _special(r2)
    if special is not None:
        return special
    v = float(r2)
    for d in range(decimals, _MAX_DECIMALS + 1):
        text = f"{v:.{d}f}"
        if (float(text) != 1.0 or v == 1.0) and (float(text) != 0.0 or v == 0.0):
            return text
    return f">{1.0 - 10.0**-_MAX_DECIMALS:.{_MAX_DECIMALS}f}" if v > 0.5 else f"{v:.{_MAX_DECIMALS}e}"


def fmt_percent(fraction, decimals: int = 0) -> str:
    """A fraction as percent (``0.123`` -> ``12%``), never ``-0%``."""
    special = _special(fraction)
    if special is not None:
        return special
    return _no_negative_zero(f"{100.0 * float(fraction):.{decimals}f}%")


def percent_decimals(lo, hi) -> int:
    """Decimals (0 to 2) that print ``lo`` and ``hi`` as different percents, if any do."""
    if _special(lo) is not None or _special(hi) is not None:
        return 0
    for d in (0, 1, 2):
        if fmt_percent(lo, d) != fmt_percent(hi, d):
            return d
    return 2


def fmt_percent_range(lo, hi) -> str:
    """``lo to hi`` in percent, with the decimals (up to 2) that keep distinct ends distinct:
    an interval of -0.15 % to -0.01 % prints as ``-0.1% to 0.0%``, never ``0% to 0%``."""
    d = percent_decimals(lo, hi)
    return f"{fmt_percent(lo, d)} to {fmt_percent(hi, d)}"


def unit_label(quantity: str) -> str:
    """The unit of a quantity column as printed (``displacement_mm`` -> ``mm``,
    ``kappa1_per_mm`` -> ``1/mm``); empty when the name carries none."""
    for suffix in sorted(_UNIT_LABELS, key=len, reverse=True):
        if quantity.endswith("_" + suffix):
            return _UNIT_LABELS[suffix]
    return ""


def bare_name(quantity: str) -> str:
    """A quantity column without its unit suffix (``kappa1_per_mm`` -> ``kappa1``)."""
    for suffix in sorted(_UNIT_LABELS, key=len, reverse=True):
        if quantity.endswith("_" + suffix):
            return quantity[: -len(suffix) - 1]
    return quantity


def with_unit(x, unit: str, sig: int = SIG_DIGITS) -> str:
    """``fmt(x)`` followed by its unit (nothing appended to a missing value)."""
    text = fmt(x, sig)
    return f"{text} {unit}" if unit and text not in (MISSING, "NaN") else text


def rmse_unit(unit: str) -> tuple[str, float]:
    """(unit, factor from ``unit``) an RMSE or residual in display ``unit`` is printed in
    (``"N"`` -> ``("mN", 1e3)``, ``"1/mm"`` -> ``("1/m", 1e3)``; others unchanged)."""
    return _RMSE_UNITS.get(unit, (unit, 1.0))


def lab_unit(si_unit: str) -> tuple[str, float]:
    """(lab unit, factor from SI) of a fitted parameter's SI unit (``"m"`` -> ``("mm", 1e3)``,
    ``"m/s"`` -> ``("um/s", 1e6)``; a dimensionless ``"-"`` -> ``("", 1.0)``: no unit printed)."""
    return _LAB_UNITS.get(si_unit, (si_unit, 1.0))


def shift_text(p: dict) -> str:
    """A recalibrated parameter's shift from its stated value in words (see the module docstring).

    ``p`` holds ``shift_in_stated_sds`` (None when the file states no sd) and
    ``shift_in_prior_sds``."""
    stated = p.get("shift_in_stated_sds")
    x, what = (stated, "stated sds") if stated is not None else (p["shift_in_prior_sds"], "prior sds")
    return f"{x:+.1f} {what}" if abs(x) >= 0.1 or x == 0 else f"{x:+.1g} {what}"


def stated_label(p: dict) -> str:
    """ "stated", or what stands for it when the file states no value (``p["stated_in_file"]``
    False: the kind's rule on the logs, e.g. R0 from the rows at rest)."""
    return "stated" if p.get("stated_in_file", True) else "not stated; the logs' rule gives"


def reading_text(p: dict, factor: float = 1.0, unit: str = "") -> str:
    """``"; read at rest 10 ohm (sd 0.0013)"`` for a recalibrated parameter the logs read
    directly (``p["reading"]`` holds its mean and sd in SI units, shown times ``factor`` in
    ``unit``), else ''."""
    reading = p.get("reading")
    if not reading:
        return ""
    unit = f" {unit}" if unit else ""
    return f"; read at rest {fmt(reading[0] * factor)}{unit} (sd {fmt(reading[1] * factor)})"


MAX_INTERVAL_DIGITS = 10
"""Most significant digits :func:`fmt_interval` adds to keep an interval's ends apart."""


def fmt_interval(value, lo, hi, sig: int = SIG_DIGITS) -> tuple[str, str, str]:
    """``(value, lo, hi)`` formatted with the fewest significant digits (at least ``sig``, at
    most :data:`MAX_INTERVAL_DIGITS`) at which the three that differ still print apart: a
    pinned R0 of 10.1 ohm has the interval 10.098 to 10.102, which 4 digits print as
    10.1 to 10.1."""
    pairs = ((value, lo, 0, 1), (value, hi, 0, 2), (lo, hi, 1, 2))
    for k in range(sig, MAX_INTERVAL_DIGITS + 1):
        out = (fmt(value, k), fmt(lo, k), fmt(hi, k))
        if all(a == b or out[i] != out[j] for a, b, i, j in pairs):
            return out
    return out
